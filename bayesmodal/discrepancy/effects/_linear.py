"""Shared pieces of the extension simulators: the linear rig's matrices for a batch."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...system import LinearModel, Rig


@dataclass(frozen=True)
class LinearParts:
    """Matrices of the free-damping linear model for a batch of parameter sets.

    Attributes
    ----------
    M, C, K : ndarray, shape (nb, n, n)
        Mass (kg), damping (N s/m) and stiffness (N/m) matrices.
    b : ndarray, shape (nb, n)
        Motor force per volt at each cart, N/V.
    A : ndarray, shape (nb, 2n, 2n)
        State matrix for ``(x, x')``.
    B : ndarray, shape (nb, 2n)
        Input vector, m/(V s^2) in the acceleration block.
    force_inputs : ndarray, shape (nb, 2n, n)
        ``[0; M^-1]``: how a force on each cart enters the state equation.
    net_force : ndarray, shape (nb, n, 2n)
        ``[-K, -C]``: spring and damper force on each cart from the state, N.
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    b: np.ndarray
    A: np.ndarray
    B: np.ndarray
    force_inputs: np.ndarray
    net_force: np.ndarray

    @property
    def inv_mass(self) -> np.ndarray:
        """``1 / m_i``, shape (nb, n), 1/kg."""
        return 1.0 / np.diagonal(self.M, axis1=-2, axis2=-1)


def linear_parts(rig: Rig, theta_lin: np.ndarray) -> LinearParts:
    """Matrices of ``LinearModel(rig, "free")`` for ``theta_lin`` of shape (nb, n_lin)."""
    model = LinearModel(rig, "free")
    M, C, K, b = model.matrices(theta_lin)
    A, B = model.state_space(theta_lin)
    n = rig.n_carts
    nb = theta_lin.shape[0]
    inv_m = 1.0 / np.diagonal(M, axis1=-2, axis2=-1)
    F = np.zeros((nb, 2 * n, n))
    F[:, n:, :] = inv_m[:, :, None] * np.eye(n)
    G = np.concatenate([-K, -C], axis=-1)
    return LinearParts(M, C, K, b, A, B, F, np.ascontiguousarray(G))
