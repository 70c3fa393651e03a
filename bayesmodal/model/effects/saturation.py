"""Saturation of the motor drive: the voltage (hence the force) is clipped at ``+-v_sat``.

The motor force is ``g_v clip(v, -v_sat, v_sat)``; the force limit is ``g_v v_sat``.  A
memoryless clip of the held input keeps the simulation exact.  ``v_sat = inf`` (or any level
above ``max |v|``) gives the linear model.  The clip is applied per parameter set inside
the compiled recursion (``bayesmodal.model.kernels.linear_input_run``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import zoh
from ..system import Rig
from ._base import Extension, ParamSpec
from ._input import input_sensor_map, sensors_run
from ._linear import ALL_KINDS, linear_parts


@dataclass(frozen=True)
class InputSaturation(Extension):
    """Voltage limit ``v_sat`` (V) of the motor drive.

    Examples
    --------
    >>> InputSaturation().extension_names(Rig())
    ('v_sat',)
    """

    name = "input_saturation"
    signatures = ("consistency", "gain_falls")
    kernel_stage = "saturation"
    typical = (2.5,)
    description = "motor voltage (force) clipped at +-v_sat"
    exact = True
    sensor_kinds = ALL_KINDS
    validity_rule = "linear part admissible, v_sat > 0 (inf allowed)"
    side = "input"
    input_stage = 2

    def transform_input(self, v, theta_ext):
        level = theta_ext[:, :1]
        return np.clip(np.atleast_2d(v), -level, level)

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("v_sat", "V", (0.5, 10.0), np.inf,
                          "largest voltage the drive passes; force limit g_v v_sat", 0.5),)

    def _valid_extension(self, rig, theta_lin, theta_ext):
        v = theta_ext[..., 0]
        return ~np.isnan(v) & (v > 0)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        n = rig.n_carts
        p = linear_parts(rig, theta_lin)
        Ad, Bd = zoh(p.A, p.B[..., None], dt)
        out_map = None if outputs is None else input_sensor_map(p.A, p.B, outputs, n)
        return sensors_run(Ad, np.zeros_like(Bd[..., 0]), Bd[..., 0], u, x0, n, out_map,
                           level=theta_ext[:, 0])

    def opt_bounds(self, rig):
        return np.array([1e-3]), np.array([np.inf])

    def start_grid(self, rig: Rig) -> np.ndarray:
        """No saturation, and limits from 0.5 to 8 V."""
        return np.array([[np.inf], [0.5], [1.0], [2.0], [2.5], [4.0], [8.0]])
