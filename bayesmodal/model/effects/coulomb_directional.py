"""Coulomb friction whose kinetic level depends on the direction of sliding.

Physics: a cart sliding forwards (``x_i' > 0``) feels ``-Fcp_i`` and one sliding backwards
feels ``+Fcn_i`` (rail wear, a tilted track or a bearing preload make the two differ),
with stick-slip as in ``extensions.coulomb``: a stuck cart stays while its net force is
below the static level ``Fs_i >= max(Fcp_i, Fcn_i)`` and breaks away along the force.

Numerics: the stick-slip kernel of ``extensions.coulomb`` compiled with the level chosen
by direction wherever friction acts: the held force, the break-away, and the reversal
correction ``dv = (Fcp_i + Fcn_i) dir tau / m_i`` (``bayesmodal.model.kernels.coulomb_run``
with ``Fc_backward``).  ``Fcp_i = Fcn_i`` is ``coulomb_friction``; all zero is the linear
model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import coulomb_run, zoh
from ..system import Rig
from ._base import EffectLocation, ParamSpec, cart_numbers
from ._linear import linear_parts
from .coulomb import CoulombFriction, _per_cart, cart_location


@dataclass(frozen=True)
class DirectionalCoulombFriction(CoulombFriction):
    """Per-cart kinetic levels ``Fcp_i`` (forwards), ``Fcn_i`` (backwards) and static
    ``Fs_i`` (N).  Settings ``n_sub`` and ``adaptive`` as for ``CoulombFriction``.

    Examples
    --------
    >>> DirectionalCoulombFriction().extension_names(Rig())[:4]
    ('Fcp1', 'Fcp2', 'Fcp3', 'Fcn1')
    """

    name = "coulomb_directional"
    signatures = ()  # a refinement of coulomb_friction, tried after it
    typical = (0.1, 0.15, 0.08, 0.05, 0.2, 0.12, 0.15, 0.2, 0.12)
    description = "per-cart Coulomb friction, level by direction of sliding, with stick-slip"
    #: ``_simulate`` takes ``input_stages`` (memoryless input effects applied in the
    #: kernel, ``kernels.coulomb.INPUT_STAGES``; used by ``Combined``)
    fuses_input_stages = True
    #: the end stop's force enters this kernel as a voltage on the driven cart, so a
    #: combination with it needs one input for all lanes (``Combined``)
    stop_needs_shared_input = True
    validity_rule = "linear part admissible, 0 <= Fcp_i, Fcn_i <= Fs_i, finite"

    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        fwd = tuple(ParamSpec(f"Fcp{i}", "N", (0.0, 2.0), 0.0,
                              f"kinetic friction on cart {i} sliding forwards (x' > 0)", 0.1)
                    for i in cart_numbers(rig))
        bwd = tuple(ParamSpec(f"Fcn{i}", "N", (0.0, 2.0), 0.0,
                              f"kinetic friction on cart {i} sliding backwards (x' < 0)",
                              0.1)
                    for i in cart_numbers(rig))
        static = tuple(ParamSpec(f"Fs{i}", "N", (0.0, 3.0), 0.0,
                                 f"static friction of cart {i}, >= Fcp{i}, Fcn{i}",
                                 0.1)
                       for i in cart_numbers(rig))
        return fwd + bwd + static

    def _valid_extension(self, rig, theta_lin, theta_ext):
        n = rig.n_carts
        fp, fn, fs = theta_ext[..., :n], theta_ext[..., n : 2 * n], theta_ext[..., 2 * n :]
        ok = (fp >= 0) & (fn >= 0) & (fs >= fp) & (fs >= fn)
        return np.all(np.isfinite(theta_ext), axis=-1) & np.all(ok, axis=-1)

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, input_stages=(), stop=None,
                  outputs=None):
        parts = linear_parts(rig, theta_lin)
        h = dt / self.n_sub
        Ah, Fh, Rh = zoh(parts.A, parts.force_inputs, h, ramp=True)
        Ad, Fd, Rd = zoh(parts.A, parts.force_inputs, dt, ramp=True)
        Bh, Bd = (np.einsum("bij,bj->bi", F, parts.b) for F in (Fh, Fd))
        fwd, bwd, static = _per_cart(rig, theta_ext, 3)
        return coulomb_run(
            Ah, Bh, Fh, Rh, Ad, Bd, Fd, Rd, parts.net_force, parts.b, parts.inv_mass,
            fwd, static, u, int(self.n_sub), h, x0, adaptive=self.adaptive,
            Fc_backward=bwd, input_stages=input_stages,
            stop=stop, outputs=outputs,
        )

    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """The cart with the largest static friction ``Fs_i``."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        fs = self.split(rig, theta)[1][2 * rig.n_carts :]
        return cart_location(rig, fs)

    # optimise (Fcp, Fcn, Fs - max(Fcp, Fcn)) >= 0 so that box bounds keep Fs admissible
    def to_opt(self, rig, theta_ext):
        n = rig.n_carts
        w = np.array(theta_ext, dtype=float)
        w[..., 2 * n :] -= np.maximum(w[..., :n], w[..., n : 2 * n])
        return w

    def from_opt(self, rig, w):
        n = rig.n_carts
        th = np.array(w, dtype=float)
        th[..., 2 * n :] += np.maximum(th[..., :n], th[..., n : 2 * n])
        return th

    def start_grid(self, rig: Rig) -> np.ndarray:
        """Equal and unequal levels on all carts, ``Fs = 1.5 max(Fcp, Fcn)``."""
        n = rig.n_carts
        grid = [np.zeros(3 * n)]
        for fc in (0.05, 0.1, 0.2, 0.4):
            for fp, fn in ((fc, fc), (fc, 0.5 * fc), (0.5 * fc, fc)):
                grid.append(np.r_[np.full(n, fp), np.full(n, fn), np.full(n, 1.5 * fc)])
        return np.array(grid)
