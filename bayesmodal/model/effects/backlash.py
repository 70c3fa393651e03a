"""Backlash in the rack-pinion drive between the motor and cart 1.

The pinion (with the motor's reflected mass ``m_p``, part of ``m1``) sits in a gap of total
width ``gap_m`` in the rack of cart 1.  Let ``delta = x_m - x_1``:

- engaged (``delta = side * gap_m / 2``): motor and cart 1 move together as in the linear
  model (total mass ``m1``); the contact force on cart 1 is ``g_v v - m_p x_1''`` and the
  contact opens when it would have to pull (``side * force < 0``);
- disengaged (``|delta| < gap_m / 2``): cart 1 moves without the motor (mass
  ``m1 - m_p``, no drive force) and the motor accelerates freely under ``g_v v``; reaching
  the other flank closes the contact with a plastic impact (momentum conserved).

The rig starts at rest with the pinion in the middle of the gap.  ``gap_m = 0`` gives the
linear model.  Numerics: the two linear modes are stepped exactly (ZOH over sub-steps
``dt / n_sub``); switches are detected at sub-step boundaries and corrected to second
order for the time since the event (see ``bayesmodal.model.kernels.backlash_run``).

Sensors: every kind (``Rig.output_kinds``), read at the sample from the state there.  A
position or velocity is the cart's state.  An acceleration is that of the mode the drive
is in at the sample, once the first sub-step's switch checks (with the sample's input)
are made: with the gap closed, cart 1 and the motor as one body, ``(F1 + g_v u) / m1``
(the force transmitted through the contact included: cart 1 alone feels
``F1 + Fcon``, ``Fcon`` as above, which is the same); with the gap open, cart 1 without
the motor and without the drive force, ``F1 / (m1 - m_p)``.  ``F1`` is the spring and
damper force on cart 1 and ``u`` the input held from the sample.  The other carts do not
touch the drive: their accelerations are the linear model's rows in either mode.  The
motor's own inertia carries no sensor (it is not a cart): with the gap open it
accelerates at ``g_v u / m_p``, closed with cart 1.  An impact is an instantaneous
velocity jump inside a sub-step: no sample's acceleration holds it (it shows as the
jump of the velocity readings).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._errors import ModelError
from ..kernels import backlash_run, expm_batched, zoh
from ..system import LinearModel, Rig
from ._base import EffectLocation, Extension, ParamSpec, cart_numbers
from ._linear import (
    ALL_KINDS,
    acceleration_columns,
    kernel_order,
    linear_parts,
    parts_from,
    sensor_map,
)


@dataclass(frozen=True)
class Backlash(Extension):
    """Drive backlash: gap width ``gap_m`` (m) and reflected motor mass ``m_p`` (kg).

    Parameters
    ----------
    n_sub : int
        Sub-steps per sample interval.  The default 2 keeps the error against an
        event-driven reference below 0.75 encoder counts on pulse inputs (about 0.5).

    Examples
    --------
    >>> Backlash().extension_names(Rig())
    ('gap_m', 'm_p')
    """

    n_sub: int = 2

    name = "backlash"
    typical = (3e-4, 0.2)
    needs = "one_drive"
    sensor_kinds = ALL_KINDS
    description = "gap gap_m in the rack-pinion drive of cart 1 (motor mass m_p, plastic contact)"
    exact = False
    validity_rule = "linear part admissible, gap_m >= 0, 0 < m_p < m1"

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (
            ParamSpec("gap_m", "m", (0.0, 1e-3), 0.0,
                      "total free play of the pinion in the rack of cart 1", 1e-4),
            ParamSpec("m_p", "kg", (0.05, 0.5), 0.2,
                      "motor and pinion inertia reflected to the rack (part of m1)", 0.05),
        )

    def _valid_extension(self, rig, theta_lin, theta_ext):
        gap, m_p = theta_ext[..., 0], theta_ext[..., 1]
        ok = np.isfinite(gap) & np.isfinite(m_p) & (gap >= 0) & (m_p > 0)
        why = self.unsupported(rig)
        if why:
            raise ModelError(why)
        # the mass of the driven cart with the motor, kg
        d = kernel_order(rig).driven
        return ok & (m_p < LinearModel(rig, "free").matrices(theta_lin)[0][..., d, d])

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        h = dt / self.n_sub
        gap = np.ascontiguousarray(theta_ext[:, 0])
        m_p = np.ascontiguousarray(theta_ext[:, 1])
        engaged = linear_parts(rig, theta_lin)  # the driven cart first
        Ae, Be = zoh(engaged.A, engaged.B[..., None], h)
        # disengaged: the driven cart without the motor mass, no drive force
        M = engaged.M.copy()
        M[:, 0, 0] -= m_p
        cart = parts_from(M, engaged.C, engaged.K, np.zeros_like(engaged.b))
        Adis = expm_batched(cart.A * h)
        extra = {} if outputs is None else {
            "outputs": outputs, "columns": acceleration_columns(rig, outputs),
            "out_map": sensor_map(engaged.A, engaged.B, outputs, rig.n_carts,
                                  engaged.force_inputs)}
        return backlash_run(
            Ae, Be[..., 0], Adis, engaged.net_force[:, 0, :], engaged.M[:, 0, 0], m_p,
            engaged.b[:, 0], gap, u, int(self.n_sub), h, x0, **extra,
        )

    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """Always the drive of the driven cart; strength is the gap, m."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        gap = self.split(rig, theta)[1][0]
        d = kernel_order(rig).driven
        return EffectLocation("drive", d, f"rack-pinion drive of cart {cart_numbers(rig)[d]}",
                              np.array([gap]))

    def opt_bounds(self, rig):
        return np.array([0.0, 1e-3]), np.array([np.inf, np.inf])

    def start_grid(self, rig: Rig) -> np.ndarray:
        """Gaps 0..0.5 mm with a 0.2 kg motor mass."""
        return np.array([[g, 0.2] for g in (0.0, 2e-5, 5e-5, 1e-4, 2e-4, 5e-4)])
