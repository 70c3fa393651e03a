"""Where an effect acts, as the diagnosis reports it: carts, springs or sensors by number.

``effect_location`` turns an effect's own location (``Extension.location_of``) into the
1-based numbers a user reads on the rig (carts by their number, with a clamped cart
skipped; springs and sensors by their place in the rig description), listing every element
at least ``LOCATION_FRACTION`` as strong as the strongest.  ``final_causes`` restates the
causes a forward selection found in terms of its final model.
"""

from __future__ import annotations

import numpy as np

from ...model.effects import EXTENSIONS, Extension, get_extension
from ...model.effects._base import cart_numbers
from ...model.effects._linear import kernel_order
from ...model.system import Rig
from .forward import Cause

__all__ = ["LOCATION_FRACTION", "effect_location", "final_causes"]

#: Elements whose strength is at least this fraction of the strongest are reported too.
LOCATION_FRACTION = 0.25


def effect_location(ext: Extension, rig: Rig, theta) -> tuple[list[int] | None, str | None]:
    """The carts (by number), springs (by their place in ``rig.springs``) or sensors (by
    their place in ``rig.sensors``), 1-based, where the effect acts, and a label.

    Parameters
    ----------
    ext : Extension
    rig : Rig
    theta : array_like, shape (P,)
        The extended model's parameters (``ext.names(rig)``).

    Returns
    -------
    tuple of (list of int or None, str or None)
        The element numbers (None for an effect at the input) and the label.
    """
    loc = ext.location_of(rig, theta)
    if loc.kind == "input" or loc.index is None:
        return None, loc.label
    order = kernel_order(rig)
    if loc.kind == "sensor":
        def number(i):
            return i + 1
    elif loc.kind == "spring":
        def number(i):
            return order.spring_index[i] + 1
    else:
        def number(i):
            return cart_numbers(rig)[i]
    if loc.kind == "drive":
        return [number(loc.index)], loc.label
    s = np.abs(np.asarray(loc.strength, float))
    if ext.name == "cubic_stiffness":
        s = s / np.asarray(rig.springs_n_m, float)[list(order.spring_index)]
    elif ext.name == "coulomb_friction":
        # the kinetic level acts whenever a cart slides and is well identified; a static
        # level on a cart without kinetic friction only matters while it sticks and can
        # take almost any value
        fc = np.asarray(ext.split(rig, np.asarray(theta, float))[1][: rig.n_carts])
        if fc.max() > 0:
            s = fc
    elif ext.name == "coulomb_directional":
        w = np.asarray(ext.split(rig, np.asarray(theta, float))[1])
        n = rig.n_carts
        fc = np.maximum(w[:n], w[n : 2 * n])
        if fc.max() > 0:
            s = fc
    idx = [number(int(i)) for i in np.flatnonzero(s >= LOCATION_FRACTION * s.max())] \
        if s.max() > 0 else [number(loc.index)]
    if len(idx) == 1 and idx[0] != number(loc.index):
        return idx, f"{loc.kind} {idx[0]}"
    kind = "carts" if loc.kind == "cart" else "springs"
    label = loc.label if len(idx) == 1 else f"{kind} {', '.join(map(str, idx))}"
    return idx, label


def final_causes(causes, fwd, rig, model) -> tuple:
    """The causes found, restricted to the final model's effects: a refinement replaced by
    what it refines takes the simpler name, a removed effect is dropped, and every cause
    takes its parameters and location from the final fit (the first step's fit lacked the
    later effects: measured on a pair case, friction spread over two carts there that the
    final model puts on one).  Order: as found; gains: as measured when found.

    Parameters
    ----------
    causes : sequence of Cause
        The causes in the order found.
    fwd : ForwardResult
        The forward selection's result (final effects, fit, simplifications).
    rig : Rig
    model : LinearModel
        The linear model under the effects.

    Returns
    -------
    tuple of Cause
    """
    p = model.n_params
    ext = get_extension(list(fwd.names))
    own = dict(zip(ext.extension_names(rig), fwd.fit.theta[p:], strict=True))
    out, seen = [], set()
    for c in causes:
        name = c.cause
        for eff, simpler in fwd.simplified:
            if name == eff and simpler is not None and simpler in fwd.names:
                name = simpler
        if name not in fwd.names or name in seen:
            continue
        seen.add(name)
        s_ext = EXTENSIONS[name]
        par = {n: float(own[n]) for n in s_ext.extension_names(rig)}
        loc, lab = effect_location(s_ext, rig, np.r_[fwd.fit.theta[:p], list(par.values())])
        out.append(Cause(cause=name, location=loc, location_label=lab, parameters=par,
                         gain=dict(c.gain),
                         replaces=c.replaces if name == c.cause else None))
    return tuple(out)
