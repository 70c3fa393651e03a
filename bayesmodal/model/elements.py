"""The elements a rig is built of: carts, springs, dampers, the drive and the sensors.

Each element checks itself on construction (``ModelError`` naming what to change) and is
frozen; ``Rig`` (``bayesmodal.model.rig``) joins them into a layout and checks how they fit
together.  The sensor units and the quantity each one measures are here too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._errors import ModelError

__all__ = [
    "Cart",
    "Spring",
    "Damper",
    "Drive",
    "Sensor",
    "ECP_M_PER_COUNT",
    "FRAME",
    "INPUT_KINDS",
    "MASS_KINDS",
    "SENSOR_UNITS",
    "SENSOR_KINDS",
    "SENSOR_ORDERS",
    "STANDARD_GRAVITY_M_S2",
]

#: Metres per encoder count of the ECP 210 rig (0.0706 m per 16000 counts).
ECP_M_PER_COUNT = 0.0706 / 16000

#: Name of the fixed frame (ground) as a spring or damper end.
FRAME = "frame"

#: How a cart's mass enters: estimated without a nominal value, estimated with a nominal
#: value (the fit's start), or known (fixed, not a parameter).
MASS_KINDS = ("unknown", "nominal", "known")

#: What a record's input column holds: a command voltage (V) or a measured force (N).
INPUT_KINDS = ("voltage", "force")

#: Standard gravity, m/s^2 per g (the unit of many accelerometers).
STANDARD_GRAVITY_M_S2 = 9.80665

#: Sensor units and their fixed scale in SI units of their kind (m, m/s, m/s^2) per unit
#: (None: the scale must be given).
SENSOR_UNITS = {"m": 1.0, "mm": 1e-3, "count": None, "m/s": 1.0, "m/s^2": 1.0,
                "g": STANDARD_GRAVITY_M_S2}

#: The quantity each sensor unit measures.
SENSOR_KINDS = {"m": "position", "mm": "position", "count": "position",
                "m/s": "velocity", "m/s^2": "acceleration", "g": "acceleration"}

#: Time derivative of the position each kind measures.
SENSOR_ORDERS = {"position": 0, "velocity": 1, "acceleration": 2}


def _finite_positive(value, what: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{what} must be a number, got {value!r}") from None
    if not (np.isfinite(x) and x > 0):
        raise ModelError(f"{what} must be finite and > 0, got {value!r}")
    return x


@dataclass(frozen=True)
class Cart:
    """A cart on the rail.

    Parameters
    ----------
    name : str
        Unique name (the ECP carts are ``"1"``, ``"2"``, ``"3"``); not ``"frame"``.
    mass : {"unknown", "nominal", "known"}
        ``"unknown"``: estimated; ``"nominal"``: estimated, starting from ``mass_kg``;
        ``"known"``: fixed at ``mass_kg`` and not a parameter.
    mass_kg : float, optional
        Mass, kg; required for ``"nominal"`` and ``"known"``.
    """

    name: str
    mass: str = "unknown"
    mass_kg: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or self.name == FRAME:
            raise ModelError(f"a cart needs a non-empty name other than {FRAME!r}, "
                             f"got {self.name!r}")
        if self.mass not in MASS_KINDS:
            raise ModelError(f"cart {self.name!r}: mass must be one of {MASS_KINDS}, "
                             f"got {self.mass!r}")
        if self.mass == "unknown":
            if self.mass_kg is not None:
                object.__setattr__(self, "mass_kg", _finite_positive(
                    self.mass_kg, f"cart {self.name!r}: mass_kg"))
        else:
            if self.mass_kg is None:
                raise ModelError(f"cart {self.name!r}: a {self.mass} mass needs mass_kg")
            object.__setattr__(self, "mass_kg", _finite_positive(
                self.mass_kg, f"cart {self.name!r}: mass_kg"))


@dataclass(frozen=True)
class Spring:
    """A linear spring between two carts or between a cart and the frame.

    Parameters
    ----------
    a, b : str
        Cart names; ``b`` (or ``a``) may be ``"frame"``.
    stiffness_n_m : float
        Known stiffness, or the prior's centre (and the fit's start) when unknown, N/m.
    known : bool
        True (default): fixed.  False: estimated, parameter ``name``.
    prior_sd_n_m : float, optional
        Unknown springs: standard deviation of a normal prior (truncated at 0), N/m; omitted:
        a uniform prior on ``[stiffness_n_m / 10, 10 stiffness_n_m]``.
    name : str
        Parameter name when unknown; default ``k<index>`` (1-based spring index).
    """

    a: str
    b: str
    stiffness_n_m: float
    known: bool = True
    prior_sd_n_m: float | None = None
    name: str = ""

    def __post_init__(self) -> None:
        where = f"spring {self.name or (self.a + '-' + self.b)!r}"
        object.__setattr__(self, "stiffness_n_m", _finite_positive(
            self.stiffness_n_m, f"{where}: stiffness_n_m (N/m)"))
        if not isinstance(self.known, bool):
            raise ModelError(f"{where}: known must be true or false, got {self.known!r}")
        if self.prior_sd_n_m is not None:
            object.__setattr__(self, "prior_sd_n_m", _finite_positive(
                self.prior_sd_n_m, f"{where}: prior_sd_n_m (N/m)"))
        if self.a == self.b:
            raise ModelError(f"{where} joins {self.a!r} to itself; give two different ends")


@dataclass(frozen=True)
class Damper:
    """A viscous damper of the free damping model between two carts or a cart and the frame."""

    a: str
    b: str = FRAME

    def __post_init__(self) -> None:
        if self.a == self.b:
            raise ModelError(f"damper joins {self.a!r} to itself; give two different ends")


@dataclass(frozen=True)
class Drive:
    """A cart pushed by the motor: force ``share * g_v * v`` (share may be negative)."""

    cart: str
    share: float = 1.0

    def __post_init__(self) -> None:
        s = float(self.share)
        if not np.isfinite(s) or s == 0:
            raise ModelError(f"drive on cart {self.cart!r}: share must be finite and non-zero, "
                             f"got {self.share!r}")
        object.__setattr__(self, "share", s)


@dataclass(frozen=True)
class Sensor:
    """A sensor on a cart: its position, velocity or acceleration.

    Parameters
    ----------
    cart : str
    unit : {"m", "mm", "count", "m/s", "m/s^2", "g"}
        Unit of the raw record; it sets the kind (``SENSOR_KINDS``): position (m, mm,
        encoder counts), velocity (m/s) or acceleration (m/s^2, or g = 9.80665 m/s^2).
    m_per_unit : float, optional
        SI units of the kind (m, m/s or m/s^2) per unit of the record; fixed by the unit
        except for ``"count"``, where it is required (metres per count).  A negative value
        stands for a sensor counting the other way (folded into ``sign``).
    sign : {1, -1}
        -1 for a sensor mounted or wired the other way round (positive towards -x).

    Examples
    --------
    >>> s = Sensor("2", "g", sign=-1)
    >>> s.kind, s.si_per_unit
    ('acceleration', -9.80665)
    """

    cart: str
    unit: str = "m"
    m_per_unit: float | None = None
    sign: int = 1

    def __post_init__(self) -> None:
        where = f"sensor on cart {self.cart!r}"
        if self.unit not in SENSOR_UNITS:
            raise ModelError(f"{where}: unit {self.unit!r} is not supported; use one of "
                             f"{tuple(SENSOR_UNITS)}")
        if isinstance(self.sign, bool) or self.sign not in (1, -1):
            raise ModelError(f"{where}: sign must be 1 or -1, got {self.sign!r}")
        sign = int(self.sign)
        fixed = SENSOR_UNITS[self.unit]
        scale = self.m_per_unit
        if scale is not None:
            try:
                scale = float(scale)
            except (TypeError, ValueError):
                raise ModelError(f"{where}: m_per_unit must be a number, got "
                                 f"{self.m_per_unit!r}") from None
            if np.isfinite(scale) and scale < 0:  # a scale counting the other way
                scale, sign = -scale, -sign
        if fixed is None:
            if scale is None:
                raise ModelError(f"{where}: unit 'count' needs m_per_unit (metres per count)")
            scale = _finite_positive(scale, f"{where}: m_per_unit")
        else:
            if scale is not None and scale != fixed:
                raise ModelError(f"{where}: unit {self.unit!r} is {fixed} SI units per unit, "
                                 f"got m_per_unit={self.m_per_unit!r}; drop m_per_unit")
            scale = fixed
        object.__setattr__(self, "m_per_unit", scale)
        object.__setattr__(self, "sign", sign)

    @property
    def kind(self) -> str:
        """``"position"``, ``"velocity"`` or ``"acceleration"``."""
        return SENSOR_KINDS[self.unit]

    @property
    def order(self) -> int:
        """Time derivative of the position measured: 0, 1 or 2."""
        return SENSOR_ORDERS[self.kind]

    @property
    def si_per_unit(self) -> float:
        """Signed scale from the record's unit to SI (m, m/s or m/s^2 along +x)."""
        return self.sign * self.m_per_unit

