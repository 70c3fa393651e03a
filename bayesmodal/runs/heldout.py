"""Scores of the records a run holds out (``[data] heldout``): scored, never fitted.

:func:`heldout_scores` predicts each held-out record from the posterior (a record of a
several-record run as a new record, its per-record parameters drawn from their
populations) and gives its log predictive density, fit percents and the coverage of its
90 % band, beside the same numbers on the fitted records (``summary.json`` form).
"""

from __future__ import annotations

import numpy as np

from ..inference import likelihood_from_idata, posterior_matrix, predictive_check
from ..inference.coverage_reference import reference_fields
from ..inference.predictive import predict_new_record, score_samples
from ..metrics import fit_percent
from .crosscheck import predictive_coverage
from .prepare import PreparedRun

__all__ = ["heldout_scores", "coverage_records"]


def heldout_scores(prep: PreparedRun, idata) -> dict | None:
    """Scores of the held-out records under the posterior.

    Parameters
    ----------
    prep : PreparedRun
        The run; its ``heldout`` records are scored.
    idata : arviz.InferenceData
        The run's posterior.

    Returns
    -------
    dict or None
        lpd, fit percents (%) and 90 % band coverage per held-out record, with the fitted
        records' coverage beside them (``summary.json`` form); None without held-out
        records.
    """
    if not prep.heldout:
        return None

    if idata.posterior.attrs.get("record_layout_json"):
        return _as_new_records(prep, idata)
    lik = likelihood_from_idata(idata, prep.heldout)
    draws = posterior_matrix(idata, list(lik.names)).reshape(-1, lik.n_params)
    ps = predictive_check(lik, draws)
    # references for the held-out numbers: the same scores on the fitted records
    fitted = predictive_check(likelihood_from_idata(idata), draws)
    return {"experiments": list(ps.experiments), "lpd": ps.lpd,
            "lpd_per_obs": ps.lpd_per_obs, "mean_log_lik": ps.mean_log_lik,
            "fitted_lpd_per_obs": fitted.lpd_per_obs,
            "fit_percent_median": np.asarray(ps.fit_percent_median).tolist(),
            "fit_percent_lo": np.asarray(ps.fit_percent_lo).tolist(),
            "fit_percent_hi": np.asarray(ps.fit_percent_hi).tolist(),
            "records": coverage_records(lik, draws, prep.config.sampler.seed),
            "fitted_records": coverage_records(likelihood_from_idata(idata), draws,
                                                prep.config.sampler.seed)}



def coverage_records(lik, draws, seed) -> list[dict]:
    """Coverage of the 90 % posterior-predictive band per record.

    Parameters
    ----------
    lik : likelihood
        The records and their likelihood.
    draws : ndarray, shape (n_draws, n_params)
        Posterior draws.
    seed : int
        Seed of the band's simulated noise.

    Returns
    -------
    list of dict
        Per record: coverage, width (m), fit percent (%) and band factor of the 90 % band.
    """

    return [{"name": c["name"], "coverage_90": c["coverage"].tolist(),
             "width_90": c["width_m"].tolist(), "fit_percent": c["fit_percent"].tolist(),
             "band_factor_90": c["band_factor"].tolist(),
             **({} if c["reference"] is None else
                reference_fields(c["reference"], {0.9: c["coverage"]}, c["band_factor"]))}
            for c in predictive_coverage(lik, draws, prob=0.9, rng=seed)]



def _as_new_records(prep: PreparedRun, idata) -> dict:
    """Held-out records of a several-record run, each predicted as a new record (gain and
    offset drawn from their populations): fit percents, band coverage and lpd."""

    lik = likelihood_from_idata(idata)
    draws = posterior_matrix(idata, list(lik.names)).reshape(-1, lik.n_params)
    rng = np.random.default_rng(prep.config.sampler.seed)
    draws = draws[rng.choice(draws.shape[0], min(200, draws.shape[0]), replace=False)]
    scores, fits = [], []
    for e in prep.heldout:
        y_hat, y_pred, ll = predict_new_record(lik, draws, e, rng=rng)
        scores.append(score_samples(e.name, e.y_m, y_pred, ll))
        fits.append([fit_percent(e.y_m, yh) for yh in y_hat])
    fits = np.array(fits)  # (n_exp, S, n_out)
    q = np.quantile(fits, [0.5, 0.05, 0.95], axis=1)
    n_obs = sum(e.n_samples * e.n_outputs for e in prep.heldout)
    lpd = float(sum(s.lpd for s in scores))
    return {"experiments": [e.name for e in prep.heldout], "lpd": lpd,
            "lpd_per_obs": lpd / n_obs, "mean_log_lik": None,
            "fit_percent_median": q[0].tolist(), "fit_percent_lo": q[1].tolist(),
            "fit_percent_hi": q[2].tolist(), "scores": [s.to_dict() for s in scores],
            "records": [{"name": sc.name, "coverage_90": sc.coverage_90.tolist(),
                         "width_90": (sc.width_90 * np.std(e.y_m, axis=0)).tolist(),
                         "fit_percent": sc.fit_percent.tolist(),
                         "band_factor_90": sc.band_factor_90.tolist(),
                         **sc.reference_dict()}
                        for sc, e in zip(scores, prep.heldout, strict=True)],
            "predicted_as": "new records (per-record parameters drawn from the population)"}
