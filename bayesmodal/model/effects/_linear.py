"""Shared pieces of the extension simulators: the linear rig's matrices for a batch, in
the order of degrees of freedom the compiled kernels take.

The kernels put the driven cart first: the end stop, the backlash of the rack-pinion and
the lagged motor force all act on degree of freedom 0.  On any rig with one driven cart
the simulators therefore reorder the degrees of freedom (``kernel_order``: the driven cart
first, the others in the rig's order), run the kernel, and put the positions back in the
rig's order.  Reordering is exact (it only moves numbers), and on the chain driven at
cart 1 it is the identity, so nothing is moved at all.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..system import LinearModel, Rig, state_space_from


@dataclass(frozen=True)
class KernelOrder:
    """How the kernels' degrees of freedom map to a rig's.

    Attributes
    ----------
    perm : ndarray of int, shape (n,)
        Kernel degree of freedom ``k`` is the rig's degree of freedom ``perm[k]``.
    inverse : ndarray of int, shape (n,)
        Rig degree of freedom ``i`` is the kernel's ``inverse[i]``.
    identity : bool
        True when ``perm`` is ``0, 1, ..., n - 1`` (nothing to move).
    driven : int or None
        The rig's degree of freedom the motor drives, None when it drives none or several.
    outputs : ndarray of int or None
        Rig degree of freedom of each sensor, None when every one is measured in order.
    springs : tuple of (int, int)
        Each spring with a free end as kernel degrees of freedom ``(a, b)``, its extension
        ``x_b - x_a``; ``-1`` for an end at the frame or a clamped cart.
    spring_index : tuple of int
        Position of each of those springs in ``rig.springs``.
    """

    perm: np.ndarray
    inverse: np.ndarray
    identity: bool
    driven: int | None
    outputs: np.ndarray | None
    springs: tuple[tuple[int, int], ...]
    spring_index: tuple[int, ...]


@functools.lru_cache(maxsize=64)
def kernel_order(rig: Rig) -> KernelOrder:
    """The kernels' order of a rig's degrees of freedom: the driven cart first."""
    free = rig.free_carts
    n = len(free)
    driven = [free.index(d.cart) for d in rig.drive if d.share != 0.0]
    d = driven[0] if len(driven) == 1 else None
    perm = np.arange(n) if d is None else np.r_[d, [i for i in range(n) if i != d]]
    inverse = np.argsort(perm)
    outputs = rig.sensor_dofs
    if outputs.size == n and np.array_equal(outputs, np.arange(n)):
        outputs = None
    springs, index = [], []
    for i, s in enumerate(rig.springs):
        ends = tuple(int(inverse[free.index(e)]) if e in free else -1 for e in (s.a, s.b))
        if ends != (-1, -1):
            springs.append(ends)
            index.append(i)
    return KernelOrder(perm, inverse, bool(np.array_equal(perm, np.arange(n))), d, outputs,
                       tuple(springs), tuple(index))


def to_kernel(order: KernelOrder, a: np.ndarray, axis: int = -1) -> np.ndarray:
    """``a`` with its axis of degrees of freedom in kernel order (a copy if moved)."""
    return a if order.identity else np.take(a, order.perm, axis=axis)


def state_to_kernel(order: KernelOrder, x0: np.ndarray) -> np.ndarray:
    """States ``(x, x')`` of shape (nb, 2n) in kernel order."""
    if order.identity:
        return x0
    n = order.perm.size
    return np.ascontiguousarray(x0[:, np.r_[order.perm, n + order.perm]])


def outputs_from_kernel(order: KernelOrder, y: np.ndarray) -> np.ndarray:
    """Kernel positions (nb, N, n) as the rig's sensor outputs (nb, N, n_outputs)."""
    if not order.identity:
        y = y[..., order.inverse]
    if order.outputs is not None:
        y = y[..., order.outputs]
    return y


@dataclass(frozen=True)
class LinearParts:
    """Matrices of the free-damping linear model for a batch of parameter sets, in kernel
    order (``kernel_order``).

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
    """Matrices of ``LinearModel(rig, "free")`` for ``theta_lin`` of shape (nb, n_lin), in
    kernel order."""
    model = LinearModel(rig, "free")
    M, C, K, b = model.matrices(theta_lin)
    order = kernel_order(rig)
    if order.identity:
        A, B = model.state_space(theta_lin)
    else:
        p = order.perm
        M, C, K = (a[:, p][:, :, p] for a in (M, C, K))
        b = b[:, p]
        A, B = state_space_from(M, C, K, b)
    return parts_from(M, C, K, b, A, B)


def parts_from(M, C, K, b, A=None, B=None) -> LinearParts:
    """``LinearParts`` of matrices already in kernel order (``A, B`` built if not given)."""
    if A is None:
        A, B = state_space_from(M, C, K, b)
    n = M.shape[-1]
    nb = M.shape[0]
    inv_m = 1.0 / np.diagonal(M, axis1=-2, axis2=-1)
    F = np.zeros((nb, 2 * n, n))
    F[:, n:, :] = inv_m[:, :, None] * np.eye(n)
    G = np.concatenate([-K, -C], axis=-1)
    return LinearParts(M, C, K, b, A, B, F, np.ascontiguousarray(G))


#: Every sensor kind (``Rig.output_kinds``).
ALL_KINDS = ("position", "velocity", "acceleration")


def sensor_spec(rig: Rig) -> np.ndarray | None:
    """Kernel degree of freedom and time derivative of each sensor, in sensor order.

    Returns
    -------
    ndarray of int, shape (n_outputs, 2), or None
        ``(k, order)``: kernel degree of freedom ``k`` (``kernel_order``) and 0 position,
        1 velocity, 2 acceleration; None when every sensor reads a position (the kernels
        then return positions, mapped by ``outputs_from_kernel``).
    """
    if rig.positions_only:
        return None
    inverse = kernel_order(rig).inverse
    free = rig.free_carts
    return np.array([(int(inverse[free.index(s.cart)]), s.order) for s in rig.sensors],
                    dtype=np.int64)


def sensor_map(A: np.ndarray, B: np.ndarray, spec: np.ndarray, n: int,
               force_inputs: np.ndarray | None = None):
    """Each sensor's reading as a row of the state, the held input and the plant forces.

    A sensor reads ``y = C z + D u + E f`` at the sample: a position or a velocity is a
    state; an acceleration is a velocity row of ``z' = A z + B u + F f``, with ``u`` the
    input held from the sample (its feedthrough) and ``f`` the nonlinear forces on the
    carts at the sample's state.

    Parameters
    ----------
    A : ndarray, shape (nb, s, s)
        State matrix; the first ``2 n`` states are ``(x, x')`` in kernel order (more states,
        e.g. a lagged motor force, after them).
    B : ndarray, shape (nb, s)
        Input vector, per input unit.
    spec : ndarray of int, shape (n_out, 2)
        ``sensor_spec``.
    n : int
        Degrees of freedom.
    force_inputs : ndarray, shape (nb, s, n), optional
        How a force on each cart enters ``z'`` (``LinearParts.force_inputs``); None when
        there are no plant forces.

    Returns
    -------
    C : ndarray, shape (nb, n_out, s)
    D : ndarray, shape (nb, n_out)
    E : ndarray, shape (nb, n_out, n), or None without ``force_inputs``
    """
    nb, s = B.shape
    C = np.zeros((nb, len(spec), s))
    D = np.zeros((nb, len(spec)))
    E = None if force_inputs is None else np.zeros((nb, len(spec), n))
    for o, (k, order) in enumerate(spec):
        if order < 2:
            C[:, o, order * n + k] = 1.0
            continue
        C[:, o] = A[:, n + k]
        D[:, o] = B[:, n + k]
        if E is not None:
            E[:, o] = force_inputs[:, n + k]
    return C, D, E


@functools.lru_cache(maxsize=64)
def _coupling(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Which carts each cart's springs and dampers join it to: the nonzero patterns of
    ``K`` and ``C`` (n, n) in kernel order, from the matrices at unit parameters (every
    element present, none cancelling: diagonal entries are sums of positive values)."""
    p = linear_parts(rig, np.ones((1, LinearModel(rig, "free").n_params)))
    return p.K[0] != 0.0, p.C[0] != 0.0


def acceleration_columns(rig: Rig, spec: np.ndarray) -> tuple[tuple[int, ...], ...]:
    """The states each acceleration sensor's row of the state matrix can involve: the
    positions and velocities of the carts its springs and dampers join, in kernel order
    (a compiled kernel then reads those entries only).

    Parameters
    ----------
    rig : Rig
    spec : ndarray of int, shape (n_out, 2)
        ``sensor_spec``.
    """
    K, C = _coupling(rig)
    n = K.shape[0]
    return tuple(tuple(np.flatnonzero(K[k]).tolist() + (n + np.flatnonzero(C[k])).tolist())
                 for k, order in spec if order == 2)
