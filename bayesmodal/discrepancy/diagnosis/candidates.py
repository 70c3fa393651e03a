"""The models a forward step tries, their start points and their fits.

``_options`` lists every candidate that combines with the current model (a refinement,
``REFINES``, replacing what it refines) and the exchanges of its plant-side effect;
``_input_pairs`` the pairs of input-side effects of the second look.  ``_starts`` builds
each model's start vectors from the current fit and the added effects' start grids
(``_grid``), ``_fit_from`` fits it from them (and by the global search for a stick-slip
model).  Steps 2 and 4 of the ``forward`` module docstring.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..._errors import ModelError
from ...fit._threads import thread_map
from ...fit.effects import ExtensionFit, extension_residuals, root_weights
from ...fit.global_search import is_stick_slip
from ...fit.lsq import fit_lsq
from ...model.effects import EXTENSIONS, get_extension
from .gains import _FIT_ERRORS
from .starts import extra_starts

__all__ = ["REFINES"]

#: Effects that generalise another one: at a forward step they replace it.
REFINES = {"coulomb_directional": "coulomb_friction"}



def _grid(cand, rig, cur_names, cur_par, theta_lin, exps) -> np.ndarray:
    """Start rows of the candidate's own parameters: its start grid, the element-wise one,
    and for a refinement the rows around the effect it refines."""
    c_ext = EXTENSIONS[cand]
    grid = np.concatenate([c_ext.start_grid(rig),
                           extra_starts(c_ext, rig, theta_lin, exps)])
    if cand in REFINES and REFINES[cand] in cur_names:
        # directional levels from the equal ones: Fcp = Fcn = Fc, same Fs
        n = rig.n_carts
        fc = np.array([cur_par[f"Fc{i + 1}"] for i in range(n)])
        fs = np.array([cur_par[f"Fs{i + 1}"] for i in range(n)])
        rows = [np.r_[fc, fc, fs]]
        for f in (0.6, 0.8, 1.25, 1.6):
            rows += [np.r_[fc, f * fc, np.maximum(fs, f * fc)],
                     np.r_[f * fc, fc, np.maximum(fs, f * fc)]]
        grid = np.concatenate([grid, np.array(rows)])
    return grid


def _starts(new, rig, cur_names, cur_theta, added, theta_lin, exps, n_starts, weights=None):
    """The ``n_starts`` cheapest full vectors of ``new`` (the current fit with the start
    grids of the ``added`` effects, every combination of their rows) and the cheapest
    cost (weighted by ``weights``, ``fit_extension_lsq``'s).  An effect of the current
    model that ``new`` lacks (refined or exchanged) drops out with its parameters."""
    p = theta_lin.size
    cur = get_extension(list(cur_names))
    cur_par = dict(zip(cur.extension_names(rig), cur_theta[p:], strict=True))
    grids = [(EXTENSIONS[c].extension_names(rig),
              _grid(c, rig, cur_names, cur_par, theta_lin, exps)) for c in added]
    rows = []
    for combo in itertools.product(*(range(len(g)) for _, g in grids)):
        own = dict(cur_par)
        for (names, g), i in zip(grids, combo, strict=True):
            own.update(zip(names, g[i], strict=True))
        rows.append(np.r_[cur_theta[:p], [own[k] for k in new.extension_names(rig)]])
    cands = np.array(rows)
    cands = cands[new.valid(rig, cands) & np.all(np.isfinite(cands), axis=1)]
    with np.errstate(all="ignore"):
        r = extension_residuals(new, rig, cands, exps)
        if weights is not None:
            r = r * root_weights(weights, exps)
        cost = np.sum(r**2, axis=1)
    cost = np.where(np.isfinite(cost), cost, np.inf)
    order = np.argsort(cost, kind="stable")
    return cands[order[: max(int(n_starts), 1)]], float(cost[order[0]])


def _fit_from(new, rig, starts, exps, linear, max_nfev, search=None, weights=None
              ) -> ExtensionFit | None:
    """The best local fit from ``starts`` and, for a stick-slip model when ``search``
    (a seed) is given, of the global search (``fit_extension_global``); both weigh the
    records by ``weights`` (``fit_extension_lsq``).  The fits run side by side on the
    fits' threads (``fit._threads``), the first of equal costs winning as in turn."""
    fits = []
    if search is not None and is_stick_slip(new):
        fits.append(lambda: fit_lsq(exps, rig, extension=new, search="global", linear=linear,
                                    rng=search, max_nfev=max_nfev, weights=weights))
    fits += [lambda th0=th0: fit_lsq(exps, rig, extension=new, theta0=th0, linear=linear,
                                     max_nfev=max_nfev, weights=weights)
             for th0 in starts]
    best = None
    for f in thread_map(_or_none, fits):
        if f is not None and (best is None or f.cost < best.cost):
            best = f
    return best


def _or_none(fit):
    """``fit()`` with numpy's warnings off, or None where it fails (``_FIT_ERRORS``)."""
    try:
        with np.errstate(all="ignore"):
            return fit()
    except _FIT_ERRORS:
        return None


def _global_if_better(new, rig, f, exps, linear, max_nfev, search, weights=None
                      ) -> ExtensionFit | None:
    """The global search's fit of ``new`` when it costs less than ``f`` (or ``f`` is
    None), else None."""
    fg = _fit_from(new, rig, [], exps, linear, max_nfev, search, weights)
    return fg if fg is not None and (f is None or fg.cost < f.cost) else None


def _options(names, candidates, rejected) -> list:
    """The models one forward step fits: ``(added, dropped, names, extension)`` rows.

    Every candidate not in the model that combines with it is added (a refinement
    replaces the effect it refines).  Exchanges: the model's plant-side effect is
    replaced by another plant-side candidate together with one input-side candidate
    not in the model.  Two plant-side effects never combine, so without exchanges a
    wrong plant-side effect accepted first locks the right one out: measured on the pair
    benchmark's friction + offset seed 20002 (friction 1.26 N on cart 1, offset
    0.137 V), where friction alone fits worse than the linear model (the offset hides
    it), backlash won the first step (+233 nats), and backlash + offset (+138) could
    not reach friction + offset (+24 204, the truth)."""
    out = []
    for c in candidates:
        if c in names or c in rejected:
            continue
        dropped = REFINES.get(c) if REFINES.get(c) in names else None
        base = tuple(n for n in names if n != dropped)
        try:
            out.append(((c,), dropped, base + (c,), get_extension(list(base + (c,)))))
        except ModelError:
            continue
    plant = [n for n in names if EXTENSIONS[n].side != "input"]
    free = [c for c in candidates if c not in names and c not in rejected]
    for old in plant:
        base = tuple(n for n in names if n != old)
        for q in free:
            if EXTENSIONS[q].side == "input" or q in REFINES or REFINES.get(old) == q:
                continue
            for i in free:
                if EXTENSIONS[i].side != "input":
                    continue
                try:
                    out.append(((q, i), old, base + (q, i), get_extension(list(base + (q, i)))))
                except ModelError:
                    continue
    return out


def _input_pairs(names, candidates, rejected) -> list:
    """Two input-side candidates added together, in the rows of :func:`_options`.

    Tried only when no single candidate gains significantly (``forward_select``): two
    effects in the drive can mask each other, so that each alone scores below the model
    and both together above it.  Measured on the four ECP records after stick-slip
    friction: an input offset alone lowers the least-squares cost by 61 % and a dead band
    alone by 53 %, yet each scores about 800 nats *below* friction by the AR(1) log
    density (a level change of a residual with ``phi`` near 1 is nearly free); both
    together gain 5 600 nats (docs/diagnose.md)."""
    free = [c for c in candidates if c not in names and c not in rejected
            and EXTENSIONS[c].side == "input"]
    out = []
    for a, b in itertools.combinations(free, 2):
        try:
            out.append(((a, b), None, tuple(names) + (a, b), get_extension(list(names) + [a, b])))
        except ModelError:
            continue
    return out
