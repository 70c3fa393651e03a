"""Where each parameter of a ``LinearModel`` of a general rig goes in M, C, K and b.

``_layout`` names the parameters in vector order (gain, unknown masses, dampers or
``ca, cb``, unknown springs), records the index and unit pattern of each, the known part
of K and the positivity each must have; ``_apply_ties`` merges each group of tied
parameters into its first one.  The chain rig needs none of this (``LinearModel`` fills
its matrices directly).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .._errors import ModelError
from .elements import FRAME
from .rig import Rig


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


@functools.lru_cache(maxsize=64)  # a rig is immutable; its layout is read, never written
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

