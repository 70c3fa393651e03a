"""Impact (hammer) tests: finding the hits, force and exponential windows, the FRF.

A hammer hit is a pulse of a few milliseconds; between hits the force channel carries
only its sensor's noise, and the response rings down.  The classical processing:

- **force window**: keep the force from shortly before each hit to shortly after it and
  zero the rest, which removes the force sensor's noise from the spectrum;
- **exponential window**: multiply the response (and the force) of each hit's segment by
  ``exp(-t / tau)``, so that a lightly damped response dies within the segment (no
  leakage).  Each term ``r e^(lambda t)`` becomes ``r e^((lambda - 1/tau) t)``: the
  window adds ``1/tau`` to every decay rate, and :func:`correct_exponential_window`
  subtracts it from the identified poles;
- **double impacts**: a hammer that bounces hits twice within milliseconds; the second
  hit's force is not the first's shape, and such a record is refused
  (:func:`find_impacts`).

The FRF is H1, H2 or Hv averaged over the hits, in the sensor's form (receptance,
mobility or accelerance per newton).  ``frf_from_experiment`` and ``identify`` take it
(without an exponential window) for a force input of isolated hits
(:func:`~.excitation.is_impact_train`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .._errors import DataError
from .excitation import IMPACT_THRESHOLD
from .frf import ESTIMATORS, FRF, _check_io, _estimate, summed_spectra, zoh_factor
from .result import ModalEstimate

__all__ = ["IMPACT_THRESHOLD", "Impacts", "correct_exponential_window", "find_impacts",
           "force_window", "impact_frf"]

#: Two pulses closer than this are one bouncing hit (a double impact), s.
DOUBLE_IMPACT_GAP_S = 0.05


@dataclass(frozen=True)
class Impacts:
    """The hits of a hammer record.

    Attributes
    ----------
    starts, stops : ndarray of int, shape (n_hits,)
        First sample above the threshold and one past the last, per hit.
    peaks_n : ndarray, shape (n_hits,)
        Largest force of each hit, N.
    dt : float
        Sample interval, s.
    """

    starts: np.ndarray
    stops: np.ndarray
    peaks_n: np.ndarray
    dt: float

    @property
    def n_hits(self) -> int:
        return int(self.starts.size)

    @property
    def times_s(self) -> np.ndarray:
        """Start of each hit, s from the record's first sample."""
        return self.starts * self.dt


def find_impacts(force, dt: float, *, threshold: float = IMPACT_THRESHOLD,
                 double_gap_s: float = DOUBLE_IMPACT_GAP_S) -> Impacts:
    """The hits of a hammer record, refusing a double impact.

    Parameters
    ----------
    force : ndarray, shape (N,)
        Measured force, N.
    dt : float
        Sample interval, s.
    threshold : float
        A sample belongs to a hit when ``|force|`` exceeds this fraction of the largest.
    double_gap_s : float
        Pulses separated by less than this are one bouncing hit, s.

    Returns
    -------
    Impacts

    Raises
    ------
    DataError
        No hit, or a double impact (one line with its time and the fix).

    Examples
    --------
    >>> f = np.zeros(1000); f[100:103] = 50.0; f[600:603] = 40.0
    >>> find_impacts(f, 0.001).starts.tolist()
    [100, 600]
    """
    f = np.abs(np.asarray(force, dtype=float))
    if f.ndim != 1 or f.size < 8 or not np.all(np.isfinite(f)):
        raise DataError(f"force must be a finite 1-D record of >= 8 samples, got shape "
                        f"{np.shape(force)}")
    if not 0 < threshold < 1:
        raise DataError(f"threshold must lie in (0, 1), got {threshold!r}")
    peak = float(f.max())
    if peak == 0:
        raise DataError("the force record is zero: no hit to analyse")
    above = np.r_[False, f > threshold * peak, False]
    edges = np.flatnonzero(np.diff(above.astype(np.int8)))
    starts, stops = edges[0::2], edges[1::2]
    gaps = (starts[1:] - stops[:-1]) * dt
    bounce = np.flatnonzero(gaps < double_gap_s)
    if bounce.size:
        k = int(bounce[0])
        raise DataError(
            f"double impact at t = {starts[k] * dt:.4g} s: a second pulse follows "
            f"{gaps[k] * 1e3:.3g} ms after the hit (the hammer bounced); repeat the hit, "
            "or cut the record before it")
    peaks = np.array([f[a:b].max() for a, b in zip(starts, stops, strict=True)])
    return Impacts(starts, stops, peaks, float(dt))


def force_window(force, impacts: Impacts, *, pre_s: float = 0.002,
                 post_s: float = 0.005) -> np.ndarray:
    """The force with everything but the hits zeroed.

    Parameters
    ----------
    force : ndarray, shape (N,)
        Measured force, N.
    impacts : Impacts
        From :func:`find_impacts`.
    pre_s, post_s : float
        Kept before each hit's first and after its last sample above the threshold, s.

    Returns
    -------
    ndarray, shape (N,)
        N.
    """
    f = np.asarray(force, dtype=float)
    keep = np.zeros(f.size, bool)
    pre = int(np.ceil(pre_s / impacts.dt))
    post = int(np.ceil(post_s / impacts.dt))
    for a, b in zip(impacts.starts, impacts.stops, strict=True):
        keep[max(a - pre, 0) : min(b + post, f.size)] = True
    return np.where(keep, f, 0.0)


