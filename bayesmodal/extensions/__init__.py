"""Model extensions: named simulators of effects the linear rig model leaves out.

Each extension adds its own parameters after the nine free-damping linear parameters and
reduces to the linear model at its ``null`` values.  The registry ``EXTENSIONS`` maps a
name to a ready-to-use instance:

============================  ===============================  =====================
name                          parameters (after the linear)    acts at
============================  ===============================  =====================
``coulomb_friction``          ``Fc1..Fcn, Fs1..Fsn`` (N)       each cart
``motor_lag``                 ``tau_s`` (s)                    motor input
``input_delay``               ``delay_s`` (s)                  motor input
``backlash``                  ``gap_m`` (m), ``m_p`` (kg)      drive of cart 1
``cubic_stiffness``           ``k3_1..k3_n`` (N/m^3)           each spring
``input_saturation``          ``v_sat`` (V)                    motor input
============================  ===============================  =====================

Examples
--------
>>> import numpy as np
>>> from bayesmodal.system import Rig
>>> ext = EXTENSIONS["coulomb_friction"]
>>> rig = Rig()
>>> theta = ext.null_theta(rig, np.array([6.2, 1.56, 1.46, 1.15, 2.9, 1.8, 2.0, 0.0, 0.0]))
>>> ext.simulate(rig, theta, np.r_[np.full(10, 3.0), np.zeros(90)], 0.005).shape
(100, 3)
"""

from __future__ import annotations

from ._base import EffectLocation, Extension, ParamSpec
from .backlash import Backlash
from .coulomb import CoulombFriction
from .cubic import CubicStiffness
from .fit import ExtensionFit, fit_extension_lsq
from .input_delay import InputDelay
from .motor_lag import MotorLag
from .saturation import InputSaturation

__all__ = [
    "EXTENSIONS",
    "EffectLocation",
    "Extension",
    "ExtensionFit",
    "ParamSpec",
    "Backlash",
    "CoulombFriction",
    "CubicStiffness",
    "InputDelay",
    "InputSaturation",
    "MotorLag",
    "fit_extension_lsq",
    "get_extension",
]

#: Registry of the extensions with their default numerical settings.
EXTENSIONS: dict[str, Extension] = {
    ext.name: ext
    for ext in (
        CoulombFriction(),
        MotorLag(),
        InputDelay(),
        Backlash(),
        CubicStiffness(),
        InputSaturation(),
    )
}


def get_extension(name: str) -> Extension:
    """The registered extension called ``name``.

    Raises
    ------
    ModelError
        For an unknown name (the message lists the known ones).
    """
    from .._errors import ModelError

    try:
        return EXTENSIONS[name]
    except KeyError:
        raise ModelError(
            f"unknown model extension {name!r}; known: {sorted(EXTENSIONS)}"
        ) from None
