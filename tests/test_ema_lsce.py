"""LSCE (lecture 11d): closed forms, the lecture's three-mode example, model order."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS

from bayesmodal._errors import DataError
from bayesmodal.ema import (
    LECTURE_POLES,
    error_curve,
    lecture_irfs,
    lecture_system,
    lsce,
    stabilization_diagram,
)
from bayesmodal.plots.ema import plot_error_curve, plot_stabilization


def lsce_bounds(records, dt, poles, M=None, P=None):
    """Error bounds of noise-free LSCE, from its own two least-squares problems.

    The prediction coefficients solve a zero-residual least-squares problem with the
    Hankel matrix B (rows ``h[k .. k + 2n - 1]`` of every IRF, reversed): relative error
    ``cond(B) 2n eps``, plus ``2n eps`` of the roots' companion matrix.  A root z_i of the
    polynomial alpha moves by ``||d alpha|| ||(z_i^k)|| / |alpha'(z_i)|`` and the pole
    ``ln(z) / dt`` by that over ``|z_i| dt``.  The residues solve the Vandermonde system
    V (P samples of ``z^k``): relative error ``cond(V) (P eps + P dt max|d lambda| k)``.
    Returns the absolute bound per pole (order of ``poles``, positive imaginary part)
    and the relative bound of the residues.
    """
    recs = [np.asarray(r, float).reshape(len(r), -1) for r in records]
    lam = np.r_[poles, np.conj(poles)]
    order = lam.size
    z = np.exp(lam * dt)
    rows = []
    for h in recs:
        m = h.shape[0] - order if M is None else M
        idx = order - 1 - np.arange(order)[None, :] + np.arange(m)[:, None]
        rows += [h[idx, i] for i in range(h.shape[1])]
    B = np.vstack(rows)
    alpha = np.poly(z)
    d_alpha = order * EPS * (np.linalg.cond(B) + 1) * np.linalg.norm(alpha)
    powers = np.linalg.norm(z[:, None] ** np.arange(order + 1)[None, :], axis=1)
    deriv = np.abs(np.polyval(np.polyder(alpha), z))
    d_lam = d_alpha * powers / deriv / (np.abs(z) * dt)
    p = max(len(h) for h in recs) if P is None else P
    V = z[None, :] ** np.arange(p)[:, None]
    d_res = np.linalg.cond(V) * p * (EPS + dt * np.max(d_lam))
    return d_lam[: len(poles)], d_res


def _matched(poles, truth, rtol_imag=0.03, rtol_real=0.30):
    """For each true pole, whether some estimated pole lies within the tolerances."""
    poles = np.asarray(poles)
    out = []
    for lam in truth:
        ok = (np.abs(poles.imag - lam.imag) <= rtol_imag * lam.imag) & (
            np.abs(poles.real - lam.real) <= rtol_real * abs(lam.real)
        )
        out.append(bool(np.any(ok)))
    return np.array(out)


def test_single_damped_sine_is_exact():
    # h = exp(-0.1 t) sin(2 t) = sum of residues -+ j/2 at -0.1 +- 2j
    t = np.arange(200) * 0.1
    h = np.exp(-0.1 * t) * np.sin(2.0 * t)
    res = lsce(h, 0.1, 1)
    d_lam, d_res = lsce_bounds([h], 0.1, np.array([-0.1 + 2j]))
    np.testing.assert_array_less(np.abs(res.estimate.poles - (-0.1 + 2j)), d_lam)
    np.testing.assert_allclose(res.estimate.residues, [[-0.5j]], rtol=d_res)
    assert res.error < 1e-20


def test_noise_free_lecture_system_exact_with_residues_and_shapes():
    sys = lecture_system()
    t = np.arange(100.0)
    h = sys.irf(t)
    res = lsce(h, 1.0, 3, M=40, P=40)
    d_lam, d_res = lsce_bounds([h], 1.0, LECTURE_POLES, M=40, P=40)
    np.testing.assert_array_less(np.abs(res.estimate.poles - LECTURE_POLES), d_lam)
    np.testing.assert_allclose(res.estimate.residues, sys.residues, rtol=d_res)
    # shapes normalised on output 1 are the chosen u_k[2] / u_k[1]: a ratio of residues
    np.testing.assert_allclose(res.estimate.mode_shapes[:, 1].real, [0.8, 0.5, -1.0],
                               rtol=2 * d_res)


def test_lecture_example_n3_does_not_resolve_close_modes():
    t, h, _ = lecture_irfs(np.random.default_rng(2024))
    assert t[1] - t[0] == 1.0 and t.size == 100
    res = lsce(h, 1.0, 3, M=40, P=40)
    matched = _matched(res.estimate.poles, LECTURE_POLES)
    assert not np.all(matched)  # the close modes are not both resolved
    # the isolated first mode is found in frequency
    assert _matched(res.estimate.poles, LECTURE_POLES[:1], rtol_real=np.inf)[0]
    # as in the lecture (-0.1216 + 1.5218j), the two close modes merge into one pole
    # between them, with a larger decay rate
    merged = res.estimate.poles[np.argmin(np.abs(res.estimate.poles.imag - 1.5))]
    assert 1.4140 < merged.imag < 1.6138
    assert merged.real < LECTURE_POLES[1].real


def test_lecture_example_n4_resolves_all_and_flags_computational():
    t, h, _ = lecture_irfs(np.random.default_rng(2024))
    res = lsce(h, 1.0, 4, M=40, P=40)
    est = res.estimate
    phys = est.poles[est.identified]
    assert _matched(phys, LECTURE_POLES).all()
    # exactly the three modes are kept; the fourth pair is computational
    assert est.identified.sum() == 3
    comp = est.poles[~est.identified]
    assert comp.size == 1
    assert not _matched(comp, LECTURE_POLES).any()
    assert np.all(res.contribution[~est.identified] < 0.05)
    assert np.all(res.contribution[est.identified] > 0.2)


def test_lecture_example_n4_holds_over_seeds():
    # not a lucky seed: the n = 4 fit meets the tolerances for every one of 20 seeds,
    # and the n = 3 fit fails for every one; the extra pair is flagged computational in
    # nearly all (97 of 100 seeds when this was written; one of these 20 keeps it)
    n_flagged = 0
    for seed in range(20):
        _, h, _ = lecture_irfs(seed)
        est = lsce(h, 1.0, 4, M=40, P=40).estimate
        assert _matched(est.physical().poles, LECTURE_POLES).all()
        n_flagged += int(est.identified.sum() == 3)
        assert not _matched(lsce(h, 1.0, 3, M=40, P=40).estimate.poles, LECTURE_POLES).all()
    assert n_flagged >= 18


def test_error_curve_levels_off_at_n4():
    _, h, _ = lecture_irfs(np.random.default_rng(2024))
    curve = error_curve(h, 1.0, range(1, 9), M=40, P=40)
    e = dict(zip(curve.orders.tolist(), curve.error, strict=True))
    # large drop up to n = 4, little gain after (noise floor)
    assert e[3] > 1.5 * e[4]
    assert e[4] < 1.5 * min(e[n] for n in range(5, 9))
    assert np.all(np.diff(curve.reconstruction_error[:4]) < 0)
    ax = plot_error_curve(curve)
    assert ax.get_xlabel() == "number of modes n"
    assert "error" in ax.get_ylabel()


def test_stabilization_diagram_lecture():
    _, h, _ = lecture_irfs(np.random.default_rng(2024))
    diag = stabilization_diagram(h, 1.0, range(2, 9), M=40, P=40, tol_omega=0.02, tol_zeta=0.3)
    assert diag.orders.tolist() == list(range(2, 9))
    assert len(diag.poles) == len(diag.status) == 7
    # once n >= 4 resolves them, the three physical poles repeat from order to order
    for n, poles, status in zip(diag.orders, diag.poles, diag.status, strict=True):
        if n >= 5:
            for lam in LECTURE_POLES:
                assert status[np.argmin(np.abs(poles - lam))] == "stable"
    ax = plot_stabilization(diag)
    assert ax.get_ylabel() == "number of modes n"


def test_free_decays_with_different_amplitudes_share_shapes():
    # two records of the same two-mode system with different initial conditions
    lam = np.array([-0.05 + 1.0j, -0.1 + 2.5j])
    shapes = np.array([[1.0, 0.7], [1.0, -1.4]])
    t = np.arange(150) * 0.2

    def record(c):
        amp = c[:, None] * shapes  # per-mode factor times shape
        return 2 * np.real(np.exp(t[:, None, None] * lam[None, :, None]) * amp[None]).sum(1)

    recs = [record(np.array([1.0 + 0.5j, 0.3j])), record(np.array([-0.4, 2.0 - 1.0j]))]
    res = lsce(recs, 0.2, 2)
    d_lam, d_res = lsce_bounds(recs, 0.2, lam)
    np.testing.assert_array_less(np.abs(res.estimate.poles - lam), d_lam)
    # shapes: ratios of amplitudes, after the SVD over records (another n eps)
    np.testing.assert_allclose(res.estimate.mode_shapes.real, shapes, rtol=2 * d_res + 4 * EPS)
    assert res.amplitudes.shape == (2, 4, 2)


def test_validation():
    with pytest.raises(DataError, match="M <="):
        lsce(np.ones(10), 1.0, 3, M=20)
    with pytest.raises(DataError, match="dt"):
        lsce(np.ones(10), 0.0, 1)
    with pytest.raises(DataError, match="n_modes"):
        lsce(np.ones(10), 1.0, 0)
    with pytest.raises(DataError, match="same number of outputs"):
        lsce([np.ones((20, 2)), np.ones((20, 3))], 1.0, 1)
