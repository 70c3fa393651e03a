"""A constant bias voltage added to the command: the offset of the power amplifier.

Physics: the amplifier adds a constant ``v_offset`` to every commanded voltage, so the motor
force is ``g_v (v + v_offset)``.  The drive is enabled when a record starts: the rig is at
rest at ``x = 0`` and the offset acts from ``t = 0`` on, like a small step.  A bias differs
from record to record (it drifts with temperature), hence a per-record parameter.  The
model stays linear and is simulated exactly (per-lane input in the compiled recursion
``bayesmodal.model.kernels.linear_input_run``).  ``v_offset = 0`` gives the linear model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..system import Rig
from ._base import Extension, ParamSpec
from ._input import linear_lanes_run
from ._linear import ALL_KINDS


@dataclass(frozen=True)
class InputOffset(Extension):
    """Amplifier offset ``v_offset`` (V), either sign.

    Examples
    --------
    >>> InputOffset().extension_names(Rig())
    ('v_offset',)
    """

    name = "input_offset"
    signatures = ("bias",)
    kernel_stage = "offset"
    typical = (0.15,)
    description = "constant bias v_offset added to the motor voltage (amplifier offset)"
    exact = True
    sensor_kinds = ALL_KINDS
    validity_rule = "linear part admissible, v_offset finite (either sign)"
    side = "input"
    input_stage = 0

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("v_offset", "V", (-0.5, 0.5), 0.0,
                          "constant voltage the amplifier adds to the command", 0.02),)

    def _valid_extension(self, rig, theta_lin, theta_ext):
        return np.all(np.isfinite(theta_ext), axis=-1)

    def transform_input(self, v, theta_ext):
        return np.atleast_2d(v) + theta_ext[:, :1]

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        return linear_lanes_run(rig, theta_lin, self.transform_input(u, theta_ext), dt, x0,
                                outputs=outputs)

    def opt_bounds(self, rig):
        return np.array([-np.inf]), np.array([np.inf])

    def start_grid(self, rig: Rig) -> np.ndarray:
        """No offset and offsets of +-0.05 and +-0.2 V."""
        return np.array([[0.0], [0.05], [-0.05], [0.2], [-0.2]])
