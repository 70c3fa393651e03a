"""Model choice: PSIS-LOO / WAIC, Bayesian evidence, Bayes factor, cross-experiment check.

Four views of "which damping model do the data prefer":

1. **PSIS-LOO and WAIC** (ArviZ) from the pointwise log-likelihood of the fitted data
   (:mod:`.loo`, which also gives the ELPD change between two runs).
   The rig records are autocorrelated time series; leaving one sample out is then only an
   approximation of predictive performance (neighbouring samples carry most of the left-out
   information).  With the AR(1) likelihood the pointwise terms are the conditional
   innovation densities ``p(r_k | r_{k-1})``, which are the natural one-step-ahead units.
2. **Evidence** ``Z = int L(theta) p(theta) dtheta`` by nested sampling (dynesty), with its
   error (:mod:`.evidence`).  It depends on the prior ranges (a wider prior on an unneeded
   parameter costs ``log(width ratio)``), which the report states next to it.
3. **Bayes factor** ``B = Z_a / Z_b``, read on the Kass and Raftery (1995) scale of
   ``2 ln B``: 0-2 not worth more than a bare mention, 2-6 positive, 6-10 strong, > 10 very
   strong (:mod:`.evidence`).
4. **Cross-experiment predictive check** (here): the posterior fitted on one experiment
   scores another (e.g. the steps record) by the log predictive density
   ``log (1/S) sum_s p(y_test | theta_s)`` and by the fit percentage of the predictions.

This module combines them into one verdict (:func:`model_choice`, :func:`choose_model`);
the names of :mod:`.loo` and :mod:`.evidence` stay importable from it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.special import logsumexp

from .._errors import ConfigError
from ..metrics import fit_percent
from .evidence import BayesFactor, Evidence, bayes_factor, kass_raftery, nested_evidence
from .idata import arviz, likelihood_from_idata, posterior_matrix, priors_from_idata
from .likelihood import Likelihood, as_experiments
from .loo import ElpdChange, InformationCriteria, _recorded, elpd_change, information_criteria

__all__ = [
    "InformationCriteria",
    "information_criteria",
    "Evidence",
    "nested_evidence",
    "BayesFactor",
    "bayes_factor",
    "kass_raftery",
    "PredictiveScore",
    "predictive_check",
    "ModelChoice",
    "model_choice",
    "choose_model",
    "ElpdChange",
    "elpd_change",
]


# ----------------------------------------------------------------------------- predictive
@dataclass(frozen=True)
class PredictiveScore:
    """How well a posterior predicts other experiments.

    Attributes
    ----------
    experiments : tuple of str
    lpd : float
        Log predictive density ``log (1/S) sum_s p(y_test | theta_s)`` of all test records
        jointly, nats.
    mean_log_lik : float
        ``(1/S) sum_s log p(y_test | theta_s)`` (less noisy, always <= lpd).
    n_obs : int
        Scalar observations in the test records.
    fit_percent_median, fit_percent_lo, fit_percent_hi : ndarray, shape (n_exp, n_out)
        Median and 90 % interval over draws of the fit percentage of the noise-free
        prediction.
    n_draws : int
    """

    experiments: tuple[str, ...]
    lpd: float
    mean_log_lik: float
    n_obs: int
    fit_percent_median: np.ndarray
    fit_percent_lo: np.ndarray
    fit_percent_hi: np.ndarray
    n_draws: int

    @property
    def lpd_per_obs(self) -> float:
        return self.lpd / self.n_obs


def predictive_check(test: Likelihood, draws: np.ndarray, *, max_draws: int = 400
                     ) -> PredictiveScore:
    """Score posterior draws on experiments they were not fitted to.

    Parameters
    ----------
    test : Likelihood
        The model and noise model of the fitted posterior, on the test experiments.
    draws : ndarray, shape (S, P)
        Posterior draws in ``test.names`` order.
    max_draws : int
        Evenly spaced subset of the draws used (the lpd depends on S only through Monte
        Carlo error).

    Returns
    -------
    PredictiveScore
    """
    draws = np.asarray(draws, dtype=float)
    if draws.ndim != 2 or draws.shape[1] != test.n_params:
        raise ConfigError(f"draws must have shape (S, {test.n_params}), got {draws.shape}")
    idx = np.unique(np.linspace(0, draws.shape[0] - 1, min(max_draws, draws.shape[0]))
                    .round().astype(int))
    sub = draws[idx]
    ll = np.concatenate([test(sub[i : i + 64]) for i in range(0, sub.shape[0], 64)])
    mech = test.split(sub)[0]
    fp = []  # (S, n_exp, n_out)
    for i in range(0, mech.shape[0], 64):
        yhs = test.predict(mech[i : i + 64])  # linear or extended model, per experiment
        fp.extend(
            [[fit_percent(e.y_m, yh[j]) for e, yh in zip(test.experiments, yhs, strict=True)]
             for j in range(yhs[0].shape[0])])
    fits = np.array(fp)
    q = np.quantile(fits, [0.5, 0.05, 0.95], axis=0)
    return PredictiveScore(
        experiments=tuple(e.name for e in test.experiments),
        lpd=float(logsumexp(ll) - np.log(ll.size)),
        mean_log_lik=float(np.mean(ll)),
        n_obs=test.n_data,
        fit_percent_median=q[0],
        fit_percent_lo=q[1],
        fit_percent_hi=q[2],
        n_draws=int(ll.size),
    )


# ----------------------------------------------------------------------------- the table
@dataclass(frozen=True)
class ModelChoice:
    """Which model the data prefer, by each criterion.

    Attributes
    ----------
    models : tuple of str
        Model labels (e.g. ``("free", "proportional")``).
    criteria : dict of str to InformationCriteria
    loo_compare : pandas.DataFrame
        ``arviz.compare`` table (rank, elpd_loo, p_loo, elpd_diff, weight, se, dse, ...).
    evidence : dict of str to Evidence
        Empty if not computed.
    bayes_factor : BayesFactor or None
    predictive : dict of str to PredictiveScore
        Empty if no test experiments.
    preferred : dict of str to str
        Winner by ``"loo"``, ``"waic"``, ``"evidence"``, ``"predictive"``.
    verdict : str
        One paragraph in plain words.
    """

    models: tuple[str, ...]
    criteria: dict
    loo_compare: object
    evidence: dict = field(default_factory=dict)
    bayes_factor: BayesFactor | None = None
    predictive: dict = field(default_factory=dict)
    preferred: dict = field(default_factory=dict)
    verdict: str = ""

    def as_dict(self) -> dict:
        """JSON-ready dictionary (the ``model_choice`` entry of summary files)."""
        out = {
            "models": list(self.models),
            "preferred": dict(self.preferred),
            "verdict": self.verdict,
            "loo": {m: {"elpd": c.elpd_loo, "se": c.se_loo, "p": c.p_loo,
                        "max_pareto_k": c.max_pareto_k, "n_bad_k": c.n_bad_k}
                    for m, c in self.criteria.items()},
            "waic": {m: {"elpd": c.elpd_waic, "se": c.se_waic, "p": c.p_waic}
                     for m, c in self.criteria.items()},
        }
        df = self.loo_compare
        out["loo_compare"] = {
            str(ix): {k: (float(v) if isinstance(v, (int, float, np.floating)) else str(v))
                      for k, v in row.items()}
            for ix, row in df.iterrows()
        }
        if self.evidence:
            out["evidence"] = {m: {"log_z": e.log_z, "log_z_err": e.log_z_err,
                                   "information_nats": e.information_nats,
                                   "n_calls": e.n_calls, "elapsed_s": e.elapsed_s}
                               for m, e in self.evidence.items()}
        if self.bayes_factor is not None:
            bf = self.bayes_factor
            out["bayes_factor"] = {"a": bf.a, "b": bf.b, "log_bf": bf.log_bf,
                                   "log_bf_err": bf.log_bf_err, "two_ln_b": bf.two_ln_b,
                                   "favoured": bf.favoured, "reading": bf.reading}
        if self.predictive:
            out["predictive"] = {
                m: {"experiments": list(p.experiments), "lpd": p.lpd,
                    "lpd_per_obs": p.lpd_per_obs, "mean_log_lik": p.mean_log_lik,
                    "fit_percent_median": p.fit_percent_median.tolist(),
                    "fit_percent_lo": p.fit_percent_lo.tolist(),
                    "fit_percent_hi": p.fit_percent_hi.tolist()}
                for m, p in self.predictive.items()}
        return out

    def to_markdown(self) -> str:
        """The model-choice table as Markdown, one row per criterion."""
        a, b = self.models[:2]
        rows = ["| criterion | " + a + " | " + b + " | difference | preferred |",
                "|---|---|---|---|---|"]
        ca, cb = self.criteria[a], self.criteria[b]
        d = self.loo_compare
        dse = float(d.loc[d.index[1], "dse"]) if len(d) > 1 else float("nan")
        rows.append(f"| PSIS-LOO elpd (se) | {ca.elpd_loo:.1f} ({ca.se_loo:.1f}) | "
                    f"{cb.elpd_loo:.1f} ({cb.se_loo:.1f}) | {ca.elpd_loo - cb.elpd_loo:+.1f} "
                    f"(dse {dse:.1f}) | {self.preferred.get('loo', '')} |")
        rows.append(f"| p_loo | {ca.p_loo:.1f} | {cb.p_loo:.1f} | | |")
        rows.append(f"| Pareto k > 0.7 | {ca.n_bad_k} of {ca.n_obs} | {cb.n_bad_k} of "
                    f"{cb.n_obs} | | |")
        rows.append(f"| WAIC elpd (se) | {ca.elpd_waic:.1f} ({ca.se_waic:.1f}) | "
                    f"{cb.elpd_waic:.1f} ({cb.se_waic:.1f}) | "
                    f"{ca.elpd_waic - cb.elpd_waic:+.1f} | {self.preferred.get('waic', '')} |")
        if self.evidence:
            ea, eb = self.evidence[a], self.evidence[b]
            bf = self.bayes_factor
            rows.append(f"| ln Z (err) | {ea.log_z:.1f} ({ea.log_z_err:.1f}) | "
                        f"{eb.log_z:.1f} ({eb.log_z_err:.1f}) | ln B = {bf.log_bf:+.1f} "
                        f"+- {bf.log_bf_err:.1f} | {bf.favoured} ({bf.reading}) |")
        if self.predictive:
            pa, pb = self.predictive[a], self.predictive[b]
            names = ", ".join(pa.experiments)
            rows.append(f"| lpd on {names} | {pa.lpd:.1f} | {pb.lpd:.1f} | "
                        f"{pa.lpd - pb.lpd:+.1f} | {self.preferred.get('predictive', '')} |")
            fa = ", ".join(f"{x:.1f}" for x in pa.fit_percent_median.ravel())
            fb = ", ".join(f"{x:.1f}" for x in pb.fit_percent_median.ravel())
            rows.append(f"| fit % on {names} (median) | {fa} | {fb} | | |")
        return "\n".join(rows)


def _loo_reading(diff: float, dse: float) -> str:
    if not np.isfinite(dse) or dse <= 0:
        return "cannot be judged (no standard error)"
    z = abs(diff) / dse
    if abs(diff) < 4 or z < 2:
        return f"small (|difference| {abs(diff):.1f} is {z:.1f} standard errors)"
    return f"clear (|difference| {abs(diff):.1f} is {z:.1f} standard errors)"


def model_choice(
    idatas: Mapping[str, object],
    *,
    evidences: Mapping[str, Evidence] | None = None,
    predictive: Mapping[str, PredictiveScore] | None = None,
) -> ModelChoice:
    """Combine LOO, WAIC, evidence and predictive scores into one verdict.

    Parameters
    ----------
    idatas : mapping of str to InferenceData
        Two fitted models on the same data, each with a ``log_likelihood`` group.
    evidences : mapping of str to Evidence, optional
    predictive : mapping of str to PredictiveScore, optional

    Returns
    -------
    ModelChoice
    """
    az = arviz()
    models = tuple(idatas)
    if len(models) != 2:
        raise ConfigError(f"model choice compares two models, got {len(models)}: {models}")
    a, b = models
    crit = {m: information_criteria(idatas[m]) for m in models}
    table, _ = _recorded(az.compare, dict(idatas), ic="loo", var_name="y")
    pref = {
        "loo": a if crit[a].elpd_loo >= crit[b].elpd_loo else b,
        "waic": a if crit[a].elpd_waic >= crit[b].elpd_waic else b,
    }
    dse = float(table.loc[table.index[1], "dse"])
    diff = crit[a].elpd_loo - crit[b].elpd_loo
    words = [f"PSIS-LOO prefers the {pref['loo']} model; the difference is "
             f"{_loo_reading(diff, dse)}."]
    bf = None
    evidences = dict(evidences or {})
    if evidences:
        bf = bayes_factor(evidences, a, b)
        pref["evidence"] = bf.favoured
        words.append(
            f"The evidence favours the {bf.favoured} model: ln B = {abs(bf.log_bf):.1f} "
            f"+- {bf.log_bf_err:.1f}, 2 ln B = {bf.two_ln_b:.1f}, which Kass and Raftery "
            f"call {bf.reading} (given the stated prior ranges)."
        )
    predictive = dict(predictive or {})
    if predictive:
        pa, pb = predictive[a], predictive[b]
        pref["predictive"] = a if pa.lpd >= pb.lpd else b
        words.append(
            f"On the held-out {', '.join(pa.experiments)} record the {pref['predictive']} "
            f"model predicts better (log predictive density higher by "
            f"{abs(pa.lpd - pb.lpd):.1f} nats; mean fit over outputs {a} "
            f"{np.mean(pa.fit_percent_median):.1f} %, {b} {np.mean(pb.fit_percent_median):.1f} %)."
        )
    winners = set(pref.values())
    if len(winners) == 1:
        words.append(f"All criteria agree: the data prefer the {winners.pop()} damping model.")
    else:
        words.append("The criteria disagree: " + ", ".join(
            f"{k} -> {v}" for k, v in pref.items()) + ".")
    if any(c.n_bad_k for c in crit.values()):
        words.append("Some Pareto k exceed 0.7, so PSIS-LOO is unreliable for those samples.")
    return ModelChoice(models=models, criteria=crit, loo_compare=table,
                       evidence=evidences, bayes_factor=bf, predictive=predictive,
                       preferred=pref, verdict=" ".join(words))


def choose_model(
    idatas: Mapping[str, object],
    *,
    test=None,
    evidence: bool = True,
    nlive: int = 250,
    dlogz: float = 0.5,
    rng=None,
    maxcall: int | None = None,
) -> ModelChoice:
    """Model choice between two finished runs (e.g. free vs proportional damping).

    Parameters
    ----------
    idatas : mapping of str to InferenceData
        Two runs on the same data (as written by ``to_inference_data``).
    test : Experiment or sequence of Experiment, optional
        Held-out experiments for the predictive check.
    evidence : bool
        Compute the evidence of each model by nested sampling (minutes on the rig data).
    nlive, dlogz, maxcall
        Passed to :func:`nested_evidence`.
    rng : numpy.random.Generator or int, optional

    Returns
    -------
    ModelChoice
    """

    gen = np.random.default_rng(rng)
    evs = {}
    if evidence:
        for m, idt in idatas.items():
            lik = likelihood_from_idata(idt)
            evs[m] = nested_evidence(lik, priors_from_idata(idt), nlive=nlive, dlogz=dlogz,
                                     rng=gen, maxcall=maxcall)
    pred = {}
    if test is not None:
        tests = as_experiments(test)
        for m, idt in idatas.items():
            lik = likelihood_from_idata(idt, tests)
            draws = posterior_matrix(idt, list(lik.names)).reshape(-1, lik.n_params)
            pred[m] = predictive_check(lik, draws)
    return model_choice(idatas, evidences=evs, predictive=pred)


