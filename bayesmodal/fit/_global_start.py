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

The global start of :func:`bayesmodal.fit.fit_lsq` (``search="global"``) runs SciPy's
differential evolution (:func:`evolve`,
``scipy.optimize.differential_evolution``, vectorised: each generation is one batched
call of the extension's kernel) over a box around the linear fit: the gain and masses
within ``MASS_BOX`` of it; every damper from 0 to ``DAMPER_BOX`` times the largest fitted
damper (friction takes over viscous dissipation, and the linear fit moves it between
dampers); the extension parameters within their prior bounds, those bounded below by a
null of zero extended below it and clipped, so that "absent on this cart" is a region.
The fitter then polishes the best member with its local search, and again with the friction
of every proper subset of carts set to zero (the evolution leaves small levels on carts
without friction, and the polish cannot remove them across the terraces), on the samples
the evolution saw, and the best of these once more on all samples.  Measured on
five data sets of the pair cases (friction with a dead band, seeds 1 and 3; with an
offset, seed 2; directional levels, seeds 1 and 2), two evolution seeds each: all ten fits
ended at the truth's optimum, 12-32 s each on 2 400 samples (one core, the other busy);
``tests/test_effects_global_fit.py`` checks one against the local fits' stop.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.optimize import differential_evolution

from ..data import Experiment
from ..model.effects._base import Extension
from ..model.system import LinearModel, Rig, damper_mask
from ._threads import split_rows
from .residuals import extension_residuals

__all__ = ["is_stick_slip", "search_box", "head", "clip_to_null", "evolve", "member_cost",
           "pruned_starts", "MASS_BOX", "DAMPER_BOX"]

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
    """Does the model hold stick-slip friction (alone or in a combination)?

    Parameters
    ----------
    ext : Extension

    Returns
    -------
    bool
    """
    members = getattr(ext, "effects", (ext,))
    return any(getattr(m, "name", "") in STICK_SLIP for m in members)


def search_box(ext: Extension, rig: Rig, theta_lin: np.ndarray) -> np.ndarray:
    """The box of the global search (module docstring).

    Parameters
    ----------
    ext : Extension
    rig : Rig
    theta_lin : ndarray, shape (n_linear,)
        The linear free-damping fit (the box's centre).

    Returns
    -------
    ndarray, shape (n_params, 2)
        Lower and upper end of each parameter.
    """
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
            # (``clip_to_null``), so that "no effect here" is a region the evolution can
            # land in, not a point
            lo = -ZERO_SHARE * hi
        rows.append((lo, hi))
    return np.concatenate([box, np.array(rows, dtype=float).reshape(-1, 2)])


def head(exps: list[Experiment], max_samples: int) -> list[Experiment]:
    """Each record's first ``max_samples // len(exps)`` samples (all when it is shorter)."""
    n = max(int(max_samples) // len(exps), 2)
    return [e if e.n_samples <= n else
            Experiment(e.t_s[:n], e.v_volt[:n], e.y_m[:n], name=e.name) for e in exps]


def _zero_bounded(sp) -> bool:
    """Is the parameter's null value its lower bound, zero?"""
    return sp.null == 0.0 and sp.bounds[0] == 0.0


def clip_to_null(ext: Extension, rig: Rig, theta: np.ndarray) -> np.ndarray:
    """Parameters of the extended box below a zero lower bound set to zero."""
    p = ext.linear_model(rig).n_params
    zero = np.array([_zero_bounded(sp) for sp in ext.specs(rig)])
    out = np.array(theta, dtype=float)
    ext_part = out[..., p:]
    ext_part[..., zero] = np.maximum(ext_part[..., zero], 0.0)
    return out


def member_cost(ext: Extension, rig: Rig, search: Sequence[Experiment],
                root_w: np.ndarray | None) -> Callable[[np.ndarray], np.ndarray]:
    """The cost of a generation of the evolution in SciPy's vectorised layout.

    The members are evaluated in blocks on the fits' threads (``_threads``), each row's
    sum of squares computed row by row in memory, so that a member's cost does not depend
    on the rest of its generation or on the number of threads.

    Parameters
    ----------
    ext : Extension
    rig : Rig
    search : sequence of Experiment
        The samples the evolution sees.
    root_w : ndarray, shape (n_residuals,), or None
        Square roots of the records' weights, one per stacked residual.

    Returns
    -------
    callable
        ``x`` (n_params, S) -> the sums of squares (S,); inadmissible or diverging
        members get ten times the worst finite cost plus one.
    """
    def sums(theta: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            # row by row in memory, so that a row's sum does not depend on the batch: the
            # residuals of a batch of one chunk of lanes and one output come lanes-first
            # (a sum down those columns rounds differently)
            r = np.ascontiguousarray(extension_residuals(ext, rig, theta, search))
            return np.sum((r if root_w is None else r * root_w) ** 2, axis=1)

    def cost(x: np.ndarray) -> np.ndarray:  # x: (n_params, S), SciPy's vectorised layout
        theta = clip_to_null(ext, rig, np.ascontiguousarray(x.T))
        out = np.full(theta.shape[0], np.inf)
        ok = ext.valid(rig, theta)
        if np.any(ok):
            out[ok] = split_rows(sums, theta[ok])
        # inadmissible or diverging members: worse than every admissible one but finite
        # (SciPy's convergence test squares the population's energies)
        fin = np.isfinite(out)
        worst = float(np.max(out[fin])) if np.any(fin) else 1.0
        return np.where(fin, out, 10.0 * worst + 1.0)

    return cost


def evolve(ext: Extension, rig: Rig, box: np.ndarray, search: Sequence[Experiment],
           root_w: np.ndarray | None, *, generations: int, popsize: int, seed) -> np.ndarray:
    """The best member of SciPy's differential evolution over ``box`` (module docstring).

    Parameters
    ----------
    ext : Extension
    rig : Rig
    box : ndarray, shape (n_params, 2)
        ``search_box``.
    search : sequence of Experiment
        The samples the evolution sees (``head``).
    root_w : ndarray, shape (n_residuals,), or None
        Square roots of the records' weights, one per stacked residual.
    generations, popsize : int
        SciPy's ``maxiter`` and ``popsize``.
    seed : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n_params,)
        The best member, not yet clipped to the nulls (``clip_to_null``).
    """
    res = differential_evolution(member_cost(ext, rig, search, root_w), box, vectorized=True,
                                 updating="deferred", popsize=int(popsize),
                                 maxiter=int(generations), tol=0.0, polish=False, seed=seed)
    return res.x


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
    the model without the effect).

    Parameters
    ----------
    ext : Extension
    rig : Rig
    theta : ndarray, shape (n_params,)

    Returns
    -------
    list of ndarray, shape (n_params,) each
    """
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
