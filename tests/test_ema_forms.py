"""EMA in the sensor's FRF form (receptance, mobility, accelerance) and hammer tests.

The modal truth of the two-cart rig is computed here from its matrices: the poles and
receptance residues from the eigen-decomposition of the state matrix, ``G(s) = sum_k
V[:n, k] (V^-1 B)_k / (s - lambda_k)``, and the FRF of each form as ``(jw)^p G(jw)``.
"""

from __future__ import annotations

import numpy as np
import pytest

from bayesmodal._errors import DataError
from bayesmodal.data import Experiment
from bayesmodal.ema import (
    FRF,
    circle_fit_modes,
    correct_exponential_window,
    find_impacts,
    force_window,
    identify,
    impact_frf,
    multimode_fit,
    receptance_estimate,
    to_receptance,
    welch_frf,
)
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import Cart, Drive, LinearModel, Rig, Sensor, Spring

K1, K2 = 774.0, 770.0
M1, M2, C1, C2, C12 = 1.5, 1.4, 2.0, 1.5, 0.5
THETA = np.array([M1, M2, C1, C2, C12])


def rig(*sensors) -> Rig:
    return Rig(carts=(Cart("1"), Cart("2")),
               springs=(Spring("1", "2", K1), Spring("2", "frame", K2)),
               drive=(Drive("1"),), input="force", sensors=tuple(sensors))


