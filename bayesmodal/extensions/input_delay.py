"""A pure time delay between the commanded voltage and the motor.

The motor sees ``v(t - D)`` (computation and communication latency of the controller).
With the commanded voltage held over each sample and ``D = (m + phi) dt``
(``m`` integer, ``0 <= phi < 1``), the input over ``[k dt, (k + 1) dt)`` is ``v[k-m-1]``
for the first ``phi dt`` and ``v[k-m]`` after, so the exact discrete model is::

    x[k+1] = e^{A dt} x[k] + B1 v[k-m-1] + B2 v[k-m],
    B1 = e^{A (1-phi) dt} Gamma(phi dt) B,   B2 = Gamma((1-phi) dt) B,
    Gamma(t) = int_0^t e^{A s} ds.

It is run as a linear recursion on the state ``(x, v[k-m-1])`` with each parameter set's
input shifted by its own ``m``.  ``delay_s = 0`` gives the linear model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._nl_kernels import run_per_lane
from ..system import Rig
from ._base import Extension, ParamSpec, zoh_blocks
from ._linear import linear_parts


@dataclass(frozen=True)
class InputDelay(Extension):
    """Input time delay ``delay_s`` (s), fractional multiples of ``dt`` allowed.

    Examples
    --------
    >>> InputDelay().extension_names(Rig())
    ('delay_s',)
    """

    name = "input_delay"
    description = "pure time delay delay_s of the motor input (sub-sample, exact)"
    exact = True

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        return (ParamSpec("delay_s", "s", (0.0, 0.03), 0.0,
                          "time between the commanded voltage and the motor force", 0.002),)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0):
        n = rig.n_carts
        s = 2 * n
        nb = theta_lin.shape[0]
        delay = theta_ext[:, 0] / dt
        m = np.floor(delay + 1e-12).astype(int)
        phi = np.clip(delay - m, 0.0, 1.0)
        p = linear_parts(rig, theta_lin)
        # e^{A phi dt}, Gamma(phi dt) B and e^{A (1-phi) dt}, Gamma((1-phi) dt) B per lane
        A1, G1 = _blocks_variable_step(p.A, p.B, phi * dt)
        A2, G2 = _blocks_variable_step(p.A, p.B, (1.0 - phi) * dt)
        Ad = np.zeros((nb, s + 1, s + 1))
        Ad[:, :s, :s] = A2 @ A1
        Ad[:, :s, s] = np.einsum("bij,bj->bi", A2, G1)
        Bd = np.zeros((nb, s + 1))
        Bd[:, :s] = G2
        Bd[:, s] = 1.0
        N = u.size
        U = np.zeros((nb, N))
        for i in range(nb):
            if m[i] < N:
                U[i, m[i]:] = u[: N - m[i]]
        z0 = np.zeros((nb, s + 1))
        z0[:, :s] = x0
        return run_per_lane(Ad, Bd, U, z0, n)


def _blocks_variable_step(A, B, steps):
    """``e^{A h_b}`` and ``Gamma(h_b) B`` for a per-lane step ``h_b`` (s, may be 0)."""
    nb, s, _ = A.shape
    out_A = np.empty_like(A)
    out_G = np.empty((nb, s))
    # scale A and B by the per-lane step and reuse the unit-step block exponential
    Ah, G0 = zoh_blocks(A * steps[:, None, None], (B * steps[:, None])[..., None], 1.0)
    out_A[:] = Ah
    out_G[:] = G0[..., 0]
    return out_A, out_G
