"""A dead band of the drive: no motor force below a threshold voltage.

Physics: the motor's own static friction and cogging swallow small voltages, so the
effective voltage is ``sign(v) max(|v| - v_dead, 0)`` (sharp) and no force acts while
``|v| < v_dead``.  The smooth version replaces the corners by softplus ramps of width
``w`` (V)::

    D_w(v) = w [softplus((v - v_dead) / w) - softplus((-v - v_dead) / w)],
    softplus(z) = log(1 + e^z),

which is odd, infinitely differentiable, tends to the sharp dead band as ``w -> 0`` (the
largest difference is ``w log 2``, at ``|v| = v_dead``) and is the identity at
``v_dead = 0`` for every ``w`` (``softplus(z) - softplus(-z) = z``).  The model stays linear
in the state and is simulated exactly (per-lane input, ``linear_input_run``).
``v_dead = 0`` gives the linear model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._errors import ModelError
from ..system import Rig
from ._base import Extension, ParamSpec
from ._input import linear_lanes_run
from ._linear import ALL_KINDS


def deadband(v: np.ndarray, v_dead: np.ndarray, width_v: float = 0.0) -> np.ndarray:
    """The voltage after a dead band ``v_dead`` (V), sharp (``width_v = 0``) or smooth.

    Parameters
    ----------
    v : ndarray, shape (N,) or (nb, N)
        Voltage, V.
    v_dead : ndarray, shape (nb, 1) or scalar
        Threshold, V (>= 0).
    width_v : float
        Softplus width of the smooth version, V; 0 for the sharp dead band.

    Returns
    -------
    ndarray, shape broadcast of ``v`` and ``v_dead``

    Examples
    --------
    >>> deadband(np.array([-1.0, 0.1, 0.5]), 0.2)
    array([-0.8,  0. ,  0.3])
    """
    v = np.asarray(v, dtype=float)
    if width_v == 0.0:
        return np.sign(v) * np.maximum(np.abs(v) - v_dead, 0.0)
    return width_v * (np.logaddexp(0.0, (v - v_dead) / width_v)
                      - np.logaddexp(0.0, (-v - v_dead) / width_v))


@dataclass(frozen=True)
class DriveDeadband(Extension):
    """Drive dead band ``v_dead`` (V).

    Parameters
    ----------
    width_v : float
        Smoothing width of the corners, V (0: sharp dead band).  The simulated output is
        continuous in ``v_dead`` either way; with ``width_v > 0`` it is also smooth.

    Examples
    --------
    >>> DriveDeadband().extension_names(Rig())
    ('v_dead',)
    """

    width_v: float = 0.0

    name = "drive_deadband"
    signatures = ("gain_rises",)
    kernel_stage = "deadband"
    typical = (0.05,)  # below the 0.2 V sweep of the benchmark: the carts still move
    description = "no motor force below |v| = v_dead (motor static friction, cogging)"
    exact = True
    sensor_kinds = ALL_KINDS
    side = "input"
    input_stage = 1

    def __post_init__(self) -> None:
        if not (np.isfinite(self.width_v) and self.width_v >= 0):
            raise ModelError(f"drive_deadband: width_v must be finite and >= 0 V, "
                             f"got {self.width_v!r}; use 0 for a sharp dead band")

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("v_dead", "V", (0.0, 1.0), 0.0,
                          "voltage below which the motor produces no force", 0.05),)

    def transform_input(self, v, theta_ext):
        return deadband(np.atleast_2d(v), theta_ext[:, :1], self.width_v)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        return linear_lanes_run(rig, theta_lin, self.transform_input(u, theta_ext), dt, x0,
                                outputs=outputs)

    def start_grid(self, rig: Rig) -> np.ndarray:
        """No dead band and thresholds 0.05 to 0.5 V."""
        return np.array([[0.0], [0.05], [0.1], [0.2], [0.5]])
