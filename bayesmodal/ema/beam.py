"""The lecture's test structure: an Euler-Bernoulli cantilever beam, finite elements.

Lecture 11 uses a clamped-free steel beam with ``l = 1.8 m``, ``A = 9.0e-4 m^2``,
``I = 7e-8 m^4``, ``rho = 7800 kg/m^3`` (the lecture does not state Young's modulus; steel,
``E = 2.1e11 Pa``, is used here), 18 two-node Hermite elements with a deflection and a
rotation per node (36 degrees of freedom after clamping node 0), and Rayleigh damping
``B = 0.1 M + 2e-5 K``.  The element matrices are the standard cubic-Hermite ones,

    K_e = EI / h^3 [[12, 6h, -12, 6h], [6h, 4h^2, -6h, 2h^2], [-12, -6h, 12, -6h],
                    [6h, 2h^2, -6h, 4h^2]],
    M_e = rho A h / 420 [[156, 22h, 54, -13h], [22h, 4h^2, 13h, -3h^2],
                         [54, 13h, 156, -22h], [-13h, -3h^2, -22h, 4h^2]].

With Rayleigh damping the undamped modes ``phi_k`` (mass-normalised) decouple the
equations, each mode having ``zeta_k = alpha / (2 omega_k) + beta omega_k / 2``, so that

    H_ij(w) = (j w)^p sum_k phi_k[i] phi_k[j] / (omega_k^2 - w^2 + 2 j zeta_k omega_k w)

with ``p = 0, 1, 2`` for displacement, velocity and acceleration per force.  The
analytical cantilever frequencies are ``omega_n = (beta_n L)^2 sqrt(EI / (rho A L^4))``
with ``beta_n L = 1.8751, 4.6941, 7.8548, 10.9955, 14.1372, ...``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .._errors import ModelError
from .frf import FRF

__all__ = ["CantileverBeam", "CANTILEVER_BETA_L"]

#: Roots of ``cos(x) cosh(x) = -1``: ``beta_n L`` of a clamped-free beam.
CANTILEVER_BETA_L = np.array([1.8751, 4.6941, 7.8548, 10.9955, 14.1372])

_RESPONSES = {"displacement": 0, "velocity": 1, "acceleration": 2}


@dataclass(frozen=True)
class CantileverBeam:
    """Clamped-free Euler-Bernoulli beam in finite elements with Rayleigh damping.

    Parameters
    ----------
    length_m : float
        Beam length, m.
    n_elements : int
        Number of equal elements.
    area_m2 : float
        Cross-section area, m^2.
    inertia_m4 : float
        Second moment of area, m^4.
    density_kg_m3 : float
        Mass density, kg/m^3.
    youngs_modulus_pa : float
        Young's modulus, Pa.
    alpha_per_s : float
        Mass-proportional damping coefficient (``B = alpha M + beta K``), 1/s.
    beta_s : float
        Stiffness-proportional damping coefficient, s.

    Examples
    --------
    >>> beam = CantileverBeam()
    >>> beam.n_dof
    36
    >>> bool(np.allclose(beam.natural_frequencies()[:2], beam.analytical_frequencies(2), rtol=1e-3))
    True
    """

    length_m: float = 1.8
    n_elements: int = 18
    area_m2: float = 9.0e-4
    inertia_m4: float = 7e-8
    density_kg_m3: float = 7800.0
    youngs_modulus_pa: float = 2.1e11
    alpha_per_s: float = 0.1
    beta_s: float = 2e-5

    def __post_init__(self) -> None:
        for name in ("length_m", "area_m2", "inertia_m4", "density_kg_m3", "youngs_modulus_pa"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ModelError(f"{name} must be finite and > 0, got {v!r}")
        if int(self.n_elements) < 1:
            raise ModelError(f"n_elements must be >= 1, got {self.n_elements}")
        if self.alpha_per_s < 0 or self.beta_s < 0:
            raise ModelError("Rayleigh damping coefficients must be >= 0")

    @property
    def n_dof(self) -> int:
        """Degrees of freedom after clamping: deflection and rotation of each free node."""
        return 2 * int(self.n_elements)

    @property
    def tip_dof(self) -> int:
        """Index of the deflection of the free end."""
        return self.n_dof - 2

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Mass, damping and stiffness matrices of the clamped beam.

        Returns
        -------
        M : ndarray, shape (n_dof, n_dof), kg (kg m^2 for rotations)
        B : ndarray, shape (n_dof, n_dof), N s/m
        K : ndarray, shape (n_dof, n_dof), N/m
        """
        ne = int(self.n_elements)
        h = self.length_m / ne
        EI = self.youngs_modulus_pa * self.inertia_m4
        rA = self.density_kg_m3 * self.area_m2
        Ke = EI / h**3 * np.array([
            [12, 6 * h, -12, 6 * h],
            [6 * h, 4 * h**2, -6 * h, 2 * h**2],
            [-12, -6 * h, 12, -6 * h],
            [6 * h, 2 * h**2, -6 * h, 4 * h**2],
        ])
        Me = rA * h / 420 * np.array([
            [156, 22 * h, 54, -13 * h],
            [22 * h, 4 * h**2, 13 * h, -3 * h**2],
            [54, 13 * h, 156, -22 * h],
            [-13 * h, -3 * h**2, -22 * h, 4 * h**2],
        ])
        n = 2 * (ne + 1)
        M = np.zeros((n, n))
        K = np.zeros((n, n))
        for e in range(ne):
            s = slice(2 * e, 2 * e + 4)
            M[s, s] += Me
            K[s, s] += Ke
        M, K = M[2:, 2:], K[2:, 2:]  # clamp node 0
        B = self.alpha_per_s * M + self.beta_s * K
        return M, B, K

    def modes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Undamped modes and their Rayleigh damping ratios.

        Returns
        -------
        omega_rad_s : ndarray, shape (n_dof,)
            Natural frequencies, ascending, rad/s.
        zeta : ndarray, shape (n_dof,)
            ``alpha / (2 omega) + beta omega / 2``.
        phi : ndarray, shape (n_dof, n_dof)
            Mass-normalised mode shapes as columns.
        """
        M, _, K = self.matrices()
        w2, phi = scipy.linalg.eigh(K, M)
        omega = np.sqrt(w2)
        zeta = self.alpha_per_s / (2 * omega) + self.beta_s * omega / 2
        return omega, zeta, phi

    def natural_frequencies(self) -> np.ndarray:
        """Undamped natural frequencies of the FE model, shape (n_dof,), rad/s."""
        return self.modes()[0]

    def poles(self) -> np.ndarray:
        """Exact poles ``-zeta omega + j omega sqrt(1 - zeta^2)`` (underdamped modes), 1/s."""
        omega, zeta, _ = self.modes()
        under = zeta < 1
        return -zeta[under] * omega[under] + 1j * omega[under] * np.sqrt(1 - zeta[under] ** 2)

    def analytical_frequencies(self, n: int = 5) -> np.ndarray:
        """Continuous-beam natural frequencies ``(beta_n L)^2 sqrt(EI / (rho A L^4))``, rad/s.

        Parameters
        ----------
        n : int
            Number of modes, at most 5 (tabulated ``beta_n L``).
        """
        if not 1 <= n <= CANTILEVER_BETA_L.size:
            raise ModelError(f"n must be between 1 and {CANTILEVER_BETA_L.size}, got {n}")
        EI = self.youngs_modulus_pa * self.inertia_m4
        rA = self.density_kg_m3 * self.area_m2
        return CANTILEVER_BETA_L[:n] ** 2 * np.sqrt(EI / (rA * self.length_m**4))

    def frf(
        self,
        omega_rad_s,
        *,
        input_dof: int | None = None,
        output_dofs=None,
        response: str = "velocity",
    ) -> FRF:
        """FRF from a force at ``input_dof`` to the responses at ``output_dofs``.

        Parameters
        ----------
        omega_rad_s : ndarray, shape (n_freq,)
            Increasing frequencies, rad/s.
        input_dof : int, optional
            Forced degree of freedom (default: deflection of the free end).
        output_dofs : int or sequence of int, optional
            Responses (default: the input, i.e. the collocated FRF).
        response : {"displacement", "velocity", "acceleration"}

        Returns
        -------
        FRF
            Units m/N, m/(N s) or m/(N s^2).
        """
        if response not in _RESPONSES:
            raise ModelError(f"response must be one of {tuple(_RESPONSES)}, got {response!r}")
        p = _RESPONSES[response]
        j = self.tip_dof if input_dof is None else int(input_dof)
        outs = np.atleast_1d(j if output_dofs is None else output_dofs).astype(int)
        if not (0 <= j < self.n_dof and np.all((0 <= outs) & (outs < self.n_dof))):
            raise ModelError(f"degrees of freedom must lie in 0..{self.n_dof - 1}")
        omega, zeta, phi = self.modes()
        w = np.asarray(omega_rad_s, dtype=float)
        den = omega[None, :] ** 2 - w[:, None] ** 2 + 2j * zeta * omega * w[:, None]
        part = phi[outs][None, :, :] * phi[j][None, None, :] / den[:, None, :]
        H = (1j * w[:, None]) ** p * part.sum(axis=2)
        units = {0: "m/N", 1: "m/(N s)", 2: "m/(N s^2)"}[p]
        return FRF(w, H, None, "model", units, 1, None, p)
