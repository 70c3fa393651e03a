"""From a measured experiment to modal parameters with a chosen EMA method.

This glues the methods together the way lecture 11 describes the workflow: estimate the
FRF column (motor volts to cart positions, m/V), choose the band from the resonance
peaks, fit, and check the result against the FRF.

- ``"circle"``: circle fit of the ``n_modes`` most prominent peaks;
- ``"multimode"``: multi-mode fit with residual terms over the band, started from circle
  fits;
- ``"tfest"``: rational fit with ``2 * order`` poles over the band;
- ``"lsce"``: LSCE with ``order`` modes on the free decays after the pulses (pulse data,
  and step data through their increments, where each step is an impulse) or on the IRF
  from the FRF (other data).  The order is over-specified by default
  (``2 n_modes``) so that the extra roots absorb noise and the dry-friction offset; roots
  outside the band (real poles, noise modes near the Nyquist frequency) are left out of
  the estimate (they remain in ``details``) and in-band computational modes are flagged.

Frequencies where the input has (almost) no energy, such as the zeros of the spectrum of
rectangular pulses, are left out of the peaks and the fits (``FRF.reliable``).

Whatever the method, a mode is finally kept as identified only if the FRF shows a
resonance where it lies (``peak_prominence`` of at least ``min_prominence`` in some output
over ``nu +- 3 zeta omega``).  This is how a mode that the excitation did not reach (the
third mode in the sine sweeps, report section 5) is reported as not identified.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .._errors import ConfigError, DataError
from ..data import check_identifiable
from .circle import circle_fit_modes
from .excitation import free_decay_segments, is_pulse_train, step_increments
from .forms import form_units, orders_of, receptance_estimate
from .frf import FRF, peak_prominence
from .irf import impulse_response
from .lsce import StabilizationDiagram, lsce, lsce_frf, stabilization_diagram
from .multimode import _linear, modal_basis, multimode_fit
from .peaks import pick_peaks
from .record_frf import choose_frf_method, frf_from_experiment
from .result import ModalEstimate
from .tfest import tfest

__all__ = ["EMAResult", "identify", "METHODS", "default_band", "check_resonances"]

METHODS = ("lsce", "circle", "multimode", "tfest")


@dataclass(frozen=True)
class EMAResult:
    """Modal estimate of one experiment with the data it came from.

    Attributes
    ----------
    estimate : ModalEstimate
    frf : FRF
        The measured FRF (m/V).
    fitted : ndarray of complex, shape (n_freq, n_outputs), or None
        The identified model on ``frf.omega_rad_s`` (for plots).
    band : ndarray, shape (2,)
        Band used, rad/s.
    details : object
        The method's own result (``CircleFitModes``, ``MultiModeFit``, ``TFEstimate`` or
        ``LSCEResult``).
    stabilization : StabilizationDiagram or None
        LSCE fits over a range of orders (only when requested).
    frf_method : str or None
        How the FRF was estimated (``"pulse"``, ``"step"``, ``"impact"``, ``"welch"`` or
        ``"transient"``, what ``"auto"`` chose); None for an FRF given to ``identify``.
    """

    estimate: ModalEstimate
    frf: FRF
    fitted: np.ndarray | None
    band: np.ndarray
    details: object
    stabilization: StabilizationDiagram | None = None
    frf_method: str | None = None

    def as_dict(self) -> dict:
        """JSON-ready summary: the estimate plus the band and FRF settings."""
        out = self.estimate.as_dict()
        out.update({
            "band_rad_s": self.band.tolist(),
            "frf_method": self.frf_method,
            "frf_units": self.frf.units,
            "frf_estimator": self.frf.estimator,
            "frf_averages": int(self.frf.n_averages),
            "mode_shape_reference": f"output {self.estimate.reference + 1} (cart 1 = 1)",
        })
        return out


def default_band(frf: FRF, n_modes: int) -> tuple[float, float]:
    """Band around the ``n_modes`` most prominent peaks: 0.4 x lowest to 1.4 x highest.

    Raises
    ------
    DataError
        When the FRF shows no resonance peak where the input has energy.
    """
    pk = pick_peaks(frf, n_modes)
    if pk.omega_rad_s.size == 0:
        raise DataError(
            "no mode identified: the FRF shows no resonance peak where the input has energy "
            f"({frf.omega_rad_s[0]:.3g}..{frf.omega_rad_s[-1]:.3g} rad/s); give the band "
            "with --band LO HI (rad/s), or a record that excites the modes (pulses, or a "
            "step that is followed long enough to settle)")
    lo = max(frf.omega_rad_s[0], 0.4 * pk.omega_rad_s.min())
    hi = min(frf.omega_rad_s[-1], 1.4 * pk.omega_rad_s.max())
    return float(lo), float(hi)


def check_resonances(
    estimate: ModalEstimate, frf: FRF, *, min_prominence: float = 1.5, width: float = 3.0
) -> ModalEstimate:
    """Mark modes not identified where the FRF shows no resonance peak at the pole.

    For a pole ``mu + j nu`` the band ``nu +- width |mu|`` is examined.  Some output must
    have its largest ``|H|`` in the band within ``|mu| / 2`` (plus two frequency steps) of
    ``nu``, rising above both band edges by ``min_prominence`` (``peak_prominence``).  An
    isolated mode passes easily (``sqrt(1 + width^2)`` = 3.2 for one mode alone); a pole
    that only borrows the flank of a neighbouring mode, or a band where ``|H|`` just
    levels off, does not.

    Parameters
    ----------
    estimate : ModalEstimate
    frf : FRF
    min_prominence : float
        Required rise of the peak above the band edges.
    width : float
        Half-width of the band checked, in ``|mu| = zeta omega`` (at most 35 % of the
        frequency and at least 3 frequency steps).

    Returns
    -------
    ModalEstimate
        A copy with updated ``identified`` and notes.
    """
    ident = np.array(estimate.identified, bool)
    notes = list(estimate.notes)
    w = frf.omega_rad_s
    step = float(np.median(np.diff(w)))
    for k in np.flatnonzero(ident):
        mu, nu = estimate.poles[k].real, estimate.poles[k].imag
        half = max(min(width * abs(mu), 0.35 * nu), 3 * step)
        lo, hi = nu - half, nu + half
        if lo < w[0] or hi > w[-1]:
            continue
        if np.count_nonzero((w >= lo) & (w <= hi)) < 3:
            ident[k] = False
            notes.append(f"mode at {estimate.omega_rad_s[k]:.4g} rad/s not identified: the "
                         "input has (almost) no energy around it")
            continue
        sub = frf.band(lo, hi)
        mag = np.abs(sub.H)
        i = np.argmax(mag, axis=0)
        near = np.abs(sub.omega_rad_s[i] - nu) <= 0.5 * abs(mu) + 2 * step
        prom = peak_prominence(frf, (lo, hi))
        best = float(np.max(np.where(near, prom, 0.0)))
        if best < min_prominence:
            ident[k] = False
            notes.append(
                f"mode at {estimate.omega_rad_s[k]:.4g} rad/s not identified: no resonance "
                f"peak at the pole in the FRF (rise {best:.3g} < {min_prominence})"
            )
    return replace(estimate, identified=ident, notes=tuple(notes))


def _subset(est: ModalEstimate, keep: np.ndarray) -> ModalEstimate:
    return replace(est, omega_rad_s=est.omega_rad_s[keep], zeta=est.zeta[keep],
                   poles=est.poles[keep], residues=est.residues[keep],
                   mode_shapes=est.mode_shapes[keep], identified=est.identified[keep],
                   pole_cov=None if est.pole_cov is None else est.pole_cov[keep])


def _fitted_from_poles(frf: FRF, poles: np.ndarray, band) -> np.ndarray:
    # residues and residual terms by linear least squares with the poles fixed
    sub = frf.band(*band)
    G, _ = modal_basis(sub.omega_rad_s, poles, frf.derivative_order)
    a, _ = _linear(G, sub.H)
    Gall, _ = modal_basis(frf.omega_rad_s, poles, frf.derivative_order)
    return Gall @ a


def _lsce_fit(u, y, dt: float, full: FRF, band, n: int, *, stride, decay_s, reference,
              stabilization_orders):
    """LSCE of order ``n`` on the free decays after the pulses (pulse data) or on the IRF
    of the whole FRF ``full`` (other data); the fit and its stabilisation diagram (None
    without ``stabilization_orders``)."""
    stab = None
    if is_pulse_train(u):
        seg = free_decay_segments(u, dt, duration_s=decay_s)
        recs = [y[a:b] for a, b in seg]
        stride = _stride(stride, dt, band, min(b - a for a, b in seg), n)
        det = lsce(recs, dt, n, stride=stride, reference=reference)
        if stabilization_orders is not None:
            stab = stabilization_diagram(recs, dt, stabilization_orders, stride=stride)
    else:
        irf = impulse_response(full)
        stride = _stride(stride, irf.dt, band, irf.h.shape[0], n)
        det = lsce_frf(full, n, stride=stride, reference=reference)
        if stabilization_orders is not None:
            stab = stabilization_diagram(irf.h, irf.dt, stabilization_orders, stride=stride)
    return det, stab


def _in_band(est: ModalEstimate, band) -> ModalEstimate:
    """Keep the oscillating poles of the band; the rest (real poles, noise modes near the
    Nyquist frequency) stay in the fit's ``details``, named in a note."""
    keep = (est.poles.imag >= band[0]) & (est.poles.imag <= band[1])
    dropped = [f"{lam:.4g}" for lam in est.poles[~keep]]
    est = _subset(est, keep)
    if dropped:
        est = replace(est, notes=est.notes + (
            f"{len(dropped)} root(s) outside the band left out: {', '.join(dropped)} 1/s",))
    return est


