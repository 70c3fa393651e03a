"""Code of ``e^{-x}``, ``1 - e^{-x}`` and ``(1 - e^{-x}) / x`` for the generated kernels.

numba (without SVML) compiles ``math.exp`` to a library call, which keeps a lane loop
scalar; this code is arithmetic, integer and bit operations only, so it vectorises.

Range reduction: for ``x >= 0`` (clipped at ``EXP_CLIP``) let ``k = round(x / ln 2)``
and ``r = x - k ln 2``, so that ``|r| <= ln(2) / 2`` and::

    e^{-x} = 2^{-k} e^{-r} = s (1 - r Q(r)),   s = 2^{-k},
    Q(r) = (1 - e^{-r}) / r = sum_j (-r)^j / (j + 1)!,
    1 - e^{-x} = (1 - s) + s r Q(r).

``k`` is rounded by adding and subtracting ``1.5 2^52`` (round to nearest in the default
mode, exact; the product ``x / ln 2`` fused into the addition), ``r`` takes ``k ln 2``
in two parts (``LN2_HI`` + ``LN2_LO``, each product fused into its subtraction) so that
it is accurate to its last bit, and ``s`` is built from its exponent bits
(``_codegen.pow2_neg``).  ``Q`` is the polynomial of degree 10 of least relative error
on ``|r| <= ln(2) / 2`` (``Q_COEFFS``; 1.8e-17, where the Taylor series needs degree 12
for the same), evaluated by Horner's rule with fused multiply-adds.  For ``k = 0``
(``x < ln(2) / 2``) ``1 - e^{-x} = x Q(x)`` has no cancellation and
``(1 - e^{-x}) / x = Q(x)`` needs no division and is 1 at ``x = 0`` (the constant
coefficient rounds to 1); for ``k >= 1`` the sum ``(1 - s) + s r Q`` is at least 0.29
and the quotient is taken by division.  Measured against 80-bit ``np.expm1`` over
``[1e-12, 40]`` (``tests/test_kernel_exp.py``): relative errors at most 1.3e-16
(``e^{-x}``, as numpy's own ``exp``), 1.7e-16 (``1 - e^{-x}``) and 2.1e-16 (the
quotient).  The pieces join at the ``k`` boundaries to within that error, so the results
are continuous in ``x`` to rounding.

Every operation is IEEE-rounded (fused multiply-adds written as ``fma``), so the scalar
and the vectorised code give the same bits (a batch equals its single-lane runs).
"""

from __future__ import annotations

import numpy as np

#: Arguments of ``e^{-x}`` are clipped at this value (``e^{-40} = 4e-18``, nil next to 1).
EXP_CLIP = 40.0
#: ``1 / ln 2``.
LOG2E = 1.4426950408889634
#: ``ln 2`` in two parts: the float64 nearest to it and the rest.
LN2_HI = float.fromhex("0x1.62e42fefa39efp-1")
LN2_LO = float.fromhex("0x1.abc9e3b39803fp-56")
#: ``1.5 2^52``: ``(y + ROUNDER) - ROUNDER`` is ``y`` rounded to an integer, for
#: ``0 <= y < 2^51``.
ROUNDER = 6755399441055744.0
#: ``Q(r) = (1 - e^{-r}) / r`` on ``|r| <= ln(2) / 2``: coefficients of ``r^0 .. r^10`` of
#: the polynomial of least relative error (``minimax_series(10)``, computed in 80-bit
#: arithmetic), rounded to float64.
Q_COEFFS = tuple(float.fromhex(c) for c in (
    "0x1.0000000000000p+0", "-0x1.0000000000005p-1", "0x1.5555555555530p-3",
    "-0x1.5555555552131p-5", "0x1.111111111a20ep-7", "-0x1.6c16c17f259d9p-10",
    "0x1.a01a01710ea2ap-13", "-0x1.a019a6bd6a4ebp-16", "0x1.71de8e621f927p-19",
    "-0x1.28a274173b20bp-22", "0x1.ae6441bf878a3p-26"))


def _q_exact(r: np.ndarray) -> np.ndarray:
    """``(1 - e^{-r}) / r`` in long double (its series near 0)."""
    r = np.asarray(r, dtype=np.longdouble)
    out = np.empty_like(r)
    small = np.abs(r) < 1e-3
    acc = np.zeros_like(r[small])
    for j in range(20, -1, -1):  # sum_j (-r)^j / (j + 1)!, Horner
        acc = acc * -r[small] + 1 / np.longdouble(np.prod(np.arange(1, j + 2, dtype=float)))
    out[small] = acc
    big = r[~small]
    out[~small] = -np.expm1(-big) / big
    return out


