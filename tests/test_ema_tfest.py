"""Rational transfer-function fit: exact recovery, noise, model order."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TABLE3

from bayesmodal._errors import DataError
from bayesmodal.ema import FRF, tfest
from bayesmodal.model.system import LinearModel, Rig


def rig_frf(w, theta=TABLE3):
    model = LinearModel(Rig(), "free")
    A, B = model.state_space(theta)
    return np.array([np.linalg.solve(1j * wi * np.eye(6) - A, B)[:3] for wi in w]), A


def test_exact_rig_transfer_function():
    w = np.linspace(2, 60, 600)
    H, A = rig_frf(w)
    fit = tfest(FRF(w, H), 6, n_zeros=4)
    lam = np.linalg.eigvals(A)
    lam = np.sort_complex(lam[lam.imag > 0])
    est = fit.estimate
    np.testing.assert_allclose(np.sort_complex(est.poles), lam, rtol=1e-7)
    assert fit.relative_error < 1e-8
    np.testing.assert_allclose(fit.frf(w), H, rtol=1e-6)
    # mode shapes = residue columns normalised on cart 1 = model's complex modes
    from bayesmodal.modal import complex_modes

    cm = complex_modes(A)
    np.testing.assert_allclose(est.mode_shapes, np.asarray(cm.shapes).T, rtol=1e-5)


def test_noisy_rig_and_overfit_order():
    rng = np.random.default_rng(5)
    w = np.linspace(2, 60, 600)
    H, A = rig_frf(w)
    noisy = H * (1 + 0.01 * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)))
    lam = np.linalg.eigvals(A)
    lam = np.sort_complex(lam[lam.imag > 0])
    for n_poles in (6, 10):
        est = tfest(FRF(w, noisy), n_poles).estimate
        phys = est.poles[est.identified]
        assert phys.size >= 3
        k = [np.argmin(np.abs(phys - x)) for x in lam]
        np.testing.assert_allclose(np.abs(phys[k]), np.abs(lam), rtol=0.005)
        np.testing.assert_allclose(-phys[k].real / np.abs(phys[k]), -lam.real / np.abs(lam),
                                   rtol=0.1)


def test_underfit_order_misses_a_mode():
    w = np.linspace(2, 60, 600)
    H, A = rig_frf(w)
    est = tfest(FRF(w, H), 4).estimate  # two modes for three resonances
    assert est.identified.sum() <= 2


def test_validation():
    w = np.linspace(1, 2, 10)
    with pytest.raises(DataError, match="n_poles"):
        tfest(FRF(w, np.ones(10)), 0)
    with pytest.raises(DataError, match="too few"):
        tfest(FRF(w[:2], np.ones(2)), 8)
