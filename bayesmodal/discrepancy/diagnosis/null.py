"""Decision thresholds of the residual diagnostics, calibrated on the null hypothesis.

The null hypothesis is "the linear model is right": the data are the fitted linear model's
prediction plus noise.  The noise model is the one fitted to the linear residuals (AR(1)
per output, ``r_k = phi r_{k-1} + e_k``) with the encoder quantisation applied on top, as
in the measured data.

Calibration (a parametric-bootstrap Monte Carlo test):

1. simulate ``n_null`` data sets ``quantise(y_pred + AR(1) noise)`` of every training
   experiment (same inputs, same lengths);
2. refit the linear model to each (least squares, started at the fitted parameters) and
   run every single-experiment diagnostic on its residuals, exactly as on the data;
3. map each diagnostic statistic ``s_d`` to a standardised score
   ``z_d = (g(s_d) - mean_null) / sd_null`` (``g`` = log for the chi-square-like
   portmanteau statistics, identity otherwise; ``sd_null`` floored at a per-diagnostic
   resolution so that a statistic that never moves under the null, e.g. zero stuck
   episodes, cannot produce an infinite score);
4. the workflow statistic is ``T = max_d z_d`` (over diagnostics and training
   experiments).  Its null distribution is the ``n_null`` values ``T_i``; the threshold
   is the ``ceil((1 - alpha) (n_null + 1))``-th smallest of them.  When the null model is
   right, the rank of the data's ``T`` among the ``T_i`` is uniform (exchangeability), so
   ``P(T > threshold) <= alpha``: the family-wise false-positive rate of the whole set of
   diagnostics is at most ``alpha`` (5 %) whatever the dependence between them.  This
   needs ``n_null >= 1 / alpha - 1`` (19 for 5 %).

Each diagnostic's own threshold on its statistic's scale is the value at which its
``z_d`` reaches the common threshold: ``g^-1(mean_null + T_threshold * sd_null)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..._errors import ConfigError, DataError, ModelError
from ..._progress import progress_bar
from ...data import ECP_M_PER_COUNT, Experiment
from ...fit.lsq import fit_lsq
from ...inference.likelihood import simulate_noise
from ...model.simulate import simulate_linear
from ...model.system import LinearModel
from ..checks import (
    RESIDUAL_DIAGNOSTICS,
    Diagnostic,
    diagnostics_for,
    linear_residuals,
    smooth_derivative,
)

__all__ = [
    "NoiseModel",
    "NullCalibration",
    "TRANSFORMS",
    "calibrate_null",
    "diagnostic_statistics",
    "fit_noise",
    "infer_quantum",
    "quantise",
]

#: Per diagnostic: (transform, floor of the null standard deviation on the transformed
#: scale).  ``log`` is used for the portmanteau statistics (chi-square-like, heavy upper
#: tail); the others are t-like, shares, counts or ratios.
TRANSFORMS: dict[str, tuple[str, float]] = {
    "whiteness": ("log", 0.05),
    "input_correlation": ("log", 0.05),
    "friction_signature": ("identity", 0.25),
    "decay_envelope": ("identity", 0.05),
    "amplitude_dependence": ("identity", 0.25),
    "stick": ("identity", 0.5),
    "residual_spectrum": ("identity", 1.0),
    "gain_error": ("identity", 0.25),
    "input_bias": ("identity", 0.25),
    "drive_gain": ("identity", 0.25),
}


@dataclass(frozen=True)
class NoiseModel:
    """AR(1) noise per output plus encoder quantisation.

    Attributes
    ----------
    sigma_m : ndarray, shape (n_out,)
        Innovation standard deviation of the (unquantised) noise, m.
    phi : ndarray, shape (n_out,)
        Lag-1 coefficient.
    quantum_m : float
        Encoder resolution, m (0: no quantisation).
    """

    sigma_m: np.ndarray
    phi: np.ndarray
    quantum_m: float

    @property
    def marginal_sd_m(self) -> np.ndarray:
        """Stationary standard deviation ``sigma / sqrt(1 - phi^2)``, m."""
        return self.sigma_m / np.sqrt(1.0 - self.phi**2)


def infer_quantum(experiments: Sequence[Experiment], default: float = ECP_M_PER_COUNT,
                  tol: float = 1e-6) -> float:
    """The encoder count if every position is a whole number of counts, else 0.

    ECP files are in counts (converted with 0.0706/16000 m each); a CSV in SI units may be
    quantised too or not.  Returns ``default`` when all positions are within ``tol`` counts
    of a multiple of it, else 0.0 (no quantisation in the null model).
    """
    for e in experiments:
        c = e.y_m / default
        if np.max(np.abs(c - np.round(c))) > tol:
            return 0.0
    return float(default)


def quantise(y: np.ndarray, quantum_m: float) -> np.ndarray:
    """Round to whole encoder counts (identity for ``quantum_m == 0``)."""
    if quantum_m <= 0:
        return y
    return np.round(y / quantum_m) * quantum_m


def fit_noise(residuals: Sequence[np.ndarray], quantum_m: float) -> NoiseModel:
    """Moment estimates of the AR(1) noise per output, pooled over experiments.

    The quantisation error (variance ``q^2 / 12``, white) is removed from the residual
    variance before the AR(1) parameters are formed, because the null simulation
    quantises again: ``var_noise = max(var_r - q^2/12, 0.1 var_r)``,
    ``phi = acov_1 / var_noise`` (clipped to [-0.999, 0.999]),
    ``sigma = sqrt(var_noise (1 - phi^2))``.

    Parameters
    ----------
    residuals : sequence of ndarray, each shape (N_e, n_out), m
    quantum_m : float
    """
    r = [np.asarray(x, float) - np.mean(x, axis=0) for x in residuals]
    var = sum(np.sum(x**2, axis=0) for x in r) / sum(x.shape[0] for x in r)
    acov = sum(np.sum(x[1:] * x[:-1], axis=0) for x in r) / sum(x.shape[0] - 1 for x in r)
    var_noise = np.maximum(var - quantum_m**2 / 12.0, 0.1 * var)
    var_noise = np.maximum(var_noise, 1e-30)
    phi = np.clip(acov / var_noise, -0.999, 0.999)
    sigma = np.sqrt(var_noise * (1.0 - phi**2))
    return NoiseModel(sigma_m=sigma, phi=phi, quantum_m=float(quantum_m))


def diagnostic_statistics(diags: dict[str, Diagnostic]) -> dict[str, float]:
    """The raw statistic of every diagnostic (NaN when it could not be computed)."""
    return {k: float(d.statistic) for k, d in diags.items()}


def _g(name: str, s):
    kind = TRANSFORMS.get(name, ("identity", 0.25))[0]
    s = np.asarray(s, float)
    if kind == "log":
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.log(np.maximum(s, 1e-300))
    return s


def _g_inv(name: str, x: float) -> float:
    kind = TRANSFORMS.get(name, ("identity", 0.25))[0]
    return float(np.exp(x)) if kind == "log" else float(x)


def run_diagnostics(experiment: Experiment, model: LinearModel, theta: np.ndarray, *,
                    quantum_m: float, y_pred: np.ndarray | None = None,
                    names: Sequence[str] | None = None) -> dict[str, Diagnostic]:
    """Every single-experiment diagnostic of one experiment at ``theta``.

    With ``y_pred`` (e.g. an extended model's prediction, in the sensors' units) the
    residuals are taken against it instead of the linear simulation; the linear
    parameters still give M, C, K (and, on velocity or acceleration records, the
    predicted velocities).  ``names`` default: those that apply to the model's sensors
    (``checks.diagnostics_for``).
    """
    q = quantum_m if quantum_m > 0 else ECP_M_PER_COUNT
    res = linear_residuals(experiment, model, theta, quantum_m=q)
    if y_pred is not None:
        from dataclasses import replace

        v_pred = (smooth_derivative(y_pred, experiment.dt, res.smooth_window)
                  if model.rig.positions_only else res.v_pred)
        res = replace(res, y_pred=np.ascontiguousarray(y_pred), v_pred=v_pred,
                      residual=experiment.y_m - y_pred)
    names = diagnostics_for(model) if names is None else tuple(names)
    return {k: RESIDUAL_DIAGNOSTICS[k](res) for k in names}


@dataclass(frozen=True)
class NullCalibration:
    """Null distribution of the diagnostics and the workflow's decision threshold.

    Attributes
    ----------
    keys : tuple of (str, int)
        ``(diagnostic, training-experiment index)`` of every calibrated statistic.
    null_statistics : ndarray, shape (n_null, n_keys)
        Raw statistics on the null data sets (NaN where not computable).
    mean, sd : ndarray, shape (n_keys,)
        Null mean and (floored) standard deviation on the transformed scale.
    null_max : ndarray, shape (n_null,)
        ``T_i = max_d z_d`` of every null data set.
    threshold : float
        Threshold on ``T`` (standardised units): the
        ``ceil((1 - alpha)(n_null + 1))``-th smallest ``T_i``.
    alpha : float
        Family-wise false-positive rate targeted.
    noise : NoiseModel
    n_null : int
    rule : str
        The decision rule in words.
    """

    keys: tuple[tuple[str, int], ...]
    null_statistics: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    null_max: np.ndarray
    threshold: float
    alpha: float
    noise: NoiseModel
    n_null: int
    rule: str

    def scores(self, stats: Sequence[dict[str, float]]) -> np.ndarray:
        """Standardised scores ``z`` (n_keys,) of one set of raw statistics per experiment.

        Statistics that could not be computed (NaN) score ``-inf`` (no evidence).
        """
        raw = np.array([stats[i][name] for name, i in self.keys], float)
        z = np.empty(raw.size)
        for j, (name, _) in enumerate(self.keys):
            g = _g(name, raw[j])
            z[j] = (g - self.mean[j]) / self.sd[j] if np.isfinite(g) else -np.inf
        return z

    def p_value(self, t_max: float) -> float:
        """Monte Carlo p-value ``(1 + #{T_i >= T}) / (n_null + 1)``."""
        return float((1 + np.sum(self.null_max >= t_max)) / (self.n_null + 1))

    def statistic_threshold(self, j: int) -> float:
        """Threshold of key ``j`` on the raw statistic's scale."""
        name = self.keys[j][0]
        return _g_inv(name, self.mean[j] + self.threshold * self.sd[j])


def calibrate_null(
    experiments: Sequence[Experiment],
    model: LinearModel,
    theta: np.ndarray,
    *,
    noise: NoiseModel,
    n_null: int = 40,
    alpha: float = 0.05,
    rng=None,
    names: Sequence[str] | None = None,
    refit_nfev: int = 20,
    progress: bool = False,
    extension_fit=None,
    weights=None,
) -> NullCalibration:
    """Simulate the fitted linear model with its noise, refit, run the diagnostics.

    With ``extension_fit`` (an ``ExtensionFit``) the null model is that extended model
    instead (forward selection recalibrates the diagnostics on the model accepted so
    far): the null data are its simulation plus ``noise``, each is refitted with the
    extended model (``fit_extension_lsq`` from the generating parameters, at most
    ``refit_nfev`` evaluations) and the diagnostics are taken against the refitted
    prediction, exactly as on the data.

    Parameters
    ----------
    experiments : sequence of Experiment
        The training experiments (the linear model was fitted to all of them jointly).
    model : LinearModel
    theta : ndarray, shape (n_params,)
        The fitted linear parameters (ignored with ``extension_fit``).
    noise : NoiseModel
        From ``fit_noise`` on the residuals of the null model.
    n_null : int
        Number of null data sets; at least ``ceil(1 / alpha) - 1``.
    alpha : float
        Family-wise false-positive rate of the whole set of diagnostics.
    rng : numpy.random.Generator or int, optional
    names : sequence of str, optional
        Diagnostics to calibrate (default: those of ``RESIDUAL_DIAGNOSTICS`` that apply to
        the model's sensors, ``checks.diagnostics_for``).
    refit_nfev : int
        Evaluations allowed to each null refit.  The refit starts at the parameters that
        generated the null data, so it converges in a few steps; a refit stopped early
        leaves the null residuals slightly larger than converged ones, which errs towards
        fewer false positives.
    progress : bool
        Progress over the null data sets on stderr (``bayesmodal._progress``).
    extension_fit : ExtensionFit, optional
        The extended model to calibrate on (default: the linear model at ``theta``).
    weights : {None, "spread"}
        The extended model's refits weigh the null records so (``fit_extension_lsq``),
        as its fit weighed the data.

    Returns
    -------
    NullCalibration

    Raises
    ------
    ConfigError
        If ``alpha`` is not in (0, 1) or ``n_null`` is too small for it.
    """
    if not (0 < alpha < 1):
        raise ConfigError(f"alpha must be in (0, 1), got {alpha!r}")
    n_min = int(np.ceil(1.0 / alpha - 1.0 - 1e-9))
    if int(n_null) < n_min:
        raise ConfigError(
            f"n_null = {n_null} null data sets cannot calibrate a {alpha:g} false-positive "
            f"rate; need at least {n_min}")
    experiments = list(experiments)
    if not experiments:
        raise DataError("no experiments to calibrate on")
    rng = np.random.default_rng(rng)
    names = diagnostics_for(model) if names is None else tuple(names)
    keys = tuple((nm, i) for i in range(len(experiments)) for nm in names)
    n_null = int(n_null)
    ef = extension_fit
    if ef is not None:
        theta = np.asarray(ef.theta, float)
    sims = []
    for e in experiments:
        y_pred = (simulate_linear(model, theta, e.v_volt, e.dt) if ef is None
                  else ef.extension.simulate(ef.rig, theta, e.v_volt, e.dt))
        eps = simulate_noise(np.broadcast_to(noise.sigma_m, (n_null, e.n_outputs)),
                             np.broadcast_to(noise.phi, (n_null, e.n_outputs)),
                             e.n_samples, rng)
        sims.append(quantise(y_pred[None] + eps, noise.quantum_m))
    raw = np.full((n_null, len(keys)), np.nan)
    bar = progress_bar(n_null, desc="diagnose: null calibration", unit="data set",
                       enabled=progress)
    for b in range(n_null):
        null_exps = [Experiment(e.t_s, e.v_volt, sims[i][b], name=f"{e.name} (null {b})")
                     for i, e in enumerate(experiments)]
        try:
            with np.errstate(all="ignore"):  # rejected wild trial steps of the optimiser
                if ef is None:
                    fit = fit_lsq(null_exps, model, theta0=theta, max_nfev=refit_nfev)
                else:
                    fit = fit_lsq(null_exps, ef.rig, extension=ef.extension, theta0=theta,
                                  linear=ef.linear, max_nfev=refit_nfev, weights=weights)
        except ModelError:
            # the refit ran off to an impossible point (e.g. a damper to infinity): keep
            # the generating parameters for this null set rather than drop it
            fit = None
        th = theta if fit is None else fit.theta
        if ef is None:
            preds = [None] * len(null_exps)
        else:
            preds = [ef.extension.simulate(ef.rig, th, e.v_volt, e.dt) for e in null_exps]
            th = th[: model.n_params]
        stats = [diagnostic_statistics(run_diagnostics(e, model, th, quantum_m=noise.quantum_m,
                                                       names=names, y_pred=yp))
                 for e, yp in zip(null_exps, preds, strict=True)]
        raw[b] = [stats[i][nm] for nm, i in keys]
        bar.update(1)
    bar.close()
    g = np.column_stack([_g(nm, raw[:, j]) for j, (nm, _) in enumerate(keys)])
    mean = np.empty(len(keys))
    sd = np.empty(len(keys))
    for j, (nm, _) in enumerate(keys):
        col = g[:, j][np.isfinite(g[:, j])]
        floor = TRANSFORMS.get(nm, ("identity", 0.25))[1]
        mean[j] = np.mean(col) if col.size else 0.0
        sd[j] = max(np.std(col, ddof=1) if col.size > 1 else 0.0, floor)
    z = np.where(np.isfinite(g), (g - mean) / sd, -np.inf)
    null_max = z.max(axis=1)
    k = int(np.ceil((1.0 - alpha) * (n_null + 1)))
    threshold = float(np.sort(null_max)[min(k, n_null) - 1])
    rule = (
        f"discrepancy when T = max over {len(keys)} standardised diagnostic statistics "
        f"exceeds {threshold:.2f}, the {k}-th smallest of its {n_null} values on data "
        f"simulated from the fitted "
        f"{'linear model' if ef is None else ef.extension.name + ' model'} with AR(1) "
        f"noise and quantisation "
        f"(Monte Carlo test, family-wise false-positive rate <= {alpha:g})"
    )
    return NullCalibration(keys=keys, null_statistics=raw, mean=mean, sd=sd,
                           null_max=null_max, threshold=threshold, alpha=float(alpha),
                           noise=noise, n_null=n_null, rule=rule)
