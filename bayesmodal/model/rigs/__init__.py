"""Rig descriptions as TOML files, and the shipped presets.

A description lists the carts, springs, dampers, drive, sensors and clamped carts of a
rectilinear rig (see docs/rigs.md for a walk-through)::

    name = "ECP 210, two carts, frame spring at the driven cart"
    clamped = []                        # optional
    ties = [["k1", "k2"]]               # optional: unknown parameters that share one
                                        # value (equal springs, equal masses)

    [[carts]]
    name = "1"
    mass = "unknown"                    # "unknown" | "nominal" | "known"; mass_kg for the last two

    [[springs]]
    name = "k1"                         # optional (default k<index>)
    between = ["1", "frame"]
    stiffness_n_m = 770.0
    known = true                        # false: estimated; prior_sd_n_m = ... optional

    [dampers]                           # optional; default: every cart to the frame and
    ground = ["1", "2"]                 # across every spring between two carts
    pairs = [["1", "2"]]
    # or: proportional = true           # C = ca M + cb K (no ground/pairs then); false
                                        # declares the free model

    [drive]                             # optional; omitted: no input (free decays)
    carts = ["1"]
    shares = [1.0]                      # optional
    gain_n_v = 6.2                      # optional: a known input gain (else g_v is estimated)
    input = "voltage"                   # optional: "force" for a measured force in N
                                        # (gain 1, no g_v; no gain_n_v then)

    [[sensors]]                         # optional; default: every free cart, metres
    cart = "1"
    unit = "count"                      # position "m" | "mm" | "count", velocity "m/s",
                                        # acceleration "m/s^2" | "g" (9.80665 m/s^2)
    m_per_unit = 4.4125e-06             # counts only (negative: counting the other way)
    sign = 1                            # optional: -1 for a sensor facing -x

Several sensors may sit on one cart when their kinds differ (an encoder and an
accelerometer).  Records hold each sensor's reading in SI units of its kind (m, m/s,
m/s^2), each along +x.

With no known mass, spring or gain the rig is identified per unit of drive gain
(``Rig.per_unit_gain``).

The presets ship as package data (``bayesmodal/model/rigs/*.toml``); ``load_rig`` accepts a
preset name or a path.  ``ecp210-3cart`` is ``Rig()``, the layout of the reference report.
"""

from __future__ import annotations

import os
import tempfile
import tomllib
from collections.abc import Mapping
from importlib import resources
from pathlib import Path

import tomli_w

from ..._errors import ModelError
from ..elements import FRAME, Cart, Damper, Drive, Sensor, Spring
from ..rig import Rig

__all__ = [
    "PRESETS",
    "DEFAULT_PRESET",
    "load_rig",
    "save_rig",
    "rig_from_dict",
    "rig_to_dict",
    "rig_from_toml",
    "rig_to_toml",
]

#: Names of the shipped rig descriptions.
PRESETS = ("ecp210-1cart", "ecp210-2cart", "ecp210-2cart-frame-at-drive", "ecp210-3cart")

#: The layout of the reference report (equal to ``Rig()``).
DEFAULT_PRESET = "ecp210-3cart"

_TOP = {"name", "clamped", "carts", "springs", "dampers", "drive", "sensors", "ties"}
_CART = {"name", "mass", "mass_kg"}
_SPRING = {"name", "between", "stiffness_n_m", "known", "prior_sd_n_m"}
_DAMPERS = {"ground", "pairs", "proportional"}
_DRIVE = {"carts", "shares", "gain_n_v", "input"}
_SENSOR = {"cart", "unit", "m_per_unit", "sign"}


def _keys(table, allowed: set[str], where: str) -> Mapping:
    if not isinstance(table, Mapping):
        raise ModelError(f"{where} must be a table, got {table!r}")
    extra = sorted(set(table) - allowed)
    if extra:
        raise ModelError(f"{where}: unknown key {extra[0]!r}; allowed: {sorted(allowed)}")
    return table


def _names(value, where: str) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, list):
        raise ModelError(f"{where} must be a list of cart names, got {value!r}")
    return tuple(str(v) for v in value)


def _tables(value, where: str) -> list:
    if not isinstance(value, list):
        raise ModelError(f"{where} must be an array of tables ([[{where}]]), got {value!r}")
    return value


