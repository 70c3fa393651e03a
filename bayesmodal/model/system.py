"""The rig model: carts on a rail joined by springs and dampers, driven by a motor.

The default rig is a chain: spring ``i`` joins cart ``i`` and cart ``i + 1``; the last spring
joins cart ``n`` to the frame; the motor drives cart 1.  For three carts with
``k = (k1, k2, k3)`` the equations of motion are (report eq. 3, with errata 1 and 2)::

    m1 x1'' = k1 (x2 - x1) + c12 (x2' - x1') - c1 x1' + g_v v
    m2 x2'' = k1 (x1 - x2) + k2 (x3 - x2) + c12 (x1' - x2') + c23 (x3' - x2') - c2 x2'
    m3 x3'' = k2 (x2 - x3) + c23 (x2' - x3') - c3 x3' - k3 x3

so that ``M x'' + C x' + K x = b v`` with ``K[n-1, n-1] = k_{n-1} + k_n`` and
``b = (g_v, 0, ..., 0)``.  The state is ``(x, x')`` and

    A = [[0, I], [-M^-1 K, -M^-1 C]],   B = [0; M^-1 b].

Any other rectilinear layout is described by a ``Rig`` with explicit ``carts``, ``springs``,
``dampers``, ``drive``, ``sensors`` and ``clamped`` carts (see docs/rigs.md and
``bayesmodal.model.rigs`` for the TOML form).  Every two-node element between carts ``i`` and
``j`` with value ``k`` adds ``k`` to ``K[i, i]`` and ``K[j, j]`` and ``-k`` to ``K[i, j]``
and ``K[j, i]``; an element to the frame (or to a clamped cart) adds only ``K[i, i]``.
Clamped carts are not degrees of freedom.  Unknown springs are parameters ``k*`` appended
after the damping parameters; carts of known mass drop out of the parameter vector, as does
``g_v`` when the input gain is known.

Two damping models are supported: ``"free"`` (a damper from each listed cart to the frame,
``c1..cn``, and one across each listed pair, ``c12, c23, ...``; by default every cart and
every spring between two carts) and ``"proportional"`` (``C = ca M + cb K``).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .._errors import ModelError

#: Metres per encoder count of the ECP 210 rig (0.0706 m per 16000 counts).
ECP_M_PER_COUNT = 0.0706 / 16000

__all__ = [
    "default_start",
    "ECP_M_PER_COUNT",
    "Rig",
    "Cart",
    "Spring",
    "Damper",
    "Drive",
    "Sensor",
    "LinearModel",
    "DAMPING_MODELS",
    "ECP210_SPRINGS_N_M",
    "FRAME",
    "MASS_KINDS",
    "SENSOR_UNITS",
    "SENSOR_KINDS",
    "STANDARD_GRAVITY_M_S2",
    "INPUT_KINDS",
]

#: Nominal springs of the ECP Model 210 three-cart rig, N/m (report Table 1).
ECP210_SPRINGS_N_M = (774.0, 770.0, 396.0)

DAMPING_MODELS = ("free", "proportional")

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


def _pair_name(i: int, n: int) -> str:
    # 1-based indices of the relative damper between cart i and cart i+1
    return f"c{i}{i + 1}" if n < 10 else f"c{i}_{i + 1}"


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


def _as_tuple(items, kind, what: str) -> tuple:
    if items is None:
        return None
    if isinstance(items, (str, bytes)) or not isinstance(items, Sequence):
        raise ModelError(f"{what} must be a list, got {items!r}")
    out = tuple(items)
    for it in out:
        if not isinstance(it, kind):
            raise ModelError(f"{what} must hold {kind.__name__} objects, got {it!r}")
    return out


@dataclass(frozen=True)
class Rig:
    """Layout of a rectilinear rig: carts, springs, dampers, drive, sensors, clamps.

    ``Rig()`` is the ECP Model 210 three-cart chain; ``Rig(springs_n_m=(...))`` a chain of
    ``len(springs_n_m)`` carts (spring ``i`` joins cart ``i`` and ``i + 1``, the last one
    joins the last cart to the frame, the motor drives cart 1, an encoder on every cart).
    Any other layout gives ``carts`` and ``springs`` (and optionally the rest); see
    docs/rigs.md and ``bayesmodal.model.rigs.load_rig`` for the TOML form.

    Parameters
    ----------
    springs_n_m : tuple of float, optional
        Chain shorthand: spring stiffnesses, N/m.  Give either this or ``carts``.  After
        construction it holds the nominal stiffness of every spring in ``springs`` order.
    carts : tuple of Cart
        Carts in order; cart ``i`` (1-based) has the parameters ``m<i>`` and ``c<i>``.
    springs : tuple of Spring
    dampers : tuple of Damper, optional
        Dampers of the free damping model; default: one from every unclamped cart to the
        frame and one across every spring joining two unclamped carts.
    drive : tuple of Drive
        Carts the motor pushes; empty for a rig with no input (free decays only).
    sensors : tuple of Sensor, optional
        Measured carts in the order of the record's columns; default every unclamped cart.
    clamped : tuple of str
        Carts fixed to the frame (not degrees of freedom).
    gain_n_v : float, optional
        Known input gain, N/V (then ``g_v`` is not a parameter); default estimated.  A
        force input holds it at 1.
    input : {"voltage", "force"}
        What the record's input column holds: the motor's command voltage, V, through
        the drive gain ``g_v``; or the measured force on the driven carts, N (a load cell
        on a shaker, an instrumented hammer), with the gain fixed at 1 and not a
        parameter.  The force sensor's own noise is not modelled (docs/accelerometers.md
        gives the bias that leaves).  ``[drive] input = "force"`` in TOML.
    damping : {"free", "proportional"}, optional
        The damping model the description declares (``[dampers] proportional = true`` or
        ``false`` in TOML); ``LinearModel`` refuses another one.  None (default): not
        declared, chosen with the model.
    ties : tuple of tuple of str
        Groups of unknown parameters of one kind that share one value (``(("k1", "k2"),)``
        for "you may assume k1 = k2", ``(("m1", "m2"),)`` for equal masses); the first
        name of a group is the parameter, the others follow it.  ``ties = [["k1", "k2"]]``
        in TOML.
    name : str
        Free-text label.

    Examples
    --------
    >>> rig = Rig()
    >>> rig.n_carts
    3
    >>> float(rig.stiffness_matrix()[2, 2])
    1166.0
    >>> two = Rig(carts=(Cart("1"), Cart("2")),
    ...           springs=(Spring("1", "frame", 770.0), Spring("1", "2", 396.0)),
    ...           drive=(Drive("1"),))
    >>> two.stiffness_matrix().tolist()
    [[1166.0, -396.0], [-396.0, 396.0]]
    """

    springs_n_m: tuple[float, ...] | None = None
    carts: tuple[Cart, ...] = ()
    springs: tuple[Spring, ...] = ()
    dampers: tuple[Damper, ...] | None = None
    drive: tuple[Drive, ...] | None = None
    sensors: tuple[Sensor, ...] | None = None
    clamped: tuple[str, ...] = ()
    gain_n_v: float | None = None
    input: str = "voltage"
    damping: str | None = None
    ties: tuple[tuple[str, ...], ...] = ()
    name: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if self.damping is not None and self.damping not in DAMPING_MODELS:
            raise ModelError(f"rig damping must be one of {DAMPING_MODELS} or None (not "
                             f"declared), got {self.damping!r}")
        if not self.carts:
            k = np.asarray(ECP210_SPRINGS_N_M if self.springs_n_m is None else self.springs_n_m,
                           dtype=float)
            if k.ndim != 1 or k.size < 1:
                raise ModelError(
                    f"springs_n_m must be a non-empty 1-D sequence, got {self.springs_n_m!r}"
                )
            if not np.all(np.isfinite(k)) or np.any(k <= 0):
                raise ModelError(
                    f"every spring stiffness must be finite and > 0 N/m, got {k.tolist()}")
            if self.springs:
                raise ModelError("springs given without carts; list the carts too")
            n = k.size
            names = [str(i + 1) for i in range(n)]
            set_(self, "carts", tuple(Cart(c) for c in names))
            set_(self, "springs", tuple(
                Spring(names[i], names[i + 1] if i + 1 < n else FRAME, float(k[i]),
                       name=f"k{i + 1}") for i in range(n)))
            if self.drive is None:
                set_(self, "drive", (Drive("1"),))
            if self.sensors is None:
                set_(self, "sensors", tuple(Sensor(c, "count", ECP_M_PER_COUNT)
                                            for c in names))
        elif self.springs_n_m is not None and tuple(float(k) for k in self.springs_n_m) != tuple(
                float(s.stiffness_n_m) for s in self.springs):
            # (equal values come from dataclasses.replace of a built rig)
            raise ModelError("give either springs_n_m (a chain) or carts and springs, not both "
                             "(with dataclasses.replace of springs pass springs_n_m=None)")
        carts = _as_tuple(self.carts, Cart, "carts")
        springs = _as_tuple(self.springs, Spring, "springs")
        cart_names = [c.name for c in carts]
        dup = sorted({c for c in cart_names if cart_names.count(c) > 1})
        if dup:
            raise ModelError(f"duplicate cart {dup[0]!r}; give every cart a unique name")
        known_ends = set(cart_names) | {FRAME}
        clamped = tuple(str(c) for c in (self.clamped or ()))
        for c in clamped:
            if c not in cart_names:
                raise ModelError(f"clamped cart {c!r} is not a cart; carts are {cart_names}")
        if len(set(clamped)) != len(clamped):
            raise ModelError(f"duplicate clamped cart in {list(clamped)}; list each once")
        free = [c for c in cart_names if c not in clamped]
        if not free:
            raise ModelError("every cart is clamped; leave at least one cart free")

        # springs: ends, names, duplicates
        named = []
        pairs = set()
        for i, s in enumerate(springs):
            for end in (s.a, s.b):
                if end not in known_ends:
                    raise ModelError(f"spring {s.name or i + 1!r} joins unknown cart {end!r}; "
                                     f"carts are {cart_names} (or {FRAME!r})")
            if not s.name:
                s = Spring(s.a, s.b, s.stiffness_n_m, s.known, s.prior_sd_n_m, f"k{i + 1}")
            pair = frozenset((s.a, s.b))
            if pair in pairs:
                raise ModelError(f"duplicate spring between {s.a!r} and {s.b!r}; combine "
                                 "parallel springs into one (stiffnesses add)")
            pairs.add(pair)
            named.append(s)
        snames = [s.name for s in named]
        dup = sorted({s for s in snames if snames.count(s) > 1})
        if dup:
            raise ModelError(f"duplicate spring name {dup[0]!r}; give every spring a unique name")
        clash = [s for s in snames if s in _RESERVED or s[:1] in "mcxv"
                 or s.startswith(("sigma", "phi"))]
        if clash:
            raise ModelError(f"spring name {clash[0]!r} clashes with a parameter name; "
                             "use names such as k1, k_left")
        springs = tuple(named)

        # every free cart must reach the frame (or a clamped cart) through springs
        grounded = {FRAME, *clamped}
        reach = set(grounded)
        changed = True
        while changed:
            changed = False
            for s in springs:
                if (s.a in reach) != (s.b in reach):
                    reach |= {s.a, s.b}
                    changed = True
        lost = [c for c in free if c not in reach]
        if lost:
            raise ModelError(
                f"cart {lost[0]!r} has no spring path to the frame (K is singular); add a "
                "spring from it or a neighbour to the frame, or clamp it")

        # dampers
        if self.dampers is None:
            dampers = tuple(Damper(c) for c in free) + tuple(
                Damper(s.a, s.b) for s in springs
                if s.a in free and s.b in free)
        else:
            dampers = _as_tuple(self.dampers, Damper, "dampers")
            seen = set()
            for d in dampers:
                for end in (d.a, d.b):
                    if end not in known_ends:
                        raise ModelError(f"damper {d.a}-{d.b} joins unknown cart {end!r}; "
                                         f"carts are {cart_names} (or {FRAME!r})")
                    if end in clamped:
                        raise ModelError(f"damper {d.a}-{d.b} ends at clamped cart {end!r}; "
                                         "give it as a damper to the frame instead")
                pair = frozenset((d.a, d.b))
                if pair in seen:
                    raise ModelError(f"duplicate damper between {d.a!r} and {d.b!r}; "
                                     "list each pair once")
                seen.add(pair)
            # ground dampers first (a cart on either end), then pairs, as in the chain
            dampers = tuple(Damper(d.b if d.a == FRAME else d.a) for d in dampers
                            if FRAME in (d.a, d.b)) + tuple(
                d for d in dampers if FRAME not in (d.a, d.b))

        drive = _as_tuple(() if self.drive is None else self.drive, Drive, "drive")
        for d in drive:
            if d.cart not in cart_names:
                raise ModelError(f"driven cart {d.cart!r} is not a cart; carts are {cart_names}")
            if d.cart in clamped:
                raise ModelError(f"driven cart {d.cart!r} is clamped; drive a free cart")
        dcarts = [d.cart for d in drive]
        if len(set(dcarts)) != len(dcarts):
            raise ModelError(f"duplicate driven cart in {dcarts}; list each once")

        sensors = (tuple(Sensor(c) for c in free) if self.sensors is None
                   else _as_tuple(self.sensors, Sensor, "sensors"))
        if not sensors:
            raise ModelError("no sensors; list at least one measured cart")
        for s in sensors:
            if s.cart not in cart_names:
                raise ModelError(f"sensor on {s.cart!r}, which is not a cart; carts are "
                                 f"{cart_names}")
            if s.cart in clamped:
                raise ModelError(f"sensor on clamped cart {s.cart!r}; it never moves, "
                                 "remove it")
        placed = [(s.cart, s.kind) for s in sensors]
        twice = sorted({p for p in placed if placed.count(p) > 1})
        if twice:
            raise ModelError(f"two {twice[0][1]} sensors on cart {twice[0][0]!r}; list one "
                             "sensor of each kind per cart")

        if self.input not in INPUT_KINDS:
            raise ModelError(f"input must be one of {INPUT_KINDS}, got {self.input!r}")
        if self.input == "force":
            if not drive:
                raise ModelError("a force input needs the carts it pushes; list them in "
                                 "[drive] carts")
            if self.gain_n_v is not None and float(self.gain_n_v) != 1.0:
                raise ModelError(f"a force input has gain 1 (N per N), got gain_n_v="
                                 f"{self.gain_n_v!r}; drop gain_n_v")
            set_(self, "gain_n_v", 1.0)
        if self.gain_n_v is not None:
            set_(self, "gain_n_v", _finite_positive(self.gain_n_v, "gain_n_v (N/V)"))
        ties = self.ties or ()
        if isinstance(ties, (str, bytes)) or not isinstance(ties, Sequence):
            raise ModelError(f"ties must be a list of name lists, got {ties!r}")
        groups, seen = [], set()
        for g in ties:
            if isinstance(g, (str, bytes)) or not isinstance(g, Sequence) or len(g) < 2:
                raise ModelError(f"each tie is a list of at least two parameter names, e.g. "
                                 f"[\"k1\", \"k2\"]; got {g!r}")
            g = tuple(str(x) for x in g)
            twice = [x for x in g if x in seen or g.count(x) > 1]
            if twice:
                raise ModelError(f"parameter {twice[0]!r} is in two ties (or twice in one); "
                                 "merge them into one group")
            seen |= set(g)
            groups.append(g)
        set_(self, "ties", tuple(groups))
        set_(self, "carts", carts)
        set_(self, "springs", springs)
        set_(self, "dampers", dampers)
        set_(self, "drive", drive)
        set_(self, "sensors", sensors)
        set_(self, "clamped", clamped)
        set_(self, "springs_n_m", tuple(s.stiffness_n_m for s in springs))

    # ------------------------------------------------------------------ layout
    @property
    def free_carts(self) -> tuple[str, ...]:
        """Names of the carts that move (the degrees of freedom), in order."""
        return tuple(c.name for c in self.carts if c.name not in self.clamped)

    @property
    def n_carts(self) -> int:
        """Number of degrees of freedom (unclamped carts)."""
        return len(self.free_carts)

    @property
    def n_outputs(self) -> int:
        """Number of measured outputs (sensors)."""
        return len(self.sensors)

    @property
    def is_chain(self) -> bool:
        """True for the chain layout ``Rig(springs_n_m=...)`` describes (any sensor units).

        The chain has carts ``"1".."n"`` of unknown mass, spring ``i`` between cart ``i`` and
        ``i + 1`` (the last to the frame), all known, the default dampers, the motor on
        cart 1 with share 1 and unknown gain, a sensor on every cart in order, no clamps.
        """
        cached = self.__dict__.get("_is_chain")
        if cached is None:
            cached = self._chain_layout()
            object.__setattr__(self, "_is_chain", cached)  # not a field: eq and hash ignore it
        return cached

    def _chain_layout(self) -> bool:
        n = len(self.carts)
        names = [str(i + 1) for i in range(n)]
        chain = Rig(springs_n_m=self.springs_n_m) if len(self.springs) == n else None
        return (
            chain is not None
            and [c.name for c in self.carts] == names
            and all(c.mass == "unknown" for c in self.carts)
            and all(s.known for s in self.springs)
            and [(s.a, s.b) for s in self.springs] == [(s.a, s.b) for s in chain.springs]
            and self.dampers == chain.dampers
            and self.drive == chain.drive
            and [s.cart for s in self.sensors] == names
            and all(s.kind == "position" for s in self.sensors)
            and not self.clamped
            and self.gain_n_v is None
            and not self.ties
        )

    @property
    def per_unit_gain(self) -> bool:
        """True when nothing absolute is known (no known mass, spring or input gain) and a
        motor drives the rig: the model then fixes the gain at 1 and every mass, damper
        and spring is identified per unit of drive gain (kg per N/V = V s^2/m, N s/m per
        N/V = V s/m, N/m per N/V = V/m).  Frequencies, damping ratios and mode shapes do
        not depend on the scale."""
        free = self.free_carts
        known_mass = any(c.mass == "known" for c in self.carts if c.name in free)
        known_spring = any(s.known and (s.a in free or s.b in free) for s in self.springs)
        return bool(self.drive) and self.gain_n_v is None and not (known_mass or known_spring)

    def require_chain(self, what: str) -> None:
        """Raise ModelError unless the rig is the chain driven at cart 1 (``is_chain``).

        Parameters
        ----------
        what : str
            What needs the chain, for the message (e.g. ``"the coulomb_friction extension"``).
        """
        if not self.is_chain:
            raise ModelError(
                f"{what}: needs the chain rig (spring i joins cart i to i+1, the last to the "
                "frame, all known; motor on cart 1; a sensor on every cart; no clamps); this "
                "rig is not one, use the linear model (fit_lsq, sample_posterior) instead")

    def cart_index(self, name: str) -> int:
        """1-based position of a cart in ``carts`` (its parameter number)."""
        return [c.name for c in self.carts].index(name) + 1

    @property
    def sensor_dofs(self) -> np.ndarray:
        """Degree of freedom each sensor measures, shape (n_outputs,), in sensor order."""
        free = self.free_carts
        return np.array([free.index(s.cart) for s in self.sensors])

    def output_matrix(self) -> np.ndarray:
        """Which cart each sensor reads, shape (n_outputs, n_carts): ``y = C_out x`` for
        position sensors (m), ``C_out x'`` for velocity and ``C_out x''`` for acceleration
        sensors."""
        free = self.free_carts
        out = np.zeros((self.n_outputs, self.n_carts))
        for i, s in enumerate(self.sensors):
            out[i, free.index(s.cart)] = 1.0
        return out

    @property
    def output_kinds(self) -> tuple[str, ...]:
        """Kind of each sensor in record order: ``"position"``, ``"velocity"`` or
        ``"acceleration"``."""
        return tuple(s.kind for s in self.sensors)

    @property
    def positions_only(self) -> bool:
        """True when every sensor measures a position."""
        return all(s.kind == "position" for s in self.sensors)

    def require_positions(self, what: str) -> None:
        """Raise ModelError unless every sensor measures a position.

        Parameters
        ----------
        what : str
            What needs position outputs, for the message (e.g. ``"the cubic_spring
            extension"``).
        """
        if not self.positions_only:
            kinds = sorted({k for k in self.output_kinds if k != "position"})
            raise ModelError(
                f"{what}: needs position sensors only (m, mm, count), this rig has "
                f"{' and '.join(kinds)} sensors; fit the linear model (fit_lsq, "
                "sample_posterior), which simulates every sensor kind")

    def input_vector(self) -> np.ndarray:
        """Drive shares per degree of freedom, shape (n_carts,); ``b = g_v * input_vector``."""
        free = self.free_carts
        d = np.zeros(self.n_carts)
        for dr in self.drive:
            d[free.index(dr.cart)] = dr.share
        return d

    def stiffness_matrix(self) -> np.ndarray:
        """Stiffness matrix K, shape (n, n), N/m (unknown springs at their nominal value)."""
        if self.is_chain:
            return chain_matrix(np.asarray(self.springs_n_m), grounded_last=True)
        return sum(s.stiffness_n_m * self.element_pattern(s.a, s.b) for s in self.springs)

    def element_pattern(self, a: str, b: str) -> np.ndarray:
        """Unit matrix of a two-node element, shape (n_carts, n_carts).

        ``+1`` on the diagonal of each free end, ``-1`` off the diagonal when both ends are
        free; an end at the frame or at a clamped cart contributes nothing.
        """
        free = self.free_carts
        idx = [free.index(e) for e in (a, b) if e in free]
        out = np.zeros((self.n_carts, self.n_carts))
        for i in idx:
            out[i, i] += 1.0
        if len(idx) == 2:
            out[idx[0], idx[1]] -= 1.0
            out[idx[1], idx[0]] -= 1.0
        return out


#: Names a spring may not take (they are other parameters).
_RESERVED = ("g_v", "ca", "cb")


def chain_matrix(elements: np.ndarray, *, grounded_last: bool) -> np.ndarray:
    """Assemble the matrix of a chain of two-node elements.

    Parameters
    ----------
    elements : ndarray, shape (..., m)
        Element values; element ``i`` (0-based) joins node ``i`` and ``i + 1``.  If
        ``grounded_last`` the last element joins the last node to ground, so that the chain
        has ``m`` nodes; otherwise it has ``m + 1`` nodes.

    Returns
    -------
    ndarray, shape (..., n, n)
    """
    e = np.asarray(elements, dtype=float)
    m = e.shape[-1]
    n = m if grounded_last else m + 1
    out = np.zeros(e.shape[:-1] + (n, n))
    n_links = n - 1
    for i in range(n_links):
        k = e[..., i]
        out[..., i, i] += k
        out[..., i + 1, i + 1] += k
        out[..., i, i + 1] -= k
        out[..., i + 1, i] -= k
    if grounded_last:
        out[..., n - 1, n - 1] += e[..., m - 1]
    return out


@dataclass(frozen=True)
class _Layout:
    """Where each parameter goes in M, C, K and b (built once per LinearModel)."""

    names: tuple[str, ...]
    gain: int | None  # index of g_v, or None (known gain or no drive)
    mass_idx: np.ndarray  # parameter indices of the unknown masses
    mass_dof: np.ndarray  # their degrees of freedom
    masses0: np.ndarray  # known masses (1 where a parameter fills in), kg
    k_idx: np.ndarray  # parameter indices of the unknown springs
    k_pat: np.ndarray  # (n_k, n, n) unit patterns
    K0: np.ndarray  # known part of K, N/m
    c_idx: np.ndarray  # free damping: parameter indices
    c_pat: np.ndarray  # (n_c, n, n)
    positive: np.ndarray  # bool mask of parameters that must be > 0
    outputs: np.ndarray | None  # sensor DOF indices, None when every DOF in order


def _layout(rig: Rig, damping: str) -> _Layout:
    n = rig.n_carts
    free = rig.free_carts
    n_all = len(rig.carts)
    names: list[str] = []
    positive: list[bool] = []
    gain = None
    if rig.drive and rig.gain_n_v is None and not rig.per_unit_gain:
        gain = 0
        names.append("g_v")
        positive.append(True)
    mass_idx, mass_dof = [], []
    masses0 = np.ones(n)
    for c in rig.carts:
        if c.name not in free:
            continue
        dof = free.index(c.name)
        if c.mass == "known":
            masses0[dof] = c.mass_kg
        else:
            mass_idx.append(len(names))
            mass_dof.append(dof)
            names.append(f"m{rig.cart_index(c.name)}")
            positive.append(True)
    c_idx, c_pat = [], []
    if damping == "proportional":
        names += ["ca", "cb"]
        positive += [True, False]
    else:
        for d in rig.dampers:
            if d.b == FRAME:
                names.append(f"c{rig.cart_index(d.a)}")
                positive.append(True)
            else:
                i, j = sorted((rig.cart_index(d.a), rig.cart_index(d.b)))
                names.append(f"c{i}{j}" if n_all < 10 else f"c{i}_{j}")
                positive.append(False)
            c_idx.append(len(names) - 1)
            c_pat.append(rig.element_pattern(d.a, d.b))
    K0 = np.zeros((n, n))
    k_idx, k_pat = [], []
    for s in rig.springs:
        pat = rig.element_pattern(s.a, s.b)
        if s.known:
            K0 = K0 + s.stiffness_n_m * pat
        else:
            k_idx.append(len(names))
            k_pat.append(pat)
            names.append(s.name)
            positive.append(True)
    outputs = rig.sensor_dofs
    if (outputs.size == n and np.array_equal(outputs, np.arange(n))
            and rig.positions_only):
        outputs = None
    if rig.ties:
        names, positive, (gain, mass_idx, c_idx, k_idx) = _apply_ties(
            rig, names, positive, (gain, mass_idx, c_idx, k_idx))
    return _Layout(
        names=tuple(names), gain=gain, mass_idx=np.array(mass_idx, int),
        mass_dof=np.array(mass_dof, int), masses0=masses0, k_idx=np.array(k_idx, int),
        k_pat=np.array(k_pat).reshape(-1, n, n), K0=K0, c_idx=np.array(c_idx, int),
        c_pat=np.array(c_pat).reshape(-1, n, n), positive=np.array(positive, bool),
        outputs=outputs)


def _kind_of(name: str) -> str:
    """``gain``, ``mass``, ``damper`` or ``spring`` of a linear parameter name."""
    if name == "g_v":
        return "gain"
    if name[0] == "m" and name[1:].isdigit():
        return "mass"
    if name in ("ca", "cb") or (name[0] == "c" and name[1:].replace("_", "").isdigit()):
        return "damper"
    return "spring"


def _apply_ties(rig: Rig, names: list, positive: list, index_lists: tuple):
    """Merge each tie group into its first parameter: the names and positivity without the
    followers, and every parameter index (``None``, an int or a list) mapped to the new
    vector, a follower to its group's first parameter."""
    head = {}
    for g in rig.ties:
        unknown = [x for x in g if x not in names]
        if unknown:
            springs = {s.name: s for s in rig.springs}
            hint = (f"spring {unknown[0]} is known; only unknown springs (known = false) can "
                    "be tied" if unknown[0] in springs else
                    f"the model's parameters are {tuple(names)}")
            raise ModelError(f"tie {list(g)}: {unknown[0]!r} is not a parameter ({hint})")
        kinds = {_kind_of(x) for x in g}
        if len(kinds) > 1:
            raise ModelError(f"tie {list(g)} joins parameters of different kinds ({sorted(kinds)});"
                             " tie masses with masses, springs with springs, dampers with "
                             "dampers")
        for x in g[1:]:
            head[x] = g[0]
    kept = [x for x in names if x not in head]
    new = {x: kept.index(head.get(x, x)) for x in names}

    def remap(idx):
        if idx is None:
            return None
        if isinstance(idx, int):
            return new[names[idx]]
        return [new[names[j]] for j in idx]

    pos = [p for x, p in zip(names, positive, strict=True) if x not in head]
    return kept, pos, tuple(remap(i) for i in index_lists)


def _check_scale(rig: Rig) -> None:
    # Scaling every mass, damper and spring by a factor a scales the motion by 1/a under a
    # fixed force, and leaves a free decay unchanged: something absolute must be known.
    free = rig.free_carts
    known_mass = any(c.mass == "known" for c in rig.carts if c.name in free)
    known_spring = any(s.known and (s.a in free or s.b in free) for s in rig.springs)
    known_gain = rig.gain_n_v is not None and bool(rig.drive)
    if not (known_mass or known_spring or known_gain or rig.per_unit_gain):
        raise ModelError(
            "masses, springs and input gain cannot be separated (all unknown: scaling them "
            "together gives the same motion); add a known mass (mass = \"known\", mass_kg), "
            "a known spring (known = true) or the input gain from a static-gain record "
            "(gain_n_v, see `bayesmodal static`)")


@dataclass(frozen=True)
class LinearModel:
    """Linear rig model with a chosen damping model.

    Parameters
    ----------
    rig : Rig
        Layout, known masses and springs.
    damping : {"free", "proportional"}
        Damping model.

    Attributes
    ----------
    names : tuple of str
        Parameter names in vector order: ``g_v`` (unless the gain is known), the unknown
        masses ``m<i>``, the damping (``c<i>`` to the frame, then ``c<i><j>`` across pairs;
        or ``ca, cb``), then the unknown springs.  For ``Rig()``: ``("g_v", "m1", "m2",
        "m3", "c1", "c2", "c3", "c12", "c23")`` or ``("g_v", "m1", "m2", "m3", "ca",
        "cb")``.  Units: g_v N/V, masses kg, c* N s/m, ca 1/s, cb s, k* N/m.

    Raises
    ------
    ModelError
        For an unknown damping model, or a rig whose masses, springs and gain are all
        unknown (see ``docs/rigs.md``).

    Examples
    --------
    >>> model = LinearModel(Rig(), "proportional")
    >>> model.names
    ('g_v', 'm1', 'm2', 'm3', 'ca', 'cb')
    """

    rig: Rig = field(default_factory=Rig)
    damping: str = "free"

    def __post_init__(self) -> None:
        if self.damping not in DAMPING_MODELS:
            raise ModelError(f"damping must be one of {DAMPING_MODELS}, got {self.damping!r}")
        if not isinstance(self.rig, Rig):
            raise ModelError(f"rig must be a Rig, got {type(self.rig).__name__}")
        if self.rig.damping is not None and self.rig.damping != self.damping:
            raise ModelError(
                f"the rig declares {self.rig.damping} damping ([dampers] proportional = "
                f"{str(self.rig.damping == 'proportional').lower()}) but {self.damping} "
                "damping was asked for; drop one of the two")
        _check_scale(self.rig)
        chain = self.rig.is_chain
        object.__setattr__(self, "_chain", chain)
        object.__setattr__(self, "_layout", None if chain else _layout(self.rig, self.damping))

    @property
    def n_carts(self) -> int:
        """Number of degrees of freedom (unclamped carts)."""
        return self.rig.n_carts

    @property
    def n_outputs(self) -> int:
        """Number of measured outputs (the rig's sensors)."""
        return self.rig.n_outputs

    @property
    def output_index(self) -> np.ndarray | None:
        """Degree of freedom of each output, shape (n_outputs,); None for all, in order."""
        return None if self._chain else self._layout.outputs

    @functools.cached_property
    def output_spec(self) -> np.ndarray | None:
        """Degree of freedom and time derivative (0 position, 1 velocity, 2 acceleration)
        of each output, shape (n_outputs, 2) int; None when every sensor reads a position
        (the outputs are then the positions ``output_index`` picks)."""
        if self.rig.positions_only:
            return None
        free = self.rig.free_carts
        return np.array([(free.index(s.cart), s.order) for s in self.rig.sensors],
                        dtype=np.int64)

    @property
    def n_states(self) -> int:
        return 2 * self.rig.n_carts

    @functools.cached_property  # (read on every likelihood call: built once)
    def names(self) -> tuple[str, ...]:
        if not self._chain:
            return self._layout.names
        n = self.rig.n_carts
        masses = tuple(f"m{i + 1}" for i in range(n))
        if self.damping == "proportional":
            return ("g_v",) + masses + ("ca", "cb")
        absolute = tuple(f"c{i + 1}" for i in range(n))
        relative = tuple(_pair_name(i + 1, n) for i in range(n - 1))
        return ("g_v",) + masses + absolute + relative

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def scale(self) -> str:
        """``"absolute"``, or ``"per_unit_gain"`` when nothing absolute is known
        (``Rig.per_unit_gain``: masses in V s^2/m, dampers in V s/m, springs in V/m)."""
        return "per_unit_gain" if self.rig.per_unit_gain else "absolute"

    @property
    def tied(self) -> dict[str, str]:
        """Each tied parameter that follows another: ``{"k2": "k1"}`` for ``ties =
        [["k1", "k2"]]``."""
        return {x: g[0] for g in self.rig.ties for x in g[1:]}

    def as_vector(self, params: dict[str, float]) -> np.ndarray:
        """Parameter vector, shape (n_params,), from a name-to-value mapping.

        Raises
        ------
        ModelError
            If a name is missing or unknown.
        """
        missing = [n for n in self.names if n not in params]
        unknown = [n for n in params if n not in self.names]
        if missing or unknown:
            raise ModelError(
                f"parameters for damping={self.damping!r}: missing {missing}, unknown {unknown}"
            )
        return np.array([float(params[n]) for n in self.names])

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        """Name-to-value mapping of a parameter vector of shape (n_params,)."""
        theta = np.asarray(theta, dtype=float)
        return {n: float(v) for n, v in zip(self.names, theta, strict=True)}

    # ------------------------------------------------------------------ validity
    def valid(self, theta: np.ndarray) -> np.ndarray:
        """Boolean mask, shape (...,), of physically admissible parameter sets.

        Admissible: finite, g_v > 0, masses > 0, unknown springs > 0, every damping
        coefficient >= 0.  For proportional damping ``ca >= 0`` and ``cb >= 0`` (which
        makes C positive semi-definite and the system stable).
        """
        theta = np.asarray(theta, dtype=float)
        ok = np.all(np.isfinite(theta), axis=-1)
        if not self._chain:
            pos = self._layout.positive
            ok &= np.all(theta[..., pos] > 0, axis=-1)
            ok &= np.all(theta[..., ~pos] >= 0, axis=-1)
            return ok
        n = self.rig.n_carts
        ok &= theta[..., 0] > 0
        ok &= np.all(theta[..., 1 : 1 + n] > 0, axis=-1)
        ok &= np.all(theta[..., 1 + n :] >= 0, axis=-1)
        return ok

    def check(self, theta: np.ndarray) -> np.ndarray:
        """Validate and return theta as a float array of shape (..., n_params)."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape[-1:] != (self.n_params,):
            raise ModelError(
                f"parameter vector must have length {self.n_params} {self.names}, "
                f"got shape {theta.shape}"
            )
        bad = ~self.valid(theta)
        if np.any(bad):
            first = theta[bad][0] if theta.ndim > 1 else theta
            springs = "" if self._chain else ", springs > 0"
            raise ModelError(
                "impossible parameters (need finite values, g_v > 0, masses > 0, damping >= 0"
                f"{springs}): {self.as_dict(first)}"
            )
        return theta

    # ------------------------------------------------------------------ matrices
    def matrices(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Mass, damping, stiffness matrices and input vector.

        Parameters
        ----------
        theta : ndarray, shape (..., n_params)

        Returns
        -------
        M, C, K : ndarray, shape (..., n, n)
            kg, N s/m, N/m, over the degrees of freedom (unclamped carts).
        b : ndarray, shape (..., n)
            Force per volt at each cart, N/V.
        """
        theta = np.asarray(theta, dtype=float)
        if not self._chain:
            return self._general_matrices(theta)
        n = self.rig.n_carts
        batch = theta.shape[:-1]
        masses = theta[..., 1 : 1 + n]
        M = masses[..., :, None] * np.eye(n)
        K = np.broadcast_to(self.rig.stiffness_matrix(), batch + (n, n)).copy()
        if self.damping == "proportional":
            ca = theta[..., 1 + n]
            cb = theta[..., 2 + n]
            C = ca[..., None, None] * M + cb[..., None, None] * K
        else:
            absolute = theta[..., 1 + n : 1 + 2 * n]
            relative = theta[..., 1 + 2 * n :]
            C = chain_matrix(relative, grounded_last=False) if n > 1 else np.zeros(batch + (1, 1))
            C = C + absolute[..., :, None] * np.eye(n)
        b = np.zeros(batch + (n,))
        b[..., 0] = theta[..., 0]
        return M, C, K, b

    def _general_matrices(self, theta: np.ndarray):
        lay = self._layout
        n = self.rig.n_carts
        batch = theta.shape[:-1]
        masses = np.broadcast_to(lay.masses0, batch + (n,)).copy()
        masses[..., lay.mass_dof] = theta[..., lay.mass_idx]
        M = masses[..., :, None] * np.eye(n)
        K = lay.K0 + np.einsum("...j,jab->...ab", theta[..., lay.k_idx], lay.k_pat)
        if self.damping == "proportional":
            ia = self.names.index("ca")
            C = theta[..., ia, None, None] * M + theta[..., ia + 1, None, None] * K
        else:
            C = np.einsum("...j,jab->...ab", theta[..., lay.c_idx], lay.c_pat)
        if lay.gain is not None:
            g = theta[..., lay.gain]
        elif self.rig.per_unit_gain:
            g = np.ones(batch)  # everything per unit of drive gain
        else:
            g = np.full(batch, self.rig.gain_n_v if self.rig.gain_n_v is not None else 0.0)
        b = g[..., None] * self.rig.input_vector()
        return M, C, K, b

    def state_space(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Continuous state-space matrices for state ``(x, x')`` and input v.

        Returns
        -------
        A : ndarray, shape (..., 2n, 2n), 1/s and 1/s^2 blocks
        B : ndarray, shape (..., 2n), m/(V s^2) in the acceleration block
        """
        return state_space_from(*self.matrices(theta))


def state_space_from(M, C, K, b) -> tuple[np.ndarray, np.ndarray]:
    """State-space matrices of ``M x'' + C x' + K x = b v`` for state ``(x, x')``.

    Parameters
    ----------
    M, C, K : ndarray, shape (..., n, n)
        Mass (diagonal, kg), damping (N s/m) and stiffness (N/m) matrices.
    b : ndarray, shape (..., n)
        Force per volt, N/V.

    Returns
    -------
    A : ndarray, shape (..., 2n, 2n), 1/s and 1/s^2 blocks
    B : ndarray, shape (..., 2n), m/(V s^2) in the acceleration block
    """
    n = M.shape[-1]
    inv_m = 1.0 / np.diagonal(M, axis1=-2, axis2=-1)  # M is diagonal
    batch = M.shape[:-2]
    A = np.zeros(batch + (2 * n, 2 * n))
    A[..., :n, n:] = np.eye(n)
    A[..., n:, :n] = -inv_m[..., :, None] * K
    A[..., n:, n:] = -inv_m[..., :, None] * C
    B = np.zeros(batch + (2 * n,))
    B[..., n:] = inv_m * b
    return A, B


def param_kinds(model: LinearModel) -> tuple[str, ...]:
    """Kind of each parameter: gain, mass, ground (damper), pair (damper), ca, cb, spring."""
    out = []
    for name in model.names:
        if name == "g_v":
            out.append("gain")
        elif name in ("ca", "cb"):
            out.append(name)
        elif name[0] == "m" and name[1:].isdigit():
            out.append("mass")
        elif name[0] == "c" and name[1:].isdigit() and int(name[1:]) <= len(model.rig.carts):
            out.append("ground")
        elif name[0] == "c":
            out.append("pair")
        else:
            out.append("spring")
    return tuple(out)


def log_scale_mask(model: LinearModel) -> np.ndarray:
    """Parameters a fit moves on a log scale, shape (n_params,) bool: the positive scale
    parameters (gain, masses, dampers to the frame, ``ca``, springs); the dampers across
    two carts and ``cb``, which may vanish, stay linear."""
    return np.array([k in ("gain", "mass", "ground", "ca", "spring")
                     for k in param_kinds(model)])


def damper_mask(model: LinearModel) -> np.ndarray:
    """The free damping model's dampers (to the frame and across two carts), shape
    (n_params,) bool."""
    return np.array([k in ("ground", "pair") for k in param_kinds(model)])


#: Damping ratio a damper at a cart of given mass starts from (``default_start``).
START_DAMPING_RATIO = 0.05


def default_start(model: LinearModel) -> np.ndarray:
    """A neutral starting point: g_v 5.25 N/V (nominal), masses 1 kg, small damping.

    Carts of nominal mass start at their mass and unknown springs at their nominal stiffness;
    a damper to the frame at a cart of given mass ``m`` (diagonal stiffness ``k``) starts
    at ``2 START_DAMPING_RATIO sqrt(m k)``, one across a pair at a tenth of that.  On a rig
    identified per unit of drive gain (``Rig.per_unit_gain``) masses, dampers and springs
    start at these values divided by the nominal gain.

    Parameters
    ----------
    model : LinearModel

    Returns
    -------
    ndarray, shape (n_params,)
        In ``model.names`` order.
    """
    n = model.n_carts
    if model.rig.is_chain:
        if model.damping == "proportional":
            tail = [1.0, 1e-4]
        else:
            tail = [1.0] * n + [0.1] * (n - 1)
        return np.array([5.25] + [1.0] * n + tail)
    rig = model.rig
    nominal_mass = {f"m{rig.cart_index(c.name)}": c.mass_kg for c in rig.carts
                    if c.mass_kg is not None}
    springs = {s.name: s.stiffness_n_m for s in rig.springs}
    base = {"gain": 5.25, "ground": 1.0, "pair": 0.1, "ca": 1.0, "cb": 1e-4}
    # per unit of drive gain: the nominal values divided by the nominal gain (the
    # natural frequencies of the start are the nominal ones)
    per_unit = 1.0 / base["gain"] if rig.per_unit_gain else 1.0
    # the dampers' starts are a 1 kg cart's; a damper at a cart whose mass is given starts
    # at a damping ratio of START_DAMPING_RATIO, c = 2 zeta sqrt(m k) (a torsional disk of
    # 2e-3 kg m^2 on 5.3 N m/rad starts at 0.01 N m s/rad, not at a damping ratio of 7,
    # from which the fit does not find its way)
    ratio = {}
    if model.damping == "free":
        diag = np.diag(rig.stiffness_matrix())
        mass = {c.name: c.mass_kg for c in rig.carts if c.mass_kg is not None}
        free = rig.free_carts
        for name, d in zip([n for n, k in zip(model.names, param_kinds(model), strict=True)
                            if k in ("ground", "pair")], rig.dampers, strict=True):
            ends = [e for e in (d.a, d.b) if e in mass]
            if ends:
                c = 2 * START_DAMPING_RATIO * np.sqrt(mass[ends[0]] * diag[free.index(ends[0])])
                ratio[name] = c / base["ground"]
    out = []
    for name, kind in zip(model.names, param_kinds(model), strict=True):
        if kind == "mass":
            out.append(nominal_mass.get(name, 1.0) * per_unit)
        elif kind == "spring":
            out.append(springs[name] * per_unit)
        elif kind in ("ground", "pair"):
            out.append(base[kind] * ratio.get(name, 1.0) * per_unit)
        else:
            out.append(base[kind])
    return np.array(out)
