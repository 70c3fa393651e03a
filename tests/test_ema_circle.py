"""Circle fit (lecture 11b) against exact single- and two-mode FRFs."""

from __future__ import annotations

import numpy as np
import pytest

from bayesmodal._errors import DataError
from bayesmodal.ema import FRF, circle_fit, circle_fit_modes, fit_circle, pick_peaks


def two_mode(w, lam, A, R=0.0):
    """Receptance-like FRF with conjugate pole pairs and a constant residual."""
    jw = 1j * np.asarray(w)[:, None]
    lam = np.asarray(lam)[None, :]
    A = np.asarray(A)[None, :]
    return np.sum(A / (jw - lam) + np.conj(A) / (jw - np.conj(lam)), axis=1) + R


def test_fit_circle_exact_and_rejects_degenerate():
    rng = np.random.default_rng(0)
    z = 1e-3 * (2 - 1j + 0.5 * np.exp(1j * rng.uniform(0, 3, 12)))
    c, r = fit_circle(z)
    assert c == pytest.approx(1e-3 * (2 - 1j), abs=1e-15)
    assert r == pytest.approx(0.5e-3, rel=1e-12)
    with pytest.raises(DataError, match="at least 3"):
        fit_circle(z[:2])
    with pytest.raises(DataError, match="coincide"):
        fit_circle(np.ones(5, complex))


def test_single_mode_with_complex_residue_and_residual():
    lam = -0.3 + 12.0j
    A = 0.02 - 0.05j  # psi in the fourth quadrant
    R = 0.004 + 0.001j
    w = np.linspace(10.5, 13.5, 301)
    H = A / (1j * w - lam) + R  # exactly a circle (no conjugate term)
    fit = circle_fit(w, H)
    assert fit.pole == pytest.approx(lam, rel=1e-4)
    assert fit.residue == pytest.approx(A, rel=1e-3)
    assert fit.residual == pytest.approx(R, abs=1e-3 * abs(A / lam.real))
    assert fit.circle_error < 1e-10
    # the model reproduces the data
    np.testing.assert_allclose(fit.model(w), H, rtol=1e-3, atol=1e-6)


def test_two_modes_with_noise_within_the_bandwidth_error():
    lam = np.array([-0.2 + 10.0j, -0.5 + 25.0j])
    A = np.array([-0.05j, -0.08j])
    w = np.arange(5.0, 35.0, 0.02)
    rng = np.random.default_rng(11)
    H = two_mode(w, lam, A)
    noise = rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)
    noise *= 0.01 * np.abs(H).max()
    res = circle_fit_modes(FRF(w, (H + noise)[:, None]), 2)
    est = res.estimate
    assert est.identified.all()
    # frequencies well within the half-power bandwidth, damping within 10 %
    np.testing.assert_allclose(est.omega_rad_s, np.abs(lam), rtol=0.1 * 2 * 0.02)
    np.testing.assert_allclose(est.zeta, -lam.real / np.abs(lam), rtol=0.10)


def test_mode_shapes_from_several_outputs():
    lam = np.array([-0.2 + 10.0j, -0.5 + 25.0j])
    shapes = np.array([[1.0, 0.6, -0.4], [1.0, -1.5, 0.8]])
    base = np.array([-0.05j, -0.08j])
    w = np.arange(5.0, 35.0, 0.02)
    H = np.column_stack([two_mode(w, lam, base * shapes[:, i]) for i in range(3)])
    est = circle_fit_modes(FRF(w, H), 2).estimate
    np.testing.assert_allclose(est.mode_shapes.real, shapes, atol=0.02)
    assert np.max(np.abs(est.mode_shapes.imag)) < 0.02


def test_negative_control_no_resonance():
    w = np.linspace(1, 10, 200)
    smooth = FRF(w, 1.0 / (1 + 1j * w / 3.0))  # first-order low-pass: no peak
    assert pick_peaks(smooth).omega_rad_s.size == 0
    with pytest.raises(DataError, match="no resonance"):
        circle_fit_modes(smooth, 1)
    # forcing a band on it: the fit is marked not identified
    res = circle_fit_modes(smooth, bands=np.array([[4.0, 6.0]]))
    assert not res.estimate.identified.any()


def test_too_few_points():
    with pytest.raises(DataError, match="at least 6"):
        circle_fit(np.arange(4.0), np.ones(4, complex))
