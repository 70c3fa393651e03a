"""The posterior-mode search (``bayesmodal.inference.mode``): the extension's optimiser
coordinates, the alternative starts, and the mode of a known truth from a fit that ends on
the face ``Fs = Fc``, where the Stribeck speed does nothing."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TABLE3
from reference_effects import simulate_lugre_ref
from scipy import stats

from bayesmodal.data import ECP_M_PER_COUNT, Experiment
from bayesmodal.inference.likelihood import Likelihood
from bayesmodal.inference.mode import _OptCoordinates, posterior_mode
from bayesmodal.inference.priors import default_priors
from bayesmodal.inference.sampling import LogPosterior
from bayesmodal.model.effects import EXTENSIONS, get_extension
from bayesmodal.model.system import LinearModel, Rig

RIG = Rig()
DT = 0.005
COUNT = ECP_M_PER_COUNT
# a pronounced Stribeck bump on every cart (N, N/m, N s/m, m/s)
LUGRE = np.array([0.1, 0.15, 0.08, 0.45, 0.5, 0.38, 2e4, 100.0, 0.004])


def _record(seed=0, n=400):
    """Pulses and held steps through LuGre friction, from the independent stiff-ODE
    reference, with white noise of one count and quantisation."""
    u = np.zeros(n)
    u[1:10], u[100:180], u[220:228], u[300:360] = 3.0, 0.6, -2.5, -0.7
    y = simulate_lugre_ref(RIG.springs_n_m, np.r_[TABLE3, LUGRE], u, DT)
    rng = np.random.default_rng(seed)
    y = np.round((y + COUNT * rng.standard_normal(y.shape)) / COUNT) * COUNT
    return Experiment(np.arange(n) * DT, u, y, name="pulses")


def _log_post(exp, extension="lugre_friction"):
    model = LinearModel(RIG, "free")
    lik = Likelihood(model, [exp], "white", extension)
    return LogPosterior(lik, default_priors(model, noise="white", extension=lik.extension))


def test_optimiser_coordinates_turn_the_static_level_into_the_excess():
    lp = _log_post(_record(n=60), "lugre_friction+input_offset")
    pri = lp.priors
    coords = _OptCoordinates(lp.likelihood, pri)
    theta = np.r_[TABLE3, LUGRE, 0.02, np.full(3, 1.2 * COUNT)]
    z = pri.to_sampling(theta[None])
    u = coords.to_u(z)
    fs = [pri.names.index(f"Fs{i}") for i in (1, 2, 3)]
    fc = [pri.names.index(f"Fc{i}") for i in (1, 2, 3)]
    np.testing.assert_allclose(u[0, fs], LUGRE[3:6] - LUGRE[:3], rtol=1e-14)
    others = np.setdiff1d(np.arange(pri.n_params), fs)
    assert np.array_equal(u[0, others], z[0, others])
    np.testing.assert_allclose(coords.to_z(u), z, rtol=0, atol=1e-15)
    assert np.array_equal(u[0, fc], LUGRE[:3])
    # without an extension: the identity
    lin = _log_post(_record(n=60), None)
    c0 = _OptCoordinates(lin.likelihood, lin.priors)
    z0 = lin.priors.to_sampling(np.r_[TABLE3, np.full(3, COUNT)][None])
    assert c0.ext is None and np.array_equal(c0.to_u(z0), z0)


def test_lugre_mode_starts_put_a_stribeck_bump_on_the_fit_and_combined_keeps_the_rest():
    ext = EXTENSIONS["lugre_friction"]
    fit = np.r_[0.2, 0.07, 0.21, 0.2, 0.07, 0.21, 3e3, 14.0, 2e-4]
    rows = ext.mode_starts(RIG, fit)
    assert rows.shape == (len(ext.STRIBECK_STARTS), 9)
    for r, (vs, excess) in zip(rows, ext.STRIBECK_STARTS, strict=True):
        np.testing.assert_allclose(r[3:6] - r[:3], excess)
        assert r[8] == vs and np.array_equal(r[[0, 1, 2, 6, 7]], fit[[0, 1, 2, 6, 7]])
        assert ext.valid(RIG, np.r_[TABLE3, r])
    both = get_extension("drive_deadband+lugre_friction+input_offset")
    theta_ext = np.r_[0.015, fit, 0.01]
    rows2 = both.mode_starts(RIG, theta_ext)
    np.testing.assert_array_equal(rows2[:, 1:10], rows)
    assert np.all(rows2[:, 0] == 0.015) and np.all(rows2[:, 10] == 0.01)
    # extensions without a degenerate face give none
    assert EXTENSIONS["coulomb_friction"].mode_starts(RIG, fit[:6]).shape == (0, 6)


@pytest.mark.parametrize("seed", [0, 1])
def test_mode_search_from_the_face_fs_equal_fc_reaches_the_known_truths_mode(seed):
    """A fit that ends on ``Fs = Fc`` with a tiny Stribeck speed (as least squares does on
    the measured records).  At the maximiser the log posterior exceeds the truth's by
    ``chi2_P / 2`` (Wilks), so it must exceed it by more than the 1e-4 quantile of that;
    the start is far below (the check cannot pass by staying put)."""
    exp = _record(seed)
    lp = _log_post(exp)
    pri = lp.priors
    truth = np.r_[TABLE3, LUGRE, np.full(3, np.sqrt(1 + 1 / 12) * COUNT)]
    start = truth.copy()
    start[[pri.names.index(f"Fs{i}") for i in (1, 2, 3)]] = LUGRE[:3]
    start[pri.names.index("v_stribeck")] = 2e-4

    def value(theta):
        return float(lp(pri.to_sampling(np.atleast_2d(theta)))[0, 0])

    wilks = stats.chi2.ppf(1e-4, pri.n_params) / 2
    assert value(start) < value(truth) - 10 * wilks  # a control: the start is far off
    mode = posterior_mode(lp, start)
    assert value(mode) > value(truth) + wilks
