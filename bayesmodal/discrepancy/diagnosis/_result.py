"""Result types of the ``diagnose`` workflow."""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from ..._json import to_jsonable
from ...model.effects import EXTENSIONS

__all__ = ["TestOutcome", "CandidateScore", "Interval", "Diagnosis", "CAUSES"]

#: Causes the workflow can name: none, or any registered effect.
CAUSES = ("none",) + tuple(EXTENSIONS)


@dataclass(frozen=True)
class TestOutcome:
    """One diagnostic on one training experiment, judged against the null calibration.

    Attributes
    ----------
    name : str
        Diagnostic name (``RESIDUAL_DIAGNOSTICS`` key).
    experiment : str
    statistic : float
        Raw statistic of the diagnostic.
    threshold : float
        Calibrated threshold on the raw statistic's scale.
    z : float
        Standardised score (null mean 0, sd 1 on the transformed scale).
    exceeded : bool
        ``z`` above the workflow threshold.
    suggests : tuple of str
        Causes the diagnostic's signature points to (when it exceeded).
    location : str or None
    summary : str
    """

    name: str
    experiment: str
    statistic: float
    threshold: float
    z: float
    exceeded: bool
    suggests: tuple[str, ...]
    location: str | None
    summary: str

    def as_dict(self) -> dict:
        return to_jsonable({"name": self.name, "experiment": self.experiment,
                       "statistic": self.statistic, "threshold": self.threshold,
                       "z": self.z, "exceeded": self.exceeded,
                       "suggests": list(self.suggests), "location": self.location,
                       "summary": self.summary})


@dataclass(frozen=True)
class CandidateScore:
    """One candidate extension fitted by least squares.

    Attributes
    ----------
    name : str
    signature : float
        Sum of the standardised scores of the exceeded diagnostics that suggest it.
    fitted : bool
        False when it was not fitted (outside the top candidates) or the fit failed.
    gain_nll : float
        Drop of the AR(1)-whitened negative log-likelihood (profiled noise) on the
        training data, nats (also with several training records, whose test adds the
        output error's, ``scoring.Criterion``).
    lr_statistic : float
        ``2 gain_nll``.
    n_params : int
        Extension parameters.
    p_value : float
        ``chi2.sf(lr_statistic, n_params)``; with several records the Bonferroni
        ``2 min`` of it and the output error's normal tail.
    score : float
        BIC gain ``lr_statistic - n_params ln N`` (ranking key).
    significant : bool
        ``p_value`` below ``alpha / n_candidates``.
    passes : bool
        The extended model's residuals pass the diagnostics of its signature.
    location : list of int or None
        1-based cart or spring indices where it acts.
    params : dict
        Extension parameters, SI units.
    message : str
    """

    name: str
    signature: float
    fitted: bool
    gain_nll: float
    lr_statistic: float
    n_params: int
    p_value: float
    score: float
    significant: bool
    passes: bool
    location: list[int] | None
    params: Mapping[str, float]
    message: str = ""

    def as_dict(self) -> dict:
        return to_jsonable({"name": self.name, "score": self.score, "signature": self.signature,
                       "fitted": self.fitted, "gain_nll": self.gain_nll,
                       "lr_statistic": self.lr_statistic, "n_params": self.n_params,
                       "p_value": self.p_value, "significant": self.significant,
                       "passes": self.passes, "location": self.location,
                       "params": dict(self.params), "message": self.message})


@dataclass(frozen=True)
class Interval:
    """Median and equal-tailed credible interval of one parameter."""

    median: float
    lo: float
    hi: float

    def as_dict(self) -> dict:
        return to_jsonable({"median": self.median, "lo": self.lo, "hi": self.hi})


