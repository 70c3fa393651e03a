"""LuGre friction on every cart: pre-sliding bristles, Stribeck effect, smooth in its parameters.

Physics: each cart rests on elastic bristles whose mean deflection ``z_i`` grows with the
sliding velocity and relaxes towards the steady level ``g_i(v) / sigma0``, so that the
friction force rises as a stiff spring before sliding (pre-sliding) and falls from the
static to the Coulomb level as the cart speeds up (Stribeck)::

    z_i' = v_i - sigma0 |v_i| z_i / g_i(v_i),
    g_i(v) = Fc_i + (Fs_i - Fc_i) exp(-(v / v_stribeck)^2),
    f_i = -(sigma0 z_i + sigma1 z_i')        (friction force on cart i).

Unlike the stick-slip Coulomb model it has no switching, and the simulated positions are
continuous (indeed smooth away from ``v = 0``) in every parameter.  Viscous friction is the
linear model's ``c_i``.  The bristles start relaxed (``z = 0``).  ``Fc_i = Fs_i = 0`` gives
the linear model (``sigma0``, ``sigma1``, ``v_stribeck`` then do nothing).

Numerics: the linear rig is stepped exactly (ZOH over sub-steps ``dt / n_sub``) with the
friction force held at its mean over the sub-step, the bristle equation solved exactly
with the mid-step velocity frozen; second order (``bayesmodal.model.kernels.lugre``).  The
explicit coupling of the bristle spring to a cart needs ``sqrt(sigma0 / m_i) h`` well
below 1: at the prior's upper ``sigma0 = 1e5 N/m``, ``m = 1.1 kg`` and the default
``h = 1.25 ms`` it is 0.38.

Sensors: every kind (``Rig.output_kinds``).  A position or velocity is the cart's state
at the sample; an acceleration is ``M^-1`` times the forces at the sample: springs,
dampers (the viscous part), the input held from the sample (its feedthrough), and the
friction ``-(sigma0 z_i + sigma1 z_i')`` with the bristle rate of the equation above at
the sample's velocity and deflection (not the mean force the scheme holds over a
sub-step), and an end stop's force when combined with one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import lugre_run, zoh
from ..system import Rig
from ._base import EffectLocation, Extension, ParamSpec, cart_numbers
from ._linear import ALL_KINDS, acceleration_columns, linear_parts, sensor_map
from .coulomb import _per_cart, cart_location


@dataclass(frozen=True)
class LuGreFriction(Extension):
    """LuGre friction: per-cart ``Fc_i``, ``Fs_i`` (N), shared ``sigma0`` (N/m),
    ``sigma1`` (N s/m) and ``v_stribeck`` (m/s).

    Parameters
    ----------
    n_sub : int
        Sub-steps per sample interval (default 4: ``h = 1.25 ms`` at ``dt = 5 ms``).  The
        error is second order in ``h``: 1.3 encoder counts at the default on pulses and a
        held step, 0.35 with 8 sub-steps (0.6 at the prior's stiffest bristles);
        ``tests/test_effects_new.py`` checks it against an independent stiff ODE solution
        within the step-doubling error estimate.  The default was 8 until 25 Nov 2026: on
        the four measured records the log-likelihood at 8 sub-steps minus that at 4 is
        3.7 +- 4.7 nats over posterior draws (the records' residuals are hundreds of
        counts), at half the cost (docs/discrepancy.md, "A posterior that converges").

    Examples
    --------
    >>> LuGreFriction().extension_names(Rig())[-3:]
    ('sigma0', 'sigma1', 'v_stribeck')
    """

    n_sub: int = 4

    #: ``_simulate`` takes ``input_stages`` (memoryless input effects applied in the
    #: kernel, ``kernels.coulomb.INPUT_STAGES``; used by ``Combined``)
    fuses_input_stages = True
    sensor_kinds = ALL_KINDS

    name = "lugre_friction"
    default_candidate = False
    revision = "n_sub=4"
    typical = (0.1, 0.15, 0.08, 0.15, 0.2, 0.12, 2e4, 100.0, 0.005)
    description = "LuGre friction per cart (bristles: pre-sliding, Stribeck; smooth)"
    exact = False
    validity_rule = ("linear part admissible, 0 <= Fc_i <= Fs_i, sigma0 > 0, sigma1 >= 0, "
                     "v_stribeck > 0, finite")

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        kinetic = tuple(
            ParamSpec(f"Fc{i}", "N", (0.0, 2.0), 0.0,
                      f"Coulomb friction force on cart {i} sliding fast", 0.1)
            for i in cart_numbers(rig))
        static = tuple(
            ParamSpec(f"Fs{i}", "N", (0.0, 3.0), 0.0,
                      f"static friction level of cart {i} (v -> 0), >= Fc{i}", 0.1)
            for i in cart_numbers(rig))
        return kinetic + static + (
            ParamSpec("sigma0", "N/m", (1e3, 1e5), 2e4,
                      "bristle stiffness: slope of friction against pre-sliding travel", 5e3),
            ParamSpec("sigma1", "N s/m", (0.0, 300.0), 100.0,
                      "bristle damping (micro-damping of pre-sliding motion)", 20.0),
            ParamSpec("v_stribeck", "m/s", (1e-4, 0.05), 0.005,
                      "speed over which friction falls from the static to the Coulomb level",
                      1e-3),
        )

    def _valid_extension(self, rig, theta_lin, theta_ext):
        n = rig.n_carts
        fc, fs = theta_ext[..., :n], theta_ext[..., n : 2 * n]
        s0, s1, vs = (theta_ext[..., 2 * n + j] for j in range(3))
        return (np.all(np.isfinite(theta_ext), axis=-1)
                & np.all((fc >= 0) & (fs >= fc), axis=-1) & (s0 > 0) & (s1 >= 0) & (vs > 0))

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, input_stages=(), stop=None,
                  outputs=None):
        n = rig.n_carts
        parts = linear_parts(rig, theta_lin)
        h = dt / self.n_sub
        Ah, Fh = zoh(parts.A, parts.force_inputs, h)
        Bh = np.einsum("bij,bj->bi", Fh, parts.b)  # the motor is a force on the carts
        e = theta_ext
        fc, fs = _per_cart(rig, e, 2)
        extra = {} if outputs is None else {
            "outputs": outputs, "columns": acceleration_columns(rig, outputs),
            "out_map": sensor_map(parts.A, parts.B, outputs, n, parts.force_inputs)}
        return lugre_run(Ah, Bh, Fh, parts.net_force, parts.b, parts.inv_mass, fc,
                         fs, e[:, 2 * n], e[:, 2 * n + 1], e[:, 2 * n + 2], u,
                         int(self.n_sub), h, x0, input_stages=input_stages,
                         stop=stop, **extra)

    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """The cart with the largest static level ``Fs_i``."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        n = rig.n_carts
        fs = self.split(rig, theta)[1][n : 2 * n]
        return cart_location(rig, fs)

    # optimise (Fc, Fs - Fc) >= 0 so that the box bounds keep Fs >= Fc
    def to_opt(self, rig, theta_ext):
        n = rig.n_carts
        w = np.array(theta_ext, dtype=float)
        w[..., n : 2 * n] = w[..., n : 2 * n] - w[..., :n]
        return w

    def from_opt(self, rig, w):
        n = rig.n_carts
        th = np.array(w, dtype=float)
        th[..., n : 2 * n] = th[..., n : 2 * n] + th[..., :n]
        return th

    def opt_bounds(self, rig):
        n = rig.n_carts
        lo = np.r_[np.zeros(2 * n), 1e2, 0.0, 1e-5]
        return lo, np.full(2 * n + 3, np.inf)

    #: Stribeck bumps the posterior-mode search also starts from: (v_stribeck m/s, excess
    #: Fs_i - Fc_i in N), typical of small carts on rails (docs/discrepancy.md).
    STRIBECK_STARTS = ((1e-3, 0.5), (3e-3, 0.3))

    def mode_starts(self, rig: Rig, theta_ext: np.ndarray) -> np.ndarray:
        """The fit with a Stribeck bump on every cart (``STRIBECK_STARTS``).

        On the face ``Fs_i = Fc_i`` the Stribeck speed does nothing, so a local search from
        a fit that ends there (least squares of the four measured records does) cannot
        find the static levels the posterior wants: 300 nats above the face on the four
        records, at ``v_stribeck`` about 1.5 mm/s.
        """
        n = rig.n_carts
        theta_ext = np.asarray(theta_ext, dtype=float)
        rows = []
        for vs, excess in self.STRIBECK_STARTS:
            r = theta_ext.copy()
            r[n : 2 * n] = r[:n] + excess
            r[2 * n + 2] = vs
            rows.append(r)
        return np.array(rows)

    def start_grid(self, rig: Rig) -> np.ndarray:
        """Equal levels on all carts (``Fc`` 0..0.8 N, ``Fs = 1.5 Fc``), bristles at their
        typical values."""
        n = rig.n_carts
        tail = [2e4, 100.0, 0.005]
        grid = [np.r_[np.zeros(2 * n), tail]]
        for fc in (0.05, 0.1, 0.2, 0.4, 0.8):
            grid.append(np.r_[np.full(n, fc), np.full(n, 1.5 * fc), tail])
        return np.array(grid)
