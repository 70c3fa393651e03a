"""The rig model: a chain of carts joined by springs, driven at cart 1.

Spring ``i`` joins cart ``i`` and cart ``i + 1``; the last spring joins cart ``n`` to the
frame.  For three carts with ``k = (k1, k2, k3)`` the equations of motion are (report eq. 3,
with errata 1 and 2)::

    m1 x1'' = k1 (x2 - x1) + c12 (x2' - x1') - c1 x1' + g_v v
    m2 x2'' = k1 (x1 - x2) + k2 (x3 - x2) + c12 (x1' - x2') + c23 (x3' - x2') - c2 x2'
    m3 x3'' = k2 (x2 - x3) + c23 (x2' - x3') - c3 x3' - k3 x3

so that ``M x'' + C x' + K x = b v`` with ``K[n-1, n-1] = k_{n-1} + k_n`` and
``b = (g_v, 0, ..., 0)``.  The state is ``(x, x')`` and

    A = [[0, I], [-M^-1 K, -M^-1 C]],   B = [0; M^-1 b].

Two damping models are supported: ``"free"`` (absolute dampers ``c1..cn`` to the frame and
relative dampers ``c12, c23, ...`` between neighbours) and ``"proportional"``
(``C = ca M + cb K``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._errors import ModelError

__all__ = ["Rig", "LinearModel", "DAMPING_MODELS", "ECP210_SPRINGS_N_M"]

#: Nominal springs of the ECP Model 210 three-cart rig, N/m (report Table 1).
ECP210_SPRINGS_N_M = (774.0, 770.0, 396.0)

DAMPING_MODELS = ("free", "proportional")


def _pair_name(i: int, n: int) -> str:
    # 1-based indices of the relative damper between cart i and cart i+1
    return f"c{i}{i + 1}" if n < 10 else f"c{i}_{i + 1}"


@dataclass(frozen=True)
class Rig:
    """Geometry and known stiffnesses of a chain of carts.

    Parameters
    ----------
    springs_n_m : tuple of float, length n_carts
        Spring stiffnesses, N/m.  Spring ``i`` joins cart ``i`` and ``i + 1``; the last one
        joins the last cart to the frame.

    Examples
    --------
    >>> rig = Rig()
    >>> rig.n_carts
    3
    >>> rig.stiffness_matrix()[2, 2]
    1166.0
    """

    springs_n_m: tuple[float, ...] = ECP210_SPRINGS_N_M

    def __post_init__(self) -> None:
        k = np.asarray(self.springs_n_m, dtype=float)
        if k.ndim != 1 or k.size < 1:
            raise ModelError(
                f"springs_n_m must be a non-empty 1-D sequence, got {self.springs_n_m!r}"
            )
        if not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise ModelError(f"every spring stiffness must be finite and > 0 N/m, got {k.tolist()}")
        object.__setattr__(self, "springs_n_m", tuple(float(x) for x in k))

    @property
    def n_carts(self) -> int:
        """Number of carts (degrees of freedom)."""
        return len(self.springs_n_m)

    def stiffness_matrix(self) -> np.ndarray:
        """Stiffness matrix K, shape (n, n), N/m."""
        return chain_matrix(np.asarray(self.springs_n_m), grounded_last=True)


def chain_matrix(elements: np.ndarray, *, grounded_last: bool) -> np.ndarray:
    """Assemble the matrix of a chain of two-node elements.

    Parameters
    ----------
    elements : ndarray, shape (..., m)
        Element values; element ``i`` (0-based) joins node ``i`` and ``i + 1``.  If
        ``grounded_last`` the last element joins the last node to ground, so that the chain
        has ``m`` nodes; otherwise it has ``m + 1`` nodes.

    Returns
    -------
    ndarray, shape (..., n, n)
    """
    e = np.asarray(elements, dtype=float)
    m = e.shape[-1]
    n = m if grounded_last else m + 1
    out = np.zeros(e.shape[:-1] + (n, n))
    n_links = n - 1
    for i in range(n_links):
        k = e[..., i]
        out[..., i, i] += k
        out[..., i + 1, i + 1] += k
        out[..., i, i + 1] -= k
        out[..., i + 1, i] -= k
    if grounded_last:
        out[..., n - 1, n - 1] += e[..., m - 1]
    return out


@dataclass(frozen=True)
class LinearModel:
    """Linear rig model with a chosen damping model.

    Parameters
    ----------
    rig : Rig
        Known geometry and springs.
    damping : {"free", "proportional"}
        Damping model.

    Attributes
    ----------
    names : tuple of str
        Parameter names in vector order, e.g. ``("g_v", "m1", "m2", "m3", "c1", "c2", "c3",
        "c12", "c23")`` or ``("g_v", "m1", "m2", "m3", "ca", "cb")``.  Units: g_v N/V,
        masses kg, c* N s/m, ca 1/s, cb s.

    Examples
    --------
    >>> model = LinearModel(Rig(), "proportional")
    >>> model.names
    ('g_v', 'm1', 'm2', 'm3', 'ca', 'cb')
    """

    rig: Rig = field(default_factory=Rig)
    damping: str = "free"

    def __post_init__(self) -> None:
        if self.damping not in DAMPING_MODELS:
            raise ModelError(f"damping must be one of {DAMPING_MODELS}, got {self.damping!r}")

    @property
    def n_carts(self) -> int:
        return self.rig.n_carts

    @property
    def n_states(self) -> int:
        return 2 * self.rig.n_carts

    @property
    def names(self) -> tuple[str, ...]:
        n = self.rig.n_carts
        masses = tuple(f"m{i + 1}" for i in range(n))
        if self.damping == "proportional":
            return ("g_v",) + masses + ("ca", "cb")
        absolute = tuple(f"c{i + 1}" for i in range(n))
        relative = tuple(_pair_name(i + 1, n) for i in range(n - 1))
        return ("g_v",) + masses + absolute + relative

    @property
    def n_params(self) -> int:
        return len(self.names)

    def as_vector(self, params: dict[str, float]) -> np.ndarray:
        """Parameter vector, shape (n_params,), from a name-to-value mapping.

        Raises
        ------
        ModelError
            If a name is missing or unknown.
        """
        missing = [n for n in self.names if n not in params]
        unknown = [n for n in params if n not in self.names]
        if missing or unknown:
            raise ModelError(
                f"parameters for damping={self.damping!r}: missing {missing}, unknown {unknown}"
            )
        return np.array([float(params[n]) for n in self.names])

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        """Name-to-value mapping of a parameter vector of shape (n_params,)."""
        theta = np.asarray(theta, dtype=float)
        return {n: float(v) for n, v in zip(self.names, theta, strict=True)}

    # ------------------------------------------------------------------ validity
    def valid(self, theta: np.ndarray) -> np.ndarray:
        """Boolean mask, shape (...,), of physically admissible parameter sets.

        Admissible: finite, g_v > 0, masses > 0, every damping coefficient >= 0.  For
        proportional damping ``ca >= 0`` and ``cb >= 0`` (which makes C positive
        semi-definite and the system stable).
        """
        theta = np.asarray(theta, dtype=float)
        n = self.rig.n_carts
        ok = np.all(np.isfinite(theta), axis=-1)
        ok &= theta[..., 0] > 0
        ok &= np.all(theta[..., 1 : 1 + n] > 0, axis=-1)
        ok &= np.all(theta[..., 1 + n :] >= 0, axis=-1)
        return ok

    def check(self, theta: np.ndarray) -> np.ndarray:
        """Validate and return theta as a float array of shape (..., n_params)."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape[-1:] != (self.n_params,):
            raise ModelError(
                f"parameter vector must have length {self.n_params} {self.names}, "
                f"got shape {theta.shape}"
            )
        bad = ~self.valid(theta)
        if np.any(bad):
            first = theta[bad][0] if theta.ndim > 1 else theta
            raise ModelError(
                "impossible parameters (need finite values, g_v > 0, masses > 0, damping >= 0): "
                f"{self.as_dict(first)}"
            )
        return theta

    # ------------------------------------------------------------------ matrices
    def matrices(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Mass, damping, stiffness matrices and input vector.

        Parameters
        ----------
        theta : ndarray, shape (..., n_params)

        Returns
        -------
        M, C, K : ndarray, shape (..., n, n)
            kg, N s/m, N/m.
        b : ndarray, shape (..., n)
            Force per volt at each cart, N/V.
        """
        theta = np.asarray(theta, dtype=float)
        n = self.rig.n_carts
        batch = theta.shape[:-1]
        masses = theta[..., 1 : 1 + n]
        M = masses[..., :, None] * np.eye(n)
        K = np.broadcast_to(self.rig.stiffness_matrix(), batch + (n, n)).copy()
        if self.damping == "proportional":
            ca = theta[..., 1 + n]
            cb = theta[..., 2 + n]
            C = ca[..., None, None] * M + cb[..., None, None] * K
        else:
            absolute = theta[..., 1 + n : 1 + 2 * n]
            relative = theta[..., 1 + 2 * n :]
            C = chain_matrix(relative, grounded_last=False) if n > 1 else np.zeros(batch + (1, 1))
            C = C + absolute[..., :, None] * np.eye(n)
        b = np.zeros(batch + (n,))
        b[..., 0] = theta[..., 0]
        return M, C, K, b

    def state_space(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Continuous state-space matrices for state ``(x, x')`` and input v.

        Returns
        -------
        A : ndarray, shape (..., 2n, 2n), 1/s and 1/s^2 blocks
        B : ndarray, shape (..., 2n), m/(V s^2) in the acceleration block
        """
        M, C, K, b = self.matrices(theta)
        n = self.rig.n_carts
        inv_m = 1.0 / np.diagonal(M, axis1=-2, axis2=-1)  # M is diagonal
        batch = M.shape[:-2]
        A = np.zeros(batch + (2 * n, 2 * n))
        A[..., :n, n:] = np.eye(n)
        A[..., n:, :n] = -inv_m[..., :, None] * K
        A[..., n:, n:] = -inv_m[..., :, None] * C
        B = np.zeros(batch + (2 * n,))
        B[..., n:] = inv_m * b
        return A, B
