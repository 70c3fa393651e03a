"""A drive gain that depends on the voltage amplitude.

Physics: the motor's torque constant and the amplifier's gain change with the size of the
signal (magnetic saturation of the motor, a non-linear output stage), so the force is
``g_v v (1 + kappa |v|)`` instead of ``g_v v``: ``kappa > 0`` gives large voltages more
force than a linear gain fitted on small ones, ``kappa < 0`` less.  It is memoryless and
acts on the amplifier output, after the saturation.  The model stays linear in the state
and is simulated exactly (per-lane input, ``linear_input_run``).  ``kappa_per_V = 0``
gives the linear model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..system import Rig
from ._base import Extension, ParamSpec
from ._input import linear_lanes_run
from ._linear import ALL_KINDS


@dataclass(frozen=True)
class AmplitudeGain(Extension):
    """Relative gain change per volt ``kappa_per_V`` (1/V), either sign.

    Examples
    --------
    >>> AmplitudeGain().extension_names(Rig())
    ('kappa_per_V',)
    """

    name = "amplitude_gain"
    signatures = ("gain_rises", "gain_falls")
    kernel_stage = "gain"
    default_candidate = False
    typical = (0.02,)
    description = "drive gain g_v (1 + kappa |v|) growing or falling with the voltage"
    exact = True
    sensor_kinds = ALL_KINDS
    validity_rule = "linear part admissible, |kappa_per_V| <= 0.05 (a monotone drive up to 10 V)"
    side = "input"
    input_stage = 2.5

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("kappa_per_V", "1/V", (-0.05, 0.05), 0.0,
                          "relative change of the drive gain per volt of amplitude", 0.005),)

    def _valid_extension(self, rig, theta_lin, theta_ext):
        k = theta_ext[..., 0]
        return np.isfinite(k) & (np.abs(k) <= 0.05)

    def transform_input(self, v, theta_ext):
        v = np.atleast_2d(v)
        return v * (1.0 + theta_ext[:, :1] * np.abs(v))

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        return linear_lanes_run(rig, theta_lin, self.transform_input(u, theta_ext), dt, x0,
                                outputs=outputs)

    def opt_bounds(self, rig):
        return np.array([-0.05]), np.array([0.05])

    def start_grid(self, rig: Rig) -> np.ndarray:
        """No change and +-1 %, +-3 % per volt."""
        return np.array([[0.0], [0.01], [-0.01], [0.03], [-0.03]])
