"""Peer check: sdypy-EMA's LSCF on the same FRFs as our LSCE (optional dependency)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from conftest import TABLE3

from bayesmodal.data import Experiment
from bayesmodal.ema import frf_from_experiment, identify
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig


def _pyema():
    for name in ("sdypy.EMA", "pyEMA"):
        try:
            return importlib.import_module(name)
        except ImportError:
            continue
    pytest.skip("sdypy-EMA is not installed (pip install 'bayesmodal[peer]' to run this check)")


def lscf_poles(frf, *, order: int = 20, f_max_hz: float = 10.0) -> np.ndarray:
    """Stable poles (Im > 0) of sdypy-EMA's LSCF at one polynomial order, 1/s."""
    pyEMA = _pyema()
    f = frf.omega_rad_s / (2 * np.pi)
    sel = f <= f_max_hz
    freq = np.r_[0.0, f[sel]]  # sdypy expects a grid from 0 Hz
    H = np.column_stack([frf.H[sel][0].real[:, None], frf.H[sel].T])  # (n_outputs, n_freq)
    model = pyEMA.Model(frf=H, freq=freq, lower=0.5, upper=freq[-1], pol_order_high=order,
                        frf_form="receptance")
    model.get_poles(method="lscf", show_progress=False)
    p = np.asarray(model.all_poles[-1])
    return p[(p.imag > 0) & (p.real < 0)]


def test_lscf_agrees_with_lsce_on_simulated_rig():
    _pyema()
    model = LinearModel(Rig(), "free")
    dt = 0.005
    u = np.zeros(7401)
    for s in range(1, 7380, 2000):
        u[s : s + 9] = 3.0006
        u[s + 9] = 2.25045
    y = simulate_linear(model, TABLE3, u, dt)
    rng = np.random.default_rng(20240601)
    exp = Experiment(np.arange(u.size) * dt, u, y + 1e-4 * rng.standard_normal(y.shape))
    ours = identify(exp, "lsce").estimate.physical()
    assert ours.n_modes == 3
    theirs = lscf_poles(frf_from_experiment(exp))
    k = [np.argmin(np.abs(np.abs(theirs) - w)) for w in ours.omega_rad_s]
    np.testing.assert_allclose(np.abs(theirs[k]), ours.omega_rad_s, rtol=0.01)
    np.testing.assert_allclose(-theirs[k].real / np.abs(theirs[k]), ours.zeta, rtol=0.15)
