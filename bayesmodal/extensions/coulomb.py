"""Coulomb friction with stick-slip on every cart.

Each cart ``i`` feels a dry friction force with a kinetic (Coulomb) level ``Fc_i`` and a
static (break-away) level ``Fs_i >= Fc_i``:

- sliding (``x_i' != 0``): ``f_i = -Fc_i sign(x_i')``;
- stuck (``x_i' = 0``): the friction holds the cart, ``f_i = -F_i``, as long as the net
  non-friction force ``F_i = b_i v - (K x)_i - (C x')_i`` stays below ``Fs_i`` in size;
  above it the cart breaks away in the direction of ``F_i``.

A sliding cart whose velocity reaches zero sticks when ``|F_i| < Fs_i`` there, and
otherwise reverses.  This is the stick the rig shows after every pulse: the carts stop
abruptly a few tens of encoder counts away from their equilibrium.

Numerics: exact ZOH of the linear rig over sub-steps ``h = dt / n_sub`` with the friction
forces as held inputs, events inside a sub-step located on cubic Hermite interpolants and
corrected (see ``bayesmodal._nl_kernels.coulomb_run``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._nl_kernels import coulomb_run, zoh
from ..system import Rig
from ._base import EffectLocation, Extension, ParamSpec
from ._linear import linear_parts


@dataclass(frozen=True)
class CoulombFriction(Extension):
    """Per-cart Coulomb friction ``Fc_i`` (N) with static level ``Fs_i >= Fc_i`` (N).

    Parameters
    ----------
    n_sub : int
        Sub-steps per sample interval.  The default 4 keeps the error against the
        event-driven reference below 0.1 encoder count on the measured impulse input
        across the friction posterior, including its high-static-friction region (Fs1
        about 1.4 N), where one sub-step is off by 450 counts (a stick decision flips)
        and two by 2 counts; one sub-step is accurate only for small static levels.

    Examples
    --------
    >>> ext = CoulombFriction()
    >>> ext.extension_names(Rig())
    ('Fc1', 'Fc2', 'Fc3', 'Fs1', 'Fs2', 'Fs3')
    """

    n_sub: int = 4

    name = "coulomb_friction"
    description = "per-cart Coulomb friction with stick-slip (static level Fs >= Fc)"
    exact = False
    validity_rule = "linear part admissible, 0 <= Fc_i <= Fs_i, finite"

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        n = rig.n_carts
        kinetic = tuple(
            ParamSpec(f"Fc{i + 1}", "N", (0.0, 2.0), 0.0,
                      f"kinetic (Coulomb) friction force on sliding cart {i + 1}", 0.1)
            for i in range(n)
        )
        static = tuple(
            ParamSpec(f"Fs{i + 1}", "N", (0.0, 3.0), 0.0,
                      f"static friction (break-away force) of cart {i + 1}, >= Fc{i + 1}", 0.1)
            for i in range(n)
        )
        return kinetic + static

    def _valid_extension(self, rig, theta_lin, theta_ext):
        n = rig.n_carts
        fc, fs = theta_ext[..., :n], theta_ext[..., n:]
        return np.all(np.isfinite(theta_ext), axis=-1) & np.all((fc >= 0) & (fs >= fc), axis=-1)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0):
        n = rig.n_carts
        parts = linear_parts(rig, theta_lin)
        h = dt / self.n_sub
        Ah, Fh = zoh(parts.A, parts.force_inputs, h)
        Bh = np.einsum("bij,bj->bi", Fh, parts.b)  # the motor is a force on the carts
        return coulomb_run(
            Ah, Bh, Fh, parts.net_force, parts.b, parts.inv_mass,
            theta_ext[:, :n], theta_ext[:, n:], u, int(self.n_sub), h, x0,
        )

    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """The cart with the largest static friction ``Fs_i``."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        fs = self.split(rig, theta)[1][rig.n_carts :]
        i = int(np.argmax(fs))
        return EffectLocation("cart", i, f"cart {i + 1}", fs.copy())

    # optimise (Fc, Fs - Fc) >= 0 so that the box bounds keep Fs >= Fc
    def to_opt(self, rig, theta_ext):
        n = rig.n_carts
        w = np.array(theta_ext, dtype=float)
        w[..., n:] = w[..., n:] - w[..., :n]
        return w

    def from_opt(self, rig, w):
        n = rig.n_carts
        th = np.array(w, dtype=float)
        th[..., n:] = th[..., n:] + th[..., :n]
        return th

    def start_grid(self, rig: Rig) -> np.ndarray:
        """Equal levels on all carts: ``Fc`` in 0..0.8 N, ``Fs = Fc`` or ``1.5 Fc``."""
        n = rig.n_carts
        grid = [np.zeros(2 * n)]
        for fc in (0.05, 0.1, 0.2, 0.4, 0.8):
            for ratio in (1.0, 1.5):
                grid.append(np.r_[np.full(n, fc), np.full(n, ratio * fc)])
        return np.array(grid)