def _ties(value, where: str) -> tuple[tuple[str, ...], ...]:
    if not isinstance(value, list) or not all(isinstance(g, list) for g in value):
        raise ModelError(f"{where}: ties must be a list of name lists, e.g. ties = "
                         f"[[\"k1\", \"k2\"]], got {value!r}")
    return tuple(tuple(str(x) for x in g) for g in value)


def rig_from_dict(d: Mapping, *, where: str = "rig") -> Rig:
    """Build a ``Rig`` from the parsed TOML tables (see the module docstring).

    Parameters
    ----------
    d : mapping
        Top-level table of a rig description.
    where : str
        Prefix of error messages (a file name).

    Raises
    ------
    ModelError
        One line naming the problem and the fix (unknown key, spring to an unknown cart,
        duplicate element, cart with no path to the frame, unsupported sensor unit, ...).

    Examples
    --------
    >>> rig = rig_from_dict({"carts": [{"name": "1"}],
    ...                      "springs": [{"between": ["1", "frame"], "stiffness_n_m": 500.0}],
    ...                      "drive": {"carts": ["1"]}})
    >>> rig.n_carts, rig.springs[0].name
    (1, 'k1')
    """
    _keys(d, _TOP, where)
    if "carts" not in d or "springs" not in d:
        raise ModelError(f"{where}: a rig needs [[carts]] and [[springs]] tables")
    try:
        carts = []
        for i, c in enumerate(_tables(d["carts"], "carts")):
            c = _keys(c, _CART, f"{where}: carts[{i}]")
            if "name" not in c:
                raise ModelError(f"{where}: carts[{i}] needs a name")
            carts.append(Cart(str(c["name"]), c.get("mass", "unknown"), c.get("mass_kg")))
        springs = []
        for i, s in enumerate(_tables(d["springs"], "springs")):
            s = _keys(s, _SPRING, f"{where}: springs[{i}]")
            ends = _names(s.get("between"), f"{where}: springs[{i}].between")
            if len(ends) != 2 or "stiffness_n_m" not in s:
                raise ModelError(f"{where}: springs[{i}] needs between = [cart, cart or "
                                 f"{FRAME!r}] and stiffness_n_m")
            springs.append(Spring(ends[0], ends[1], s["stiffness_n_m"], s.get("known", True),
                                  s.get("prior_sd_n_m"), str(s.get("name", ""))))
        dampers = None
        damping = None
        if "dampers" in d:
            t = _keys(d["dampers"], _DAMPERS, f"{where}: dampers")
            prop = t.get("proportional")
            if prop is not None:
                if not isinstance(prop, bool):
                    raise ModelError(f"{where}: dampers.proportional must be true or false, "
                                     f"got {prop!r}")
                damping = "proportional" if prop else "free"
                if prop and ("ground" in t or "pairs" in t):
                    raise ModelError(
                        f"{where}: dampers.proportional = true (C = ca M + cb K) contradicts "
                        "the listed dampers ground/pairs; remove one or the other")
        if "dampers" in d and set(t) != {"proportional"}:
            # (only "proportional" given: the default dampers)
            dampers = [Damper(c) for c in _names(t.get("ground", []), "dampers.ground")]
            for p in t.get("pairs", []):
                ends = _names(p, f"{where}: dampers.pairs")
                if len(ends) != 2:
                    raise ModelError(f"{where}: dampers.pairs entries are [cart, cart], got {p!r}")
                dampers.append(Damper(*ends))
        drive = ()
        gain = None
        input_kind = "voltage"
        if "drive" in d:
            t = _keys(d["drive"], _DRIVE, f"{where}: drive")
            dc = _names(t.get("carts", []), f"{where}: drive.carts")
            shares = t.get("shares", [1.0] * len(dc))
            if not isinstance(shares, list) or len(shares) != len(dc):
                raise ModelError(f"{where}: drive.shares needs one number per driven cart "
                                 f"{list(dc)}, got {shares!r}")
            drive = tuple(Drive(c, s) for c, s in zip(dc, shares, strict=True))
            gain = t.get("gain_n_v")
            input_kind = t.get("input", "voltage")
        sensors = None
        if "sensors" in d:
            sensors = []
            for i, s in enumerate(_tables(d["sensors"], "sensors")):
                s = _keys(s, _SENSOR, f"{where}: sensors[{i}]")
                if "cart" not in s:
                    raise ModelError(f"{where}: sensors[{i}] needs a cart")
                sensors.append(Sensor(str(s["cart"]), s.get("unit", "m"), s.get("m_per_unit"),
                                      s.get("sign", 1)))
        return Rig(carts=tuple(carts), springs=tuple(springs),
                   dampers=None if dampers is None else tuple(dampers), drive=drive,
                   sensors=None if sensors is None else tuple(sensors),
                   clamped=_names(d.get("clamped", []), f"{where}: clamped"),
                   gain_n_v=gain, input=input_kind, damping=damping,
                   ties=_ties(d.get("ties", []), where),
                   name=str(d.get("name", "")))
    except ModelError as exc:
        msg = str(exc)
        raise ModelError(msg if msg.startswith(where) else f"{where}: {msg}") from None


