"""Did a least-squares fit determine its parameters?  A verdict with the reason and the fix.

An output-error fit always returns numbers, also when the record cannot support them: a
drive wired the other way round (+V moves the carts to negative counts) drives the gain
to its bound 0; an input column that is not the motor command
leaves parameters that run off to 1e19 with no finite standard error.  The estimate of
such a fit is not an answer, and :func:`identify` says so.  A fit is *not identified*
when

- a parameter whose zero switches the model off (the drive gain ``g_v``, a mass, a
  spring) is indistinguishable from that bound: zero lies within one standard error, a
  relative standard error of at least ``MAX_RELATIVE_STDERR = 1``, above which the
  one-sigma interval holds zero and values of the other sign, so the data determine
  neither its size nor its sign (a reversed drive ends with ``g_v = 6e-10 +- 0.07 N/V``);
- a standard error is not finite (the Gauss-Newton matrix ``J^T J`` is singular at the
  estimate);
- a damper fitted on a log scale (``c1..cn``, ``ca``) has a relative standard error above
  ``1 / sqrt(eps)``: the Jacobian comes from forward differences with a relative step of
  ``1e-7 ~ sqrt(eps)``, so its columns carry relative errors of that order and a standard
  error beyond ``1 / sqrt(eps)`` times the estimate is numerical noise, not information.
  A damper is not held to the bound of 1: a standard error above a damping estimate
  says the damping is poorly determined, which is a legitimate answer (the measured fast
  sweep's ``c2`` has a relative standard error of 0.998);
- the Jacobian is rank-deficient: a singular value of the column-equilibrated Jacobian
  below ``max(n_rows, n_columns) eps s_max``, the rounding level of the singular value
  decomposition itself (``numpy.linalg.matrix_rank``'s tolerance);
- the model explains less than the record's mean on some record and cart (fit percent
  below 0, the level of the constant prediction ``y = mean(y)``).

Dampers that may vanish (``c12``, ``c23``, ``cb``, fitted on a linear scale from the bound
0) need only a finite standard error: one above such an estimate says the damper is
compatible with none.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ._errors import IdentificationError
from ._format import param_unit, sig
from .model.system import log_scale_mask as _log_mask
from .model.system import param_kinds

__all__ = ["Identification", "identify", "MAX_RELATIVE_STDERR", "MAX_RELATIVE_STDERR_DAMPER"]

#: Largest relative standard error of a parameter that cannot vanish: above it the
#: one-sigma interval holds zero, so neither the size nor the sign is determined.
MAX_RELATIVE_STDERR = 1.0

#: Largest relative standard error of a damper fitted on a log scale: beyond it the
#: error is below the resolution of the forward-difference Jacobian (relative step
#: ~ sqrt(eps)).
MAX_RELATIVE_STDERR_DAMPER = 1.0 / np.sqrt(np.finfo(float).eps)

#: Parameter kinds whose zero switches the model off (no drive, no inertia, no spring).
_ESSENTIAL = ("gain", "mass", "spring")

#: The input of a closed-loop record: the effort the controller applied drives the carts
#: (an output-error fit of it is consistent, tests/test_closed_loop.py), the reference
#: does not.
_CLOSED_LOOP = ("in a closed-loop record the control effort, 'Control Effort' of an ECP "
                "export, not the commanded position")

#: What a bound at zero says, and the fix, by parameter kind.
_BOUND_FIX = {
    "gain": ("the carts do not move with the input as the model drives them; if +V moves "
             "the carts to negative counts the drive is reversed: read the record with "
             "--input-scale -1 (ReadOptions(input_scale=-1)); otherwise check that the "
             "input column is the motor command in volts (--columns v=NAME)"),
    "mass": ("the model is switched off; check that the input column is the motor command "
             "in volts and its sign (--columns v=NAME, --input-scale, -1 for a reversed "
             f"drive; {_CLOSED_LOOP})"),
    "spring": ("the model is switched off; check that the input column is the motor "
               "command in volts and its sign (--columns v=NAME, --input-scale, -1 for a "
               f"reversed drive; {_CLOSED_LOOP})"),
}

_INPUT_FIX = ("check that the input column is the motor command in volts (--columns "
              f"v=NAME, --input-scale; {_CLOSED_LOOP}) and that the record excites every "
              "cart")


@dataclass(frozen=True)
class Identification:
    """Verdict on a least-squares fit: were its parameters determined by the data?

    Attributes
    ----------
    identified : bool
        True when none of the checks of this module fails.
    reason : str
        The first problem found, naming the cause and the fix, on one line; ``""`` when
        identified.
    problems : tuple of str
        Every problem found, most decisive first (``reason`` is ``problems[0]``).
    rules : tuple of str
        The rule behind each problem, in the same order: ``"bound"`` (a gain, mass or
        spring indistinguishable from 0), ``"stderr"`` (a standard error not finite),
        ``"jacobian"`` (not finite or rank-deficient), ``"fit"`` (below 0 %),
        ``"damper"`` (a log-scale damper beyond the Jacobian's resolution).
    relative_stderr : ndarray, shape (n_params,)
        Standard error over the absolute estimate, per parameter (``inf`` for an estimate
        of 0, ``nan`` for a standard error that is not finite).
    singular_values : ndarray, shape (n_columns,), or None
        Singular values of the column-equilibrated Jacobian (each column scaled to unit
        norm), largest first; None when the fit did not keep them.
    rank : int or None
        Numerical rank of that Jacobian (values above ``max(shape) eps s_max``).
    min_fit_percent : float
        Smallest fit percent over records and carts, percent.
    """

    identified: bool
    reason: str
    problems: tuple[str, ...]
    rules: tuple[str, ...]
    relative_stderr: np.ndarray
    singular_values: np.ndarray | None
    rank: int | None
    min_fit_percent: float

    def as_dict(self) -> dict:
        """JSON-ready fields: ``identified``, ``reason``, ``problems``."""
        return {"identified": self.identified, "reason": self.reason,
                "problems": list(self.problems)}


def _value(name: str, value: float, se: float) -> str:
    unit = param_unit(name)
    return f"{name} = {sig(value, 3)} +- {sig(se, 2)}" + (f" {unit}" if unit else "")


def identify(result, names: Sequence[str] | None = None) -> Identification:
    """The identifiability verdict of an output-error least-squares fit.

    Parameters
    ----------
    result : LSQResult
        A fit of :func:`bayesmodal.fit.fit_lsq`.
    names : sequence of str, optional
        Record names for the messages, one per record (default ``record 1..n``).

    Returns
    -------
    Identification

    Examples
    --------
    >>> from bayesmodal.data import Experiment
    >>> from bayesmodal.fit import fit_lsq
    >>> from bayesmodal.model.simulate import simulate_linear
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> truth = np.array([6.2, 1.5, 1.4, 1.1, 1.5, 1e-4])
    >>> t = np.arange(2000) * 0.005
    >>> v = (t < 0.05) * 3.0
    >>> y = simulate_linear(model, truth, v, 0.005)
    >>> identify(fit_lsq(Experiment(t, v, y), model)).identified
    True
    >>> verdict = identify(fit_lsq(Experiment(t, v, -y), model))   # a reversed drive
    >>> verdict.identified, verdict.reason.split(" (")[0]
    (False, 'the drive gain g_v is indistinguishable from its bound 0')
    """

    model = result.model
    theta = np.asarray(result.theta, float)
    d = np.diag(np.asarray(result.cov, float))
    with np.errstate(invalid="ignore"):  # NaN variances stay NaN, negative ones become NaN
        se = np.where(d >= 0, np.sqrt(np.abs(d)), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = se / np.abs(theta)
    kinds = param_kinds(model)
    can_vanish = ~_log_mask(model)
    fits = np.atleast_2d(np.asarray(result.fit_percent, float))
    if names is None:
        names = [f"record {i + 1}" for i in range(fits.shape[0])]
    problems: list[str] = []
    rules: list[str] = []

    def add(rule: str, text: str) -> None:
        rules.append(rule)
        problems.append(text)

    # 1. a parameter whose zero switches the model off, indistinguishable from that zero
    for i, (name, kind) in enumerate(zip(model.names, kinds, strict=True)):
        if kind in _ESSENTIAL and (theta[i] <= 0 or rel[i] >= MAX_RELATIVE_STDERR):
            what = {"gain": "the drive gain", "mass": "the mass",
                    "spring": "the spring"}[kind]
            add("bound", f"{what} {name} is indistinguishable from its bound 0 (zero "
                            f"within one standard error: {_value(name, theta[i], se[i])}): "
                            f"{_BOUND_FIX[kind]}")
    # 2. standard errors that are not finite
    bad = [i for i in range(theta.size) if not np.isfinite(se[i])]
    if bad:
        # the names only: an estimate without an error says nothing, and where the fit
        # stopped on a singular J^T J depends on the optimiser's path
        shown = ", ".join(model.names[i] for i in bad[:3])
        add("stderr", f"no finite standard error for {shown} (J^T J is singular at the "
                        f"estimate): the data do not determine them; {_INPUT_FIX}")
    # 3. a rank-deficient Jacobian
    s = result.jac_singular_values
    rank = None
    if s is not None and not np.all(np.isfinite(s)):
        add("jacobian", "the Jacobian is not finite at the estimate (a parameter ran off "
                        f"to an extreme): the data do not determine it; {_INPUT_FIX}")
    elif s is not None and np.size(s):
        s = np.asarray(s, float)
        tol = max(result.jac_shape[0], s.size) * np.finfo(float).eps * s[0]
        rank = int(np.sum(s > tol))
        if rank < s.size:
            add("jacobian", f"the Jacobian is rank-deficient (rank {rank} of {s.size}; "
                            f"smallest singular value {sig(s[-1] / s[0], 2)} of the "
                            "largest): some parameters are not determined by these "
                            f"records; {_INPUT_FIX}, or fix the undetermined parameters "
                            "in the rig (--rig FILE, docs/rigs.md)")
    # 4. worse than the record's mean
    min_fit = float(np.min(fits)) if fits.size else float("nan")
    if fits.size and min_fit < 0:
        e, k = np.unravel_index(int(np.argmin(fits)), fits.shape)
        add("fit", f"the model explains less than the record's mean (fit "
                        f"{min_fit:.1f} % on output {k + 1} of {names[e]}): the estimate "
                        "does not describe the record; check the input's sign "
                        "(--input-scale -1 for a reversed drive) and column (--columns "
                        "v=NAME), and the rig (--rig FILE)")
    # 5. dampers on a log scale whose standard error is beyond the Jacobian's resolution
    loose = [i for i in range(theta.size) if not can_vanish[i] and kinds[i] not in _ESSENTIAL
             and np.isfinite(se[i]) and rel[i] > MAX_RELATIVE_STDERR_DAMPER]
    if loose:
        shown = ", ".join(_value(model.names[i], theta[i], se[i]) for i in loose[:3])
        add("damper", f"standard error over {sig(MAX_RELATIVE_STDERR_DAMPER, 2)} times "
                        f"the estimate for {shown}: the data do not determine them; "
                        f"{_INPUT_FIX}")
    return Identification(
        identified=not problems,
        reason=problems[0] if problems else "",
        problems=tuple(problems),
        rules=tuple(rules),
        relative_stderr=rel,
        singular_values=s,
        rank=rank,
        min_fit_percent=min_fit,
    )


#: The rule whose failure makes an analysis built on the linear fit a wrong answer: a fit
#: below the record's mean (a reversed drive, an input that is not the motor command).
#: A gain or mass near 0 alone is not: the sampler leaves a poor least-squares start on
#: short records (a fold of two 400-sample records ends at m1 = 0.005 +- 0.11 kg and
#: samples well); nor is a singular J^T J: on records with strong dry friction the
#: linear fit's dampers end on their bound, and those are the records ``diagnose`` is for.
STARTING_POINT_RULES = ("fit",)


def require_identified(result, experiments, what: str,
                       rules: Sequence[str] = STARTING_POINT_RULES) -> None:
    """Raise ``IdentificationError`` when the linear least-squares fit that ``what`` (a
    posterior, a diagnosis) starts from fails one of ``rules`` (:func:`identify`).

    An analysis built on such a fit would sample, or search for effects around, an
    estimate that is not an answer; one line names the records, the cause and the fix.

    Parameters
    ----------
    result : LSQResult
        The least-squares fit.
    experiments : sequence of Experiment
        The records it was fitted to (their names and sources name them).
    what : str
        The analysis that needs the fit, e.g. ``"the posterior"``.
    rules : sequence of str
        The rules that refuse (``Identification.rules``); default
        ``STARTING_POINT_RULES``.
    """

    exps = list(experiments)
    verdict = identify(result, [e.name for e in exps])
    failed = [p for p, r in zip(verdict.problems, verdict.rules, strict=True) if r in rules]
    if failed:
        where = ", ".join(str(e.source or e.name) for e in exps)
        raise IdentificationError(f"{where}: not identified: the linear least-squares fit "
                                  f"{what} starts from does not determine its parameters: "
                                  f"{failed[0]}")
