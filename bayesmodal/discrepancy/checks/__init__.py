"""Residual diagnostics: what does the linear simulation get wrong?

Each diagnostic is a pure function of the residuals of the linear model,
``LinearResiduals`` (from ``linear_residuals(experiment, model, theta)``), returning a
frozen ``Diagnostic(name, statistic, p_value, threshold, detected, suggests, location,
summary, detail)``; ``suggests`` names the model extensions
(``bayesmodal.model.effects.EXTENSIONS``) the evidence points to.

================================  ===================================  =======================
function                          looks for                            suggests
================================  ===================================  =======================
``whiteness``                     structure left after AR whitening    (anything)
``input_residual_correlation``    misfit locked to the input           input_delay, motor_lag
``friction_signature``            force residual ~ -Fc sign(velocity)  coulomb_friction
``decay_envelope``                linear (not exponential) free decay  coulomb_friction
``amplitude_dependence``          frequency changing with amplitude    cubic_stiffness
``stick_detection``               carts at rest off equilibrium        coulomb_friction
``residual_spectrum``             peaks away from the modelled modes   unmodelled_mode
``gain_error``                    residual proportional to prediction  sensor_gain, input_gain
``input_bias``                    response to a constant input offset  input_offset
``drive_gain_amplitude``          gain asked changing with amplitude   drive_deadband,
                                                                       input_saturation,
                                                                       amplitude_gain
``cross_experiment_consistency``  fits that do not transfer            nonlinear effects
================================  ===================================  =======================

``RESIDUAL_DIAGNOSTICS`` lists the single-experiment ones by name, all with the signature
``f(res, **options) -> Diagnostic``.

Sensor kinds: ``whiteness``, ``input_correlation``, ``residual_spectrum``, ``gain_error``
and ``input_bias`` read only the residual and the prediction, each in the output's own
units and kind (position m, velocity m/s, acceleration m/s^2), and apply to any sensor.
The others (``NEEDS_POSITIONS``) read the measured motion as cart positions (rest,
envelope, amplitude, differentiated positions): ``diagnostics_for(model)`` leaves them
out unless every sensor reads a position, one per moving cart in cart order, and
``skipped_for(model)`` says which and why.
"""

from __future__ import annotations

from ._result import Diagnostic
from ._stats import ljung_box
from .amplitude import amplitude_dependence
from .bias import input_bias
from .consistency import cross_experiment_consistency
from .decay import decay_envelope
from .drive_gain import drive_gain_amplitude, input_events
from .friction import force_residual, friction_signature
from .gain import gain_error
from .input_correlation import input_residual_correlation, prediction_lag
from .residuals import (
    LinearResiduals,
    constant_input_segments,
    linear_residuals,
    noise_level,
    smooth_derivative,
)
from .spectrum import residual_spectrum
from .stick import stick_detection
from .whiteness import whiteness

__all__ = [
    "Diagnostic",
    "LinearResiduals",
    "NEEDS_POSITIONS",
    "RESIDUAL_DIAGNOSTICS",
    "amplitude_dependence",
    "constant_input_segments",
    "cross_experiment_consistency",
    "decay_envelope",
    "diagnostics_for",
    "drive_gain_amplitude",
    "force_residual",
    "friction_signature",
    "gain_error",
    "input_bias",
    "input_events",
    "input_residual_correlation",
    "linear_residuals",
    "ljung_box",
    "noise_level",
    "prediction_lag",
    "residual_spectrum",
    "skipped_for",
    "smooth_derivative",
    "stick_detection",
    "whiteness",
]

#: Single-experiment diagnostics by name, each ``f(res: LinearResiduals, **options)``.
RESIDUAL_DIAGNOSTICS = {
    "whiteness": whiteness,
    "input_correlation": input_residual_correlation,
    "friction_signature": friction_signature,
    "decay_envelope": decay_envelope,
    "amplitude_dependence": amplitude_dependence,
    "stick": stick_detection,
    "residual_spectrum": residual_spectrum,
    "gain_error": gain_error,
    "input_bias": input_bias,
    "drive_gain": drive_gain_amplitude,
}

#: Diagnostics that read the measured record as cart positions (output j: cart j).
NEEDS_POSITIONS = frozenset({"friction_signature", "decay_envelope", "amplitude_dependence",
                             "stick", "drive_gain"})


def _positions_in_cart_order(model) -> bool:
    return bool(model.rig.positions_only and model.output_index is None)


def diagnostics_for(model) -> tuple[str, ...]:
    """Names of the ``RESIDUAL_DIAGNOSTICS`` that apply to ``model``'s sensors.

    Parameters
    ----------
    model : LinearModel

    Returns
    -------
    tuple of str
        All of them when every sensor reads a position, one per moving cart in cart
        order; otherwise those that read only the residual (``NEEDS_POSITIONS`` out).
    """
    if _positions_in_cart_order(model):
        return tuple(RESIDUAL_DIAGNOSTICS)
    return tuple(k for k in RESIDUAL_DIAGNOSTICS if k not in NEEDS_POSITIONS)


def skipped_for(model) -> str | None:
    """One line naming the diagnostics ``diagnostics_for(model)`` leaves out, or None.

    Parameters
    ----------
    model : LinearModel
    """
    if _positions_in_cart_order(model):
        return None
    kinds = sorted(set(model.rig.output_kinds))
    left = ", ".join(k for k in RESIDUAL_DIAGNOSTICS if k in NEEDS_POSITIONS)
    return (f"skipped on {' and '.join(kinds)} records (they read positions, one per cart): "
            f"{left}; the others read the residual in the sensors' own units")
