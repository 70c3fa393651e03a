"""First-order lag between the motor voltage and the force on cart 1.

The amplifier and motor windings make the force follow the voltage with a time constant::

    tau f' = g_v v - f,      f acts on cart 1 instead of g_v v.

The model stays linear: the state ``(x, x', f)`` is simulated exactly by zero-order hold
(batched compiled recursion, ``bayesmodal.discrepancy.kernels.linear_input_run``).  With
``tau_s = 0`` the force follows instantly and the model is the linear one (the lag state
is then unused); so does a lag below ``INSTANT_LAG`` of the sample interval, whose hold
would not be accurate (``_input.INSTANT_LAG``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...system import Rig
from ..kernels import linear_input_run, zoh
from ._base import Extension, ParamSpec
from ._input import effective_lag
from ._linear import linear_parts


@dataclass(frozen=True)
class MotorLag(Extension):
    """Voltage-to-force lag with time constant ``tau_s`` (s).

    Examples
    --------
    >>> MotorLag().extension_names(Rig())
    ('tau_s',)
    """

    name = "motor_lag"
    description = "first-order lag tau_s between motor voltage and force"
    exact = True
    side = "input"
    input_stage = 3

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("tau_s", "s", (0.0, 0.05), 0.0,
                          "time constant of the first-order lag from voltage to motor force",
                          0.005),)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0):
        n = rig.n_carts
        s = 2 * n
        nb = theta_lin.shape[0]
        tau = effective_lag(theta_ext[:, 0], dt)  # a lag far below dt is instantaneous
        p = linear_parts(rig, theta_lin)
        Ad = np.zeros((nb, s + 1, s + 1))
        Bd = np.zeros((nb, s + 1))
        instant = tau == 0.0
        if np.any(instant):  # the linear model; the lag state stays at zero
            A1, B1 = zoh(p.A[instant], p.B[instant, :, None], dt)
            Ad[instant, :s, :s] = A1
            Bd[instant, :s] = B1[..., 0]
        lag = ~instant
        if np.any(lag):
            A = np.zeros((int(lag.sum()), s + 1, s + 1))
            A[:, :s, :s] = p.A[lag]
            A[:, n, s] = p.inv_mass[lag, 0]  # the lagged force drives cart 1
            A[:, s, s] = -1.0 / tau[lag]
            B = np.zeros((A.shape[0], s + 1))
            B[:, s] = p.b[lag, 0] / tau[lag]
            A1, B1 = zoh(A, B[..., None], dt)
            Ad[lag], Bd[lag] = A1, B1[..., 0]
        z0 = np.zeros((nb, s + 1))
        z0[:, :s] = x0
        return linear_input_run(Ad, np.zeros_like(Bd), Bd, u, z0, n)