def minimax_series(degree: int, iterations: int = 30) -> np.ndarray:
    """Coefficients (lowest first, long double) of the polynomial of ``degree`` with the
    least largest relative error to ``Q(r) = (1 - e^{-r}) / r`` on ``|r| <= ln(2) / 2``.

    Remez exchange: solve ``p(r_i) + (-1)^i E Q(r_i) = Q(r_i)`` on ``degree + 2``
    reference points (from the Chebyshev extrema), move them to the extrema of the
    relative error on a grid of 20 001 points, repeat.  Long double is 80-bit on x86-64;
    where it is float64 the result is only as good as float64.  ``Q_COEFFS`` is
    ``minimax_series(10)`` rounded to float64.
    """
    ld = np.longdouble
    a = ld(0.5) * np.log(ld(2)) * (1 + ld(1e-12))  # a margin for the rounding of r
    n = degree + 2
    x = -a * np.cos(np.pi * np.arange(n, dtype=ld) / (n - 1))
    grid = np.linspace(-a, a, 20001, dtype=ld)
    q_grid = _q_exact(grid)
    coef = np.zeros(degree + 1, dtype=ld)
    for _ in range(iterations):
        f = _q_exact(x)
        A = np.column_stack([x**j for j in range(degree + 1)] + [(-1.0) ** np.arange(n) * f])
        b = f.copy()
        for c in range(n):  # Gaussian elimination with partial pivoting, in long double
            p = c + int(np.argmax(np.abs(A[c:, c])))
            A[[c, p]], b[[c, p]] = A[[p, c]], b[[p, c]]
            m = A[c + 1 :, c] / A[c, c]
            A[c + 1 :] -= m[:, None] * A[c]
            b[c + 1 :] -= m * b[c]
        sol = np.zeros(n, dtype=ld)
        for c in range(n - 1, -1, -1):
            sol[c] = (b[c] - A[c, c + 1 :] @ sol[c + 1 :]) / A[c, c]
        coef = sol[: degree + 1]
        err = (np.polyval(coef[::-1], grid) - q_grid) / q_grid
        runs = np.split(np.arange(grid.size), np.flatnonzero(np.diff(np.sign(err))) + 1)
        extrema = [run[np.argmax(np.abs(err[run]))] for run in runs]
        if len(extrema) > n:  # keep the n largest, in order
            extrema = sorted(sorted(extrema, key=lambda i: -abs(err[i]))[:n])
        if len(extrema) < n:
            break
        x = grid[extrema]
    return coef


def _reduced(t: str, x: str, tag: str) -> list[str]:
    """Code of ``k{tag}`` (rounded ``min(x, EXP_CLIP) / ln 2``), ``s{tag} = 2^-k``,
    ``r{tag}`` and ``q{tag} = Q(r)``; ``x >= 0``."""
    coef = Q_COEFFS
    # Horner's rule one step a line (``codegen.interleave`` can then alternate the steps
    # of several arguments)
    horner = [f"{t}q{tag} = fma(r{tag}, {coef[-1]!r}, {coef[-2]!r})"]
    horner += [f"{t}q{tag} = fma(r{tag}, q{tag}, {c!r})" for c in reversed(coef[:-2])]
    return [
        f"{t}y{tag} = {x} if {x} < {EXP_CLIP!r} else {EXP_CLIP!r}",
        f"{t}k{tag} = fma(y{tag}, {LOG2E!r}, {ROUNDER!r}) - {ROUNDER!r}",
        f"{t}r{tag} = fma(k{tag}, {-LN2_HI!r}, y{tag})",
        f"{t}r{tag} = fma(k{tag}, {-LN2_LO!r}, r{tag})",
        f"{t}s{tag} = pow2_neg(k{tag})",
    ] + horner


def exp_neg(t: str, x: str, out: str, tag: str = "_e") -> list[str]:
    """Code of ``out = e^{-x}`` for ``x >= 0`` (``e^{-EXP_CLIP}`` above ``EXP_CLIP``).

    Parameters
    ----------
    t : str
        Indentation.
    x, out : str
        Names of the argument and the result.
    tag : str
        Suffix of the temporaries (``y, k, r, s, q``).

    Returns
    -------
    list of str
        Source lines.
    """
    return _reduced(t, x, tag) + [f"{t}{out} = fma(-(s{tag} * r{tag}), q{tag}, s{tag})"]


def one_minus_exp(t: str, x: str, om: str, q: str, tag: str = "_m") -> list[str]:
    """Code of ``om = 1 - e^{-x}`` and ``q = om / x`` for ``x >= 0``.

    Both to a relative error of about 2e-16, with ``q -> 1`` as ``x -> 0`` and no
    division below ``x = ln(2) / 2``; above ``EXP_CLIP``, ``om = 1 - e^{-EXP_CLIP}`` and
    ``q = om / x``.  The names ``om`` and ``q`` must differ from ``x``.

    Parameters
    ----------
    t : str
        Indentation.
    x, om, q : str
        Names of the argument and the two results.
    tag : str
        Suffix of the temporaries (``y, k, r, s, q``).

    Returns
    -------
    list of str
        Source lines.
    """
    return _reduced(t, x, tag) + [
        f"{t}{om} = fma(s{tag} * r{tag}, q{tag}, 1.0 - s{tag})",
        f"{t}{q} = q{tag} if k{tag} == 0.0 else {om} / {x}",
    ]
