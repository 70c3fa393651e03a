"""Bayesian inference for the rig: priors, likelihood, sampling, propagation, comparison.

Layers: :mod:`.priors` and :mod:`.likelihood` are NumPy only; :mod:`.sampling` adds emcee;
:mod:`.idata`, :mod:`.summary`, :mod:`.loo` and :mod:`.compare` build on ArviZ (0.x
InferenceData API).

Typical use::

    from bayesmodal.inference import sample_posterior, summary_dict, to_inference_data
    run = sample_posterior(experiment, LinearModel(Rig(), "free"), noise="ar1", rng=1)
    idata = to_inference_data(run, rng=1)
    summary = summary_dict(idata)   # bayesmodal.runs.write_run writes a run folder
"""

from .compare import ModelChoice, PredictiveScore, choose_model, model_choice, predictive_check
from .evidence import BayesFactor, Evidence, bayes_factor, kass_raftery, nested_evidence
from .idata import (
    experiments_from_idata,
    extension_from_idata,
    likelihood_from_idata,
    load_idata,
    model_from_idata,
    posterior_matrix,
    priors_from_idata,
    save_idata,
    to_inference_data,
    with_pointwise_loglik,
)
from .likelihood import Likelihood, ar1_terms, simulate_noise, white_terms
from .loo import ElpdChange, InformationCriteria, elpd_change, information_criteria
from .noise_spec import NOISE_MODELS, NoiseSpec, parse_noise
from .priors import LogUniform, Normal, PriorSet, Uniform, default_priors, noise_names
from .propagate import (
    Interval,
    ModalSamples,
    credible_interval,
    hdi,
    modal_intervals,
    propagate_modes,
)
from .run_length import RunLength, converged_from
from .sampling import (
    ConvergenceWarning,
    Diagnostics,
    LogPosterior,
    PosteriorRun,
    convergence_diagnostics,
    default_moves,
    posterior_mode,
    sample_posterior,
)
from .spec import LikelihoodSpec, SamplerSpec
from .summary import (
    ComparisonRow,
    comparison_markdown,
    lsq_vs_posterior,
    parameter_intervals,
    posterior_modes,
    summary_dict,
)
from .threads import ThreadedLogPosterior, resolve_threads

__all__ = [
    "LikelihoodSpec",
    "SamplerSpec",
    "BayesFactor",
    "ComparisonRow",
    "ConvergenceWarning",
    "Diagnostics",
    "ElpdChange",
    "Evidence",
    "InformationCriteria",
    "Interval",
    "Likelihood",
    "LogPosterior",
    "LogUniform",
    "ModalSamples",
    "ModelChoice",
    "NOISE_MODELS",
    "NoiseSpec",
    "Normal",
    "PosteriorRun",
    "PredictiveScore",
    "PriorSet",
    "RunLength",
    "ThreadedLogPosterior",
    "Uniform",
    "ar1_terms",
    "bayes_factor",
    "choose_model",
    "comparison_markdown",
    "converged_from",
    "convergence_diagnostics",
    "credible_interval",
    "default_moves",
    "default_priors",
    "elpd_change",
    "experiments_from_idata",
    "extension_from_idata",
    "hdi",
    "information_criteria",
    "kass_raftery",
    "likelihood_from_idata",
    "load_idata",
    "lsq_vs_posterior",
    "modal_intervals",
    "model_choice",
    "model_from_idata",
    "nested_evidence",
    "noise_names",
    "parse_noise",
    "parameter_intervals",
    "posterior_matrix",
    "posterior_mode",
    "posterior_modes",
    "predictive_check",
    "priors_from_idata",
    "propagate_modes",
    "resolve_threads",
    "sample_posterior",
    "save_idata",
    "simulate_noise",
    "summary_dict",
    "to_inference_data",
    "with_pointwise_loglik",
    "white_terms",
]
