"""Residuals of the linear model and the signals the diagnostics derive from them.

``residual = y_measured - y_predicted`` with the prediction of a (usually least-squares
fitted) ``LinearModel`` simulated from rest, each output as its sensor reads it (position
m, velocity m/s, acceleration m/s^2: ``simulate_linear``), so the residual is in the
output's own units.  Velocities come from the model prediction (exact: the velocity
states of the ZOH simulation, noise-free) and from the measurement: the Savitzky-Golay
smoothed derivative of a position record, a velocity sensor's own reading, NaN for an
accelerometer (its record cannot be integrated to velocity reliably; the diagnostics
that need measured motion are left out there, ``checks.diagnostics_for``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_coeffs, savgol_filter

from ..._errors import DataError
from ...data import ECP_M_PER_COUNT, Experiment
from ...model.simulate import simulate_linear, simulate_state_space
from ...model.system import LinearModel

__all__ = [
    "LinearResiduals",
    "linear_residuals",
    "smooth_derivative",
    "constant_input_segments",
    "noise_level",
    "measured_velocity",
]


@dataclass(frozen=True, eq=False)
class LinearResiduals:
    """Measured data, linear prediction and residuals of one experiment.

    Attributes
    ----------
    experiment : Experiment
    model : LinearModel
    theta : ndarray, shape (n_params,)
        Linear parameters the prediction used.
    y_pred : ndarray, shape (N, n_outputs)
        Predicted output of each sensor, in its units (position m, velocity m/s,
        acceleration m/s^2).
    v_pred : ndarray, shape (N, n_outputs)
        Predicted velocities of the measured carts, m/s (exact, noise-free).
    residual : ndarray, shape (N, n)
        ``y_measured - y_pred``, in each output's units.
    v_meas : ndarray, shape (N, n)
        Measured velocity of each sensor's cart, m/s: the smoothed derivative of a
        position, a velocity sensor's reading, NaN for an accelerometer.
    smooth_window : int
        Savitzky-Golay window (samples, odd) used for derivatives.
    quantum_m : float
        Position resolution of the sensor, m (the encoder count).
    """

    experiment: Experiment
    model: LinearModel
    theta: np.ndarray
    y_pred: np.ndarray
    v_pred: np.ndarray
    residual: np.ndarray
    v_meas: np.ndarray
    smooth_window: int
    quantum_m: float

    @property
    def dt(self) -> float:
        """Sample interval, s."""
        return self.experiment.dt

    @property
    def u(self) -> np.ndarray:
        """Input voltage, V, shape (N,)."""
        return self.experiment.v_volt

    @property
    def y(self) -> np.ndarray:
        """Measured positions, m, shape (N, n)."""
        return self.experiment.y_m

    @property
    def n_outputs(self) -> int:
        return self.experiment.n_outputs

    def matrices(self):
        """``M, C, K, b`` of the linear model at ``theta`` (kg, N s/m, N/m, N/V)."""
        M, C, K, b = self.model.matrices(self.theta)
        return M, C, K, b


def linear_residuals(
    experiment: Experiment,
    model: LinearModel,
    theta: np.ndarray,
    *,
    smooth_window: int | None = None,
    quantum_m: float = ECP_M_PER_COUNT,
) -> LinearResiduals:
    """Simulate the linear model and form the residuals.

    Parameters
    ----------
    experiment : Experiment
    model : LinearModel
    theta : ndarray, shape (n_params,)
        E.g. ``fit_lsq(experiment, model).theta``.
    smooth_window : int, optional
        Savitzky-Golay window, samples (odd, >= 5).  Default: about 40 ms, i.e. a quarter
        of the period of a 6.7 Hz mode, at least 5 samples.
    quantum_m : float
        Sensor resolution, m (default one ECP encoder count, 0.0706/16000 m).

    Returns
    -------
    LinearResiduals

    Raises
    ------
    DataError
        If the experiment and the model disagree on the number of carts.

    Examples
    --------
    >>> from bayesmodal.data import find_data, load_experiment
    >>> from bayesmodal.fit import fit_lsq
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> p = find_data("ecp210-3dof/data_impulses.mat")
    >>> if p:
    ...     e = load_experiment(p)
    ...     model = LinearModel(Rig(), "free")
    ...     res = linear_residuals(e, model, fit_lsq(e, model).theta)
    """
    model.check_record(experiment)
    theta = model.check(np.asarray(theta, dtype=float))
    if theta.ndim != 1:
        raise DataError(f"theta must be one parameter vector, got shape {theta.shape}")
    dt = experiment.dt
    if smooth_window is None:
        smooth_window = max(5, int(round(0.04 / dt)) | 1)
    smooth_window = int(smooth_window)
    if smooth_window < 5 or smooth_window % 2 == 0:
        raise DataError(f"smooth_window must be odd and >= 5 samples, got {smooth_window}")
    if experiment.n_samples < 4 * smooth_window:
        raise DataError(
            f"{experiment.name}: {experiment.n_samples} samples are too few for the "
            f"diagnostics (need >= {4 * smooth_window})"
        )
    n = model.n_carts
    A, B = model.state_space(theta)
    states = simulate_state_space(A, B, experiment.v_volt, dt, 2 * n)[0]
    # the measured carts' positions and velocities (every cart in order on the chain)
    out = np.arange(n) if model.output_index is None else np.asarray(model.output_index)
    if model.output_spec is not None:  # velocity or acceleration sensors
        out = np.asarray(model.output_spec[:, 0])
        y_pred = np.ascontiguousarray(simulate_linear(model, theta, experiment.v_volt, dt))
    else:
        y_pred = np.ascontiguousarray(states[:, out])
    v_pred = np.ascontiguousarray(states[:, n + out])
    return LinearResiduals(
        experiment=experiment,
        model=model,
        theta=theta,
        y_pred=y_pred,
        v_pred=v_pred,
        residual=experiment.y_m - y_pred,
        v_meas=measured_velocity(experiment.y_m, model.rig.output_kinds, dt, smooth_window),
        smooth_window=smooth_window,
        quantum_m=float(quantum_m),
    )


def measured_velocity(y: np.ndarray, kinds, dt: float, window: int) -> np.ndarray:
    """Velocity of each sensor's cart from its record, m/s, shape (N, n).

    Parameters
    ----------
    y : ndarray, shape (N, n)
        The record, each column in its sensor's SI units.
    kinds : sequence of str, length n
        ``"position"``, ``"velocity"`` or ``"acceleration"`` per column.
    dt : float
        Sample interval, s.
    window : int
        Savitzky-Golay window for a position's derivative, samples (odd).

    Returns
    -------
    ndarray, shape (N, n)
        Smoothed derivative of a position, a velocity as read, NaN for an acceleration.
    """
    v = np.full(y.shape, np.nan)
    for j, kind in enumerate(kinds):
        if kind == "position":
            v[:, j] = smooth_derivative(y[:, j], dt, window, deriv=1)
        elif kind == "velocity":
            v[:, j] = y[:, j]
    return v


def smooth_derivative(x: np.ndarray, dt: float, window: int, *, deriv: int = 1,
                      polyorder: int = 3) -> np.ndarray:
    """Savitzky-Golay smoothed value (``deriv=0``) or derivative of ``x`` along axis 0.

    Parameters
    ----------
    x : ndarray, shape (N, ...)
    dt : float
        Sample interval, s.
    window : int
        Odd window length, samples.
    deriv : int
        0, 1 or 2.

    Returns
    -------
    ndarray, shape (N, ...), units of x per s**deriv
    """
    return savgol_filter(x, window, polyorder, deriv=deriv, delta=dt, axis=0, mode="interp")


def derivative_noise_gain(window: int, dt: float, *, deriv: int = 1, polyorder: int = 3) -> float:
    """Standard deviation of the SG derivative of unit white noise, 1/s**deriv."""
    c = savgol_coeffs(window, polyorder, deriv=deriv, delta=dt)
    return float(np.sqrt(np.sum(c**2)))


def noise_level(residual: np.ndarray, quantum_m: float) -> np.ndarray:
    """Robust level of the broadband (sample-to-sample) noise of each output, m, shape (n,).

    From the third difference, which suppresses smooth model error by ``(omega dt)^3``
    while white noise of variance ``s^2`` gives variance ``20 s^2``:
    ``1.4826 MAD(diff3(r)) / sqrt(20)``, floored at the quantisation noise ``q / sqrt(12)``.
    """
    d = np.diff(residual, n=3, axis=0)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return np.maximum(1.4826 * mad / np.sqrt(20.0), quantum_m / np.sqrt(12))


def constant_input_segments(u: np.ndarray, min_samples: int, *, skip: int = 0):
    """Runs of constant input, as ``(start, stop)`` sample indices (stop exclusive).

    The state at sample ``k`` depends on the inputs before ``k``; a run of equal inputs
    ``u[a:b]`` therefore gives free motion (about the equilibrium of that input) over the
    samples ``a + 1 .. b`` (the first sample still carries the previous input's force).

    Parameters
    ----------
    u : ndarray, shape (N,)
    min_samples : int
        Shortest run kept (after skipping).
    skip : int
        Samples dropped at the start of each run (transients, filter edges).

    Returns
    -------
    list of (int, int)
    """
    u = np.asarray(u, dtype=float)
    change = np.flatnonzero(np.diff(u) != 0) + 1
    starts = np.r_[0, change]
    stops = np.r_[change, u.size]
    out = []
    for a, b in zip(starts, stops, strict=True):
        a2 = a + 1 + skip
        b2 = min(b + 1, u.size)
        if b2 - a2 >= min_samples:
            out.append((int(a2), int(b2)))
    return out