@dataclass(frozen=True)
class Diagnosis:
    """What the linear simulation gets wrong, and what fixes it.

    Attributes
    ----------
    discrepancy : bool
        The diagnostics reject the linear model at the calibrated threshold.
    cause : str
        One of ``CAUSES``.
    location : list of int or None
        1-based cart (friction, backlash: cart 1) or spring (cubic) indices; None for the
        input effects and for ``"none"``.
    location_label : str or None
    explained : bool
        No discrepancy, or an extension was accepted and its residuals pass every
        residual diagnostic.  False with ``discrepancy``: no catalogued extension was
        accepted, or the accepted one leaves diagnostics beyond their threshold (listed in
        ``notes``; ``cause`` names the extension that explains part of the misfit).
    statistic, threshold, p_value : float
        Workflow statistic ``T`` (max standardised score), its threshold and Monte Carlo
        p-value.
    tests : tuple of TestOutcome
        Every diagnostic of the linear model.
    tests_after : tuple of TestOutcome
        The diagnostics of the accepted extended model (empty when none).
    ranking : tuple of CandidateScore
        Candidates, best first.
    parameters : Mapping
        Extension parameters of the final model (``effects``) ``{name: Interval}``
        (credible intervals with the posterior, else the least-squares estimate with a
        Laplace interval; see ``interval_method``).
    linear_parameters : Mapping
        ``{name: {"before", "after", "change_percent"}}``: the linear parameters fitted
        alone and within the final model.
    gain : Mapping
        Linear model against the final model: ``model`` (its name, the effects joined
        by ``+``), ``fit_percent_before/after`` (per training experiment, per output),
        ``heldout_fit_percent_before/after`` (per held-out experiment), ``delta_elpd``,
        ``delta_elpd_se``, ``criterion``; with the posterior, ``posterior``: the same fit
        percents as medians over posterior draws with 90 % intervals (``*_lo``,
        ``*_hi``) and ``heldout_delta_lpd``.
    interval_method : str
        ``"posterior"`` (emcee, converged chains), ``"posterior_unconverged"`` (emcee
        chains that failed the convergence checks: the intervals are not a posterior
        summary; ``notes`` say why), ``"laplace"`` or ``"none"``.
    experiments : tuple of str
    train : tuple of int
    n_null : int
    alpha : float
    rule : str
    notes : tuple of str
    causes : tuple of Cause
        Every effect found, in the order found (forward selection); the first is
        ``cause``/``location``.  Empty for ``"none"``.
    effects : tuple of str
        The effects of the final model (a refinement replaces what it refines).
    weights : str
        How the least-squares fits weighed the training records: ``"none"`` (the sum of
        squared residuals) or ``"spread"`` (``effects.fit.record_weights``).
    """

    discrepancy: bool
    cause: str
    location: list[int] | None
    location_label: str | None
    explained: bool
    statistic: float
    threshold: float
    p_value: float
    tests: tuple[TestOutcome, ...]
    tests_after: tuple[TestOutcome, ...]
    ranking: tuple[CandidateScore, ...]
    parameters: Mapping[str, Interval]
    linear_parameters: Mapping[str, Mapping[str, float]]
    gain: Mapping[str, Any]
    interval_method: str
    experiments: tuple[str, ...]
    train: tuple[int, ...]
    n_null: int
    alpha: float
    rule: str
    notes: tuple[str, ...] = ()
    causes: tuple = ()
    effects: tuple[str, ...] = ()
    weights: str = "none"
    detail: Mapping[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        for name in ("parameters", "linear_parameters", "gain", "detail"):
            object.__setattr__(self, name, MappingProxyType(dict(getattr(self, name))))

    def as_dict(self) -> dict:
        """JSON-ready mapping (the CLI's ``--json`` output)."""
        return to_jsonable({
            "discrepancy": self.discrepancy,
            "cause": self.cause,
            "location": self.location,
            "location_label": self.location_label,
            "causes": [c.as_dict() for c in self.causes],
            "effects": list(self.effects),
            "explained": self.explained,
            "parameters": {k: v.as_dict() for k, v in self.parameters.items()},
            "interval_method": self.interval_method,
            "ranking": [c.as_dict() for c in self.ranking],
            "gain": dict(self.gain),
            "linear_parameters": {k: dict(v) for k, v in self.linear_parameters.items()},
            "tests": [t.as_dict() for t in self.tests],
            "tests_after": [t.as_dict() for t in self.tests_after],
            "statistic": self.statistic,
            "threshold": self.threshold,
            "p_value": self.p_value,
            "experiments": list(self.experiments),
            "train": list(self.train),
            "n_null": self.n_null,
            "alpha": self.alpha,
            "rule": self.rule,
            "weights": self.weights,
            "notes": list(self.notes),
            "forward_steps": self._forward_steps(),
        })

    def _forward_steps(self) -> list:
        """Forward selection's steps (``ForwardResult.steps``): per step the model, ``T``
        against its threshold, and every candidate with its gains; empty without one."""
        fw = self.detail.get("forward")
        return [dict(s) for s in fw.steps] if fw is not None else []

    def to_json(self, **kwargs) -> str:
        """``json.dumps(self.as_dict())``."""
        kwargs.setdefault("indent", 2)
        return json.dumps(self.as_dict(), **kwargs)
