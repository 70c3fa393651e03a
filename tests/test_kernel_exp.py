"""The generated kernels' exponentials (bayesmodal.model.kernels._exp) against long
double numpy: accuracy, values at 0 and at the clip, continuity across the range
reduction's pieces, and the minimax coefficients' derivation."""

from fractions import Fraction

import numpy as np
import pytest

from bayesmodal.model.kernels._codegen import _compile
from bayesmodal.model.kernels._exp import (
    EXP_CLIP,
    LOG2E,
    Q_COEFFS,
    ROUNDER,
    exp_neg,
    minimax_series,
    one_minus_exp,
)

EPS = np.finfo(float).eps  # 2.2e-16
LONG = np.finfo(np.longdouble).eps < EPS  # 80-bit long double (x86-64)


def _kernel():
    t = " " * 8
    lines = ["def kernel(xs, E, OM, Q):", "    for b in range(xs.shape[0]):", f"{t}x = xs[b]"]
    lines += exp_neg(t, "x", "e", tag="_a") + one_minus_exp(t, "x", "om", "q", tag="_b")
    lines += [f"{t}E[b] = e", f"{t}OM[b] = om", f"{t}Q[b] = q"]
    kernel = _compile(lines, "<test exp>")

    def run(xs):
        xs = np.ascontiguousarray(xs, dtype=float)
        out = [np.empty_like(xs) for _ in range(3)]
        kernel(xs, *out)
        return out

    return run


def _rel(a, exact):
    return float(np.max(np.abs((a.astype(np.longdouble) - exact) / exact)))


@pytest.mark.skipif(not LONG, reason="needs an 80-bit long double reference")
def test_exponentials_are_accurate_to_rounding():
    run = _kernel()
    xs = np.concatenate([np.geomspace(1e-12, 1.0, 4001), np.linspace(0.0, EXP_CLIP, 40001)[1:]])
    e, om, q = run(xs)
    xl = xs.astype(np.longdouble)
    om_exact = -np.expm1(-xl)
    # as accurate as numpy's own exp (about 1e-16 here): a few units of rounding
    assert _rel(e, np.exp(-xl)) < 2 * EPS
    assert _rel(om, om_exact) < 2 * EPS
    assert _rel(q, om_exact / xl) < 2 * EPS


def test_values_at_zero_and_beyond_the_clip():
    run = _kernel()
    e, om, q = run(np.array([0.0, 2 * EXP_CLIP]))
    assert (e[0], om[0], q[0]) == (1.0, 0.0, 1.0)  # the quotient tends to 1 without 0/0
    assert e[1] == pytest.approx(np.exp(-EXP_CLIP), rel=2 * EPS)  # clipped argument
    # exact by construction: e^{-EXP_CLIP} is below half a unit of 1, so 1 - e rounds to
    # 1, and the quotient is then one correctly rounded division
    assert om[1] == 1.0 and q[1] == 1.0 / (2 * EXP_CLIP)  # om / x with x itself


def test_pieces_join_to_rounding_at_every_reduction_boundary():
    """Where k = round(x / ln 2) steps, at x = (k + 1/2) ln 2, the neighbouring floats
    take different pieces (and, at k = 0 -> 1, the quotient switches from the series to
    a division): the results change as the functions do between them, to a few units of
    rounding, with no jump."""
    run = _kernel()

    def k(x):  # the kernel's own rounding of x / ln 2: one fused multiply-add, exact here
        return np.array([float(Fraction(v) * Fraction(LOG2E) + Fraction(ROUNDER)) - ROUNDER
                         for v in np.atleast_1d(x)])

    # the neighbouring floats around (k + 1/2) ln 2 between which k steps
    below = (np.arange(58) + 0.5) * np.log(2.0)
    for _ in range(8):
        below = np.where(k(below) > np.arange(58), np.nextafter(below, 0.0), below)
        up = np.nextafter(below, np.inf)
        below = np.where(k(up) == np.arange(58), up, below)
    above = np.nextafter(below, np.inf)
    assert np.all((k(below) == np.arange(58)) & (k(above) == np.arange(58) + 1))
    lo, hi = run(below), run(above)

    def exact(x):
        x = x.astype(np.longdouble)
        om = -np.expm1(-x)
        return np.exp(-x), om, om / x

    for a, b, ea, eb in zip(lo, hi, exact(below), exact(above), strict=True):
        step = (b - a) - (eb - ea).astype(float)  # the jump beyond the functions' change
        assert np.all(np.abs(step) <= 4 * EPS * np.abs(a)), np.max(np.abs(step / a))


def _series_error(coef) -> tuple[float, float]:
    """Largest relative error of the polynomial ``coef`` (lowest first, evaluated in long
    double) to ``Q(r) = (1 - e^{-r}) / r`` on the reduced range ``|r| <= ln(2) / 2``, and
    the bound on how much rounding each coefficient to float64 can move it:
    ``sum_i |c_i| a^i (eps / 2) / min Q``."""
    a = np.log(np.longdouble(2)) / 2
    r = np.linspace(-1.0, 1.0, 4001, dtype=np.longdouble) * a
    r = r[r != 0]
    exact = -np.expm1(-r) / r
    coef = np.asarray(coef, dtype=np.longdouble)
    err = float(np.max(np.abs(np.polyval(coef[::-1], r) / exact - 1)))
    powers = a ** np.arange(coef.size, dtype=np.longdouble)
    rounding = float(np.sum(np.abs(coef) * powers) * (EPS / 2) / np.min(exact))
    return err, rounding


@pytest.mark.skipif(not LONG, reason="the coefficients were computed in 80-bit arithmetic")
def test_minimax_coefficients_are_reproduced():
    """The stored coefficients are the minimax polynomial's to their float64 rounding.

    The monomial coefficients of a minimax polynomial on a short interval are
    ill-conditioned (another platform's long double and numpy recompute some of them
    several float64 units apart) while its values are not, so the check is on the
    values: the stored polynomial's error is the recomputed one's plus at most the
    rounding of its coefficients, and the recomputed one's is below float64 rounding."""
    coef = minimax_series(10)
    err_minimax, _ = _series_error(coef)
    assert err_minimax < EPS / 2  # the point of an 80-bit derivation
    err_stored, rounding = _series_error(Q_COEFFS)
    assert err_stored <= err_minimax + rounding
    # negative control: one coefficient moved by a few thousand of its float64 units
    # (1e-12 relative) breaks the bound
    moved = np.array(Q_COEFFS)
    moved[3] *= 1 + 1e-12
    assert _series_error(moved)[0] > err_minimax + rounding
