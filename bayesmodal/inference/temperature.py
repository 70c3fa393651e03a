"""Calibrating the temperature of a generalised posterior by leave-one-record-out coverage.

A tempered ("generalised") posterior ``p(theta) L(theta)^(1/T)`` (``LogPosterior``'s
``temperature``) widens the parameter posterior of a misspecified model: for a posterior
dominated by a Gaussian-shaped likelihood, its covariance scales with ``T``.  The
temperature is a number the data must choose.  Here it is chosen by what the intervals
are for, predicting records the posterior has not seen:

1. for each ``T`` of a grid (on a log scale), run the leave-one-record-out study
   (``crossval``: sample on all records but one, predict that one) with the tempered
   posterior, and record the 90 % predictive bands' coverage of every held-out record and
   output, and their mean width;
2. summarise the coverages per ``T`` by a *criterion*: ``"mean"`` (the average over
   held-out records and outputs) or ``"worst"`` (the held-out record with the lowest
   coverage, averaged over its outputs);
3. take the smallest ``T`` at which the criterion reaches the nominal 90 %, by linear
   interpolation in ``log T`` between the first pair of neighbouring grid points that
   brackets it.  The coverage need not grow with ``T``: tempering loosens the noise
   parameters too, and with AR(1) noise near ``phi = 1`` the band's stationary spread
   ``sigma / sqrt(1 - phi^2)`` shrinks when ``phi`` moves away from 1 (measured on the
   ECP records, docs/uncertainty.md);
4. optionally (``refine``) run the study once more at that ``T``: the coverage reported
   at the chosen temperature is then measured, not interpolated.

If the criterion is already at the target at the smallest ``T`` of the grid, that ``T`` is
returned (``status = "above"``); if no ``T`` of the grid reaches it, the one with the
highest criterion (``status = "below"``; extend the grid, or accept that tempering does not
reach the target).

The alternative of Syring & Martin (2019, Biometrika 106, 479), choosing ``T`` so that
posterior credible sets of a bootstrap of the data cover the full-data estimate at the
nominal rate, needs one posterior per bootstrap sample and per iteration of the
temperature (hundreds of MCMC runs of several minutes each on the four ECP records, and a
bootstrap of autocorrelated records needs blocks long against the correlation time of
hundreds of samples, i.e. few blocks per record); the coverage of held-out records asks
the question the intervals are meant to answer at the cost of one study per grid point.

Each leave-one-record-out study costs as much as ``crossval`` (about 4-10 minutes for the
linear model on the four ECP records and 2 cores); a grid of four temperatures and the
refinement therefore take five studies.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from .._errors import ConfigError
from .crossval import CrossvalSpec, _map, crossval

__all__ = ["TemperatureCalibration", "DEFAULT_TEMPERATURES", "CRITERIA", "solve_temperature",
           "calibrate", "calibrate_loro"]

#: Default grid of temperatures (the four ECP records need large ones: the parameter
#: posterior is some fifty times narrower than the spread across records).
DEFAULT_TEMPERATURES = (1.0, 10.0, 100.0, 1000.0)

#: Summaries of the coverages of one study: see the module docstring.
CRITERIA = ("mean", "worst")


@dataclass(frozen=True)
class TemperatureCalibration:
    """A calibrated temperature and the coverage curve it came from.

    Attributes
    ----------
    temperature : float
        The chosen temperature ``T``.
    status : {"bracketed", "above", "below"}
        Whether the target lies inside the grid's coverage range (see the module
        docstring).
    target : float
        Nominal coverage of the 90 % bands (0.9).
    criterion : {"mean", "worst"}
    temperatures : ndarray, shape (K,)
        Every temperature evaluated, increasing (the chosen one included when refined).
    coverage : ndarray, shape (K, R, n_out)
        Coverage of the 90 % band per temperature, held-out record and output.
    width : ndarray, shape (K, R, n_out)
        Mean 90 % band width over the record's standard deviation.
    records : tuple of str
        Held-out record names (axis R).
    """

    temperature: float
    status: str
    target: float
    criterion: str
    temperatures: np.ndarray
    coverage: np.ndarray
    width: np.ndarray
    records: tuple[str, ...] = ()

    @property
    def summary(self) -> np.ndarray:
        """The criterion per temperature, shape (K,)."""
        return criterion_value(self.coverage, self.criterion)

    def to_dict(self) -> dict:
        return {"temperature": self.temperature, "status": self.status, "target": self.target,
                "criterion": self.criterion, "method": "loro_coverage",
                "records": list(self.records),
                "curve": [{"temperature": float(t), "criterion": float(s),
                           "coverage_90": c.tolist(), "width_90": w.tolist(),
                           "mean_coverage_90": float(np.mean(c)),
                           "mean_width_90": float(np.mean(w))}
                          for t, s, c, w in zip(self.temperatures, self.summary,
                                                self.coverage, self.width, strict=True)]}

    def table(self) -> str:
        """Plain-text coverage curve: one row per temperature."""
        rows = [f"temperature  {self.criterion} cov90  mean cov90  min cov90  mean width90"]
        for t, s, c, w in zip(self.temperatures, self.summary, self.coverage, self.width,
                              strict=True):
            mark = "  <- chosen" if t == self.temperature else ""
            rows.append(f"{t:11.4g}  {s:10.3f}  {np.mean(c):10.3f}  {np.min(c):9.3f}  "
                        f"{np.mean(w):12.2f}{mark}")
        rows.append(f"chosen T = {self.temperature:.4g} ({self.status}; target "
                    f"{self.target:g}, criterion {self.criterion})")
        return "\n".join(rows)


def criterion_value(coverage: np.ndarray, criterion: str) -> np.ndarray:
    """The criterion of coverages of shape (..., R, n_out), shape (...)."""
    if criterion == "mean":
        return np.mean(coverage, axis=(-2, -1))
    if criterion == "worst":
        return np.min(np.mean(coverage, axis=-1), axis=-1)
    raise ConfigError(f"criterion must be one of {CRITERIA}, got {criterion!r}")


def solve_temperature(temperatures: Sequence[float], value: Sequence[float],
                      target: float = 0.9) -> tuple[float, str]:
    """The smallest temperature at which a coverage curve reaches ``target``.

    Parameters
    ----------
    temperatures : sequence of float, increasing, > 0
    value : sequence of float
        The coverage criterion at each temperature.
    target : float

    Returns
    -------
    temperature : float
        Linear interpolation in ``log T`` between the first neighbouring grid points whose
        values bracket ``target``; the first grid point if it is already there
        (``"above"``); the grid point of the highest value if none reaches it
        (``"below"``).
    status : {"bracketed", "above", "below"}

    Examples
    --------
    >>> t, status = solve_temperature([1, 10, 100], [0.5, 0.7, 0.95], 0.9)
    >>> round(t, 3), status  # 10 ** (1 + 0.2 / 0.25)
    (63.096, 'bracketed')
    """
    t = np.asarray(temperatures, dtype=float)
    v = np.asarray(value, dtype=float)
    if t.ndim != 1 or t.size != v.size or t.size < 1 or np.any(t <= 0) or np.any(
            np.diff(t) <= 0):
        raise ConfigError(f"temperatures must be increasing and > 0 with one value each, got "
                          f"{t.tolist()} and {v.size} values")
    if v[0] >= target:
        return float(t[0]), "above"
    if not np.any(v >= target):
        return float(t[int(np.argmax(v))]), "below"
    i = int(np.argmax(v >= target))  # the first crossing (v[i - 1] < target <= v[i])
    x0, x1 = np.log(t[i - 1]), np.log(t[i])
    frac = (target - v[i - 1]) / (v[i] - v[i - 1])
    return float(np.exp(x0 + frac * (x1 - x0))), "bracketed"


def calibrate(evaluate: Callable[[float], tuple[np.ndarray, np.ndarray]],
              temperatures: Sequence[float] = DEFAULT_TEMPERATURES, *, target: float = 0.9,
              criterion: str = "mean", refine: bool = True,
              records: Sequence[str] = ()) -> TemperatureCalibration:
    """Choose a temperature from held-out coverages (the steps of the module docstring).

    Parameters
    ----------
    evaluate : callable
        ``evaluate(T) -> (coverage, width)``, each shape (R, n_out): the 90 % band
        coverage and relative width of every held-out record and output of a study at
        temperature ``T`` (e.g. a leave-one-record-out study, :func:`calibrate_loro`).
    temperatures : sequence of float
        The grid, > 0 (sorted here).
    target : float
        Nominal coverage, in (0, 1).
    criterion : {"mean", "worst"}
    refine : bool
        Evaluate once more at the interpolated temperature (when bracketed).
    records : sequence of str
        Names of the held-out records (for the report).

    Returns
    -------
    TemperatureCalibration
    """
    grid = np.unique(np.asarray(temperatures, dtype=float))
    if grid.size < 1 or np.any(~np.isfinite(grid)) or np.any(grid <= 0):
        raise ConfigError(f"temperatures must be finite and > 0, got {list(temperatures)}")
    if not 0 < target < 1:
        raise ConfigError(f"target coverage must be in (0, 1), got {target}")
    criterion_value(np.zeros((1, 1)), criterion)  # checks the name
    cov, wid = {}, {}
    for t in grid:
        cov[t], wid[t] = (np.asarray(a, dtype=float) for a in evaluate(float(t)))
    ts = sorted(cov)
    value = [float(criterion_value(cov[t], criterion)) for t in ts]
    chosen, status = solve_temperature(ts, value, target)
    if refine and status == "bracketed" and chosen not in cov:
        cov[chosen], wid[chosen] = (np.asarray(a, dtype=float) for a in evaluate(chosen))
        ts = sorted(cov)
    return TemperatureCalibration(
        temperature=chosen, status=status, target=float(target), criterion=criterion,
        temperatures=np.array(ts), coverage=np.array([cov[t] for t in ts]),
        width=np.array([wid[t] for t in ts]), records=tuple(records))


def calibrate_loro(experiments, spec=None, *, temperatures: Sequence[float] =
                   DEFAULT_TEMPERATURES, target: float = 0.9, criterion: str = "mean",
                   refine: bool = True, workers: int | None = None,
                   scheduler: str | None = None, progress=None, joint: bool = True):
    """Calibrate the temperature by leave-one-record-out coverage (``crossval`` per ``T``).

    Parameters
    ----------
    experiments : sequence of Experiment
        At least two records.
    spec : CrossvalSpec, optional
        Model, noise, layout and sampler settings; its ``temperature`` is replaced by each
        grid value.
    temperatures, target, criterion, refine
        See :func:`calibrate`.
    workers, scheduler, progress
        See ``crossval``.
    joint : bool
        Add the joint run on all records to the study at the chosen temperature.

    Returns
    -------
    calibration : TemperatureCalibration
    result : CrossvalResult
        The study at the chosen temperature (with the joint run on all records).

    Examples
    --------
    >>> # cal, res = calibrate_loro([imp, steps, fast, slow], CrossvalSpec(n_steps=3000))
    >>> # print(cal.table()); print(res.table())
    """

    spec = CrossvalSpec() if spec is None else spec
    exps = list(experiments)
    studies = {}
    say = progress or (lambda line: None)

    def evaluate(t: float):
        say(f"temperature {t:.4g}: leave-one-record-out study")
        res = crossval(exps, replace(spec, temperature=t), workers=workers,
                       scheduler=scheduler, joint=False, progress=progress)
        studies[t] = res
        return (np.array([f.scores.coverage_90 for f in res.folds]),
                np.array([f.scores.width_90 for f in res.folds]))

    cal = calibrate(evaluate, temperatures, target=target, criterion=criterion,
                    refine=refine, records=[e.name for e in exps])
    final = studies[cal.temperature]
    if joint:
        say(f"calibrated temperature {cal.temperature:.4g} ({cal.status}); joint run")
        final = _with_joint(final, exps, workers, scheduler, progress)
    return cal, final


def _with_joint(res, exps, workers, scheduler, progress):
    """A study's result with the joint run on all records added."""

    joint = _map([(res.spec, exps, None)], workers, scheduler, progress)[0]
    return replace(res, joint=joint)
