"""Numbers for people: significant digits, units, estimates with their standard errors.

Every text output of the package (the CLI's tables and summaries) formats its numbers
here, so that a value always carries its unit and only the digits its standard error
supports, and a parameter sitting on its bound reads ``0 (at bound)`` instead of the
optimiser's ``1.25999e-43``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable

import numpy as np

__all__ = ["param_unit", "sig", "values", "estimate", "percent"]

#: Units of the rig parameters by name pattern (``LinearModel.names`` and extensions).
_UNITS = (
    (r"g_v", "N/V"),
    (r"m\d+", "kg"),
    (r"k\d+", "N/m"),
    (r"c\d+", "N s/m"),
    (r"ca", "1/s"),
    (r"cb", "s"),
    (r"sigma.*", "m"),
)


#: Units per unit of drive gain (N/V) of a rig where nothing absolute is known.
PER_UNIT_GAIN = {"kg": "V s^2/m", "N/m": "V/m", "N s/m": "V s/m"}


def param_unit(name: str, per_unit_gain: bool = False) -> str:
    """Unit of a rig parameter (``"kg"`` for ``"m2"``), or ``""`` when not known;
    ``per_unit_gain``: per N/V of drive gain (``"V s^2/m"`` for a mass).

    Examples
    --------
    >>> param_unit("c12"), param_unit("cb"), param_unit("phi1"), param_unit("m1", True)
    ('N s/m', 's', '', 'V s^2/m')
    """
    for pattern, unit in _UNITS:
        if re.fullmatch(pattern, name):
            return PER_UNIT_GAIN.get(unit, unit) if per_unit_gain else unit
    return ""


def _unit(text: str, unit: str) -> str:
    return f"{text} {unit}" if unit else text


def sig(x: float, digits: int = 4) -> str:
    """``x`` with ``digits`` significant digits (``"nan"`` for NaN, ``"0"`` for zero).

    Examples
    --------
    >>> sig(27.40381), sig(0.0022104, 3), sig(123456.0)
    ('27.4', '0.00221', '1.235e+05')
    """
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    if x == 0:
        return "0"
    return f"{x:.{digits}g}"


def values(xs: Iterable[float], *, unit: str = "", digits: int = 4) -> str:
    """Comma-separated values with significant digits and one trailing unit.

    Examples
    --------
    >>> values([8.28081, 27.4038, 41.8258], unit="rad/s")
    '8.281, 27.4, 41.83 rad/s'
    """
    return _unit(", ".join(sig(x, digits) for x in np.ravel(list(xs))), unit)


def percent(xs: Iterable[float], decimals: int = 1) -> str:
    """Percentages with a fixed number of decimals: ``"93.5 %, 81.2 %"``."""
    return ", ".join(f"{float(x):.{decimals}f} %" for x in np.ravel(list(xs)))


def estimate(value: float, se: float | None = None, *, unit: str = "", lower: float | None = None,
             upper: float | None = None, digits: int = 4) -> str:
    """An estimate with its standard error, rounded to the digits the error supports.

    The value is rounded to the decimal place of the standard error's second significant
    digit (``6.223 +- 0.012``); very small or large numbers share one power of ten
    (``(8.58 +- 0.10)e-05``).  A value within ``sqrt(eps)`` (relative to its standard
    error, or 1) of ``lower`` or ``upper`` prints as that bound with ``(at bound)``.

    Parameters
    ----------
    value : float
    se : float, optional
        Standard error; without it (or when not finite and positive) ``digits``
        significant digits are shown and the error as ``nan`` if it was given.
    unit : str
        Appended once at the end.
    lower, upper : float, optional
        Bounds of the parameter (e.g. 0 for a damping coefficient).
    digits : int
        Significant digits when there is no usable standard error.

    Examples
    --------
    >>> estimate(1.25999e-43, 0.44, unit="N s/m", lower=0.0)
    '0 (at bound) +- 0.44 N s/m'
    >>> estimate(6.22345, 0.01234, unit="N/V")
    '6.223 +- 0.012 N/V'
    >>> estimate(8.583e-05, 1.02e-06, unit="s")
    '(8.58 +- 0.10)e-05 s'
    """
    value = float(value)
    has_se = se is not None and math.isfinite(float(se)) and float(se) > 0
    tol = math.sqrt(np.finfo(float).eps) * (float(se) if has_se else 1.0)
    for bound in (lower, upper):
        if bound is not None and math.isfinite(value) and abs(value - bound) <= tol:
            text = f"{sig(bound, digits)} (at bound)"
            if se is not None:
                text += f" +- {sig(se, 2)}"
            return _unit(text, unit)
    if not has_se:
        text = sig(value, digits)
        if se is not None:
            text += f" +- {sig(se, 2)}"
        return _unit(text, unit)
    se = float(se)
    scale = max(abs(value), se)
    exp10 = math.floor(math.log10(scale)) if scale > 0 else 0
    if exp10 < -3 or exp10 > 4:
        # one shared power of ten
        v, s = value / 10.0**exp10, se / 10.0**exp10
        dec = max(0, 1 - math.floor(math.log10(s)))
        return _unit(f"({v:.{dec}f} +- {s:.{dec}f})e{exp10:+03d}", unit)
    dec = max(0, 1 - math.floor(math.log10(se)))
    return _unit(f"{value:.{dec}f} +- {se:.{dec}f}", unit)
