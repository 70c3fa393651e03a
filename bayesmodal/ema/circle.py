"""Circle fit: a single-mode estimate from the Nyquist plot (lecture 11b).

Near a weakly damped resonance ``nu_k`` only one term of the modal sum matters and the
others are lumped into a complex constant ``R_k + j I_k``:

    H(w) ~ (A_R + j A_I) / (-mu + j (w - nu)) + R + j I.

Since ``1 / (-mu + j (w - nu)) = -(1 + e^{j phi(w)}) / (2 mu)`` with
``phi(w) = 2 arctan((w - nu) / mu)``, the points lie on a circle with centre
``R0 + j I0 = (R + j I) - (A_R + j A_I) / (2 mu)`` and radius ``r = |A| / |2 mu|``.  The
algorithm:

1. least-squares circle through the FRF points of the band: centre and radius;
2. the angle ``theta(w) = phi(w) + psi`` of ``H - centre`` sweeps fastest at the
   resonance (``d^2 theta / dw^2 = 0`` at ``w = nu``): ``nu`` is where
   ``|d theta / d w|`` peaks (parabolic interpolation between points), and
   ``psi = theta(nu)`` is the phase of the residue;
3. with ``phi_a``, ``phi_b`` at ``w_a < nu < w_b``,
   ``mu = (w_a - w_b) / (tan(phi_a / 2) - tan(phi_b / 2))`` (< 0); the median over all
   such pairs is used; by default ``psi, nu, mu`` are then refined together by least
   squares on the angles of all points (robust to noise on a fine grid);
4. ``|A| = r |2 mu|``, ``A = |A| e^{j psi}`` and ``R + j I = centre + A / (2 mu)`` (the
   point of the circle opposite the resonance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .._errors import DataError
from .frf import FRF, peak_prominence
from .peaks import pick_peaks
from .result import ModalEstimate, modal_estimate

__all__ = ["CircleFit", "fit_circle", "circle_fit", "circle_fit_modes", "CircleFitModes"]


@dataclass(frozen=True)
class CircleFit:
    """Circle fit of one mode in one FRF.

    Attributes
    ----------
    pole : complex
        ``mu + j nu``, 1/s.
    residue : complex
        ``A_R + j A_I``, FRF units times rad/s.
    residual : complex
        ``R + j I``, the other modes' contribution (FRF units).
    centre : complex
        Circle centre ``R0 + j I0`` (FRF units).
    radius : float
        Circle radius (FRF units).
    omega_rad_s : ndarray, shape (n_points,)
        Frequencies used, rad/s.
    H : ndarray of complex, shape (n_points,)
        FRF points used.
    circle_error : float
        RMS distance of the points from the circle divided by the radius.
    mu_spread : float
        Relative interquartile range of the pairwise ``mu`` estimates.
    """

    pole: complex
    residue: complex
    residual: complex
    centre: complex
    radius: float
    omega_rad_s: np.ndarray
    H: np.ndarray
    circle_error: float
    mu_spread: float

    @property
    def omega_n_rad_s(self) -> float:
        """Undamped natural frequency ``|pole|``, rad/s."""
        return float(abs(self.pole))

    @property
    def zeta(self) -> float:
        """Damping ratio ``-mu / |pole|``."""
        return float(-self.pole.real / abs(self.pole))

    def model(self, omega_rad_s) -> np.ndarray:
        """The single-mode approximation ``A / (-mu + j (w - nu)) + R + jI``."""
        w = np.asarray(omega_rad_s, dtype=float)
        mu, nu = self.pole.real, self.pole.imag
        return self.residue / (-mu + 1j * (w - nu)) + self.residual


def fit_circle(z: np.ndarray) -> tuple[complex, float]:
    """Least-squares (algebraic) circle through points of the complex plane.

    Minimises ``sum (x^2 + y^2 + D x + E y + F)^2``, linear in ``(D, E, F)``; the centre
    is ``-(D + j E) / 2`` and the radius ``sqrt((D^2 + E^2) / 4 - F)``.

    Parameters
    ----------
    z : ndarray of complex, shape (n,), n >= 3

    Returns
    -------
    centre : complex
    radius : float

    Examples
    --------
    >>> z = 1 + 2j + 3 * np.exp(1j * np.linspace(0, 2, 10))
    >>> c, r = fit_circle(z)
    >>> bool(np.isclose(c, 1 + 2j) and np.isclose(r, 3))
    True
    """
    z = np.asarray(z, dtype=complex).ravel()
    if z.size < 3:
        raise DataError(f"a circle needs at least 3 points, got {z.size}")
    # centre and scale first, for conditioning (FRF values may be ~1e-3)
    z0 = z.mean()
    s = np.max(np.abs(z - z0))
    if s == 0:
        raise DataError("all points coincide; no circle")
    x, y = ((z - z0) / s).real, ((z - z0) / s).imag
    G = np.column_stack([x, y, np.ones_like(x)])
    D, E, F = np.linalg.lstsq(G, -(x**2 + y**2), rcond=None)[0]
    c = complex(-D / 2, -E / 2)
    r2 = (D**2 + E**2) / 4 - F
    if r2 <= 0:
        raise DataError("degenerate circle fit (points on a line?)")
    return z0 + s * c, float(s * np.sqrt(r2))


def circle_fit(
    omega_rad_s,
    H,
    band: tuple[float, float] | None = None,
    *,
    refine: float | None = 3.0,
    angle_fit: bool = True,
) -> CircleFit:
    """Circle fit of one mode in one FRF.

    Parameters
    ----------
    omega_rad_s : ndarray, shape (n_freq,)
        Frequencies, rad/s.
    H : ndarray of complex, shape (n_freq,)
        One FRF.
    band : (lo, hi), optional
        Band around the resonance, rad/s (all points by default); a few half-power
        bandwidths either side of the peak works well.
    refine : float or None
        If given, fit a second time on the points with ``|w - nu| <= refine |mu|`` from
        the first fit (``phi`` within ``+-2 arctan(refine)``), provided there are at least
        6: points far from the resonance crowd together and carry the other modes'
        influence rather than this mode's circle.
    angle_fit : bool
        Finish by a least-squares fit of ``theta(w) = psi + 2 arctan((w - nu) / mu)`` to
        the angles of all points, started from the lecture's estimates (steps 2-3).  On a
        fine frequency grid the angle differences of neighbouring points are dominated
        by noise, and the largest one is a poor estimate of ``nu``.

    Returns
    -------
    CircleFit

    Raises
    ------
    DataError
        Too few points (need 6), or no resonance sweep in the band.

    Examples
    --------
    >>> lam, A = -0.2 + 10j, -0.05j
    >>> w = np.linspace(9, 11, 81)
    >>> H = A / (1j * w - lam) + np.conj(A) / (1j * w - np.conj(lam))
    >>> fit = circle_fit(w, H)
    >>> round(fit.omega_n_rad_s, 3), round(fit.zeta, 4)
    (10.002, 0.02)
    """
    w = np.asarray(omega_rad_s, dtype=float)
    H = np.asarray(H, dtype=complex)
    if H.shape != w.shape:
        raise DataError(f"omega {w.shape} and H {H.shape} must have the same shape")
    if band is not None:
        sel = (w >= band[0]) & (w <= band[1])
        w, H = w[sel], H[sel]
    fit = _circle_fit_once(w, H, angle_fit)
    if refine is not None:
        mu, nu = fit.pole.real, fit.pole.imag
        sel = np.abs(w - nu) <= refine * abs(mu)
        if 6 <= np.count_nonzero(sel) < w.size:
            try:
                fit = _circle_fit_once(w[sel], H[sel], angle_fit)
            except DataError:
                pass
    return fit


def _circle_fit_once(w: np.ndarray, H: np.ndarray, angle_fit: bool = True) -> CircleFit:
    if w.size < 6:
        raise DataError(f"circle fit needs at least 6 FRF points in the band, got {w.size}")
    centre, r = fit_circle(H)
    err = float(np.sqrt(np.mean((np.abs(H - centre) - r) ** 2)) / r)
    theta = np.unwrap(np.angle(H - centre))
    # angle sweep rate at the midpoints; the resonance is where it is largest
    wm = 0.5 * (w[1:] + w[:-1])
    rate = np.abs(np.diff(theta) / np.diff(w))
    i = int(np.argmax(rate))
    if 0 < i < rate.size - 1:
        y0, y1, y2 = rate[i - 1 : i + 2]
        den = y0 - 2 * y1 + y2
        d = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5)) if den < 0 else 0.0
        h = wm[i + 1] - wm[i] if d > 0 else wm[i] - wm[i - 1]
        nu = wm[i] + d * h
    else:
        nu = wm[i]
    if not w[0] < nu < w[-1]:
        raise DataError(f"no resonance inside the band [{w[0]:g}, {w[-1]:g}] rad/s")
    psi = float(np.interp(nu, w, theta))
    phi = np.angle(np.exp(1j * (theta - psi)))  # wrapped to (-pi, pi]
    # pairs far enough from the resonance (phi ~ 0, noisy) and from its opposite (tan blows up)
    usable = (np.abs(phi) > np.deg2rad(10)) & (np.abs(phi) < np.deg2rad(170))
    below = np.flatnonzero((w < nu) & usable)
    above = np.flatnonzero((w > nu) & usable)
    if below.size == 0 or above.size == 0:
        # fall back on the nearest points either side
        below = np.flatnonzero(w < nu)[-2:]
        above = np.flatnonzero(w > nu)[:2]
    ta = np.tan(phi[below] / 2)[:, None]
    tb = np.tan(phi[above] / 2)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        mus = (w[below][:, None] - w[above][None, :]) / (ta - tb)
    mus = mus[np.isfinite(mus)]
    if mus.size == 0:
        raise DataError("circle fit: no usable pair of points around the resonance")
    mu = float(np.median(mus))
    q75, q25 = np.percentile(mus, [75, 25])
    spread = float(abs(q75 - q25) / abs(mu)) if mu != 0 else np.inf
    if angle_fit and mu < 0 and w.size >= 6:
        # all points at once: least squares of theta(w) = psi + 2 arctan((w - nu) / mu),
        # started from the estimates above (a differenced angle is noisy on a fine grid)
        def resid(x):
            return theta - (x[0] + 2 * np.arctan((w - x[1]) / x[2]))

        x0 = np.array([psi, nu, mu])
        try:
            sol = least_squares(resid, x0, x_scale=np.array([1.0, abs(mu), abs(mu)]),
                                bounds=([-np.inf, w[0], -np.inf], [np.inf, w[-1], 0.0]))
            if sol.success and sol.x[2] < 0:
                psi, nu, mu = (float(v) for v in sol.x)
        except ValueError:
            pass
    A = r * abs(2 * mu) * np.exp(1j * psi)
    residual = centre + A / (2 * mu)
    return CircleFit(complex(mu, nu), complex(A), complex(residual), complex(centre), r,
                     w, H, err, spread)


@dataclass(frozen=True)
class CircleFitModes:
    """Circle fits of several modes in several FRFs.

    Attributes
    ----------
    estimate : ModalEstimate
        Poles averaged over the outputs (weighted by circle radius), residues from each
        output's circle.
    fits : tuple of tuple of CircleFit
        ``fits[k][i]`` is the fit of mode ``k`` in output ``i`` (None where it failed).
    bands : ndarray, shape (n_modes, 2)
        Bands used, rad/s.
    """

    estimate: ModalEstimate
    fits: tuple
    bands: np.ndarray

    def model(self, omega_rad_s) -> np.ndarray:
        """Sum of the fitted single-mode terms (without residual constants), shape (n, s)."""
        w = np.asarray(omega_rad_s, dtype=float)
        lam = self.estimate.poles
        R = self.estimate.residues
        out = np.zeros((w.size, R.shape[1]), complex)
        for k in range(lam.size):
            out += R[k] / (1j * w[:, None] - lam[k])
            out += np.conj(R[k]) / (1j * w[:, None] - np.conj(lam[k]))
        return out


def circle_fit_modes(
    frf: FRF,
    n_modes: int | None = None,
    *,
    bands: np.ndarray | None = None,
    search_band: tuple[float, float] | None = None,
    half_widths: float = 2.0,
    reference: int = 0,
    max_circle_error: float = 0.15,
    min_prominence: float = 1.3,
) -> CircleFitModes:
    """Circle fit of each resonance of a column of FRFs.

    Parameters
    ----------
    frf : FRF
        One input, ``s`` outputs.
    n_modes : int, optional
        Number of modes to fit when ``bands`` is not given (most prominent peaks).
    bands : ndarray, shape (n_modes, 2), optional
        Band around each mode, rad/s; by default from ``pick_peaks``.
    search_band : (lo, hi), optional
        Band searched for peaks, rad/s.
    half_widths : float
        Half-width of automatic bands, in half-power bandwidths.
    reference : int
        Output the mode shapes are normalised on.
    max_circle_error : float
        A mode is marked not identified if the points of every output deviate from their
        circle by more than this fraction of the radius (RMS) ...
    min_prominence : float
        ... or if no output shows a peak at least this prominent (``peak_prominence``).

    Returns
    -------
    CircleFitModes
    """
    if bands is None:
        peaks = pick_peaks(frf, n_modes, band=search_band, half_widths=half_widths)
        bands = peaks.band
    bands = np.asarray(bands, dtype=float).reshape(-1, 2)
    if bands.shape[0] == 0:
        raise DataError("no resonance peak found for the circle fit")
    poles, residues, ident, fits, notes = [], [], [], [], []
    for k, (lo, hi) in enumerate(bands):
        row = []
        for i in range(frf.n_outputs):
            try:
                row.append(circle_fit(frf.omega_rad_s, frf.H[:, i], (lo, hi)))
            except DataError as exc:
                row.append(None)
                notes.append(f"mode {k + 1}, output {i + 1}: {exc}")
        fits.append(tuple(row))
        ok = [f for f in row if f is not None and f.pole.real < 0]
        if not ok:
            poles.append(complex(np.nan, 0.5 * (lo + hi)))
            residues.append(np.full(frf.n_outputs, np.nan + 0j))
            ident.append(False)
            notes.append(f"mode {k + 1}: no stable circle in [{lo:.4g}, {hi:.4g}] rad/s")
            continue
        wts = np.array([f.radius for f in ok])
        lam = complex(np.sum(wts * np.array([f.pole for f in ok])) / wts.sum())
        mu = lam.real
        # residue of each output from its circle, with the averaged decay rate
        R = np.array(
            [f.radius * abs(2 * mu) * np.exp(1j * np.angle(f.residue)) if f is not None
             else np.nan for f in row],
            dtype=complex,
        )
        poles.append(lam)
        residues.append(R)
        good_circle = min(f.circle_error for f in ok) <= max_circle_error
        try:
            prominent = np.nanmax(peak_prominence(frf, (lo, hi))) >= min_prominence
        except DataError:  # band too narrow for the frequency grid
            prominent = False
        ident.append(bool(good_circle and prominent))
        if not good_circle:
            notes.append(f"mode {k + 1}: points do not lie on a circle")
        if not prominent:
            notes.append(f"mode {k + 1}: no resonance peak in [{lo:.4g}, {hi:.4g}] rad/s")
    est = modal_estimate("circle", np.array(poles), np.array(residues), np.array(ident),
                         reference=reference, notes=notes)
    return CircleFitModes(est, tuple(fits), bands)
