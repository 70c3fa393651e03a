"""Cross-checks of a posterior run: LSCE modal estimates and residual diagnostics.

Both are independent of the sampler.  LSCE (``bayesmodal.ema``) uses only the measured
input and outputs, never the rig model, so its natural frequencies and damping ratios are
a model-free check of the posterior intervals.  The residuals of the model at the
posterior median show what the linear model leaves out: their autocorrelation function
(ACF) against the white-noise band, and, where ``bayesmodal.discrepancy.checks`` is installed,
its named tests (whiteness, friction signature, ...).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._errors import ConfigError, DataError, ModelError
from ..data import Experiment
from ..discrepancy.checks import RESIDUAL_DIAGNOSTICS, LinearResiduals, linear_residuals
from ..discrepancy.checks.residuals import smooth_derivative
from ..ema import identify
from ..ema.result import match_modes
from ..inference import simulate_noise
from ..inference.coverage_reference import MIN_REFERENCE_DRAWS, coverage_reference
from ..inference.predictive import band_factor
from ..metrics import fit_percent
from ..model.simulate import simulate_linear
from ..model.system import LinearModel

__all__ = ["LSCECheck", "lsce_check", "ResidualCheck", "residual_check", "sample_acf",
           "predictive_coverage"]

# what a cross-check may raise on data it cannot handle; anything else is a bug
_EXPECTED = (ConfigError, DataError, ModelError, ValueError, np.linalg.LinAlgError)


@dataclass(frozen=True)
class LSCECheck:
    """LSCE modal estimate of one experiment.

    Attributes
    ----------
    experiment : str
    omega_rad_s : ndarray, shape (n_found,)
        Natural frequencies of the identified modes, rad/s.
    zeta : ndarray, shape (n_found,)
        Damping ratios, dimensionless.
    error : str or None
        Why no estimate was possible (then the arrays are empty).
    """

    experiment: str
    omega_rad_s: np.ndarray
    zeta: np.ndarray
    error: str | None = None

    def matched(self, reference_omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Estimates nearest each reference frequency, shape (n_ref,) each (NaN if none)."""
        ref = np.asarray(reference_omega, float)
        om = np.full(ref.size, np.nan)
        ze = np.full(ref.size, np.nan)
        if self.omega_rad_s.size:
            idx = match_modes(self.omega_rad_s, ref)
            used = set()
            for i, j in enumerate(idx):
                # one estimate per reference mode, within 25 % of it
                if j >= 0 and j not in used and abs(self.omega_rad_s[j] - ref[i]) < 0.25 * ref[i]:
                    om[i], ze[i] = self.omega_rad_s[j], self.zeta[j]
                    used.add(int(j))
        return om, ze

    def as_dict(self) -> dict:
        return {"experiment": self.experiment, "omega_rad_s": self.omega_rad_s.tolist(),
                "zeta": self.zeta.tolist(), "error": self.error}


def lsce_check(experiment: Experiment, n_modes: int) -> LSCECheck:
    """LSCE estimate (``bayesmodal.ema.identify``) of the identified modes of one record.

    Parameters
    ----------
    experiment : Experiment
    n_modes : int
        Modes sought (the number of carts).

    Returns
    -------
    LSCECheck
        With ``error`` set (and empty arrays) when the record does not allow an estimate.
    """

    try:
        full = identify(experiment, "lsce", n_modes=n_modes).estimate
    except _EXPECTED as exc:
        return LSCECheck(experiment.name, np.empty(0), np.empty(0),
                         f"{type(exc).__name__}: {exc}")
    est = full.physical()
    error = None
    if est.n_modes == 0:
        error = "no mode identified" + (f" ({'; '.join(full.notes)})" if full.notes else "")
    return LSCECheck(experiment.name, np.asarray(est.omega_rad_s, float),
                     np.asarray(est.zeta, float), error)


