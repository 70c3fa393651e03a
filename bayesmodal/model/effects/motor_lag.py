"""First-order lag between the motor voltage and the force on cart 1.

The amplifier and motor windings make the force follow the voltage with a time constant::

    tau f' = g_v v - f,      f acts on cart 1 instead of g_v v.

The model stays linear: the state ``(x, x', f)`` is simulated exactly by zero-order hold
(batched compiled recursion, ``_input.linear_lanes_run``, shared with the combined
models).  With ``tau_s = 0`` the force follows instantly and the model is the linear
one (the lag state is then unused); so does a lag below ``INSTANT_LAG`` of the sample
interval, whose hold would not be accurate (``_input.INSTANT_LAG``).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..system import Rig
from ._base import Extension, ParamSpec
from ._input import linear_lanes_run
from ._linear import ALL_KINDS


@dataclass(frozen=True)
class MotorLag(Extension):
    """Voltage-to-force lag with time constant ``tau_s`` (s).

    Examples
    --------
    >>> MotorLag().extension_names(Rig())
    ('tau_s',)
    """

    name = "motor_lag"
    signatures = ("lag",)
    typical = (0.01,)
    description = "first-order lag tau_s between motor voltage and force"
    exact = True
    sensor_kinds = ALL_KINDS
    side = "input"
    input_stage = 3
    needs = "one_drive"  # the lagged force acts on the driven cart

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("tau_s", "s", (0.0, 0.05), 0.0,
                          "time constant of the first-order lag from voltage to motor force",
                          0.005),)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        # the lag state's system and hold are shared with the combined models
        # (``_input.linear_lanes_run``; a lag far below dt is instantaneous there)
        return linear_lanes_run(rig, theta_lin, u, dt, x0, tau=theta_ext[:, 0],
                                outputs=outputs)
