"""A pure time delay between the commanded voltage and the motor.

The motor sees ``v(t - D)`` (computation and communication latency of the controller).
With the commanded voltage held over each sample and ``D = (m + phi) dt``
(``m`` integer, ``0 <= phi < 1``), the input over ``[k dt, (k + 1) dt)`` is ``v[k-m-1]``
for the first ``phi dt`` and ``v[k-m]`` after, so the exact discrete model is::

    x[k+1] = e^{A dt} x[k] + B1 v[k-m-1] + B2 v[k-m],
    B1 = e^{A (1-phi) dt} Gamma(phi dt) B,   B2 = Gamma((1-phi) dt) B,
    Gamma(t) = int_0^t e^{A s} ds.

It is run as this linear recursion, batched, with each parameter set's input shifted by its
own ``m`` inside the compiled kernel (``bayesmodal.model.kernels.linear_input_run``).
``delay_s = 0`` gives the linear model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import zoh
from ..system import Rig
from ._base import Extension, ParamSpec
from ._input import input_sensor_map, sensors_run, split_delay
from ._linear import ALL_KINDS, linear_parts


@dataclass(frozen=True)
class InputDelay(Extension):
    """Input time delay ``delay_s`` (s), fractional multiples of ``dt`` allowed.

    Examples
    --------
    >>> InputDelay().extension_names(Rig())
    ('delay_s',)
    """

    name = "input_delay"
    signatures = ("lag",)
    typical = (0.0123,)
    description = "pure time delay delay_s of the motor input (sub-sample, exact)"
    exact = True
    sensor_kinds = ALL_KINDS
    side = "input"
    input_stage = 4

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("delay_s", "s", (0.0, 0.03), 0.0,
                          "time between the commanded voltage and the motor force", 0.002),)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        n = rig.n_carts
        m, phi = split_delay(theta_ext[:, 0], dt)
        p = linear_parts(rig, theta_lin)
        # e^{A phi dt}, Gamma(phi dt) B and e^{A (1-phi) dt}, Gamma((1-phi) dt) B per lane
        A1, G1 = _blocks_variable_step(p.A, p.B, phi * dt)
        A2, G2 = _blocks_variable_step(p.A, p.B, (1.0 - phi) * dt)
        B1 = np.einsum("bij,bj->bi", A2, G1)
        out_map = None if outputs is None else input_sensor_map(p.A, p.B, outputs, n, phi)
        return sensors_run(A2 @ A1, B1, G2, u, x0, n, out_map, shift=m)


def _blocks_variable_step(A, B, steps):
    """``e^{A h_b}`` and ``Gamma(h_b) B`` for a per-lane step ``h_b`` (s, may be 0)."""
    Ah, G0 = zoh(A, B[..., None], steps)
    return Ah, G0[..., 0]
