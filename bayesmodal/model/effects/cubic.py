"""Cubic (hardening or softening) springs.

Spring ``i`` pulls with ``k_i d_i + k3_i d_i^3`` where ``d_i`` is its extension
(``x_{i+1} - x_i``, or ``-x_n`` for the last spring to the frame).  Stiffness that grows
with amplitude raises the natural frequencies of large oscillations.

Numerics: the linear part is exact (ZOH over sub-steps ``dt / n_sub``) and the cubic forces
enter as an input by the second-order exponential Runge-Kutta scheme ETD2RK (see
``bayesmodal.model.kernels.cubic_run``).  ``k3_i = 0`` gives the linear model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import cubic_run, zoh
from ..system import FRAME, Rig
from ._base import EffectLocation, Extension, ParamSpec
from ._linear import ALL_KINDS, acceleration_columns, kernel_order, linear_parts, sensor_map


def spring_label(rig: Rig, i: int) -> str:
    """``"spring 1 (cart 1 - cart 2)"``: the ``i``-th spring with a free end (0-based),
    numbered as in ``rig.springs``, with its ends."""
    j = kernel_order(rig).spring_index[i]
    s = rig.springs[j]
    ends = [e if e == FRAME else f"cart {e}" for e in (s.a, s.b)]
    return f"spring {j + 1} ({ends[0]} - {ends[1]})"


def n_springs(rig: Rig) -> int:
    """Number of springs with at least one free end (each has a ``k3_i``)."""
    return len(kernel_order(rig).springs)


@dataclass(frozen=True)
class CubicStiffness(Extension):
    """Cubic stiffness ``k3_i`` (N/m^3) of every spring.

    Parameters
    ----------
    n_sub : int
        Sub-steps per sample interval.

    Examples
    --------
    >>> CubicStiffness().extension_names(Rig())
    ('k3_1', 'k3_2', 'k3_3')
    """

    n_sub: int = 2

    name = "cubic_stiffness"
    signatures = ("consistency", "amplitude_frequency")
    typical = (1e5, -5e4, 1e5)
    description = "spring force k_i d + k3_i d^3 (hardening k3 > 0, softening k3 < 0)"
    exact = False
    validity_rule = "linear part admissible, k3_i finite (either sign)"
    sensor_kinds = ALL_KINDS

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return tuple(
            ParamSpec(f"k3_{j + 1}", "N/m^3", (-2e5, 2e5), 0.0,
                      f"cubic stiffness of {spring_label(rig, i)}", 2e4)
            for i, j in enumerate(kernel_order(rig).spring_index)
        )

    def _valid_extension(self, rig, theta_lin, theta_ext):
        return np.all(np.isfinite(theta_ext), axis=-1)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, stop=None, outputs=None):
        p = linear_parts(rig, theta_lin)
        h = dt / self.n_sub
        Ah, F0h, F1h = zoh(p.A, p.force_inputs, h, ramp=True)
        Bh = np.einsum("bij,bj->bi", F0h, p.b)  # the motor is a force on the carts
        out_map = None if outputs is None else sensor_map(p.A, p.B, outputs, rig.n_carts,
                                                          p.force_inputs)
        return cubic_run(Ah, Bh, F0h, F1h, theta_ext, u, int(self.n_sub), x0, stop=stop,
                         springs=kernel_order(rig).springs, outputs=outputs, out_map=out_map,
                         columns=None if outputs is None else acceleration_columns(rig, outputs))

    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """The spring with the largest relative cubic stiffness ``|k3_i| / k_i``."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        k3 = self.split(rig, theta)[1]
        k = np.asarray(rig.springs_n_m)[list(kernel_order(rig).spring_index)]
        rel = np.abs(k3) / k
        i = int(np.argmax(rel))
        return EffectLocation("spring", i, spring_label(rig, i), k3.copy())

    def opt_bounds(self, rig):
        n = n_springs(rig)
        return np.full(n, -np.inf), np.full(n, np.inf)

    def start_grid(self, rig: Rig) -> np.ndarray:
        """Zero, and equal hardening or softening on all springs."""
        n = n_springs(rig)
        return np.array([np.full(n, v) for v in (0.0, 2e4, -2e4, 1e5, -1e5)])
