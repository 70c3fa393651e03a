"""Plots of the EMA results (Agg backend) and the common result type."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

from bayesmodal._errors import DataError
from bayesmodal.ema import (
    FRF,
    circle_fit,
    error_curve,
    lecture_irfs,
    mac,
    mac_estimates,
    match_modes,
    modal_estimate,
    normalise_shapes,
    spectrogram,
    stabilization_diagram,
)
from bayesmodal.plots.ema import (
    plot_coherence,
    plot_error_curve,
    plot_frf,
    plot_nyquist,
    plot_spectrogram,
    plot_stabilization,
)


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def sdof(w):
    return 1 / (100 - w**2 + 0.4j * w)


def test_plot_frf_with_fit_and_modes():
    w = np.linspace(1, 20, 400)
    frf = FRF(w, np.column_stack([sdof(w), 2 * sdof(w)]), coherence=np.ones((400, 2)))
    est = modal_estimate("demo", np.array([-0.2 + 10j]), np.array([[1j, 2j]]))
    axes = plot_frf(frf, fitted=frf.H * 1.01, estimate=est, band=(2, 18), fit_band=(5, 15))
    assert axes.shape == (2,)
    assert axes[0].get_ylabel() == "|H| (m/V)"
    assert axes[1].get_xlabel() == "frequency (rad/s)"
    assert len(axes[0].lines) == 2 * 2 + 1  # measured + fit per output, one mode marker
    ax = plot_coherence(frf)
    assert ax.get_ylabel().startswith("coherence")
    with pytest.raises(DataError, match="coherence"):
        plot_coherence(FRF(w, sdof(w)))


def test_plot_nyquist():
    w = np.linspace(9, 11, 41)
    ax = plot_nyquist(circle_fit(w, sdof(w)))
    assert ax.get_xlabel() == "Re H" and ax.get_ylabel() == "Im H"
    assert any("resonance" in t.get_text() for t in ax.get_legend().get_texts())


def test_plot_stabilization_and_error_curve():
    _, h, _ = lecture_irfs(np.random.default_rng(1))
    diag = stabilization_diagram(h, 1.0, range(2, 7), M=40, P=40)
    w = np.linspace(0.05, 3.0, 300)
    ax = plot_stabilization(diag, frf=FRF(w, sdof(10 * w)), band=(0.1, 3.0))
    assert ax.get_xlabel() == "natural frequency |lambda| (rad/s)"
    labels = {t.get_text() for t in ax.get_legend().get_texts()}
    assert "new" in labels
    ax = plot_error_curve(error_curve(h, 1.0, range(1, 6), M=40, P=40))
    assert list(ax.get_xticks()) == [1, 2, 3, 4, 5]


def test_plot_spectrogram():
    dt = 0.01
    t = np.arange(4000) * dt
    sg = spectrogram(np.sin(2 * np.pi * (0.5 * t + 0.05 * t**2)), dt, nperseg=256)
    ax = plot_spectrogram(sg, omega_max=50.0)
    assert ax.get_xlabel() == "time (s)" and ax.get_ylabel() == "frequency (rad/s)"


def test_modal_estimate_sorting_conjugation_and_shapes():
    poles = np.array([-0.5 - 20j, -0.1 + 5j, -3.0 + 0j])
    R = np.array([[1 + 1j, 2 + 2j], [1j, -1j], [1.0, 0.5]])
    est = modal_estimate("demo", poles, R, [True, True, False], notes=["x"])
    np.testing.assert_allclose(est.poles, [-3.0, -0.1 + 5j, -0.5 + 20j])
    np.testing.assert_allclose(est.omega_rad_s, np.abs(est.poles))
    np.testing.assert_allclose(est.zeta, [1.0, 0.1 / abs(-0.1 + 5j), 0.5 / abs(0.5 + 20j)])
    # the conjugated pole carries the conjugate residues; shapes are ratios to output 1
    np.testing.assert_allclose(est.residues[2], [1 - 1j, 2 - 2j])
    np.testing.assert_allclose(est.mode_shapes[:, 1], [0.5, -1.0, 2.0])
    assert est.identified.tolist() == [False, True, True]
    assert est.physical().n_modes == 2
    d = est.as_dict()
    assert d["mode_shapes"][1] == [1.0, -1.0] and d["notes"] == ["x"]
    np.testing.assert_allclose(est.omega_d_rad_s, [0, 5, 20])


def test_normalise_match_and_mac():
    with pytest.raises(DataError, match="reference"):
        normalise_shapes(np.ones((2, 2)), reference=3)
    out = normalise_shapes(np.array([[0.0, 1.0], [2.0, 4.0]]))
    assert np.all(np.isnan(out[0])) and out[1].tolist() == [1.0, 2.0]
    assert match_modes(np.array([8.0, 27.0, 42.0]), np.array([41.0, 8.3])).tolist() == [2, 0]
    assert match_modes(np.empty(0), np.array([1.0])).tolist() == [-1]
    a = np.array([[1.0, 0.9, 0.6], [1.0, -0.5, -1.3]])
    m = mac_estimates(a, a * (2 - 1j))
    np.testing.assert_allclose(np.diag(m), 1.0)
    np.testing.assert_allclose(m, mac(a.T, a.T))
