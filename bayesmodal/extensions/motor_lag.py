"""First-order lag between the motor voltage and the force on cart 1.

The amplifier and motor windings make the force follow the voltage with a time constant::

    tau f' = g_v v - f,      f acts on cart 1 instead of g_v v.

The model stays linear: the state ``(x, x', f)`` is simulated exactly by zero-order hold.
With ``tau_s = 0`` the force follows instantly and the model is the linear one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..simulate import simulate_linear, simulate_state_space
from ..system import Rig
from ._base import Extension, ParamSpec
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

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("tau_s", "s", (0.0, 0.05), 0.0,
                          "time constant of the first-order lag from voltage to motor force",
                          0.005),)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0):
        n = rig.n_carts
        nb = theta_lin.shape[0]
        tau = theta_ext[:, 0]
        Y = np.empty((nb, u.size, n))
        instant = tau == 0.0
        if np.any(instant):
            model = self.linear_model(rig)
            Y[instant] = simulate_linear(model, theta_lin[instant], u, dt, x0=x0[instant])
        lag = ~instant
        if np.any(lag):
            p = linear_parts(rig, theta_lin[lag])
            s = 2 * n
            A = np.zeros((p.A.shape[0], s + 1, s + 1))
            A[:, :s, :s] = p.A
            A[:, s:, :s] = 0.0
            A[:, n, s] = p.inv_mass[:, 0]  # the lagged force drives cart 1
            A[:, s, s] = -1.0 / tau[lag]
            B = np.zeros((p.A.shape[0], s + 1))
            B[:, s] = p.b[:, 0] / tau[lag]
            z0 = np.zeros((p.A.shape[0], s + 1))
            z0[:, :s] = x0[lag]
            Y[lag] = simulate_state_space(A, B, u, dt, n, z0)
        return Y