def sample_acf(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation of each column at lags ``0..max_lag``.

    Parameters
    ----------
    x : ndarray, shape (N, n)
    max_lag : int

    Returns
    -------
    ndarray, shape (max_lag + 1, n)
        ``acf[0] == 1`` (biased estimator, denominator N, as in the Ljung-Box test).
    """
    x = np.asarray(x, float)
    x = x - x.mean(axis=0)
    n = x.shape[0]
    max_lag = min(int(max_lag), n - 1)
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(x, nfft, axis=0)
    ac = np.fft.irfft(f * np.conj(f), nfft, axis=0)[: max_lag + 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        return ac / ac[0]


@dataclass(frozen=True, eq=False)
class ResidualCheck:
    """Residuals of the model at one parameter vector on one experiment.

    Attributes
    ----------
    experiment : str
    t_s : ndarray, shape (N,), s
    residual_m : ndarray, shape (N, n_out), m
        Measured minus simulated positions.
    acf : ndarray, shape (n_lags + 1, n_out)
        Residual autocorrelation at lags ``0..n_lags``.
    lag_s : ndarray, shape (n_lags + 1,), s
    band : float
        Half-width of the 95 % band of a white sequence, ``1.96 / sqrt(N)``.
    rms_m : ndarray, shape (n_out,), m
    fit_percent : ndarray, shape (n_out,)
    diagnostics : tuple of dict
        ``{"name", "detected", "p_value", "statistic", "threshold", "suggests", "location",
        "summary"}``
        of each ``bayesmodal.discrepancy.checks.RESIDUAL_DIAGNOSTICS`` entry that applies (empty
        when the package is not available); ``{"name", "error"}`` for one that failed.
    """

    experiment: str
    t_s: np.ndarray
    residual_m: np.ndarray
    acf: np.ndarray
    lag_s: np.ndarray
    band: float
    rms_m: np.ndarray
    fit_percent: np.ndarray
    diagnostics: tuple = field(default=())

    def as_dict(self) -> dict:
        """JSON-ready summary (no per-sample arrays)."""
        n_out = self.acf.shape[1]
        lag1 = self.acf[1] if self.acf.shape[0] > 1 else np.full(n_out, np.nan)
        return {"experiment": self.experiment, "rms_m": self.rms_m.tolist(),
                "fit_percent": self.fit_percent.tolist(), "acf_lag1": lag1.tolist(),
                "white_band": self.band, "diagnostics": list(self.diagnostics)}


def _extended_residuals(experiment: Experiment, model: LinearModel, theta: np.ndarray,
                        extension, y_hat: np.ndarray):
    """``LinearResiduals`` holding the prediction of an extended model.

    The diagnostics read the prediction, its velocity and the residual; the extension's
    simulator returns positions only, so the predicted velocity is the smoothed derivative
    of the (noise-free) predicted positions.  ``theta`` keeps the linear part (the
    diagnostics that use ``M, C, K`` see the linear rig).
    """

    lin = theta[: model.n_params]
    base = linear_residuals(experiment, model, lin)
    return LinearResiduals(
        experiment=experiment, model=model, theta=lin, y_pred=y_hat,
        v_pred=smooth_derivative(y_hat, experiment.dt, base.smooth_window, deriv=1),
        residual=experiment.y_m - y_hat, v_meas=base.v_meas,
        smooth_window=base.smooth_window, quantum_m=base.quantum_m)


def _diagnostics(experiment: Experiment, model: LinearModel, theta: np.ndarray,
                 extension=None, y_hat=None) -> tuple:
    try:
        if extension is None:
            res = linear_residuals(experiment, model, theta)
        else:
            res = _extended_residuals(experiment, model, theta, extension, y_hat)
    except _EXPECTED as exc:
        return ({"name": "residuals", "error": f"{type(exc).__name__}: {exc}"},)
    out = []
    for name, fn in RESIDUAL_DIAGNOSTICS.items():
        try:
            d = fn(res)
        except _EXPECTED as exc:
            out.append({"name": name, "error": f"{type(exc).__name__}: {exc}"})
            continue
        out.append({"name": d.name, "detected": bool(d.detected),
                    "p_value": None if d.p_value is None else float(d.p_value),
                    "statistic": float(d.statistic),
                    "threshold": None if d.threshold is None else float(d.threshold),
                    "suggests": list(d.suggests),
                    "location": d.location, "summary": d.summary})
    return tuple(out)


def residual_check(experiment: Experiment, model: LinearModel, theta: np.ndarray, *,
                   max_lag_s: float = 2.0, diagnostics: bool = True,
                   extension=None) -> ResidualCheck:
    """Residuals, their ACF and the residual diagnostics at ``theta``.

    Parameters
    ----------
    experiment : Experiment
    model : LinearModel
    theta : ndarray, shape (model.n_params,) or (n_params of the extension,)
        Mechanical parameters (e.g. the posterior median); with ``extension`` the linear
        free-damping parameters followed by the extension's.
    max_lag_s : float
        Longest ACF lag, s.
    diagnostics : bool
        Run ``bayesmodal.discrepancy.checks`` when it is installed.
    extension : Extension, optional
        Predict with this model extension (``Extension.simulate``) instead of the linear
        model.

    Returns
    -------
    ResidualCheck
    """

    if extension is None:
        theta = model.check(np.asarray(theta, float))
        y_hat = simulate_linear(model, theta, experiment.v_volt, experiment.dt)
    else:
        theta = extension.check(model.rig, np.asarray(theta, float))
        y_hat = extension.simulate(model.rig, theta, experiment.v_volt, experiment.dt)
    r = experiment.y_m - y_hat
    n_lag = max(1, int(round(max_lag_s / experiment.dt)))
    acf = sample_acf(r, n_lag)
    return ResidualCheck(
        experiment=experiment.name,
        t_s=experiment.t_s,
        residual_m=r,
        acf=acf,
        lag_s=np.arange(acf.shape[0]) * experiment.dt,
        band=float(1.96 / np.sqrt(r.shape[0])),
        rms_m=np.sqrt(np.mean(r**2, axis=0)),
        fit_percent=np.atleast_1d(np.asarray(fit_percent(experiment.y_m, y_hat), float)),
        diagnostics=(_diagnostics(experiment, model, theta, extension, y_hat) if diagnostics
                     else ()),
    )


def predictive_coverage(likelihood, draws: np.ndarray, *, prob: float = 0.9,
                        max_draws: int = 200, rng=None) -> list[dict]:
    """How much of each record the posterior-predictive band covers.

    For every draw the model output plus a draw of the fitted noise model (white or AR(1))
    is a replicated measurement; the pointwise ``prob`` band of the replicates is compared
    with the measured record.  On records the posterior was not fitted to, a coverage well
    below ``prob`` means the intervals are too narrow for new data.

    Parameters
    ----------
    likelihood : bayesmodal.inference.Likelihood
        The run's model and noise model on the records to score.
    draws : ndarray, shape (S, P)
        Posterior draws in ``likelihood.names`` order.
    prob : float
        Band probability, in (0, 1).
    max_draws : int
        Evenly spaced subset of the draws used.
    rng : numpy.random.Generator or int, optional
        For the noise draws.

    Returns
    -------
    list of dict
        Per record: ``name``, ``coverage`` (n_out,) fraction of samples inside the band,
        ``width_m`` (n_out,) mean band width, m, ``fit_percent`` (n_out,) fit of the
        median noise-free prediction, ``n_draws``, ``band_factor`` (n_out,) the factor on
        the band that would cover ``prob`` (``inference.predictive.band_factor``), and
        ``reference`` (``inference.coverage_reference.CoverageReference``, None below
        ``MIN_REFERENCE_DRAWS`` draws): what a calibrated band would show.

    Examples
    --------
    >>> # predictive_coverage(likelihood_from_idata(idata, heldout), draws, rng=1)
    """

    if not 0.0 < prob < 1.0:
        raise ConfigError(f"prob must be in (0, 1), got {prob}")
    draws = np.asarray(draws, dtype=float)
    if draws.ndim != 2 or draws.shape[1] != likelihood.n_params:
        raise ConfigError(f"draws must have shape (S, {likelihood.n_params}), got "
                          f"{draws.shape}")
    rng = np.random.default_rng(rng)
    idx = np.unique(np.linspace(0, draws.shape[0] - 1, min(max_draws, draws.shape[0]))
                    .round().astype(int))
    mech, sigma, phi = likelihood.split(draws[idx])
    y_hat = likelihood.predict(mech)  # per record (S, N, n_out)
    qa = [(1 - prob) / 2, 0.5, (1 + prob) / 2]
    out = []
    for e, yh in zip(likelihood.experiments, y_hat, strict=True):
        rep = yh + simulate_noise(sigma, phi, e.n_samples, rng)
        lo, mid, hi = np.quantile(rep, qa, axis=0)
        inside = (e.y_m >= lo) & (e.y_m <= hi)
        out.append({
            "name": e.name,
            "coverage": inside.mean(axis=0),
            "width_m": (hi - lo).mean(axis=0),
            "fit_percent": np.atleast_1d(np.asarray(
                fit_percent(e.y_m, np.median(yh, axis=0)), float)),
            "n_draws": int(idx.size),
            "band_factor": band_factor(e.y_m, lo, mid, hi, prob),
            "reference": (coverage_reference(rep, (prob,))
                          if idx.size >= MIN_REFERENCE_DRAWS else None),
        })
    return out