def rig_to_dict(rig: Rig) -> dict:
    """The TOML tables of a rig (every default written out), inverse of ``rig_from_dict``.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    dict
        Nested tables of plain values, ready for ``tomli_w``.
    """
    d: dict = {"name": rig.name, "clamped": list(rig.clamped), "carts": [], "springs": []}
    for c in rig.carts:
        t = {"name": c.name, "mass": c.mass}
        if c.mass_kg is not None:
            t["mass_kg"] = c.mass_kg
        d["carts"].append(t)
    for s in rig.springs:
        t = {"name": s.name, "between": [s.a, s.b], "stiffness_n_m": s.stiffness_n_m,
             "known": s.known}
        if s.prior_sd_n_m is not None:
            t["prior_sd_n_m"] = s.prior_sd_n_m
        d["springs"].append(t)
    if rig.damping == "proportional":
        d["dampers"] = {"proportional": True}
    else:
        d["dampers"] = {"ground": [x.a for x in rig.dampers if x.b == FRAME],
                        "pairs": [[x.a, x.b] for x in rig.dampers if x.b != FRAME]}
        if rig.damping == "free":
            d["dampers"]["proportional"] = False
    if rig.drive:
        d["drive"] = {"carts": [x.cart for x in rig.drive],
                      "shares": [x.share for x in rig.drive]}
        if rig.input == "force":
            d["drive"]["input"] = "force"
        elif rig.gain_n_v is not None:
            d["drive"]["gain_n_v"] = rig.gain_n_v
    d["sensors"] = [{"cart": s.cart, "unit": s.unit, "m_per_unit": s.m_per_unit}
                    | ({"sign": -1} if s.sign < 0 else {}) for s in rig.sensors]
    if rig.ties:
        d["ties"] = [list(g) for g in rig.ties]
    return d


def rig_from_toml(text: str, *, where: str = "rig") -> Rig:
    """Parse a TOML rig description; a syntax error becomes a one-line ModelError.

    Parameters
    ----------
    text : str
        The TOML text (the tables ``rig_to_toml`` writes).
    where : str
        Where the text comes from, opening error messages (a file name, ``"[rig]"``).

    Returns
    -------
    Rig
    """
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelError(f"{where}: not valid TOML ({exc})") from None
    return rig_from_dict(d, where=where)


def rig_to_toml(rig: Rig) -> str:
    """TOML text of a rig; ``rig_from_toml(rig_to_toml(rig)) == rig``.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    str
    """
    return tomli_w.dumps(rig_to_dict(rig))


def _preset_text(name: str) -> str:
    return resources.files(__name__).joinpath(f"{name}.toml").read_text(encoding="utf-8")


def load_rig(source: str | os.PathLike) -> Rig:
    """A rig from a preset name (``PRESETS``) or a TOML file.

    Parameters
    ----------
    source : str or path
        A preset name (``"ecp210-3cart"``) or the path of a TOML rig description.

    Returns
    -------
    Rig

    Raises
    ------
    ModelError
        When the file does not exist or its description is invalid.

    Examples
    --------
    >>> load_rig("ecp210-3cart") == Rig()
    True
    """
    if isinstance(source, str) and source in PRESETS:
        return rig_from_toml(_preset_text(source), where=source)
    path = Path(source)
    if not path.is_file():
        raise ModelError(f"rig file not found: {str(source)!r}; give a TOML file or one of "
                         f"the presets {PRESETS}")
    return rig_from_toml(path.read_text(encoding="utf-8"), where=str(path))


def save_rig(rig: Rig, path: str | os.PathLike) -> None:
    """Write a rig description as TOML, atomically (temporary file, then rename).

    Parameters
    ----------
    rig : Rig
    path : str or path
        The TOML file to write; replaced if it exists.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(rig_to_toml(rig))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
