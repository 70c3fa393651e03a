"""Can any record identify the rig's unknown parameters?  A check before fitting.

A rig description can leave a direction in parameter space along which the motion at
the sensors does not change at all, whatever the record: scaling every mass, damper and
the gain together while an unknown spring in parallel with a known one absorbs the
change (a spring to the frame and one to a clamped cart act on the same cart), or
``ca`` and ``cb`` on a single cart, where ``C = ca m + cb k`` is one damper.  A fit then
returns one point of a line of equally good answers (a simulated record with ``g_v =
6.2``: ``g_v = 4.0 +- 10``, the fit 99.97 %); it is refused here, before any fitting,
with the parameters that move together and what to fix.

The test is the rank of the sensitivity of what the records can show to the unknown
parameters, at a generic point (the fit's default start, each parameter moved by a fixed
pseudo-random factor within +-20 %, so that no symmetry of round nominal values hides or
fakes a direction).  A record driven from rest shows the transfer function
``G(s) = C_out (M s^2 + C s + K)^-1 b``; a record whose initial state is estimated also
shows its free response ``C_out Z^-1 (M (s x0 + v0) + C x0)``, with ``x0, v0`` unknowns of
their own.  Both are evaluated at ``2 n_states + 2`` complex frequencies spread over the
rig's band, at 100 degrees from the real axis (away from every pole).  ``M, C, K, b``
are affine in each parameter alone, so one difference per parameter gives its
derivative exactly (up to rounding).  The columns (derivatives times the parameter:
relative sensitivities) are scaled to unit norm, and a singular value below
``RANK_TOL`` of the largest is a direction the records cannot see: structurally it is
zero to rounding (1e-16 measured), while the preset rigs' smallest is above 0.1.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ._errors import ModelError
from .model.system import default_start, param_kinds

__all__ = ["RANK_TOL", "Structure", "check_structure", "structure"]

#: Relative singular value below which a direction is not identified.
RANK_TOL = 1e-9

#: Seed of the generic point.
_SEED = 38


@dataclass(frozen=True)
class Structure:
    """The structural rank of a model's unknown parameters.

    Attributes
    ----------
    rank : int
        Number of independent directions the records can see.
    n_params : int
        Number of unknown parameters (and estimated initial states).
    singular_values : ndarray
        Of the column-scaled sensitivity, relative to the largest, largest first.
    together : tuple of str
        The model parameters of the unseen direction (a relative change, or an effect, of
        at least a tenth of its largest); empty when identified.
    """

    rank: int
    n_params: int
    singular_values: np.ndarray
    together: tuple[str, ...]

    @property
    def identified(self) -> bool:
        """True when every direction is seen."""
        return self.rank == self.n_params


def _generic_point(model) -> np.ndarray:
    u = np.random.default_rng(_SEED).uniform(-1.0, 1.0, model.n_params)
    start = default_start(model)
    return np.where(start > 0, start, 1e-3) * np.exp(0.2 * u)


def structure(model, *, forced: bool = True, free_records: int = 0) -> Structure:
    """Structural rank of ``model``'s unknown parameters.

    Parameters
    ----------
    model : LinearModel
    forced : bool
        Some record is driven (its transfer function is seen).
    free_records : int
        Records whose initial state is estimated (each adds its free response and its
        own initial positions and velocities as unknowns).

    Returns
    -------
    Structure

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> structure(LinearModel(Rig(), "free")).identified
    True
    """
    theta = _generic_point(model)
    p = theta.size
    n = model.n_carts
    M, C, K, b = model.matrices(theta)
    derivs = []
    for i in range(p):
        step = theta.copy()
        step[i] += theta[i]
        derivs.append([(a - a0) / theta[i] for a, a0 in zip(model.matrices(step),
                                                             (M, C, K, b), strict=True)])
    cout = model.rig.output_matrix()
    w2 = np.linalg.eigvals(np.linalg.solve(M, K)).real
    band = np.geomspace(0.3 * np.sqrt(w2.min()), 3.0 * np.sqrt(w2.max()), 4 * n + 2)
    rng = np.random.default_rng(_SEED + 1)
    states = [rng.uniform(0.5, 1.5, 2 * n) * rng.choice([-1, 1], 2 * n)
              for _ in range(free_records)]
    n_x = 2 * n * free_records
    rows = []
    for w in band:
        s = w * np.exp(1j * np.deg2rad(100.0))
        z = M * s**2 + C * s + K
        blocks = []
        if forced:
            x = np.linalg.solve(z, b)
            cols = [theta[i] * (cout @ np.linalg.solve(
                z, d[3] - (d[0] * s**2 + d[1] * s + d[2]) @ x)) for i, d in enumerate(derivs)]
            blocks.append(np.column_stack(cols + [np.zeros((cout.shape[0], n_x))]))
        for r, st in enumerate(states):
            x0, v0 = st[:n], st[n:]
            f = M @ (s * x0 + v0) + C @ x0
            x = np.linalg.solve(z, f)
            cols = [theta[i] * (cout @ np.linalg.solve(
                z, d[0] @ (s * x0 + v0) + d[1] @ x0 - (d[0] * s**2 + d[1] * s + d[2]) @ x))
                for i, d in enumerate(derivs)]
            own = np.zeros((cout.shape[0], n_x), complex)
            own[:, 2 * n * r: 2 * n * r + n] = cout @ np.linalg.solve(z, M * s + C)
            own[:, 2 * n * r + n: 2 * n * (r + 1)] = cout @ np.linalg.solve(z, M)
            blocks.append(np.column_stack(cols + [own]))
        for blk in blocks:
            scale = np.linalg.norm(blk)
            rows += [blk.real / scale, blk.imag / scale]
    jac = np.vstack(rows)
    norms = np.linalg.norm(jac, axis=0)
    _, sv, vt = np.linalg.svd(jac / np.where(norms > 0, norms, 1.0))
    rel = sv / sv[0]
    rank = int(np.sum(rel > RANK_TOL))
    together: tuple[str, ...] = ()
    if rank < jac.shape[1]:
        # the unseen direction, in relative changes of the parameters (the scaling
        # undone) and in their effects (as scaled): a parameter large in either moves
        v_rel = np.abs(vt[-1] / np.where(norms > 0, norms, 1.0))[:p]
        v_eff = np.abs(vt[-1])[:p]
        big = np.zeros(p, bool)
        for v in (v_rel, v_eff):
            if v.max() > 0:
                big |= v >= 0.1 * v.max()
        together = tuple(name for name, b in zip(model.names, big, strict=True) if b)
    return Structure(rank, jac.shape[1], rel, together)


@functools.lru_cache(maxsize=64)
def _cached(model, forced: bool, free_records: int) -> Structure:
    # every least-squares fit asks (the diagnosis refits many times): once per layout
    return structure(model, forced=forced, free_records=free_records)


def check_structure(model, experiments: Sequence, initial_state: str = "rest") -> None:
    """Refuse a model whose unknown parameters no record of this kind can identify.

    Parameters
    ----------
    model : LinearModel
    experiments : sequence of Experiment
        The records (which are driven decides what they can show).
    initial_state : {"rest", "estimate"}

    Raises
    ------
    ModelError
        One line naming the parameters that can change together without changing the
        motion at the sensors, and what to make known.
    """

    forced = any(np.any(e.v_volt != 0) for e in experiments)
    free = min(len(experiments), 3) if initial_state == "estimate" else 0
    st = _cached(model, forced, free)
    if st.identified:
        return
    names = st.together or model.names
    kinds = {k for n, k in zip(model.names, param_kinds(model), strict=True) if n in names}
    if kinds & {"gain", "mass", "spring"}:
        fix = ("make one of them known in the rig (a mass: mass = \"known\" and mass_kg; a "
               "spring: known = true; the gain: gain_n_v, from `bayesmodal static`; "
               "docs/rigs.md)")
    elif set(names) <= {"ca", "cb"}:
        fix = ("C = ca M + cb K gives each mode a damping that ca and cb cannot both fix "
               "here; use free damping (--damping free)")
    else:
        fix = "drop one of these dampers from the rig's [dampers] list (docs/rigs.md)"
    raise ModelError(f"the rig's unknowns cannot be identified from any record: "
                     f"{', '.join(names)} can change together without changing the motion "
                     f"at the sensors (structural rank {st.rank} of {st.n_params}); {fix}")