def identify(
    experiment,
    method: str = "lsce",
    *,
    n_modes: int = 3,
    order: int | None = None,
    band: tuple[float, float] | None = None,
    frf: FRF | None = None,
    stride: int | None = None,
    decay_s: float | None = 3.0,
    min_prominence: float = 1.5,
    reference: int = 0,
    stabilization_orders=None,
    frf_method: str = "auto",
    output_kinds: Sequence[str] | None = None,
    input_kind: str = "voltage",
) -> EMAResult:
    """Experimental modal analysis of one experiment.

    Parameters
    ----------
    experiment : bayesmodal.data.Experiment
        Motor voltage and cart positions.
    method : {"lsce", "circle", "multimode", "tfest"}
    n_modes : int
        Number of modes sought (peaks for circle and multi-mode fits).
    order : int, optional
        Model order in modes: LSCE polynomial order ``2 order`` (default ``2 n_modes``),
        tfest denominator order ``2 order`` (default ``n_modes``).
    band : (lo, hi), optional
        Band, rad/s (default ``default_band``).
    frf : FRF, optional
        Precomputed FRF (default ``frf_from_experiment(experiment)``).
    stride : int, optional
        LSCE sample stride (default: Nyquist frequency about 1.5 times the band's upper
        end, which conditions the polynomial far better than dense sampling).
    decay_s : float or None
        Length of each free decay used by LSCE on pulse data, s (None: until the next
        pulse).  Dry friction stops the rig within a few seconds.
    min_prominence : float
        See ``check_resonances``.
    reference : int
        Output the mode shapes are normalised on (0 = cart 1).
    stabilization_orders : sequence of int, optional
        With ``method="lsce"``, also fit these orders for a stabilisation diagram.
    frf_method : {"auto", "pulse", "step", "impact", "welch", "transient"}
        How the FRF is estimated (``frf_from_experiment``; ``"auto"``:
        ``choose_frf_method``, which takes ``"impact"`` for a hammer test when
        ``input_kind`` is ``"force"``).  A step record (``"step"``, or ``"transient"``
        ending at another input level) is analysed through its increments: each step is
        an impulse and LSCE fits the decays after the steps.
    output_kinds : sequence of str, optional
        Sensor kind of each output (``Rig.output_kinds``): the FRF is read in the
        sensors' form (receptance, mobility or accelerance when they share one kind) and
        the residues are returned in receptance units, divided by ``lambda^p`` per output
        (``forms.receptance_estimate``), so that mode shapes from mixed sensors compare.
        Default: every output a position.
    input_kind : {"voltage", "force"}
        What the input is (``Rig.input``): the FRF's units (per V or per N), and only a
        force's hits are read as a hammer test.

    Notes
    -----
    The frequency-domain fits, the peaks and the resonance check use only the
    frequencies where the input had energy (``FRF.reliable``); near the zeros of the
    spectrum of rectangular pulses the estimate is noise over almost nothing.

    Returns
    -------
    EMAResult

    Raises
    ------
    ConfigError
        Unknown method or invalid order.
    """
    if method not in METHODS:
        raise ConfigError(f"method must be one of {METHODS}, got {method!r}")
    if n_modes < 1 or (order is not None and order < 1):
        raise ConfigError(f"n_modes and order must be >= 1, got {n_modes}, {order}")
    u, y = experiment.v_volt, experiment.y_m
    chosen = (choose_frf_method(u, input_kind=input_kind) if frf_method == "auto"
              else frf_method)
    if chosen == "step" or (chosen == "transient" and u[-1] != u[0]):
        u, y = step_increments(u, y)
    orders = None if output_kinds is None else orders_of(output_kinds)
    if orders is not None and orders.size != y.shape[1]:
        raise ConfigError(f"output_kinds lists {orders.size} kinds for {y.shape[1]} outputs; "
                          "give one per output (Rig.output_kinds)")
    if frf is None:
        check_identifiable(experiment)
        frf = frf_from_experiment(experiment, method=chosen, input_kind=input_kind)
        if orders is not None and np.all(orders == orders[0]):
            frf = replace(frf, derivative_order=int(orders[0]),
                          units=form_units(int(orders[0]), input_kind))
    else:
        chosen = None  # an FRF given: how it was estimated is not known here
    full = frf
    frf = full.reliable()
    pre_notes = []
    if frf.omega_rad_s.size < full.omega_rad_s.size:
        pre_notes.append(f"{full.omega_rad_s.size - frf.omega_rad_s.size} of "
                         f"{full.omega_rad_s.size} frequencies left out: the input has "
                         "(almost) no energy there")
    if band is None:
        band = default_band(frf, n_modes)
    band = (float(band[0]), float(band[1]))
    dt = experiment.dt
    fitted = None
    stab = None
    if method == "circle":
        det = circle_fit_modes(frf, n_modes, search_band=band, reference=reference)
        est = det.estimate
        fitted = _fitted_from_poles(frf, est.poles[np.isfinite(est.poles)], band)
    elif method == "multimode":
        mixed = orders is not None and np.any(orders != orders[0])
        det = multimode_fit(frf, band=band, n_modes=n_modes, reference=reference,
                            derivative_orders=orders if mixed else None)
        est = det.estimate
        fitted = det.model(frf.omega_rad_s)
    elif method == "tfest":
        det = tfest(frf, 2 * (order or n_modes), band=band, reference=reference)
        est = det.estimate
        fitted = det.frf(frf.omega_rad_s)
    else:
        det, stab = _lsce_fit(u, y, dt, full, band, order or 2 * n_modes, stride=stride,
                              decay_s=decay_s, reference=reference,
                              stabilization_orders=stabilization_orders)
        est = _in_band(det.estimate, band)
        if np.any(est.identified):
            fitted = _fitted_from_poles(frf, est.poles[est.identified], band)
    est = check_resonances(est, frf, min_prominence=min_prominence)
    n_found = int(np.count_nonzero(est.identified))
    if n_found < n_modes:
        pre_notes.append(f"{n_found} of the {n_modes} modes sought identified in "
                         f"{band[0]:.4g}..{band[1]:.4g} rad/s")
    if orders is not None and np.any(orders > 0):
        est = receptance_estimate(est, orders)
        pre_notes.append("residues in receptance units: each output's divided by "
                         f"lambda^p, p = {orders.tolist()} (its sensor's derivative order)")
    est = replace(est, notes=tuple(pre_notes) + est.notes)
    return EMAResult(est, frf, fitted, np.array(band), det, stab, chosen)


def _stride(stride: int | None, dt: float, band, shortest: int, n: int) -> int:
    """LSCE sample stride: by default a Nyquist frequency about 1.5 times the band's
    upper end (which conditions the polynomial far better than dense sampling), but
    never so coarse that the shortest record keeps fewer than ``6 n`` samples (``2 n``
    coefficients need at least as many equations per record)."""
    if stride is not None:
        return stride
    by_band = int(np.floor(np.pi / (dt * 1.5 * band[1])))
    by_length = shortest // (6 * n)
    return max(1, min(by_band, by_length))
