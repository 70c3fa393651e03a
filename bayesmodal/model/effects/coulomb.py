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

Numerics: exact ZOH of the linear rig over a sample with the friction forces as held
inputs; samples with an event are taken again in sub-steps ``h = dt / n_sub`` with the
events located on cubic Hermite interpolants and corrected (see
``bayesmodal.model.kernels.coulomb_run``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import coulomb_run, zoh
from ..system import Rig
from ._base import EffectLocation, Extension, ParamSpec, cart_numbers
from ._linear import ALL_KINDS, kernel_order, linear_parts, to_kernel


def _per_cart(rig: Rig, theta_ext: np.ndarray, k: int) -> list[np.ndarray]:
    """The first ``k`` per-cart blocks of ``theta_ext`` (nb, >= k n), each (nb, n) in the
    kernels' order of the carts."""
    n = rig.n_carts
    order = kernel_order(rig)
    return [np.ascontiguousarray(to_kernel(order, theta_ext[:, j * n : (j + 1) * n]))
            for j in range(k)]


def cart_location(rig: Rig, strength: np.ndarray) -> EffectLocation:
    """The cart with the largest ``strength`` (n,), labelled with its number."""
    i = int(np.argmax(strength))
    return EffectLocation("cart", i, f"cart {cart_numbers(rig)[i]}", strength.copy())


@dataclass(frozen=True)
class CoulombFriction(Extension):
    """Per-cart Coulomb friction ``Fc_i`` (N) with static level ``Fs_i >= Fc_i`` (N).

    Parameters
    ----------
    n_sub : int
        Sub-steps per sample interval where a cart sticks, breaks away or reverses (the
        other samples are exact in one step).  With the default 4 the error against the
        event-driven reference stays below 0.5 encoder count (median 0.013) over 20
        random draws of friction levels up to 1.6 N on the measured impulse, step and
        fast-sweep inputs, and is 0.014 count at a draw of the friction posterior with a
        high static level on cart 1; with 2 it reaches 2.3 counts on the fast sweep, and
        one sub-step is hundreds of counts off there.
    adaptive : bool
        False: every sample in ``n_sub`` sub-steps with event corrections (two to four
        times slower; the same results to a few hundredths of a count).

    Examples
    --------
    >>> ext = CoulombFriction()
    >>> ext.extension_names(Rig())
    ('Fc1', 'Fc2', 'Fc3', 'Fs1', 'Fs2', 'Fs3')
    """

    n_sub: int = 4
    adaptive: bool = True

    name = "coulomb_friction"
    signatures = ("friction", "stick", "decay", "consistency", "amplitude_damping")
    typical = (0.1, 0.15, 0.08, 0.15, 0.2, 0.12)
    #: the stick-slip posterior has spikes 25-30 nats above its bulk (R-hat 1.8 after
    #: 15 000 steps on the measured records); LuGre's levels Fc, Fs are the same forces
    #: with a continuous likelihood (runs/records_friction.toml)
    sampled_as = "lugre_friction"
    description = "per-cart Coulomb friction with stick-slip (static level Fs >= Fc)"
    exact = False
    #: ``_simulate`` takes ``input_stages`` (memoryless input effects applied in the
    #: kernel, ``kernels.coulomb.INPUT_STAGES``; used by ``Combined``)
    fuses_input_stages = True
    #: the end stop's force enters this kernel as a voltage on the driven cart, so a
    #: combination with it needs one input for all lanes (``Combined``)
    stop_needs_shared_input = True
    validity_rule = "linear part admissible, 0 <= Fc_i <= Fs_i, finite"
    #: every sensor kind read in the kernel at the sample (``kernels.coulomb_run``)
    sensor_kinds = ALL_KINDS
    #: a held cart's acceleration is 0 whatever the input: ``Combined`` adds no input
    #: feedthrough to an acceleration the kernel read as exactly 0
    holds_carts = True

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        carts = cart_numbers(rig)
        kinetic = tuple(
            ParamSpec(f"Fc{i}", "N", (0.0, 2.0), 0.0,
                      f"kinetic (Coulomb) friction force on sliding cart {i}", 0.1)
            for i in carts
        )
        static = tuple(
            ParamSpec(f"Fs{i}", "N", (0.0, 3.0), 0.0,
                      f"static friction (break-away force) of cart {i}, >= Fc{i}", 0.1)
            for i in carts
        )
        return kinetic + static

    def _valid_extension(self, rig, theta_lin, theta_ext):
        n = rig.n_carts
        fc, fs = theta_ext[..., :n], theta_ext[..., n:]
        return np.all(np.isfinite(theta_ext), axis=-1) & np.all((fc >= 0) & (fs >= fc), axis=-1)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, input_stages=(), stop=None,
                  outputs=None):
        parts = linear_parts(rig, theta_lin)
        h = dt / self.n_sub
        Ah, Fh, Rh = zoh(parts.A, parts.force_inputs, h, ramp=True)
        Ad, Fd, Rd = zoh(parts.A, parts.force_inputs, dt, ramp=True)
        # the motor is a force on the carts
        Bh, Bd = (np.einsum("bij,bj->bi", F, parts.b) for F in (Fh, Fd))
        return coulomb_run(
            Ah, Bh, Fh, Rh, Ad, Bd, Fd, Rd, parts.net_force, parts.b, parts.inv_mass,
            *_per_cart(rig, theta_ext, 2), u, int(self.n_sub), h, x0,
            adaptive=self.adaptive, input_stages=input_stages, stop=stop,
            outputs=outputs,
        )

    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """The cart with the largest static friction ``Fs_i``."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        fs = self.split(rig, theta)[1][rig.n_carts :]
        return cart_location(rig, fs)

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
