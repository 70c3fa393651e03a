"""The common result of every modal parameter fit: poles, residues and mode shapes.

A mode ``k`` of an underdamped system is the conjugate pole pair
``lambda_k = mu_k +- j nu_k`` with residues ``A_k[i]`` (lecture 11, one column of the FRF
matrix measured with ``s`` sensors).  Its undamped natural frequency and damping ratio are::

    omega_k = |lambda_k|,        zeta_k = -mu_k / |lambda_k|,

and the damped frequency is ``nu_k = omega_k sqrt(1 - zeta_k^2)``.  Because the residue
matrix has rank one, ``A_k[i, l] = u_k[i] u_k[l] / c_k``: the residues of one column are
the mode shape up to a complex factor, removed here by normalising on a reference sensor
(cart 1 for the rig).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .._errors import DataError

__all__ = ["ModalEstimate", "modal_estimate", "normalise_shapes", "match_modes"]


@dataclass(frozen=True)
class ModalEstimate:
    """Modal parameters identified by one method.

    Modes are sorted by damped frequency.  Computational (non-physical) modes are kept,
    with ``identified`` False, so that nothing the method returned is hidden.

    Attributes
    ----------
    method : str
        Name of the method (``"lsce"``, ``"circle"``, ``"multimode"``, ``"tfest"``, ...).
    omega_rad_s : ndarray, shape (n_modes,)
        Undamped natural frequency ``|lambda|``, rad/s.
    zeta : ndarray, shape (n_modes,)
        Damping ratio ``-Re(lambda) / |lambda|``, dimensionless (1 for a real pole,
        negative for an unstable one).
    poles : ndarray of complex, shape (n_modes,)
        ``lambda = mu + j nu`` with ``nu >= 0``, 1/s.
    residues : ndarray of complex, shape (n_modes, n_outputs)
        Residue of the pole ``lambda`` in each FRF, in FRF units times rad/s (m/(V s) for a
        receptance in m/V).  For free-decay data these are the decay amplitudes instead.
    mode_shapes : ndarray of complex, shape (n_modes, n_outputs)
        Residues divided by the residue of the reference output; dimensionless.
    identified : ndarray of bool, shape (n_modes,)
        False for computational modes and for modes the data do not support.
    reference : int
        Index of the output the shapes are normalised on (0 = cart 1).
    notes : tuple of str
        Human-readable remarks (why a mode was rejected, settings used).
    pole_cov : ndarray, shape (n_modes, 2, 2), or None
        Covariance of ``(Re lambda, Im lambda)`` of each pole, 1/s^2, where the method
        states its error (the multi-mode fit); None otherwise.  ``omega_se`` and
        ``zeta_se`` follow from it to first order.
    """

    method: str
    omega_rad_s: np.ndarray
    zeta: np.ndarray
    poles: np.ndarray
    residues: np.ndarray
    mode_shapes: np.ndarray
    identified: np.ndarray
    reference: int = 0
    notes: tuple[str, ...] = field(default=())
    pole_cov: np.ndarray | None = None

    @property
    def omega_se(self) -> np.ndarray:
        """Standard error of ``omega_rad_s``, shape (n_modes,), rad/s; NaN without
        ``pole_cov``.  First order: ``omega = |lambda|``, gradient ``(mu, nu) / omega``."""
        return _stated_error(self, lambda mu, nu, w: np.stack([mu / w, nu / w], -1))

    @property
    def zeta_se(self) -> np.ndarray:
        """Standard error of ``zeta``, shape (n_modes,); NaN without ``pole_cov``.  First
        order: ``zeta = -mu / |lambda|``, gradient ``(-nu^2, mu nu) / omega^3``."""
        return _stated_error(self, lambda mu, nu, w: np.stack([-nu**2, mu * nu], -1) / w[:, None]
                             ** 3)

    @property
    def n_modes(self) -> int:
        """Number of modes (identified or not)."""
        return int(self.poles.size)

    @property
    def omega_d_rad_s(self) -> np.ndarray:
        """Damped natural frequency ``Im(lambda)``, shape (n_modes,), rad/s."""
        return self.poles.imag.copy()

    @property
    def real_mode_shapes(self) -> np.ndarray:
        """Real part of the normalised shapes, shape (n_modes, n_outputs)."""
        return self.mode_shapes.real.copy()

    def physical(self) -> ModalEstimate:
        """The same estimate restricted to the identified modes."""
        keep = np.asarray(self.identified, bool)
        return ModalEstimate(
            method=self.method,
            omega_rad_s=self.omega_rad_s[keep],
            zeta=self.zeta[keep],
            poles=self.poles[keep],
            residues=self.residues[keep],
            mode_shapes=self.mode_shapes[keep],
            identified=self.identified[keep],
            reference=self.reference,
            notes=self.notes,
            pole_cov=None if self.pole_cov is None else self.pole_cov[keep],
        )

    def as_dict(self) -> dict:
        """JSON-ready summary (real parts of the shapes, pole parts separately)."""
        return {
            "method": self.method,
            "omega_rad_s": self.omega_rad_s.tolist(),
            "zeta": self.zeta.tolist(),
            "omega_d_rad_s": self.omega_d_rad_s.tolist(),
            "mode_shapes": self.mode_shapes.real.tolist(),
            "mode_shapes_imag": self.mode_shapes.imag.tolist(),
            "identified": [bool(x) for x in self.identified],
            "reference_output": int(self.reference),
            "omega_se_rad_s": _json_floats(self.omega_se),
            "zeta_se": _json_floats(self.zeta_se),
            "notes": list(self.notes),
        }


def _stated_error(est: ModalEstimate, gradient) -> np.ndarray:
    """``sqrt(g^T cov g)`` per mode for the gradient ``g(mu, nu, omega)`` of a function of
    the pole; NaN for every mode without ``pole_cov``."""
    if est.pole_cov is None:
        return np.full(est.n_modes, np.nan)
    mu, nu = est.poles.real, est.poles.imag
    with np.errstate(invalid="ignore", divide="ignore"):
        g = gradient(mu, nu, np.abs(est.poles))
        return np.sqrt(np.einsum("ki,kij,kj->k", g, est.pole_cov, g))


def _json_floats(x: np.ndarray) -> list:
    """A float array as a JSON list, NaN as None."""
    return [None if not np.isfinite(v) else float(v) for v in x]


def normalise_shapes(residues: np.ndarray, reference: int = 0) -> np.ndarray:
    """Divide each row of ``residues`` by its entry at ``reference``.

    Parameters
    ----------
    residues : ndarray of complex, shape (n_modes, n_outputs)
    reference : int
        Output index to normalise on.

    Returns
    -------
    ndarray of complex, shape (n_modes, n_outputs)
        NaN rows where the reference residue is zero (a node at the reference sensor).
    """
    R = np.asarray(residues, dtype=complex)
    if R.ndim != 2:
        raise DataError(f"residues must have shape (n_modes, n_outputs), got {R.shape}")
    if not 0 <= reference < R.shape[1]:
        raise DataError(f"reference output {reference} out of range for {R.shape[1]} outputs")
    ref = R[:, reference : reference + 1]
    out = np.full_like(R, np.nan)
    ok = np.abs(ref[:, 0]) > 0
    out[ok] = R[ok] / ref[ok]
    return out


def modal_estimate(
    method: str,
    poles: np.ndarray,
    residues: np.ndarray,
    identified: np.ndarray | Sequence[bool] | None = None,
    *,
    reference: int = 0,
    notes: Sequence[str] = (),
    pole_cov: np.ndarray | None = None,
) -> ModalEstimate:
    """Build a ModalEstimate from one pole per mode and its residues.

    Parameters
    ----------
    method : str
    poles : ndarray of complex, shape (n_modes,)
        One pole per mode; a pole with negative imaginary part is replaced by its
        conjugate (and its residues conjugated), 1/s.
    residues : ndarray of complex, shape (n_modes, n_outputs)
    identified : ndarray of bool, shape (n_modes,), optional
        All True by default.
    reference : int
        Output the shapes are normalised on.
    notes : sequence of str
    pole_cov : ndarray, shape (n_modes, 2, 2), optional
        Covariance of each pole's ``(Re, Im)``, 1/s^2 (a conjugated pole's covariance
        flips the sign of its off-diagonal term).

    Returns
    -------
    ModalEstimate
        Sorted by damped frequency, then by decay rate.

    Examples
    --------
    >>> est = modal_estimate("demo", np.array([-0.1 + 2j]), np.array([[1j, 2j]]))
    >>> float(est.mode_shapes[0, 1].real)
    2.0
    """
    lam = np.atleast_1d(np.asarray(poles, dtype=complex))
    R = np.asarray(residues, dtype=complex).reshape(lam.size, -1)
    flip = lam.imag < 0
    lam = np.where(flip, lam.conj(), lam)
    R = np.where(flip[:, None], R.conj(), R)
    ident = np.ones(lam.size, bool) if identified is None else np.asarray(identified, bool)
    if ident.shape != lam.shape:
        raise DataError(f"identified has shape {ident.shape}, expected {lam.shape}")
    cov = None
    if pole_cov is not None:
        cov = np.array(pole_cov, dtype=float).reshape(lam.size, 2, 2)
        cov[flip, 0, 1] *= -1
        cov[flip, 1, 0] *= -1
    order = np.lexsort((-lam.real, lam.imag))
    lam, R, ident = lam[order], R[order], ident[order]
    cov = None if cov is None else cov[order]
    omega = np.abs(lam)
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = np.where(omega > 0, -lam.real / omega, np.nan)
    return ModalEstimate(
        method=method,
        omega_rad_s=omega,
        zeta=zeta,
        poles=lam,
        residues=R,
        mode_shapes=normalise_shapes(R, reference) if R.size else R.copy(),
        identified=ident,
        reference=reference,
        notes=tuple(notes),
        pole_cov=cov,
    )


def match_modes(estimate_omega: np.ndarray, reference_omega: np.ndarray) -> np.ndarray:
    """Index of the nearest estimated mode for each reference frequency.

    Parameters
    ----------
    estimate_omega : ndarray, shape (n_est,), rad/s
    reference_omega : ndarray, shape (n_ref,), rad/s

    Returns
    -------
    ndarray of int, shape (n_ref,)
        ``-1`` where there is no estimate at all.
    """
    est = np.asarray(estimate_omega, float)
    ref = np.asarray(reference_omega, float)
    if est.size == 0:
        return np.full(ref.size, -1)
    return np.argmin(np.abs(est[None, :] - ref[:, None]) / ref[:, None], axis=1)
