"""Propagation of posterior draws to modal quantities, and interval summaries."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS, eig_rtol, match_eigs, modal_backward, shape_atol
from scipy import stats

from bayesmodal.inference.idata import arviz
from bayesmodal.inference.propagate import (
    credible_interval,
    hdi,
    modal_intervals,
    propagate_modes,
)
from bayesmodal.modal import proportional_modal_damping, undamped_modes
from bayesmodal.model.system import LinearModel, Rig


def _draws(model, centre, n=500, rel=0.02, seed=0):
    rng = np.random.default_rng(seed)
    return np.abs(centre * (1 + rel * rng.standard_normal((n, centre.size))))


def test_matrix_iteration_rayleigh_and_eigenproblem_agree_draw_by_draw():
    from conftest import TABLE3

    model = LinearModel(Rig(), "free")
    draws = _draws(model, TABLE3, n=400)
    ms = propagate_modes(model, draws)
    assert ms.omega_rad_s.shape == (400, 3)
    # each method within its own error bound of the exact modes, draw by draw
    M, _, K, _ = model.matrices(draws)
    w2 = ms.omega_rad_s**2
    bound = {m: eig_rtol(M, K, w2, backward=modal_backward(m, K)) + eig_rtol(M, K, w2)
             for m in ("iteration", "rayleigh")}
    assert np.all(np.abs(ms.omega_iteration_rad_s / ms.omega_rad_s - 1) <= bound["iteration"])
    assert np.all(np.abs(ms.omega_rayleigh_rad_s / ms.omega_rad_s - 1) <= bound["rayleigh"])
    assert np.all(np.abs(ms.shapes_iteration - ms.shapes)
                  <= shape_atol("iteration", M, K, w2, ms.shapes))
    assert ms.max_method_difference() <= max(np.max(b) for b in bound.values())
    # negative control: a different draw set differs
    other = propagate_modes(model, _draws(model, TABLE3, n=400, seed=1), methods=("eig",))
    assert not np.allclose(other.omega_rad_s, ms.omega_rad_s)


def test_frequencies_are_the_closed_form_of_a_two_cart_chain():
    """Two equal masses m, springs k (link) and k (ground): omega^2 = k(3 -+ sqrt 5)/(2m)."""
    model = LinearModel(Rig((100.0, 100.0)), "proportional")
    m = np.array([0.5, 1.0, 2.0])
    theta = np.column_stack([np.ones(3) * 5, m, m, np.ones(3), np.zeros(3)])
    ms = propagate_modes(model, theta)
    k = 100.0
    exact = np.sqrt(k * np.array([3 - np.sqrt(5), 3 + np.sqrt(5)])[None] / (2 * m[:, None]))
    # eigh's bound and the closed form's few roundings
    M, _, K, _ = model.matrices(theta)
    rtol = eig_rtol(M, K, exact**2) + 8 * EPS
    assert np.all(np.abs(ms.omega_rad_s / exact - 1) <= rtol)


def test_proportional_damping_ratios_match_the_modal_formula():
    model = LinearModel(Rig(), "proportional")
    centre = np.array([6.2, 1.57, 1.46, 1.14, 1.6, 1e-4])
    draws = _draws(model, centre, n=200)
    ms = propagate_modes(model, draws, methods=("eig",))
    formula = proportional_modal_damping(ms.omega_rad_s, draws[:, 4], draws[:, 5])
    # the state matrix's eigenvalues move by match_eigs (their condition number times
    # n eps ||A||): zeta = -Re l / |l| by at most 2 |dl| / |l|, Im l by |dl|; the formula
    # carries the frequencies' own bound
    A, _ = model.state_space(draws)
    lam = -formula.zeta * ms.omega_rad_s + 1j * formula.damped_rad_s
    dl = match_eigs(A, lam)
    M, _, K, _ = model.matrices(draws)
    sym = eig_rtol(M, K, ms.omega_rad_s**2)
    assert np.all(np.abs(ms.zeta / formula.zeta - 1)
                  <= 2 * dl / (ms.omega_rad_s * formula.zeta) + sym)
    assert np.all(np.abs(ms.damped_rad_s / formula.damped_rad_s - 1)
                  <= dl / formula.damped_rad_s + sym)


def test_mac_to_reference_is_one_at_the_reference_and_below_elsewhere():
    from conftest import TABLE3

    model = LinearModel(Rig(), "free")
    draws = np.vstack([TABLE3, TABLE3 * np.r_[1, 1.3, 0.7, 1, 1, 1, 1, 1, 1]])
    ms = propagate_modes(model, draws, reference=TABLE3, methods=("eig",))
    assert np.allclose(ms.mac_reference[0], 1.0)
    assert np.all(ms.mac_reference[1] < 1.0)


def test_credible_interval_of_normal_draws_matches_closed_form():
    n = 200_000
    x = np.random.default_rng(4).normal(3.0, 2.0, size=(n, 2))
    iv = credible_interval(x, 0.9)
    q = stats.norm.ppf(0.95) * 2.0
    # standard error of a sample quantile: sqrt(p (1-p) / n) / pdf(quantile)
    se = np.sqrt(0.05 * 0.95 / n) / stats.norm.pdf(stats.norm.ppf(0.95), scale=2.0)
    assert np.all(np.abs(iv.hi - (3 + q)) < 4 * se)
    assert np.all(np.abs(iv.lo - (3 - q)) < 4 * se)
    # for a symmetric unimodal density the HDI is the equal-tailed interval; its end points
    # wander along the flat minimum of the width, so compare the width (the HDI is the
    # shortest interval of the draws, hence never longer than the equal-tailed one)
    width = iv.hdi_hi - iv.hdi_lo
    assert np.all(width <= iv.hi - iv.lo + 1e-12)
    assert np.all(np.abs(width - 2 * q) < 8 * se)
    assert iv.contains(3.0).all() and not iv.contains(3 + 2 * q).any()


def test_hdi_matches_arviz_and_is_shorter_than_equal_tailed_for_skewed_draws():
    az = arviz()
    x = np.random.default_rng(5).gamma(2.0, size=50_000)
    lo, hi = hdi(x, 0.9)
    ref = az.hdi(x, hdi_prob=0.9)
    assert np.allclose([lo, hi], ref, rtol=1e-3)
    iv = credible_interval(x, 0.9)
    assert hi - lo < iv.hi - iv.lo


def test_modal_intervals_shapes():
    model = LinearModel(Rig(), "proportional")
    draws = _draws(model, np.array([6.2, 1.57, 1.46, 1.14, 1.6, 1e-4]), n=300).reshape(
        10, 30, 6)
    ms = propagate_modes(model, draws, reference=draws[0, 0])
    mi = modal_intervals(ms)
    assert mi["omega_rad_s"].median.shape == (3,)
    assert mi["mode_shapes"].lo.shape == (3, 3)
    assert np.allclose(mi["mode_shapes"].median[0], 1.0)  # cart 1 normalisation
    assert set(mi) == {"omega_rad_s", "zeta", "damped_rad_s", "mode_shapes", "mac_reference"}
    # modal samples keep the (chain, draw) layout
    assert ms.omega_rad_s.shape == (10, 30, 3)
    ref = undamped_modes(*[model.matrices(draws[0, 0])[i] for i in (0, 2)])
    assert np.allclose(ms.omega_rad_s[0, 0], ref.omega_rad_s)


def test_impossible_draws_are_rejected():
    model = LinearModel(Rig(), "proportional")
    with pytest.raises(ValueError, match="impossible"):
        propagate_modes(model, np.array([[6.2, -1.0, 1.4, 1.1, 1.6, 0.0]]))
