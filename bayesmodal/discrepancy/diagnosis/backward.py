"""The backward check of forward selection: after each acceptance, simplify the model.

A refinement whose extra parameters, or an effect whose parameters, no longer gain
significantly in the current model is replaced by what it refines, or removed (step 4 of
the ``forward`` module docstring).
"""

from __future__ import annotations

import numpy as np

from ..._errors import ModelError
from ...fit.effects import ExtensionFit, extension_fit_at
from ...fit.global_search import is_stick_slip
from ...model.effects import get_extension
from .candidates import REFINES, _fit_from, _global_if_better
from .gains import _FIT_ERRORS, _lpd, _lr_keeps, _simulate
from .scoring import criterion_for


def _better_by_score(simple, rig, start, f, exps, linear, weights=None
                     ) -> ExtensionFit | None:
    """The refit ``f`` of the simpler model or its start (no refit), whichever has the
    higher score (the records' criterion), the score its test uses: a least-squares refit can lower
    the cost and the score together, and an effect at its no-effect value (a lag of
    ``tau`` = 0) must then be removed at the point where the two models coincide."""
    try:
        with np.errstate(all="ignore"):
            at = extension_fit_at(exps, simple, rig, start, linear=linear, weights=weights)
    except _FIT_ERRORS:
        return f
    if f is None:
        return at
    crit = criterion_for(exps)
    score = [crit.total(_lpd(exps, _simulate(simple, rig, x.theta, exps))) for x in (at, f)]
    return at if score[0] > score[1] else f


def _simplify(names, fit, rig, exps, linear, level, max_nfev, search=None, weights=None):
    """Backward check after each acceptance: a refinement whose extra parameters, or an
    effect whose parameters, no longer gain significantly in the current model is
    replaced by what it refines, or removed (e.g. directional friction levels that an
    input offset added later explains).  Returns ``(names, fit, changes)`` with
    ``changes`` a list of ``(effect, simpler effect or None)``."""
    changes = []
    changed = True
    while changed and len(names) >= 1:
        changed = False
        cur = get_extension(list(names))
        p = fit.theta.size - len(cur.specs(rig))
        own = dict(zip(cur.extension_names(rig), fit.theta[p:], strict=True))
        options = []
        for new, old in REFINES.items():
            if new in names:
                options.append((new, old, tuple(old if n == new else n for n in names)))
        if len(names) >= 2:
            options += [(n, None, tuple(m for m in names if m != n)) for n in names]
        for eff, simpler, simple_names in options:
            simple = get_extension(list(simple_names))
            par = dict(own)
            if eff == "coulomb_directional" and simpler is not None:
                for i in range(1, rig.n_carts + 1):
                    par[f"Fc{i}"] = 0.5 * (par[f"Fcp{i}"] + par[f"Fcn{i}"])
                    par[f"Fs{i}"] = max(par[f"Fs{i}"], par[f"Fc{i}"])
            start = np.r_[fit.theta[:p], [par[k] for k in simple.extension_names(rig)]]
            try:
                start = simple.check(rig, start)
            except ModelError:
                continue
            f = _better_by_score(simple, rig, start,
                                 _fit_from(simple, rig, [start], exps, linear, max_nfev,
                                           weights=weights),
                                 exps, linear, weights)
            keeps = f is None or _lr_keeps(cur, fit, simple, f, rig, exps, level)
            if keeps and simpler is not None and search is not None and is_stick_slip(simple):
                # before keeping a refinement, make sure the model it refines was fitted
                # to its optimum, not to a terrace near the refinement's
                fg = _global_if_better(simple, rig, f, exps, linear, max_nfev, search,
                                       weights)
                if fg is not None:
                    f = fg
                    keeps = _lr_keeps(cur, fit, simple, f, rig, exps, level)
            if keeps:
                continue
            names, fit = simple_names, f
            changes.append((eff, simpler))
            changed = True
            break
    return names, fit, changes
