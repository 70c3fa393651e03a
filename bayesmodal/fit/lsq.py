"""One output-error least-squares fitter: the linear model or a model with effects, one or
several records, shared or per-record parameters, weighted or not, a local or a global
search (the report's ``lsqnonlin`` fit, section 2.2).

The parameters minimise ``sum_e w_e sum_k ||y_e[k] - yhat_e[k; theta]||^2`` over the
records, with ``yhat`` the exact ZOH simulation from rest (for free decays of the linear
model with ``initial_state="estimate"``, from an initial state estimated with the
parameters), on each record's own time base.  Positive parameters are optimised in log
space (scale-free, masses stay positive); the dampers that may vanish (``c12, c23, ...,
cb``) on a linear scale with a zero lower bound; an extension's parameters in its own
coordinates (``Extension.to_opt``) divided by their typical size.  The Jacobian is by
forward differences, each column's perturbed points in one batched simulator call.

How the fit starts depends on the model:

- the linear model: ``theta0``, else ``default_start(model)``;
- a model with effects (``extension``), ``search="local"``: the linear free-damping fit
  (``linear``, or fitted here) crossed with the extension's start grid
  (``Extension.start_grid``) and with ``damper_scales``, ranked by cost in one batch; the
  local search runs from the ``n_starts`` best (``bayesmodal.fit.effects`` tells why);
- ``search="global"``: SciPy's differential evolution over a box around the linear fit,
  then the local search from its best member and from that member with the friction of
  each subset of carts removed (``bayesmodal.fit._global_start``);
- per-record parameters (``per_record``) or the ``"cart_spread"`` weighting: the linear
  fit with the extension at its null values, the same for every record.

All of them end in the one local search of ``bayesmodal.fit._engine``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .._errors import ConfigError, DataError, ModelError
from ..data import Experiment
from ..model.effects._base import Extension
from ..model.system import LinearModel, Rig, damper_mask, default_start
from ._engine import local_search, summarize, theta_residuals
from ._global_start import PRUNE_ROUNDS, clip_to_null, evolve, head, pruned_starts, search_box
from ._lsq_common import check_outputs, coordinates
from ._problems import extension_problem, extension_starts, linear_problem, records_problem
from .linear import check_records
from .residuals import as_list, experiment_weights, model_names, root_weights
from .result import LSQResult

__all__ = ["LSQOptions", "fit_lsq", "SEARCHES", "CART_SPREAD"]

#: Start strategies of a model with effects.
SEARCHES = ("local", "global")
#: The weighting of each record and cart by the spread of its signal (``weights=``): the
#: cost is ``0.5 sum_{r,j} (1 - fit_rj / 100)^2``, so a small sweep weighs as much as a
#: large impulse (the joint fit of several records, ``bayesmodal.fit.records``).
CART_SPREAD = "cart_spread"


@dataclass(frozen=True)
class LSQOptions:
    """How :func:`fit_lsq` fits: the model's effects, the records' layout and weights, the
    search and its budget.

    Attributes
    ----------
    extension : Extension or None
        The model's effects (``get_extension(...)``); None for the linear model.
    per_record : tuple of str
        Parameters fitted one per record (e.g. ``("g_v",)``); the others are shared.
    weights : None, "spread", "cart_spread" or tuple of float
        Weight of each record's squared residuals: all 1 (None), one number per record,
        ``"spread"`` (:func:`bayesmodal.fit.effects.record_weights`: every record weighs
        as much as the others) or ``"cart_spread"`` (:data:`CART_SPREAD`).
    search : {"local", "global"}
        Start strategy of a model with effects (module docstring).
    initial_state : {"rest", "estimate"}
        ``"estimate"`` fits each record's initial positions and velocities too (free
        decays; the linear model with shared parameters only).
    max_nfev : int or None
        Residual evaluations of each local search; None: 400 for the linear model, 200
        with an extension, 100 with per-record parameters.
    fd_step : float
        Forward-difference step of the extension's parameters in scaled optimiser
        coordinates (larger than the jumps of a stick-slip cost).
    n_starts : int
        Local searches from the best grid candidates (extension, ``search="local"``).
    damper_scales : tuple of float
        Factors on the linear fit's dampers in the grid candidates.
    generations, popsize : int
        Differential evolution (``search="global"``): generations, and members per
        parameter.
    max_samples : int
        Samples the evolution sees, shared equally by the records (their first ones).
    rng : int or numpy.random.Generator, optional
        Seeds the evolution.

    Raises
    ------
    ConfigError
        For an unknown search, a global search without an extension or with per-record
        parameters, estimated initial states with an extension or per-record parameters,
        or a search size below 1.
    """

    extension: Extension | None = None
    per_record: tuple[str, ...] = ()
    weights: tuple[float, ...] | str | None = None
    search: str = "local"
    initial_state: str = "rest"
    max_nfev: int | None = None
    fd_step: float = 1e-3
    n_starts: int = 1
    damper_scales: tuple[float, ...] = (1.0,)
    generations: int = 200
    popsize: int = 30
    max_samples: int = 4000
    rng: object = None

    def __post_init__(self):
        object.__setattr__(self, "per_record", tuple(self.per_record))
        object.__setattr__(self, "damper_scales", tuple(self.damper_scales))
        if self.weights is not None and not isinstance(self.weights, str):
            object.__setattr__(self, "weights", tuple(np.asarray(self.weights, float)))
        if self.search not in SEARCHES:
            raise ConfigError(f"search must be one of {SEARCHES}, got {self.search!r}")
        for name in ("generations", "popsize", "max_samples"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ConfigError(f"{name} must be a positive integer, got {v!r}")
        joint = bool(self.per_record) or self.weights == CART_SPREAD
        if self.search == "global" and (self.extension is None or joint):
            raise ConfigError("search='global' is for a model with effects and shared "
                              "parameters; give extension= and drop per_record")
        if self.initial_state == "estimate" and (self.extension is not None or joint):
            raise ConfigError("initial_state='estimate' is for the linear model with shared "
                              "parameters; drop extension= and per_record")


def fit_lsq(
    experiments: Experiment | Sequence[Experiment],
    model: LinearModel | Rig,
    options: LSQOptions | None = None,
    *,
    theta0: np.ndarray | None = None,
    linear: LSQResult | None = None,
    **changes,
) -> LSQResult:
    """Output-error least-squares fit of a model to one or several records.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment
    model : LinearModel or Rig
        The linear model; with an extension its free-damping linear part (a ``Rig``
        stands for ``LinearModel(rig, "free")``).
    options : LSQOptions, optional
        The model's effects, the layout, weights and search (default ``LSQOptions()``:
        the linear model, all parameters shared, unweighted).
    theta0 : ndarray, shape (n_params,) or (n_records, n_params), optional
        Starting point (the module docstring says where the fit starts without one).
    linear : LSQResult, optional
        A linear free-damping fit to the same records, the start of a model with effects
        (saves refitting it).
    **changes
        Fields of :class:`LSQOptions` that replace those of ``options``, e.g.
        ``fit_lsq(records, rig, extension=ext, weights="spread")``.

    Returns
    -------
    LSQResult

    Raises
    ------
    DataError
        For no records, a record with the wrong number of outputs, an all-zero input
        from rest or a record where nothing moves.
    ConfigError
        For unusable options or weights, or a per-record name that is not a parameter.
    ModelError
        For an impossible ``theta0``, an extension on a model that is not free damping,
        or a ``linear`` start that is not a free-damping fit of the same rig.

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> from bayesmodal.model.simulate import simulate_linear
    >>> model = LinearModel(Rig(), "proportional")
    >>> truth = np.array([6.2, 1.5, 1.4, 1.1, 1.5, 1e-4])
    >>> t = np.arange(2000) * 0.005
    >>> v = (t < 0.05) * 3.0
    >>> e = Experiment(t, v, simulate_linear(model, truth, v, 0.005))
    >>> res = fit_lsq(e, model)
    >>> bool(np.allclose(res.theta, truth, rtol=1e-4))
    True
    """
    opts = LSQOptions() if options is None else options
    if changes:
        opts = replace(opts, **changes)
    if isinstance(model, Rig):
        model = LinearModel(model, "free")
    if (opts.extension is not None or opts.per_record) and model.damping != "free":
        raise ModelError(f"effects and per-record parameters extend the free-damping linear "
                         f"model; pass the rig or LinearModel(rig, 'free'), not damping "
                         f"{model.damping!r}")
    if opts.per_record or opts.weights == CART_SPREAD:
        return _fit_records(experiments, model, opts, theta0, linear)
    if opts.extension is None:
        return _fit_linear(experiments, model, opts, theta0)
    exps = as_list(experiments)
    rig = model.rig
    check_outputs(exps, rig)
    w_exp = experiment_weights(opts.weights, exps)
    # the weights once (a named weighting reads every record), as numbers from here on
    w = None if opts.weights is None else w_exp
    if linear is None:
        linear = _fit_linear(exps, model, LSQOptions(), None)
    elif linear.model.damping != "free" or linear.model.n_carts != rig.n_carts:
        raise ModelError("the linear start must be a free-damping fit of the same rig")
    if opts.search == "global":
        return _fit_global(exps, model, opts, linear, w)
    return _fit_extension(exps, model, opts, theta0, linear, w)


def _fit_linear(experiments, model: LinearModel, opts: LSQOptions, theta0) -> LSQResult:
    exps = [experiments] if isinstance(experiments, Experiment) else list(experiments)
    check_records(model, exps, opts.initial_state)
    theta0 = default_start(model) if theta0 is None else model.check(np.asarray(theta0, float))
    w = None if opts.weights is None else experiment_weights(opts.weights, exps)
    p, starts = linear_problem(model, exps, theta0, opts.initial_state,
                               None if w is None else np.sqrt(w))
    best = local_search(p, starts, 400 if opts.max_nfev is None else opts.max_nfev)
    return summarize(p, best, weights=w, linear=None)


def _fit_extension(exps, model, opts, theta0, linear, w) -> LSQResult:
    """The local search of a model with effects from ``theta0`` or the best grid starts."""
    ext, rig = opts.extension, model.rig
    coords = coordinates(ext, rig, linear.theta)
    p = extension_problem(ext, coords, exps, opts.fd_step, None if w is None else np.sqrt(w))
    if theta0 is None:
        starts = _grid_starts(p, linear, opts.damper_scales, opts.n_starts)
    else:
        starts = [ext.check(rig, np.asarray(theta0, dtype=float))]
    best = local_search(p, extension_starts(coords, starts),
                        200 if opts.max_nfev is None else opts.max_nfev)
    return summarize(p, best, weights=w, linear=linear)


def _grid_starts(p, linear: LSQResult, damper_scales, n_starts) -> list[np.ndarray]:
    """The ``n_starts`` best start vectors: the linear fit with its dampers scaled by each
    of ``damper_scales``, crossed with ``ext.start_grid(rig)``, ranked by cost (one
    batched evaluation)."""
    ext, rig = p.ext, p.model.rig
    dampers = damper_mask(LinearModel(rig, "free"))
    grid = ext.start_grid(rig)
    lin_starts = []
    for f in damper_scales:
        th = np.array(linear.theta, dtype=float)
        th[dampers] *= float(f)
        lin_starts.append(th)
    lin_starts = np.array(lin_starts)
    cands = np.concatenate([np.repeat(lin_starts, len(grid), axis=0),
                            np.tile(grid, (len(lin_starts), 1))], axis=1)
    cands = cands[ext.valid(rig, cands)]
    r = theta_residuals(p, cands)
    order = np.argsort(np.sum(r**2, axis=1))
    return [cands[i] for i in order[: max(1, int(n_starts))]]


def _fit_global(exps, model, opts, linear, w) -> LSQResult:
    """Differential evolution on the records' first samples, then local searches from its
    best member and its pruned copies there, and the best of these once more on all
    samples (``bayesmodal.fit._global_start``)."""
    ext, rig = opts.extension, model.rig
    search = head(exps, opts.max_samples)
    # the records' weights from the whole records, as numbers the searched heads keep
    x = evolve(ext, rig, search_box(ext, rig, linear.theta), search, root_weights(w, search),
               generations=opts.generations, popsize=opts.popsize,
               seed=np.random.default_rng(opts.rng))
    best, centre = None, clip_to_null(ext, rig, x)
    for _ in range(PRUNE_ROUNDS):
        improved = False
        for start in pruned_starts(ext, rig, centre):
            f = _fit_extension(search, model, opts, ext.check(rig, start), linear, w)
            if best is None or f.cost < best.cost:
                best, improved = f, True
        if not improved:
            break
        centre = best.theta   # prune what the polish left: a cart it gave a small level
    if all(a is b for a, b in zip(search, exps, strict=True)):
        return best
    return _fit_extension(exps, model, opts, best.theta, linear, w)


def _fit_records(experiments, model, opts, theta0, linear) -> LSQResult:
    """The joint fit of several records with per-record parameters."""
    exps = [experiments] if isinstance(experiments, Experiment) else list(experiments)
    if not exps:
        raise DataError("no records given; pass at least one Experiment")
    ext, rig = opts.extension, model.rig
    check_outputs(exps, rig, "; use a rig description with as many carts")
    names = model_names(ext, rig)
    per = opts.per_record
    unknown = [q for q in per if q not in names]
    if unknown:
        raise ConfigError(f"per_record {unknown} are not parameters of the model {names}; "
                          "name model parameters only")
    R, P = len(exps), len(names)
    if theta0 is None:
        if linear is None:
            linear = _fit_linear(exps, model, LSQOptions(), None)
        start = (np.array(linear.theta, float) if ext is None
                 else ext.null_theta(rig, linear.theta))
        theta0 = np.tile(start, (R, 1))
    theta0 = np.array(np.broadcast_to(np.asarray(theta0, float), (R, P)))
    valid = model.valid(theta0) if ext is None else ext.valid(rig, theta0)
    if not np.all(valid):
        raise ModelError(f"theta0 is not admissible for {names}; start inside the prior "
                         "bounds (masses, dampers, friction levels >= 0)")
    cart = opts.weights == CART_SPREAD
    w = None if opts.weights is None or cart else experiment_weights(opts.weights, exps)
    coords = coordinates(ext, rig, theta0[0, :model.n_params])
    p, starts = records_problem(ext, model, coords, exps, names, per, theta0, opts.fd_step,
                                None if w is None else np.sqrt(w), cart)
    best = local_search(p, starts, 100 if opts.max_nfev is None else opts.max_nfev)
    return summarize(p, best, weights=w, linear=linear, per_record=per, names=names)
