"""Complex (state-space) modes for any damping.

The free response of ``z' = A z`` is a sum of ``phi exp(lambda t)``, with ``(lambda, phi)``
the eigenpairs of the state matrix A (report eq. 5c).  An underdamped mode is a complex
conjugate pair ``lambda = -zeta omega_n +- i omega_n sqrt(1 - zeta^2)``, hence

    omega_n = |lambda|,   zeta = -Re(lambda) / |lambda|,   omega_d = Im(lambda).

For proportional damping these equal the undamped frequencies, eq. 41a and
``omega_n sqrt(1 - zeta^2)``; for non-proportional ("free") damping they are the exact
values and the displacement part of phi is a complex mode shape.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .._errors import ModelError
from ._checks import normalise_on_cart1

__all__ = ["ComplexModes", "complex_modes", "state_space_modes"]


@dataclass(frozen=True)
class ComplexModes:
    """Modes of a damped system from the eigenvalues of its state matrix.

    Attributes
    ----------
    eigenvalues : ndarray, shape (..., n), complex
        The eigenvalue with positive imaginary part of each mode, 1/s.
    omega_rad_s : ndarray, shape (..., n)
        Natural frequencies ``|lambda|``, ascending, rad/s.
    zeta : ndarray, shape (..., n)
        Damping ratios ``-Re(lambda) / |lambda|``.
    damped_rad_s : ndarray, shape (..., n)
        Damped frequencies ``Im(lambda)``, rad/s.
    shapes : ndarray, shape (..., n, n), complex
        Displacement part of the eigenvectors as columns, normalised so that cart 1 is 1.

    Systems with an overdamped (non-oscillating) mode have NaN in every field.
    """

    eigenvalues: np.ndarray
    omega_rad_s: np.ndarray
    zeta: np.ndarray
    damped_rad_s: np.ndarray
    shapes: np.ndarray


def complex_modes(A) -> ComplexModes:
    """Modes from the eigen-decomposition of a state matrix for state ``(x, x')``.

    Parameters
    ----------
    A : array_like, shape (..., 2n, 2n)
        State matrix, 1/s and 1/s^2 blocks, e.g. ``LinearModel.state_space(theta)[0]``.

    Returns
    -------
    ComplexModes
        Sorted by natural frequency.

    Warns
    -----
    UserWarning
        If some systems have overdamped modes (their results are NaN).

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[0.0, 1.0], [-4.0, -0.4]])  # omega_n = 2, zeta = 0.1
    >>> cm = complex_modes(A)
    >>> cm.omega_rad_s, cm.zeta.round(12)
    (array([2.]), array([0.1]))
    """
    A = np.asarray(A, dtype=float)
    if A.ndim < 2 or A.shape[-1] != A.shape[-2] or A.shape[-1] % 2:
        raise ModelError(f"state matrix must have shape (..., 2n, 2n), got {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ModelError("state matrix has non-finite entries")
    n = A.shape[-1] // 2
    lam, vec = np.linalg.eig(A)
    # keep the n eigenvalues of largest imaginary part, i.e. one of each conjugate pair
    order = np.argsort(-lam.imag, axis=-1)[..., :n]
    lam = np.take_along_axis(lam, order, axis=-1)
    vec = np.take_along_axis(vec, order[..., None, :], axis=-1)[..., :n, :]
    scale = np.maximum(np.abs(lam), np.finfo(float).tiny)
    oscillating = lam.imag > 1e-12 * scale
    ok = np.all(oscillating, axis=-1)
    if not np.all(ok):
        warnings.warn(
            f"{int(np.sum(~ok))} system(s) have overdamped modes (real eigenvalues); "
            "their complex modes are NaN",
            stacklevel=3,
        )
        lam = np.where(ok[..., None], lam, np.nan)
        vec = np.where(ok[..., None, None], vec, 1.0)
    omega = np.abs(lam)
    order = np.argsort(omega, axis=-1)
    lam = np.take_along_axis(lam, order, axis=-1)
    vec = np.take_along_axis(vec, order[..., None, :], axis=-1)
    shapes = normalise_on_cart1(vec, stacklevel=4)
    shapes = np.where(ok[..., None, None], shapes, np.nan)
    omega = np.abs(lam)
    return ComplexModes(
        eigenvalues=lam,
        omega_rad_s=omega,
        zeta=-lam.real / omega,
        damped_rad_s=lam.imag,
        shapes=shapes,
    )


def state_space_modes(model, theta) -> ComplexModes:
    """Complex modes of a rig model at parameters theta.

    Parameters
    ----------
    model : LinearModel
    theta : array_like, shape (..., n_params)
        Parameters in ``model.names`` order.

    Returns
    -------
    ComplexModes

    Examples
    --------
    >>> from bayesmodal.model.system import LinearModel, Rig
    >>> model = LinearModel(Rig(), "proportional")
    >>> cm = state_space_modes(model, [6.223, 1.565, 1.461, 1.146, 1.528, 8.583e-05])
    >>> cm.zeta.round(3)
    array([0.093, 0.029, 0.02 ])
    """
    theta = model.check(theta)
    A, _ = model.state_space(theta)
    return complex_modes(A)
