"""The lecture's cantilever beam: FE model against theory, EMA methods on its FRF."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS, eig_angle_tol, eig_rtol, solve_tol

from bayesmodal._errors import ModelError
from bayesmodal.ema import (
    CANTILEVER_BETA_L,
    CantileverBeam,
    circle_fit_modes,
    frequency_grid,
    lsce_frf,
    multimode_fit,
    pick_peaks,
)

BAND = (20.0, 1200.0)  # modes 1, 2, 3 of the beam


@pytest.fixture(scope="module")
def beam():
    return CantileverBeam()  # l = 1.8 m, 18 elements, E = 2.1e11 Pa, B = 0.1 M + 2e-5 K


@pytest.fixture(scope="module")
def tip_frf(beam):
    # collocated velocity / force at the free end on an FFT grid: dt = 1 ms (Nyquist
    # 3142 rad/s), 2^18 samples (frequency step 0.024 rad/s, 6 points per half-power
    # bandwidth of the first mode)
    return beam.frf(frequency_grid(2**18, 1e-3), response="velocity")


@pytest.fixture(scope="module")
def truth(beam):
    omega, zeta, _ = beam.modes()
    inband = (omega > BAND[0]) & (omega < BAND[1])
    assert inband.sum() == 3
    return omega[inband], zeta[inband]


def test_matrices_shape_symmetry_and_static_tip_compliance(beam):
    M, B, K = beam.matrices()
    assert M.shape == B.shape == K.shape == (36, 36)
    np.testing.assert_allclose(M, M.T)
    np.testing.assert_allclose(K, K.T)
    np.testing.assert_allclose(B, 0.1 * M + 2e-5 * K)
    # Hermite elements are exact for nodal loads: tip compliance L^3 / (3 EI)
    compliance = np.linalg.inv(K)[beam.tip_dof, beam.tip_dof]
    np.testing.assert_allclose(compliance, 1.8**3 / (3 * 2.1e11 * 7e-8),
                               rtol=solve_tol(K) + 4 * EPS)


def test_first_five_frequencies_match_theory(beam):
    fe = beam.natural_frequencies()[:5]
    exact = beam.analytical_frequencies(5)
    # (beta_n L)^2 sqrt(EI / (rho A L^4)) with beta_n L = 1.8751, 4.6941, ...
    EI, rA = 2.1e11 * 7e-8, 7800 * 9e-4
    np.testing.assert_allclose(exact[0], 1.8751**2 * np.sqrt(EI / (rA * 1.8**4)))
    # the discretisation error of Hermite cubics is O(h^4) in the frequencies: estimated
    # from the mesh halved (Richardson, 16/15 of the difference) with the safety factor
    # 1.25 of Roache's grid convergence index; the reference is exact only to the printed
    # digits of beta_n L (0.5e-4 in beta_n L, twice that relative in beta^2)
    fine = CantileverBeam(n_elements=2 * beam.n_elements).natural_frequencies()[:5]
    discretisation = 1.25 * 16 / 15 * np.abs(fe - fine) / exact
    printed = 2 * 0.5e-4 / CANTILEVER_BETA_L[:5]
    assert np.all(np.abs(fe / exact - 1) <= discretisation + printed)
    assert np.all(fe >= exact * (1 - printed))  # a conforming FE model is stiffer
    assert np.all(fe >= fine)  # and converges from above


def test_rayleigh_damping_ratios(beam):
    omega, zeta, phi = beam.modes()
    np.testing.assert_allclose(zeta, 0.1 / (2 * omega) + 2e-5 * omega / 2)
    M, B, K = beam.matrices()
    # mass-normalised modes diagonalise B
    Bm = phi.T @ B @ phi
    # B = 0.1 M + 2e-5 K: Bm_ii = 0.1 + 2e-5 omega_i^2 to the eigenvalue bound of each
    # mode (the quotients phi^T M phi = 1 and phi^T K phi = omega^2 carry it); off the
    # diagonal, the M-angles of the two shapes (eig_angle_tol) times the same weights
    w2 = omega**2
    rtol = eig_rtol(M, K, w2) + M.shape[0] * EPS
    np.testing.assert_allclose(np.diag(Bm), 2 * zeta * omega, rtol=np.max(rtol))
    angle = eig_angle_tol(M, K, w2)
    off = (0.1 + 2e-5 * w2.max()) * (angle[:, None] + angle[None, :])
    np.testing.assert_array_less(np.abs(Bm - np.diag(np.diag(Bm))), off + np.eye(len(w2)))


def test_collocated_frf_against_direct_solve(beam):
    M, B, K = beam.matrices()
    w = np.array([30.0, 311.0, 700.0])
    frf = beam.frf(w, response="velocity")
    e = np.zeros(36)
    e[beam.tip_dof] = 1.0
    D = [K - wi**2 * M + 1j * wi * B for wi in w]
    direct = np.array([1j * wi * e @ np.linalg.solve(Di, e) for wi, Di in zip(w, D, strict=True)])
    # both are backward-stable solves of the same system: they agree to about
    # cond(D) * eps (times the size n of the system)
    rtol = np.array([np.linalg.cond(Di) for Di in D]) * len(e) * np.finfo(float).eps
    assert np.all(np.abs(frf.H[:, 0] - direct) <= rtol * np.abs(direct))
    # a collocated mobility is positive real (passive structure)
    assert np.all(frf.H.real > 0)
    assert frf.units == "m/(N s)" and frf.derivative_order == 1


def test_peaks_in_band(tip_frf, truth):
    pk = pick_peaks(tip_frf, band=BAND)
    np.testing.assert_allclose(pk.omega_rad_s, truth[0], rtol=1e-3)


def test_lsce_on_irf(tip_frf, truth):
    # IRF by inverse FFT; skip 0.1 s (modes far above the band have died out) and use
    # 10 s; the order is over-specified and extra roots are flagged computational
    res = lsce_frf(tip_frf, 6, t_start=0.1, duration=10.0)
    est = res.estimate.physical()
    sel = (est.omega_rad_s > BAND[0]) & (est.omega_rad_s < BAND[1])
    np.testing.assert_allclose(est.omega_rad_s[sel], truth[0], rtol=0.01)
    np.testing.assert_allclose(est.zeta[sel], truth[1], rtol=0.10)


def test_circle_fit(tip_frf, truth):
    res = circle_fit_modes(tip_frf, 3, search_band=BAND)
    assert res.estimate.identified.all()
    np.testing.assert_allclose(res.estimate.omega_rad_s, truth[0], rtol=0.01)
    np.testing.assert_allclose(res.estimate.zeta, truth[1], rtol=0.10)


def test_multimode_fit(tip_frf, truth):
    # lecture band: 200..1000 rad/s with modes 2 and 3, residual mass for mode 1 and
    # residual flexibility for modes 4, 5, ...
    fit = multimode_fit(tip_frf, band=(200.0, 1000.0), n_modes=2)
    np.testing.assert_allclose(fit.estimate.omega_rad_s, truth[0][1:], rtol=0.01)
    np.testing.assert_allclose(fit.estimate.zeta, truth[1][1:], rtol=0.10)
    assert fit.relative_error < 0.01
    # the wide band with all three modes
    fit = multimode_fit(tip_frf, band=BAND, n_modes=3)
    np.testing.assert_allclose(fit.estimate.omega_rad_s, truth[0], rtol=0.01)
    np.testing.assert_allclose(fit.estimate.zeta, truth[1], rtol=0.10)


def test_validation():
    with pytest.raises(ModelError, match="length_m"):
        CantileverBeam(length_m=-1.0)
    with pytest.raises(ModelError, match="response"):
        CantileverBeam().frf(np.array([1.0, 2.0]), response="strain")
    with pytest.raises(ModelError, match="between 1 and 5"):
        CantileverBeam().analytical_frequencies(6)