def truth():
    """Poles (upper half plane, by frequency) and receptance residues, shape (2, 2)."""
    M = np.diag([M1, M2])
    K = np.array([[K1, -K1], [-K1, K1 + K2]])
    C = np.array([[C1 + C12, -C12], [-C12, C2 + C12]])
    A = np.block([[np.zeros((2, 2)), np.eye(2)],
                  [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    B = np.r_[0.0, 0.0, 1.0 / M1, 0.0]
    lam, V = np.linalg.eig(A)
    beta = np.linalg.solve(V, B)
    up = np.flatnonzero(lam.imag > 0)
    up = up[np.argsort(lam[up].imag)]
    return lam[up], (V[:2, up] * beta[up]).T


def closed_form(w, p):
    """The FRF of order ``p`` on ``w`` rad/s, shape (n_freq, 2)."""
    lam, R = truth()
    jw = 1j * w[:, None]
    G = sum(R[k] / (jw - lam[k]) + R[k].conj() / (jw - lam[k].conj()) for k in range(2))
    return jw**p * G


def test_closed_form_is_the_inverse_dynamic_stiffness():
    w = np.linspace(5, 60, 7)
    M = np.diag([M1, M2])
    K = np.array([[K1, -K1], [-K1, K1 + K2]])
    C = np.array([[C1 + C12, -C12], [-C12, C2 + C12]])
    direct = np.array([np.linalg.solve(K - x**2 * M + 1j * x * C, [1.0, 0.0]) for x in w])
    np.testing.assert_allclose(closed_form(w, 0), direct, rtol=1e-10)


@pytest.mark.parametrize("p", [0, 1, 2])
def test_multimode_fit_reads_each_form(p):
    lam, R = truth()
    w = np.linspace(5.0, 60.0, 800)
    frf = FRF(w, closed_form(w, p), derivative_order=p, units="m/N")
    fit = multimode_fit(frf, band=(8.0, 50.0), n_modes=2)
    np.testing.assert_allclose(fit.estimate.poles, lam, rtol=1e-6)
    rec = receptance_estimate(fit.estimate, [p, p])
    np.testing.assert_allclose(rec.residues, R, rtol=1e-4, atol=1e-6 * np.abs(R).max())
    # the shapes are the same whatever the form (a common factor per mode)
    np.testing.assert_allclose(rec.mode_shapes, R / R[:, :1], rtol=1e-4)
    if p:  # negative control: the form's residues are not the receptance's
        assert not np.allclose(fit.estimate.residues, R, rtol=0.1)


def test_circle_fit_on_mobility_and_accelerance():
    lam, _ = truth()
    w = np.linspace(5.0, 60.0, 4000)
    for p in (1, 2):
        frf = FRF(w, closed_form(w, p), derivative_order=p, units="m/N")
        est = circle_fit_modes(frf, 2, search_band=(8.0, 50.0)).estimate
        # a circle fit reads a mode from the points near its resonance: the neighbouring
        # mode's tail is its error (a few 1e-3 relative here)
        np.testing.assert_allclose(est.omega_rad_s, np.abs(lam), rtol=2e-3)
        np.testing.assert_allclose(est.zeta, -lam.real / np.abs(lam), rtol=0.05)


def test_to_receptance_divides_each_output_by_its_order():
    w = np.linspace(5.0, 60.0, 50)
    mixed = np.column_stack([closed_form(w, 0)[:, 0], closed_form(w, 2)[:, 1]])
    frf = FRF(w, mixed, units="m/s^2/N")
    np.testing.assert_allclose(to_receptance(frf, [0, 2]).H, closed_form(w, 0), rtol=1e-12)


def test_identify_mixed_sensors_gives_receptance_shapes():
    """LSCE on the free decays after force pulses, an encoder on cart 1 and an
    accelerometer on cart 2: the shapes are those of the receptance."""
    lam, R = truth()
    r = rig(Sensor("1", "m"), Sensor("2", "m/s^2"))
    dt, n = 0.002, 6000
    f = np.zeros(n)
    for k0 in range(100, n - 10, 1500):
        f[k0 : k0 + 3] = 20.0
    y = simulate_linear(LinearModel(r, "free"), THETA, f, dt)
    e = Experiment(np.arange(n) * dt, f, y)
    res = identify(e, "lsce", n_modes=2, output_kinds=r.output_kinds, input_kind="force")
    est = res.estimate.physical()
    np.testing.assert_allclose(est.poles, lam, rtol=1e-5)
    np.testing.assert_allclose(est.mode_shapes, R / R[:, :1], rtol=1e-4)
    # negative control: read as positions, cart 2's column is lambda^2 times too large
    plain = identify(e, "lsce", n_modes=2).estimate.physical()
    assert not np.allclose(plain.mode_shapes, R / R[:, :1], rtol=0.1)


def test_hv_lies_between_h1_and_h2():
    """Noise on input and output: H1 underestimates, H2 overestimates, Hv between; all
    three within their random error of the accelerance where the coherence is high."""
    rng = np.random.default_rng(3)
    r = rig(Sensor("1", "m/s^2"), Sensor("2", "m/s^2"))
    dt, n = 0.004, 2**15
    f = rng.normal(0.0, 5.0, n)
    y = simulate_linear(LinearModel(r, "free"), THETA, f, dt)
    y_meas = y + rng.normal(0.0, 0.05 * y.std(axis=0), y.shape)
    f_meas = f + rng.normal(0.0, 0.25, n)
    est = {e: welch_frf(f_meas, y_meas, dt, estimator=e, nperseg=1024) for e in
           ("H1", "H2", "Hv")}
    a1, a2, av = (np.abs(est[e].H) for e in ("H1", "H2", "Hv"))
    assert np.all(a1 <= av * (1 + 1e-12)) and np.all(av <= a2 * (1 + 1e-12))
    np.testing.assert_allclose(av, np.sqrt(a1 * a2), rtol=1e-12)
    w = est["H1"].omega_rad_s
    band = (w > 5) & (w < 60)
    exact = np.abs(closed_form(w[band], 2))
    coh = est["H1"].coherence[band]
    # random error of |H1| (Bendat & Piersol): sqrt((1 - g^2) / (2 n_avg g^2)) relative
    se = np.sqrt((1 - coh) / (2 * est["H1"].n_averages * coh))
    good = coh > 0.9
    z = np.abs(av[band] - exact) / (exact * se)
    assert np.median(z[good]) < 2


def hammer_record(seed=0, bounce=False, dt=0.002, n=15000):
    """Three hits 10 s apart (the first mode rings down by e^-6.5 between them)."""
    rng = np.random.default_rng(seed)
    r = rig(Sensor("1", "g"), Sensor("2", "g"))
    f = np.zeros(n)
    for k0 in range(50, n - 10, 5000):
        f[k0 : k0 + 3] = [30.0, 60.0, 30.0]
    if bounce:
        f[5050 + 10 : 5050 + 12] = 20.0  # 20 ms after the second hit
    y = simulate_linear(LinearModel(r, "free"), THETA, f, dt)
    return f, y + rng.normal(0.0, 0.01, y.shape), r


def test_impact_frf_with_exponential_window_recovers_the_damping():
    lam, _ = truth()
    f, y, _ = hammer_record()
    tau = 2.0  # s: the segments are 10 s long
    frf = impact_frf(f, y, 0.002, tau_s=tau, derivative_order=2, units="m/s^2/N")
    assert frf.n_averages == 3 and frf.derivative_order == 2
    fit = multimode_fit(frf, band=(8.0, 50.0), n_modes=2)
    corrected = correct_exponential_window(fit.estimate, tau)
    zeta = -lam.real / np.abs(lam)
    np.testing.assert_allclose(corrected.omega_rad_s, np.abs(lam), rtol=1e-3)
    np.testing.assert_allclose(corrected.zeta, zeta, rtol=0.02)
    # negative control: without the correction the window's 1/tau is in the damping
    assert np.all(fit.estimate.zeta > zeta + 0.5 / (tau * np.abs(lam)))


def test_double_impact_is_refused_with_one_line():
    f, _, _ = hammer_record(bounce=True)
    with pytest.raises(DataError, match=r"double impact at t = 10\.1 s: .*ms after the hit "
                                        r"\(the hammer bounced\); repeat the hit") as info:
        find_impacts(f, 0.002)
    assert "\n" not in str(info.value)


def test_force_window_keeps_only_the_hits():
    f, _, _ = hammer_record()
    noisy = f + np.random.default_rng(1).normal(0.0, 0.5, f.size)
    hits = find_impacts(noisy, 0.002)
    assert hits.n_hits == 3
    fw = force_window(noisy, hits, pre_s=0.004, post_s=0.004)
    inside = fw != 0
    assert inside.sum() <= 3 * (3 + 2 + 2 + 2 + 2)  # each hit and 2 samples either side
    np.testing.assert_array_equal(fw[inside], noisy[inside])
    assert np.all(f[~inside] == 0)  # nothing of a hit is cut
