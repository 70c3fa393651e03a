"""Multi-mode frequency-domain fit (lecture 11c) with residual mass and flexibility."""

from __future__ import annotations

import numpy as np
import pytest

from bayesmodal._errors import DataError
from bayesmodal.ema import FRF, modal_basis, multimode_fit

LAM = np.array([-0.3 + 15.0j, -0.4 + 18.0j, -1.0 + 40.0j, -2.0 + 90.0j])
SHAPES = np.array([[1.0, 0.5], [1.0, -0.8], [1.0, 1.3], [1.0, -2.0]])


def receptance(w, lam=LAM, shapes=SHAPES):
    """Proportionally damped receptance column: A_k[i] = u_k[i] u_k[1] / (2 j nu_k)."""
    A = shapes * shapes[:, :1] / (2j * lam.imag[:, None])
    jw = 1j * w[:, None, None]
    return np.sum(A[None] / (jw - lam[None, :, None])
                  + np.conj(A)[None] / (jw - np.conj(lam)[None, :, None]), axis=1)


def test_exact_recovery_with_out_of_band_modes():
    # band 12..25 rad/s holds the two close modes; modes at 40 and 90 rad/s are outside
    # and represented by the residual terms
    w = np.linspace(12, 25, 400)
    frf = FRF(w, receptance(w))
    fit = multimode_fit(frf, LAM[:2] * (1.02 - 0.05j))
    lam = fit.estimate.poles
    np.testing.assert_allclose(lam.imag, LAM[:2].imag, rtol=2e-4)
    np.testing.assert_allclose(lam.real, LAM[:2].real, rtol=0.02)
    np.testing.assert_allclose(fit.estimate.mode_shapes.real, SHAPES[:2], atol=0.01)
    # residual flexibility of the modes above the band is positive (stiffness-like)
    assert np.all(fit.residual_flexibility[:1] > 0)
    assert fit.relative_error < 0.01
    # without residual terms the fit is clearly worse (negative control)
    bare = multimode_fit(frf, LAM[:2] * 1.02, residual_mass=False, residual_flexibility=False)
    assert bare.relative_error > 3 * fit.relative_error


def test_shared_and_averaged_poles_agree_on_exact_data():
    w = np.linspace(10, 50, 800)
    frf = FRF(w, receptance(w))
    a = multimode_fit(frf, n_modes=3)
    b = multimode_fit(frf, n_modes=3, shared=True)
    np.testing.assert_allclose(a.estimate.poles, b.estimate.poles, rtol=1e-3)
    np.testing.assert_allclose(np.abs(a.estimate.poles), np.abs(LAM[:3]), rtol=1e-3)
    assert a.per_output_poles.shape == (2, 3)
    assert np.all(np.isnan(b.per_output_poles))
    np.testing.assert_allclose(a.model(w), frf.H, rtol=0.05, atol=0.01 * np.abs(frf.H).max())


def test_mobility_residual_terms():
    # velocity response: same poles, the residual terms are multiplied by j w
    w = np.linspace(12, 25, 400)
    H = 1j * w[:, None] * receptance(w)
    fit = multimode_fit(FRF(w, H, derivative_order=1), LAM[:2] * 1.01)
    np.testing.assert_allclose(np.abs(fit.estimate.poles), np.abs(LAM[:2]), rtol=1e-3)
    G, names = modal_basis(w, LAM[:2], 1)
    assert G.shape == (400, 6) and names[:2] == ["s_star", "inv_m_star"]
    np.testing.assert_allclose(G[:, 0], 1j * w)
    np.testing.assert_allclose(G[:, 1], 1 / (1j * w))


def test_validation():
    w = np.linspace(12, 25, 4)
    with pytest.raises(DataError, match="cannot determine"):
        multimode_fit(FRF(w, receptance(w)), LAM[:2])
    with pytest.raises(DataError, match="at least one"):
        multimode_fit(FRF(np.linspace(1, 2, 50), np.ones(50)), np.array([]))
