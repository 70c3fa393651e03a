"""Posterior step of ``diagnose``: emcee samples of the linear and the accepted model.

Both models are sampled with ``bayesmodal.inference.sample_posterior`` (AR(1) noise, the
default priors; the extended model with ``extension=``) on the training experiments,
started from the workflow's least-squares fits, with one restart of the ensemble at its
best walker half-way through the burn-in (``sample_posterior(restart=...)``: the static
friction levels have separated modes of negligible mass that trap walkers).  The
extension's parameters get the median and the 90 % equal-tailed credible interval; the
models are compared by the change in PSIS-LOO ELPD with its standard error
(``bayesmodal.inference.elpd_change``), and both posteriors are scored on the training and
the held-out experiments by the fit percent of their draws
(``bayesmodal.inference.predictive_check``: median and 90 % interval over draws).
None of this feeds back into the decision.
"""

from __future__ import annotations

import numpy as np

from ..._progress import announce
from ...inference import Likelihood, elpd_change, predictive_check, sample_posterior
from ...inference.priors import noise_names
from ._result import Interval

__all__ = ["posterior_summary"]

#: Default sampler settings of the workflow (overridable by ``posterior_options``).
DEFAULTS = {"n_steps": 1500, "noise": "ar1"}


def _fits(runs: dict, name: str, model, exps, heldout, noise) -> dict:
    """Fit percents of both posteriors, in the layout of ``gain``.

    ``[heldout_]fit_percent_{before,after}`` with ``_lo``/``_hi`` (median over draws and
    90 % interval; before: the linear posterior, after: the extended one) on the training
    and the held-out experiments, and ``heldout_delta_lpd``.  They complement the
    least-squares fit percents (the decision's basis) and do not replace them: the
    friction posterior of the measured impulses is multimodal in the static levels, and
    short chains put walkers in modes whose held-out predictions differ by tens of
    points (docs/diagnose.md).
    """

    out: dict = {}
    for prefix, data in (("", exps), ("heldout_", heldout)):
        if not data:
            continue
        lpd = {}
        for when, label in (("before", "linear"), ("after", name)):
            run = runs[label]
            ps = predictive_check(
                Likelihood(model, list(data), noise, run.likelihood.extension),
                run.flat_draws)
            key = f"{prefix}fit_percent_{when}"
            out[key] = np.asarray(ps.fit_percent_median).tolist()
            out[key + "_lo"] = np.asarray(ps.fit_percent_lo).tolist()
            out[key + "_hi"] = np.asarray(ps.fit_percent_hi).tolist()
            lpd[label] = float(ps.lpd)
        if prefix:
            out["heldout_delta_lpd"] = lpd[name] - lpd["linear"]
    return out


def posterior_summary(*, exps, ext, rig, fit, linear, rng, options, heldout=(),
                      progress=False):
    """Credible intervals (90 %) and ELPD change of the extended against the linear model.

    Parameters
    ----------
    exps : list of Experiment
        Training experiments.
    ext : Extension
    rig : Rig
    fit : ExtensionFit
        Least-squares fit of the extended model (the start of its chain).
    linear : LSQResult
        Least-squares fit of the linear model (the start of its chain).
    rng : numpy.random.Generator
    options : dict
        ``sample_posterior`` keywords (``n_steps``, ``n_walkers``, ``noise``,
        ``restart``...); ``restart`` defaults to half the burn-in, ``None`` turns it off.
    heldout : sequence of Experiment
        Experiments not used in the fit, scored by both posteriors.
    progress : bool
        A line as each model's sampling starts, and the sampler's progress (stderr).

    Returns
    -------
    dict
        ``parameters`` {name: Interval}, ``delta_elpd``, ``delta_elpd_se``,
        ``criterion``, ``elpd`` (the ``ElpdChange`` as a dict), ``fits`` (see
        ``_fits``), ``notes``, ``converged`` (both chains passed the convergence
        checks of ``sample_posterior``).
    """
    opts = {**DEFAULTS, **options}
    model = linear.model
    n_out = rig.n_carts
    n_noise = len(noise_names(n_out, opts["noise"]))
    runs = {}
    notes = []
    for label, extension, start, n_par in (
        ("linear", None, linear, model.n_params + n_noise),
        (ext.name, ext, fit, ext.n_params(rig) + n_noise),
    ):
        kw = dict(opts)
        kw.setdefault("n_walkers", 2 * n_par + (2 * n_par) % 2)
        kw["n_walkers"] = max(int(kw["n_walkers"]), 2 * n_par)
        kw["n_walkers"] += kw["n_walkers"] % 2
        burn = kw.setdefault("burn", int(kw["n_steps"]) // 5)
        kw.setdefault("restart", burn // 2 if burn >= 2 else None)
        kw.setdefault("progress", progress)
        announce(f"diagnose: posterior of the {label} model (emcee, {kw['n_walkers']} "
                 f"walkers x {kw['n_steps']} steps)", enabled=progress)
        run = sample_posterior(exps, model, extension=extension, start=start,
                               rng=np.random.default_rng(rng.integers(2**63)), warn=False,
                               **kw)
        runs[label] = run
        if not run.diagnostics.converged:
            notes.append(f"posterior of the {label} model not converged: "
                         + "; ".join(run.diagnostics.problems))
    run = runs[ext.name]
    draws = run.flat_draws
    names = run.names
    params = {}
    for n in ext.extension_names(rig):
        x = draws[:, names.index(n)]
        lo, med, hi = np.quantile(x, [0.05, 0.5, 0.95])
        params[n] = Interval(float(med), float(lo), float(hi))
    change = elpd_change(runs["linear"], run, labels=("linear", ext.name))
    return {
        "parameters": params,
        "delta_elpd": change.delta,
        "delta_elpd_se": change.se,
        "criterion": "PSIS-LOO ELPD (ArviZ), AR(1) likelihood, extended minus linear",
        "elpd": change.as_dict(),
        "fits": _fits(runs, ext.name, model, exps, heldout, opts["noise"]),
        "notes": notes,
        "converged": all(r.diagnostics.converged for r in runs.values()),
    }