def impact_frf(
    force,
    y,
    dt: float,
    *,
    tau_s: float | None = None,
    estimator: str = "H1",
    pre_s: float = 0.002,
    post_s: float = 0.005,
    n_fft: int | None = None,
    threshold: float = IMPACT_THRESHOLD,
    zoh: bool = True,
    derivative_order: int = 0,
    units: str = "m/N",
) -> FRF:
    """FRF of a hammer test averaged over its hits, force- and exponentially windowed.

    Each hit's segment runs from ``pre_s`` before it to ``pre_s`` before the next hit (the
    record's end for the last); all segments are cut to the shortest.  The force is
    windowed (:func:`force_window`), then force and response are multiplied by
    ``exp(-t / tau_s)`` from the segment's start.

    Parameters
    ----------
    force : ndarray, shape (N,)
        Measured force, N.
    y : ndarray, shape (N,) or (N, n_outputs)
        Responses in SI units of their kind (m, m/s or m/s^2).
    dt : float
        Sample interval, s.
    tau_s : float, optional
        Time constant of the exponential window, s; None: no window.  Correct the
        identified poles with :func:`correct_exponential_window`.
    estimator : {"H1", "H2", "Hv"}
    pre_s, post_s : float
        Force window around each hit, s.
    n_fft : int, optional
        FFT length (default the segment length).
    threshold : float
        Hit threshold, a fraction of the largest force (:func:`find_impacts`).
    zoh : bool
        Divide out the zero-order hold (a force held between samples, as the simulators
        hold it); False for a force sampled from a continuous signal.
    derivative_order : int
        0 receptance, 1 mobility, 2 accelerance (the sensors' form).
    units : str
        Units of H (``"m/s^2/N"`` for accelerance).

    Returns
    -------
    FRF
        With the coherence over the hits when there are several.

    Raises
    ------
    DataError
        A double impact, too short segments, a bad window or estimator.
    """
    f, y, dt = _check_io(force, y, dt)
    if estimator not in ESTIMATORS:
        raise DataError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    if tau_s is not None and not (np.isfinite(tau_s) and tau_s > 0):
        raise DataError(f"tau_s must be finite and > 0 s, got {tau_s!r}")
    hits = find_impacts(f, dt, threshold=threshold)
    fw = force_window(f, hits, pre_s=pre_s, post_s=post_s)
    pre = int(np.ceil(pre_s / dt))
    starts = np.maximum(hits.starts - pre, 0)
    stops = np.r_[starts[1:], f.size]
    length = int(np.min(stops - starts))
    if length < 16:
        raise DataError(f"hits {length * dt:.3g} s apart leave too short segments; space "
                        "the hits further")
    n_fft = length if n_fft is None else int(n_fft)
    if n_fft < length:
        raise DataError(f"n_fft = {n_fft} is shorter than the segments ({length})")
    win = np.ones(length) if tau_s is None else np.exp(-np.arange(length) * dt / tau_s)
    Suu, Syu, Syy = summed_spectra(
        ((fw[a : a + length] * win, y[a : a + length] * win[:, None]) for a in starts), n_fft)
    w = 2 * np.pi * np.fft.rfftfreq(n_fft, dt)
    keep = w > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        H, coh = _estimate(Syu[keep], Suu[keep], Syy[keep], estimator)
    w = w[keep]
    if zoh:
        H = H / zoh_factor(w, dt)[:, None]
    n_avg = int(starts.size)
    power = Suu[keep] / np.max(Suu[keep])
    return FRF(w, np.nan_to_num(H), coh if n_avg > 1 else None, estimator, units, n_avg, dt,
               int(derivative_order), power, zoh_divided=bool(zoh))


def correct_exponential_window(est: ModalEstimate, tau_s: float) -> ModalEstimate:
    """Remove the damping an exponential window ``exp(-t / tau_s)`` added.

    The window turns each pole ``lambda`` into ``lambda - 1/tau_s``; the true pole is the
    identified one plus ``1/tau_s``, with ``omega = |lambda|`` and ``zeta = -Re(lambda) /
    |lambda|`` recomputed.

    Parameters
    ----------
    est : ModalEstimate
        Identified from an exponentially windowed FRF.
    tau_s : float
        The window's time constant, s.

    Returns
    -------
    ModalEstimate

    Examples
    --------
    >>> from bayesmodal.ema.result import modal_estimate
    >>> est = modal_estimate("demo", [-0.1 - 0.5 + 10j], [[1.0]])
    >>> round(float(correct_exponential_window(est, 2.0).poles[0].real), 12)
    -0.1
    """
    if not (np.isfinite(tau_s) and tau_s > 0):
        raise DataError(f"tau_s must be finite and > 0 s, got {tau_s!r}")
    lam = est.poles + 1.0 / tau_s
    omega = np.abs(lam)
    with np.errstate(divide="ignore", invalid="ignore"):
        zeta = -lam.real / omega
    return replace(est, poles=lam, omega_rad_s=omega, zeta=zeta, notes=est.notes + (
        f"exponential window tau = {tau_s:g} s: {1.0 / tau_s:.4g} 1/s of added decay "
        "removed from every pole",))
