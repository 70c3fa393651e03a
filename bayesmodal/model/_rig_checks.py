"""The checks of a rig description, one step of ``Rig.__post_init__`` each.

Each takes what a description gives (carts, clamps, springs, dampers, drive, sensors,
input, ties), raises ``ModelError`` naming what to change when the step fails, and returns
the elements as ``Rig`` keeps them: tuples, every spring named, the dampers to the frame
before the dampers across two carts.  ``Rig`` runs them in the order of this module.
"""

from __future__ import annotations

from collections.abc import Sequence

from .._errors import ModelError
from .elements import FRAME, INPUT_KINDS, Damper, Drive, Sensor, Spring, _finite_positive

#: Names a spring may not take (they are other parameters).
_RESERVED = ("g_v", "ca", "cb")


def as_tuple(items, kind, what: str) -> tuple:
    """``items`` as a tuple of ``kind`` objects (None stays None); ``what`` names them in
    the message."""
    if items is None:
        return None
    if isinstance(items, (str, bytes)) or not isinstance(items, Sequence):
        raise ModelError(f"{what} must be a list, got {items!r}")
    out = tuple(items)
    for it in out:
        if not isinstance(it, kind):
            raise ModelError(f"{what} must hold {kind.__name__} objects, got {it!r}")
    return out


def checked_clamps(cart_names: list[str], clamped) -> tuple[tuple[str, ...], list[str]]:
    """``(clamped, free)``: the clamped carts as a tuple of names and the free carts in
    order, after checking that the cart names are unique and at least one cart moves."""
    dup = sorted({c for c in cart_names if cart_names.count(c) > 1})
    if dup:
        raise ModelError(f"duplicate cart {dup[0]!r}; give every cart a unique name")
    clamped = tuple(str(c) for c in (clamped or ()))
    for c in clamped:
        if c not in cart_names:
            raise ModelError(f"clamped cart {c!r} is not a cart; carts are {cart_names}")
    if len(set(clamped)) != len(clamped):
        raise ModelError(f"duplicate clamped cart in {list(clamped)}; list each once")
    free = [c for c in cart_names if c not in clamped]
    if not free:
        raise ModelError("every cart is clamped; leave at least one cart free")
    return clamped, free


def named_springs(springs: tuple[Spring, ...], cart_names: list[str]) -> tuple[Spring, ...]:
    """The springs with a name each (``k<index>`` by default), after checking their ends,
    that no two join the same pair and that no name is repeated or another parameter's."""
    known_ends = set(cart_names) | {FRAME}
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
    return tuple(named)


def check_grounded(springs: tuple[Spring, ...], free: list[str],
                   clamped: tuple[str, ...]) -> None:
    """Every free cart reaches the frame (or a clamped cart) through springs (else K is
    singular)."""
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


def ordered_dampers(dampers, springs: tuple[Spring, ...], free: list[str],
                    clamped: tuple[str, ...], cart_names: list[str]) -> tuple[Damper, ...]:
    """The dampers of the free damping model, the ones to the frame first (written from
    their cart), then the ones across two carts; None gives the default: one from every
    free cart to the frame and one across every spring joining two free carts."""
    if dampers is None:
        return tuple(Damper(c) for c in free) + tuple(
            Damper(s.a, s.b) for s in springs
            if s.a in free and s.b in free)
    known_ends = set(cart_names) | {FRAME}
    dampers = as_tuple(dampers, Damper, "dampers")
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
    return tuple(Damper(d.b if d.a == FRAME else d.a) for d in dampers
                 if FRAME in (d.a, d.b)) + tuple(
        d for d in dampers if FRAME not in (d.a, d.b))


def checked_drive(drive, cart_names: list[str], clamped: tuple[str, ...]) -> tuple[Drive, ...]:
    """The driven carts as a tuple (None: none), each a free cart listed once."""
    drive = as_tuple(() if drive is None else drive, Drive, "drive")
    for d in drive:
        if d.cart not in cart_names:
            raise ModelError(f"driven cart {d.cart!r} is not a cart; carts are {cart_names}")
        if d.cart in clamped:
            raise ModelError(f"driven cart {d.cart!r} is clamped; drive a free cart")
    dcarts = [d.cart for d in drive]
    if len(set(dcarts)) != len(dcarts):
        raise ModelError(f"duplicate driven cart in {dcarts}; list each once")
    return drive


def checked_sensors(sensors, free: list[str], cart_names: list[str],
                    clamped: tuple[str, ...]) -> tuple[Sensor, ...]:
    """The sensors as a tuple (None: a position sensor in metres on every free cart), at
    least one, each on a free cart and one of each kind per cart."""
    sensors = (tuple(Sensor(c) for c in free) if sensors is None
               else as_tuple(sensors, Sensor, "sensors"))
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
    return sensors


def input_gain(kind: str, gain_n_v, drive: tuple[Drive, ...]) -> float | None:
    """The known input gain, N/V (None: estimated) of an input of ``kind`` (``"voltage"``
    or ``"force"``, which has gain 1 and needs driven carts)."""
    if kind not in INPUT_KINDS:
        raise ModelError(f"input must be one of {INPUT_KINDS}, got {kind!r}")
    if kind == "force":
        if not drive:
            raise ModelError("a force input needs the carts it pushes; list them in "
                             "[drive] carts")
        if gain_n_v is not None and float(gain_n_v) != 1.0:
            raise ModelError(f"a force input has gain 1 (N per N), got gain_n_v="
                             f"{gain_n_v!r}; drop gain_n_v")
        gain_n_v = 1.0
    if gain_n_v is not None:
        gain_n_v = _finite_positive(gain_n_v, "gain_n_v (N/V)")
    return gain_n_v


def tie_groups(ties) -> tuple[tuple[str, ...], ...]:
    """The tie groups as tuples of names, each of two names or more, no name in two."""
    ties = ties or ()
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
    return tuple(groups)
