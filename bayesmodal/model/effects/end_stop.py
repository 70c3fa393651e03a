"""A soft end stop on the travel of the driven cart.

Physics: beyond ``x_stop`` (m) from its rest position the driven cart (cart 1, which
carries the motor's rack) meets an elastic stop, a bumper or the end of its travel, that
pushes it back with ``k_stop (x_1 - x_stop)`` (N) while in contact and not at all
otherwise; one-sided (``side = +1``: beyond positive travel, the side where the measured
impulses of the ECP 210 need it, docs/discrepancy.md).  Only large excursions reach it:
on the measured records the 3 V pulses carry cart 1 to 27-29 mm, the steps and sweeps
below 25 mm.

``k_stop = 0`` gives the linear model (``x_stop`` then does nothing).  The stop combines
with the plant kernels that take a stop force (``STOP_KERNELS``: stick-slip and LuGre
friction, cubic springs), e.g. ``get_extension("coulomb_friction+end_stop")``.

Numerics: alone (and with cubic springs), the force enters the exact zero-order hold of
the linear rig by the second-order exponential Runge-Kutta scheme of the cubic springs
(``kernels.cubic_run``, ``n_sub`` sub-steps); with stick-slip friction it is held over
each step at its mid-step value and a lane in or near contact takes the sample in the
friction kernel's sub-steps (``kernels.stop``); with LuGre friction it is held over
each sub-step at its mid-step value with the friction force.  The kink of the force at
the contact's onset makes the error there first order in the sub-step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import cubic_run, zoh
from ..kernels.stop import checked_side
from ..system import Rig
from ._base import EffectLocation, Extension, ParamSpec, cart_numbers
from ._linear import ALL_KINDS, acceleration_columns, kernel_order, linear_parts, sensor_map

#: Plant-side effects whose kernels take the end stop's force next to their own.
STOP_KERNELS = ("coulomb_friction", "coulomb_directional", "lugre_friction",
                "cubic_stiffness")


@dataclass(frozen=True)
class EndStop(Extension):
    """An elastic end stop of the driven cart: ``x_stop`` (m), ``k_stop`` (N/m).

    Parameters
    ----------
    n_sub : int
        Sub-steps per sample interval when the stop is the only plant-side effect.
    side : {1, -1}
        The stop is met beyond ``+x_stop`` (1) or ``-x_stop`` (-1).

    Examples
    --------
    >>> EndStop().extension_names(Rig())
    ('x_stop', 'k_stop')
    """

    n_sub: int = 4
    side: int = 1

    name = "end_stop"
    default_candidate = False
    typical = (0.02, 2000.0)  # reached by the 3 V pulses of the rig-like input
    description = "a soft one-sided end stop of the driven cart (k_stop beyond x_stop)"
    exact = False
    validity_rule = "linear part admissible, x_stop > 0, k_stop >= 0, finite"
    sensor_kinds = ALL_KINDS
    #: a force that the kernels of ``STOP_KERNELS`` add to their own (``Combined``)
    plant_force = True
    needs = "one_drive"

    def __post_init__(self) -> None:
        checked_side(self.side)

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        where = "positive" if self.side > 0 else "negative"
        return (
            ParamSpec("x_stop", "m", (0.005, 0.06), 0.03,
                      f"distance from rest at which the driven cart meets its stop ({where} "
                      "travel)",
                      0.003),
            ParamSpec("k_stop", "N/m", (0.0, 2e4), 0.0,
                      "stiffness of the stop (0: no stop)", 500.0),
        )

    def _valid_extension(self, rig, theta_lin, theta_ext):
        x, k = theta_ext[..., 0], theta_ext[..., 1]
        return np.all(np.isfinite(theta_ext), axis=-1) & (x > 0) & (k >= 0)

    def stop_args(self, theta_ext: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """``(side, x_stop, k_stop)`` of the kernels (``kernels.stop``) for a batch of the
        stop's own parameters, shape (nb, 2); ``x_stop`` signed by the side."""
        theta_ext = np.asarray(theta_ext, dtype=float)
        return (self.side, self.side * np.ascontiguousarray(theta_ext[:, 0]),
                np.ascontiguousarray(theta_ext[:, 1]))

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        p = linear_parts(rig, theta_lin)
        h = dt / self.n_sub
        Ah, F0h, F1h = zoh(p.A, p.force_inputs, h, ramp=True)
        Bh = np.einsum("bij,bj->bi", F0h, p.b)  # the motor is a force on the carts
        k3 = np.zeros((theta_lin.shape[0], rig.n_carts))
        out_map = None if outputs is None else sensor_map(p.A, p.B, outputs, rig.n_carts,
                                                          p.force_inputs)
        return cubic_run(Ah, Bh, F0h, F1h, k3, u, int(self.n_sub), x0,
                         stop=self.stop_args(theta_ext), outputs=outputs, out_map=out_map,
                         columns=None if outputs is None else acceleration_columns(rig, outputs))

    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """The driven cart, at the end of its travel on the stop's side; strength
        ``k_stop``."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        ext = self.split(rig, theta)[1]
        where = "positive" if self.side > 0 else "negative"
        d = kernel_order(rig).driven
        strength = np.zeros(rig.n_carts)
        strength[d] = ext[1]
        return EffectLocation("cart", d, f"cart {cart_numbers(rig)[d]} (stop beyond {where} "
                              "travel)", strength)

    def opt_bounds(self, rig):
        return np.array([1e-3, 0.0]), np.array([np.inf, np.inf])

    def start_grid(self, rig: Rig) -> np.ndarray:
        """No stop, and stops of 0.5-3 kN/m at 20-32 mm."""
        return np.array([[0.03, 0.0], [0.02, 500.0], [0.025, 1000.0], [0.028, 2000.0],
                         [0.032, 3000.0]])
