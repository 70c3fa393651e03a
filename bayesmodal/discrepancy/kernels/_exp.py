"""Code of ``e^{-x}``, ``1 - e^{-x}`` and ``(1 - e^{-x}) / x`` for the generated kernels.

numba (without SVML) compiles ``math.exp`` to a library call, which keeps a lane loop
scalar; this code is arithmetic, integer and bit operations only, so it vectorises.

Range reduction: for ``x >= 0`` (clipped at ``EXP_CLIP``) let ``k = round(x / ln 2)``
and ``r = x - k ln 2``, so that ``|r| <= ln(2) / 2`` and::

    e^{-x} = 2^{-k} e^{-r} = s (1 - r Q(r)),   s = 2^{-k},
    Q(r) = (1 - e^{-r}) / r = sum_j (-r)^j / (j + 1)!   (j = 0 .. EXP_DEGREE),
    1 - e^{-x} = (1 - s) + s r Q(r).

``k`` is rounded by adding and subtracting ``1.5 2^52`` (round to nearest in the default
mode, exact), ``r`` takes ``k ln 2`` in two parts (``LN2_HI`` + ``LN2_LO``, each product
fused into its subtraction) so that it is accurate to its last bit, and ``s`` is built
from its exponent bits (``_codegen.pow2_neg``).  The series is truncated after
``r^12 / 13!`` (``< 1.3e-17`` at ``|r| = ln(2) / 2``) and evaluated by Horner's rule with
fused multiply-adds.  For ``k = 0`` (``x < ln(2) / 2``) ``1 - e^{-x} = x Q(x)`` has no
cancellation and ``(1 - e^{-x}) / x = Q(x)`` needs no division and tends to 1 smoothly
as ``x -> 0``; for ``k >= 1`` the sum ``(1 - s) + s r Q`` is at least 0.29 and the quotient
is taken by division.  Measured against 80-bit ``np.expm1`` over ``[1e-12, 40]``: relative
errors at most 1.3e-16 (``e^{-x}``), 1.7e-16 (``1 - e^{-x}``), 1.9e-16 (the quotient),
as small as numpy's own ``exp``.  The pieces join at the ``k`` boundaries to within that
error, so the results are continuous in ``x`` to rounding.

Every operation is IEEE-rounded (fused multiply-adds written as ``fma``), so the scalar
and the vectorised code give the same bits (a batch equals its single-lane runs).
"""

from __future__ import annotations

import math

#: Arguments of ``e^{-x}`` are clipped at this value (``e^{-40} = 4e-18``, nil next to 1).
EXP_CLIP = 40.0
#: Degree of the series of ``Q(r) = (1 - e^{-r}) / r`` on ``|r| <= ln(2) / 2``.
EXP_DEGREE = 12
#: ``1 / ln 2``.
LOG2E = 1.4426950408889634
#: ``ln 2`` in two parts: the float64 nearest to it and the rest.
LN2_HI = float.fromhex("0x1.62e42fefa39efp-1")
LN2_LO = float.fromhex("0x1.abc9e3b39803fp-56")
#: ``1.5 2^52``: ``(y + ROUNDER) - ROUNDER`` is ``y`` rounded to an integer, for
#: ``0 <= y < 2^51``.
ROUNDER = 6755399441055744.0


def _reduced(t: str, x: str, tag: str) -> list[str]:
    """Code of ``k{tag}`` (rounded ``min(x, EXP_CLIP) / ln 2``), ``s{tag} = 2^-k``,
    ``r{tag}`` and ``q{tag} = Q(r)``; ``x >= 0``."""
    coef = [(-1.0) ** j / math.factorial(j + 1) for j in range(EXP_DEGREE + 1)]
    # Horner's rule one step a line (``codegen.interleave`` can then alternate the steps
    # of several arguments)
    horner = [f"{t}q{tag} = fma(r{tag}, {coef[-1]!r}, {coef[-2]!r})"]
    horner += [f"{t}q{tag} = fma(r{tag}, q{tag}, {c!r})" for c in reversed(coef[:-2])]
    return [
        f"{t}y{tag} = {x} if {x} < {EXP_CLIP!r} else {EXP_CLIP!r}",
        f"{t}k{tag} = (y{tag} * {LOG2E!r} + {ROUNDER!r}) - {ROUNDER!r}",
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
