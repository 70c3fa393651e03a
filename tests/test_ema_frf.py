"""FRF estimation and signal tools against closed forms and known systems."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS

from bayesmodal._errors import DataError
from bayesmodal.data import Experiment
from bayesmodal.ema import (
    FRF,
    band_coherence,
    free_decay_segments,
    frequency_grid,
    frf_from_experiment,
    impulse_response,
    is_pulse_train,
    peak_prominence,
    pulse_frf,
    pulse_segments,
    spectrogram,
    spectrum,
    welch_frf,
    zoh_factor,
)
from bayesmodal.model.simulate import simulate_state_space

# a single-DOF oscillator: m = 2 kg, k = 800 N/m, c = 4 N s/m (omega_n 20 rad/s, zeta 0.05)
M_KG, K_N_M, C_NS_M = 2.0, 800.0, 4.0


def sdof_frf(w):
    """Receptance of the oscillator, m/N."""
    return 1.0 / (K_N_M - M_KG * w**2 + 1j * C_NS_M * w)


def sdof_response(u, dt):
    """Exact zero-order-hold response of the oscillator, m, shape (N,)."""
    A = np.array([[0.0, 1.0], [-K_N_M / M_KG, -C_NS_M / M_KG]])
    B = np.array([0.0, 1.0 / M_KG])
    return simulate_state_space(A[None], B[None], u, dt, 1)[0, :, 0]


def test_zoh_factor():
    w = np.array([0.0, 1.0, 50.0])
    z = zoh_factor(w, 0.01)
    assert z[0] == 1.0
    np.testing.assert_allclose(z[1:], (1 - np.exp(-1j * w[1:] * 0.01)) / (1j * w[1:] * 0.01))


def test_pulse_frf_of_zoh_system_is_the_continuous_frf():
    dt = 0.005
    # two pulses 20 s apart: each response decays to exp(-20) before the next one
    u = np.zeros(8000)
    u[1:11] = 3.0
    u[4001:4011] = 3.0
    y = sdof_response(u, dt)
    frf = pulse_frf(u, y, dt)
    assert frf.n_averages == 2
    sel = (frf.omega_rad_s > 1) & (frf.omega_rad_s < 60)
    exact = sdof_frf(frf.omega_rad_s[sel])
    # exact up to the aliases of the sampled response (relative size (w dt / 2 pi)^2 and
    # below), which the correction neglects
    np.testing.assert_allclose(frf.H[sel, 0], exact, rtol=1e-4)
    # negative control: without the hold correction the phase lags by w dt / 2
    raw = pulse_frf(u, y, dt, zoh=False)
    lag = np.angle(raw.H[sel, 0] / exact)
    np.testing.assert_allclose(lag, -frf.omega_rad_s[sel] * dt / 2, atol=1e-4)
    # coherence of noise-free repeated transients is 1
    np.testing.assert_allclose(frf.coherence[sel], 1.0, atol=1e-9)


def test_welch_h1_unbiased_h2_biased_with_output_noise():
    rng = np.random.default_rng(7)
    dt = 0.01
    u = rng.standard_normal(2**16)
    y = sdof_response(u, dt)
    y_noisy = y + np.std(y) * rng.standard_normal(y.size)  # signal-to-noise ratio 1
    h1 = welch_frf(u, y_noisy, dt, nperseg=1024)
    h2 = welch_frf(u, y_noisy, dt, nperseg=1024, estimator="H2")
    band = (5.0, 40.0)
    s1, s2 = h1.band(*band), h2.band(*band)
    exact = sdof_frf(s1.omega_rad_s)
    gam2 = s1.coherence[:, 0]
    # H2 = H1 / gamma^2 identically: the same three spectra in another order of a few
    # products and quotients (each half an ulp)
    np.testing.assert_allclose(s2.H[:, 0], s1.H[:, 0] / gam2, rtol=8 * EPS)
    # H1: relative error within 4 standard errors sqrt((1 - g2) / (2 n g2)) at almost all
    # frequencies (Hann leakage adds a little bias at the peak)
    n = h1.n_averages
    se = np.sqrt((1 - gam2) / (2 * n * gam2))
    rel = np.abs(s1.H[:, 0] / exact - 1)
    assert np.mean(rel < 4 * se + 0.02) > 0.97
    # H2 overestimates where the noise matters (low coherence)
    low = gam2 < 0.8
    assert low.sum() > 10
    assert np.median(np.abs(s2.H[low, 0] / exact[low])) > 1.2
    assert abs(np.median(np.abs(s1.H[low, 0] / exact[low])) - 1) < 0.1


def test_welch_window_choice_and_validation():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(4096)
    for win in ("hann", "boxcar", ("tukey", 0.25)):
        frf = welch_frf(u, 3.0 * u, 0.01, window=win, zoh=False)
        # FFT rounding: each bin of a length-n transform is off by about eps log2(n) of the
        # segment's norm (Parseval: sqrt(n_bins) times the RMS bin), relative to the bin
        # itself; the cross- and auto-spectra each carry it
        n_seg = 2 * (frf.omega_rad_s.size + 1)
        p = frf.input_power
        rtol = 2 * EPS * np.log2(n_seg) * np.sqrt(p.size * np.mean(p) / p)
        assert np.all(np.abs(frf.H[:, 0] / 3.0 - 1) <= rtol)
    with pytest.raises(DataError, match="nperseg"):
        welch_frf(u, u, 0.01, nperseg=4)
    with pytest.raises(DataError, match="estimator"):
        welch_frf(u, u, 0.01, estimator="H3")
    with pytest.raises(DataError, match="all zeros"):
        welch_frf(np.zeros(100), u[:100], 0.01)
    with pytest.raises(DataError, match="shape"):
        welch_frf(u, u[:100], 0.01)


def test_impulse_response_of_sdof_matches_closed_form():
    dt = 0.001
    n = 2**16  # 65.5 s, the response has decayed (exp(-1 * 65) ~ 0)
    w = frequency_grid(n, dt)
    irf = impulse_response(FRF(w[1:], sdof_frf(w[1:])))  # DC is re-created
    wn = np.sqrt(K_N_M / M_KG)
    zeta = C_NS_M / (2 * np.sqrt(K_N_M * M_KG))
    wd = wn * np.sqrt(1 - zeta**2)
    t = irf.t_s
    exact = np.exp(-zeta * wn * t) * np.sin(wd * t) / (M_KG * wd)
    sel = (t > 0.05) & (t < 5)
    np.testing.assert_allclose(irf.h[sel, 0], exact[sel], atol=2e-3 * np.max(exact))
    assert irf.dt == pytest.approx(dt)


def test_impulse_response_needs_uniform_grid():
    with pytest.raises(DataError, match="uniform"):
        impulse_response(FRF(np.array([1.0, 2.0, 4.0]), np.ones(3)))
    with pytest.raises(DataError, match="start"):
        impulse_response(FRF(np.array([3.0, 4.0, 5.0]), np.ones(3)))


def test_segments():
    u = np.zeros(300)
    u[10:15] = 1.0
    u[110:113] = -2.0
    u[250:251] = 1.0
    seg = pulse_segments(u)
    assert seg.tolist() == [[10, 15, 110], [110, 113, 250], [250, 251, 300]]
    dec = free_decay_segments(u, 0.1, skip_s=0.2, duration_s=5.0)
    assert dec.tolist() == [[17, 67], [115, 165], [253, 300]]
    assert is_pulse_train(u) and not is_pulse_train(np.ones(10))
    with pytest.raises(DataError, match="no pulse"):
        pulse_segments(np.zeros(10))
    # a pulse at the very end of the record has no free decay: dropped (kept on request)
    u[298] = 1.0
    assert pulse_segments(u)[-1].tolist() == [250, 251, 298]
    assert pulse_segments(u, drop_truncated=False)[-1].tolist() == [298, 299, 300]


def test_frf_from_experiment_picks_the_estimator():
    dt = 0.005
    u = np.zeros(4000)
    u[1:11] = 3.0
    u[2001:2011] = 3.0
    y = np.column_stack([sdof_response(u, dt), 2 * sdof_response(u, dt)])
    exp = Experiment(np.arange(u.size) * dt, u, y)
    frf = frf_from_experiment(exp)
    assert frf.n_averages == 2 and frf.n_outputs == 2
    # doubling is exact in binary floating point, and so is everything linear after it
    np.testing.assert_array_equal(frf.H[:, 1], 2 * frf.H[:, 0])
    rng = np.random.default_rng(3)
    noise = Experiment(np.arange(4096) * dt, rng.standard_normal(4096), np.zeros((4096, 1)) +
                       rng.standard_normal((4096, 1)))
    assert frf_from_experiment(noise).n_averages > 2  # Welch
    with pytest.raises(DataError, match="method"):
        frf_from_experiment(exp, method="magic")


def test_spectrum_and_spectrogram():
    dt = 0.01
    t = np.arange(1000) * dt
    x = 0.7 * np.sin(2 * np.pi * 5.0 * t)  # exactly on bin 50
    sp = spectrum(x, dt)
    k = np.argmax(sp.amplitude)
    assert sp.omega_rad_s[k] == pytest.approx(2 * np.pi * 5.0)
    # FFT rounding eps log2(n) of the record's norm, which for a sine on a bin is sqrt(2)
    # times the bin; the sine's own phase 2 pi f t carries eps 2 pi f t_max
    rel = 4 * EPS * (np.sqrt(2) * np.log2(t.size) + 2 * np.pi * 5.0 * t[-1])
    assert sp.amplitude[k] == pytest.approx(0.7, rel=rel)
    # chirp: the spectrogram's peak follows the instantaneous frequency f0 + rate t
    f0, rate = 1.0, 0.1  # up to 21 Hz, below the 50 Hz Nyquist frequency
    tt = np.arange(20000) * dt
    chirp = np.sin(2 * np.pi * (f0 * tt + 0.5 * rate * tt**2))
    sg = spectrogram(chirp, dt, nperseg=512)
    peak = sg.omega_rad_s[np.argmax(sg.psd, axis=0)]
    np.testing.assert_allclose(peak, 2 * np.pi * (f0 + rate * sg.t_s), atol=2 * np.pi * 0.3)


def test_coherence_and_prominence_checks():
    w = np.linspace(5, 40, 701)
    frf = FRF(w, sdof_frf(w), coherence=np.full((w.size, 1), 0.9))
    assert band_coherence(frf, (10, 20))[0] == pytest.approx(0.9)
    assert peak_prominence(frf, (17, 23))[0] > 2.5  # isolated mode: about sqrt(1 + 9)
    assert peak_prominence(frf, (25, 40))[0] == pytest.approx(1.0)
    assert np.isnan(band_coherence(FRF(w, sdof_frf(w)), (10, 20))[0])


def test_frf_validation():
    with pytest.raises(DataError, match="increasing"):
        FRF(np.array([2.0, 1.0]), np.ones(2))
    with pytest.raises(DataError, match="NaN"):
        FRF(np.array([1.0, 2.0]), np.array([1.0, np.nan]))
    with pytest.raises(DataError, match="derivative_order"):
        FRF(np.array([1.0, 2.0]), np.ones(2), derivative_order=3)
    with pytest.raises(DataError, match="holds"):
        FRF(np.array([1.0, 2.0, 3.0]), np.ones(3)).band(1.5, 1.9)
