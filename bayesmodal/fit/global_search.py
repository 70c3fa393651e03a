"""A global search before the local fit, for models whose cost is terraced (stick-slip).

The least-squares cost of stick-slip friction is piecewise smooth with jumps wherever a
cart sticks one sample earlier or later, and between the jumps a local optimiser only
sees the nearest terrace.  Measured on a pair case of forward selection (friction of
0.95 N on cart 3 behind a 0.11 V dead band, ``benchmarks/friction_fit_starts.py``): of
50 local fits started on the true cart at every grid level, 4 reached the truth's basin
and the others stopped 3 000 to 25 000 nats of AR(1) log density below it; the starts of
least cost (small friction everywhere) all stopped below, so no ranking of the starts by
their cost finds the right one.  Forward selection then judged optimisers' stops instead
of the data (a directional refinement "gained" 11 000 nats over a symmetric model that
was the truth).

:func:`fit_extension_global` runs SciPy's differential evolution
(``scipy.optimize.differential_evolution``, vectorised: each generation is one batched
call of the extension's kernel) over a box around the linear fit: the gain and masses
within ``MASS_BOX`` of it; every damper from 0 to ``DAMPER_BOX`` times the largest fitted
damper (friction takes over viscous dissipation, and the linear fit moves it between
dampers); the extension parameters within their prior bounds, those bounded below by a
null of zero extended below it and clipped, so that "absent on this cart" is a region.
It then polishes the best member with ``fit_extension_lsq``, and again with the friction
of every proper subset of carts set to zero (the evolution leaves small levels on carts
without friction, and the polish cannot remove them across the terraces), on the samples
the evolution saw, and the best of these once more on all samples.  Measured on
five data sets of the pair cases (friction with a dead band, seeds 1 and 3; with an
offset, seed 2; directional levels, seeds 1 and 2), two evolution seeds each: all ten fits
ended at the truth's optimum, 12-32 s each on 2 400 samples (one core, the other busy);
``tests/test_effects_global_fit.py`` checks one against the local fits' stop.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import differential_evolution

from .._errors import ConfigError
from ..data import Experiment
from ..model.effects._base import Extension
from ..model.system import LinearModel, Rig, damper_mask
from .effects import (
    ExtensionFit,
    experiment_weights,
    extension_residuals,
    fit_extension_lsq,
    root_weights,
)
from .linear import LSQResult, fit_lsq

__all__ = ["fit_extension_global", "is_stick_slip", "MASS_BOX", "DAMPER_BOX"]

#: Relative box of the drive gain and the masses around the linear fit, (low, high).
MASS_BOX = (0.7, 1.3)
#: Upper end of the dampers' box: this factor times the linear fit's largest damper plus
#: ``DAMPER_PAD``.
DAMPER_BOX = 1.2
#: Added to the dampers' upper end, N s/m (a damper the linear fit set to zero).
DAMPER_PAD = 0.1
#: Half-width of an extension parameter's box where its prior is unbounded, in units of
#: its typical size ``ParamSpec.scale``.
UNBOUNDED_SCALES = 20.0
#: Share of a zero-bounded parameter's range added below zero (clipped to zero): the
#: prior probability of the evolution's start that the effect is absent there.
ZERO_SHARE = 0.25
#: Rounds of "prune every subset of carts, polish each" after the evolution (stops early
#: when a round does not lower the cost).
PRUNE_ROUNDS = 3
#: Effects whose cost has stick-slip terraces.
STICK_SLIP = ("coulomb_friction", "coulomb_directional")


def is_stick_slip(ext: Extension) -> bool:
    """Does the model hold stick-slip friction (alone or in a combination)?"""
    members = getattr(ext, "effects", (ext,))
    return any(getattr(m, "name", "") in STICK_SLIP for m in members)


def search_box(ext: Extension, rig: Rig, theta_lin: np.ndarray) -> np.ndarray:
    """The box of the global search, shape (n_params, 2) (module docstring)."""
    theta_lin = np.asarray(theta_lin, dtype=float)
    dampers = damper_mask(LinearModel(rig, "free"))
    box = np.empty((theta_lin.size, 2))
    # the gain, the masses and the unknown springs: a factor either way
    box[~dampers] = theta_lin[~dampers, None] * np.array(MASS_BOX)[None]
    box[dampers, 0] = 0.0
    # one range for every damper: a linear fit that compensates friction sets some
    # dampers to zero and inflates others (measured: c1 21 N s/m, c2 = c3 = 0, against
    # 2.9, 1.8 and 2.1 in the data), so its own damper values bound nothing
    box[dampers, 1] = DAMPER_BOX * np.max(np.abs(theta_lin[dampers])) + DAMPER_PAD
    rows = []
    for sp in ext.specs(rig):
        lo, hi = sp.bounds
        half = UNBOUNDED_SCALES * sp.scale
        lo = lo if np.isfinite(lo) else sp.null - half
        hi = hi if np.isfinite(hi) else max(sp.null, lo) + half
        if _zero_bounded(sp):
            # a null at the lower bound: extend the box below it and clip
            # (``_clip_to_null``), so that "no effect here" is a region the evolution can
            # land in, not a point
            lo = -ZERO_SHARE * hi
        rows.append((lo, hi))
    return np.concatenate([box, np.array(rows, dtype=float).reshape(-1, 2)])


def _head(exps: list[Experiment], max_samples: int) -> list[Experiment]:
    """Each record's first ``max_samples // len(exps)`` samples (all when it is shorter)."""
    n = max(int(max_samples) // len(exps), 2)
    return [e if e.n_samples <= n else
            Experiment(e.t_s[:n], e.v_volt[:n], e.y_m[:n], name=e.name) for e in exps]


def _zero_bounded(sp) -> bool:
    """Is the parameter's null value its lower bound, zero?"""
    return sp.null == 0.0 and sp.bounds[0] == 0.0


def _clip_to_null(ext: Extension, rig: Rig, theta: np.ndarray) -> np.ndarray:
    """Parameters of the extended box below a zero lower bound set to zero."""
    p = ext.linear_model(rig).n_params
    zero = np.array([_zero_bounded(sp) for sp in ext.specs(rig)])
    out = np.array(theta, dtype=float)
    ext_part = out[..., p:]
    ext_part[..., zero] = np.maximum(ext_part[..., zero], 0.0)
    return out


def fit_extension_global(
    experiments: Experiment | Sequence[Experiment],
    ext: Extension,
    rig: Rig | None = None,
    *,
    linear: LSQResult | None = None,
    generations: int = 200,
    popsize: int = 30,
    rng=None,
    max_nfev: int = 200,
    max_samples: int = 4000,
    weights: Sequence[float] | str | None = None,
) -> ExtensionFit:
    """Differential evolution over the model's box, then the least-squares polish.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
    ext : Extension
    rig : Rig, optional
        Default ``Rig()``.
    linear : LSQResult, optional
        Linear free-damping fit to the same experiments (the box's centre).
    generations : int
        Generations of the evolution (each one batched call per experiment).
    popsize : int
        Population per parameter (SciPy's ``popsize``): ``popsize * n_params`` members.
    rng : int or numpy.random.Generator, optional
        Seeds the evolution.
    max_nfev : int
        Evaluation budget of the polish.
    max_samples : int
        Samples the evolution sees, shared equally by the records (the first ones of
        each; the polish fits all): it bounds the search's cost whatever the data's size.
    weights : sequence of float or "spread", optional
        Weight of each record in the cost (``fit_extension_lsq``), decided on the whole
        records and kept for the searched samples.

    Returns
    -------
    ExtensionFit
        The polished fit (its ``theta_start`` is where its last polish started).

    Raises
    ------
    ConfigError
        For ``generations``, ``popsize`` or ``max_samples`` below 1.
    """
    for name, v in (("generations", generations), ("popsize", popsize),
                    ("max_samples", max_samples)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ConfigError(f"{name} must be a positive integer, got {v!r}")
    exps = [experiments] if isinstance(experiments, Experiment) else list(experiments)
    rig = Rig() if rig is None else rig
    if linear is None:
        linear = fit_lsq(exps, ext.linear_model(rig))
    box = search_box(ext, rig, linear.theta)
    seed = np.random.default_rng(rng)
    search = _head(exps, max_samples)
    # the records' weights from the whole records, as numbers the searched heads keep
    w = None if weights is None else experiment_weights(weights, exps)
    root_w = root_weights(w, search)

    def cost(x: np.ndarray) -> np.ndarray:  # x: (n_params, S), SciPy's vectorised layout
        theta = _clip_to_null(ext, rig, np.ascontiguousarray(x.T))
        out = np.full(theta.shape[0], np.inf)
        ok = ext.valid(rig, theta)
        if np.any(ok):
            with np.errstate(all="ignore"):
                r = extension_residuals(ext, rig, theta[ok], search)
                out[ok] = np.sum((r if root_w is None else r * root_w) ** 2, axis=1)
        # inadmissible or diverging members: worse than every admissible one but finite
        # (SciPy's convergence test squares the population's energies)
        fin = np.isfinite(out)
        worst = float(np.max(out[fin])) if np.any(fin) else 1.0
        return np.where(fin, out, 10.0 * worst + 1.0)

    res = differential_evolution(cost, box, vectorized=True, updating="deferred",
                                 popsize=int(popsize), maxiter=int(generations), tol=0.0,
                                 polish=False, seed=seed)
    # prune and polish on the searched samples (cheap), then polish once on all of them
    best, centre = None, _clip_to_null(ext, rig, res.x)
    for _ in range(PRUNE_ROUNDS):
        improved = False
        for start in pruned_starts(ext, rig, centre):
            f = fit_extension_lsq(search, ext, rig, theta0=ext.check(rig, start),
                                  linear=linear, max_nfev=max_nfev, weights=w)
            if best is None or f.cost < best.cost:
                best, improved = f, True
        if not improved:
            break
        centre = best.theta   # prune what the polish left: a cart it gave a small level
    if all(a is b for a, b in zip(search, exps, strict=True)):
        return best
    return fit_extension_lsq(exps, ext, rig, theta0=best.theta, linear=linear,
                             max_nfev=max_nfev, weights=w)


def _cart_blocks(ext: Extension, rig: Rig) -> list[np.ndarray]:
    """Indices (in the full vector) of each cart's stick-slip friction parameters."""
    p = ext.linear_model(rig).n_params
    names = ext.extension_names(rig)
    blocks = []
    for i in range(1, rig.n_carts + 1):
        idx = [p + k for k, n in enumerate(names)
               if n in (f"Fc{i}", f"Fs{i}", f"Fcp{i}", f"Fcn{i}")]
        if idx:
            blocks.append(np.array(idx))
    return blocks


def pruned_starts(ext: Extension, rig: Rig, theta: np.ndarray) -> list[np.ndarray]:
    """``theta`` and its copies with the friction of every subset of carts set to zero.

    The evolution samples the box's interior, so a cart without friction ends with a
    small level there, which makes it stick at low speed; the local fit cannot take it
    to zero across the terraces.  The all-zero subset is left out (no friction at all is
    the model without the effect)."""
    theta = np.asarray(theta, dtype=float)
    blocks = _cart_blocks(ext, rig)
    out = [theta]
    for mask in range(1, 2 ** len(blocks) - 1):
        t = theta.copy()
        for b, idx in enumerate(blocks):
            if mask >> b & 1:
                t[idx] = 0.0
        out.append(t)
    return out
