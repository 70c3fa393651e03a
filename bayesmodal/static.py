"""Steady-state (static) analysis of a step experiment (report section 2.1).

With the carts at rest under a constant voltage ``v``, ``x' = x'' = 0`` and the equations
of motion reduce to ``K x_inf = b v`` (report eq. 11-13).  For a chain of springs
grounded at the last cart the force ``g_v v`` is carried in series by every spring, so

    k_n x_n            = g_v v          (the last spring alone holds the motor force)
    k_i (x_i - x_{i+1}) = g_v v          (i = 1 .. n-1)

and, with the last stiffness ``k_n`` taken as known (report: "k3 is fixed to the nominal
value"), the plateau levels give

    g_v     = k_n x_n / v
    k_n/k_i = (x_i - x_{i+1}) / x_n.

For three carts these are ``R31 = k3/k1 = (x1 - x2)/x3`` and ``R32 = k3/k2 = (x2 - x3)/x3``
(report eq. 15-16 with errata 8; the report's eq. 16 drops the ``1 +`` of the x2 row).

Plateaus are found without hard-coded times: the input is split into segments of
constant voltage, and in each the outputs are "settled" from the point after which a
short moving average stays within a noise-based tolerance of the segment's final level.
A margin after that point (a fraction of the settling time) keeps the tail of the
transient out of the average.

Reference level.  Dry friction makes the carts stick a little short of the linear
equilibrium: after each "off" half-cycle they rest a few tenths of a millimetre away
from zero (data_steps: x1 rests at +0.21, +0.09, -0.05, -0.02 mm).  Two conventions are
offered:

- ``reference="zero"`` (the report's): ``x_inf`` is the on-plateau level measured from
  the encoder zero, i.e. the spring equilibrium at the start of the record;
- ``reference="previous"``: ``x_inf`` is the on-plateau level minus the rest level just
  before the step, and ``v`` the voltage step.

Neither is friction-free: the on-levels stick short of the linear equilibrium, and the
rest levels that "previous" subtracts stick away from zero.  On data_steps the two give
g_v 6.050 and 6.086 N/V (0.6 % apart) and k3/k1 0.490 and 0.478 (2.5 % apart, several
standard errors), so the report job shows both; "zero" is the default because it is the
report's convention and the levels spread less from step to step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._errors import DataError, ModelError
from .data import Experiment
from .model.system import Rig

__all__ = [
    "NOMINAL_G_V",
    "Plateaus",
    "StaticResult",
    "find_plateaus",
    "steady_state",
    "static_levels",
    "gains_from_levels",
]

#: Nominal voltage-to-force gain, N/V: ``k_a k_t k_mp = 2 * 0.1 * 26.25`` (errata 9).
NOMINAL_G_V = 5.25

_REFERENCES = ("zero", "previous")


@dataclass(frozen=True)
class Plateaus:
    """Settled windows of the constant-input segments of an experiment.

    Attributes
    ----------
    start, stop : ndarray of int, shape (n_plateaus,)
        Averaging window of each plateau, samples ``start:stop``.
    segment_start, segment_stop : ndarray of int, shape (n_plateaus,)
        The constant-input segment that holds each window.
    segment_index : ndarray of int, shape (n_plateaus,)
        Position of the segment among the candidate (long enough) constant-input
        segments, so that gaps show segments that did not settle.
    v_volt : ndarray, shape (n_plateaus,)
        Input level on each plateau, V.
    level_m : ndarray, shape (n_plateaus, n_outputs)
        Mean output over each window, m.
    std_m : ndarray, shape (n_plateaus, n_outputs)
        Standard deviation of the outputs over each window, m.
    unsettled : tuple of (int, int)
        Constant-input segments ``(start, stop)`` long enough to be considered but with no
        settled window.
    """

    start: np.ndarray
    stop: np.ndarray
    segment_start: np.ndarray
    segment_stop: np.ndarray
    segment_index: np.ndarray
    v_volt: np.ndarray
    level_m: np.ndarray
    std_m: np.ndarray
    unsettled: tuple[tuple[int, int], ...] = ()

    @property
    def n_plateaus(self) -> int:
        return int(self.start.size)

    @property
    def on(self) -> np.ndarray:
        """Boolean mask, shape (n_plateaus,), of plateaus with a non-zero input."""
        return self.v_volt != 0

    @property
    def off(self) -> np.ndarray:
        """Boolean mask, shape (n_plateaus,), of rest plateaus (zero input)."""
        return self.v_volt == 0


@dataclass(frozen=True)
class StaticResult:
    """Voltage-to-force gain and stiffness ratios from the plateaus of a step experiment.

    Attributes
    ----------
    experiment : Experiment
        The analysed record.
    plateaus : Plateaus
        All settled plateaus (on and off).
    reference : {"zero", "previous"}
        How ``x_inf_m`` is referenced (see the module docstring).
    on_index : ndarray of int, shape (n_steps,)
        Index into ``plateaus`` of each on-plateau used.
    x_inf_m : ndarray, shape (n_steps, n_carts)
        Static displacement of each step, m.
    v_inf_volt : ndarray, shape (n_steps,)
        Input of each step, V.
    g_v_each : ndarray, shape (n_steps,)
        Gain from each step alone, N/V.
    ratios_each : ndarray, shape (n_steps, n_carts - 1)
        Ratios ``k_n / k_i`` from each step alone.
    g_v : float
        Gain from the step-averaged displacement per volt, N/V (the report's recipe:
        average ``x_inf`` first, then solve eq. 16).
    g_v_se : float
        Standard error of ``g_v``: sample standard deviation of ``g_v_each`` over
        ``sqrt(n_steps)`` (NaN with one step), N/V.
    ratios : ndarray, shape (n_carts - 1,)
        Ratios ``k_n / k_i`` from the averaged displacement.
    ratios_se : ndarray, shape (n_carts - 1,)
        Their standard errors across steps.
    ratio_names : tuple of str
        ``("k3/k1", "k3/k2")`` for three carts.
    nominal_g_v : float
        N/V.
    nominal_ratios : ndarray, shape (n_carts - 1,)
        ``k_n / k_i`` of the rig's nominal springs.
    g_v_error_percent, ratios_error_percent : float, ndarray
        Relative errors ``100 (estimate - nominal) / nominal`` (errata 6), percent.
    """

    experiment: Experiment
    plateaus: Plateaus
    reference: str
    on_index: np.ndarray
    x_inf_m: np.ndarray
    v_inf_volt: np.ndarray
    g_v_each: np.ndarray
    ratios_each: np.ndarray
    g_v: float
    g_v_se: float
    ratios: np.ndarray
    ratios_se: np.ndarray
    ratio_names: tuple[str, ...]
    nominal_g_v: float
    nominal_ratios: np.ndarray
    g_v_error_percent: float
    ratios_error_percent: np.ndarray

    @property
    def n_steps(self) -> int:
        return int(self.on_index.size)

    def as_dict(self) -> dict:
        """JSON-ready summary (plain floats and lists)."""
        p = self.plateaus
        return {
            "reference": self.reference,
            "g_v": self.g_v,
            "g_v_se": self.g_v_se,
            "g_v_nominal": self.nominal_g_v,
            "g_v_error_percent": self.g_v_error_percent,
            "ratios": dict(zip(self.ratio_names, self.ratios.tolist(), strict=True)),
            "ratios_se": dict(zip(self.ratio_names, self.ratios_se.tolist(), strict=True)),
            "ratios_nominal": dict(
                zip(self.ratio_names, self.nominal_ratios.tolist(), strict=True)
            ),
            "ratios_error_percent": dict(
                zip(self.ratio_names, self.ratios_error_percent.tolist(), strict=True)
            ),
            "g_v_each": self.g_v_each.tolist(),
            "ratios_each": self.ratios_each.tolist(),
            "x_inf_m": self.x_inf_m.tolist(),
            "v_inf_volt": self.v_inf_volt.tolist(),
            "plateaus": {
                "t_start_s": self.experiment.t_s[p.start].tolist(),
                "t_stop_s": self.experiment.t_s[p.stop - 1].tolist(),
                "v_volt": p.v_volt.tolist(),
                "level_m": p.level_m.tolist(),
                "n_on": int(p.on.sum()),
                "n_off": int(p.off.sum()),
            },
        }


# ---------------------------------------------------------------------- plateaus
def _constant_segments(v: np.ndarray, min_samples: int) -> list[tuple[int, int]]:
    """Runs ``(start, stop)`` of equal input values at least ``min_samples`` long."""
    atol = 1e-9 * max(1.0, float(np.max(np.abs(v))))
    change = np.flatnonzero(np.abs(np.diff(v)) > atol) + 1
    edges = np.concatenate([[0], change, [v.size]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)
            if b - a >= min_samples]


def _moving_mean(y: np.ndarray, w: int) -> np.ndarray:
    """Trailing-window means ``mean(y[k:k+w])``, shape (len(y) - w + 1, n)."""
    c = np.cumsum(np.vstack([np.zeros((1, y.shape[1])), y]), axis=0)
    return (c[w:] - c[:-w]) / w


def find_plateaus(
    experiment: Experiment,
    *,
    min_duration_s: float | None = None,
    smooth_s: float | None = None,
    n_sigma: float = 5.0,
    rel_floor: float = 1e-3,
    margin: float = 0.5,
) -> Plateaus:
    """Find the settled part of every constant-input segment.

    Each run of equal input values longer than ``min_duration_s`` is a candidate.  Its
    final level is the median of its last quarter.  A trailing moving average of
    ``smooth_s`` is compared with that level; the outputs have settled after the last
    moving-average window that deviates by more than ``tol_j = max(n_sigma * s_j /
    sqrt(w), rel_floor * range_j)`` for some output ``j`` (``s_j`` the standard deviation
    of the last quarter, ``w`` the window in samples, ``range_j`` the output's range over
    the record; the floor copes with quantised encoders whose tail is exactly constant).
    The averaging window then starts ``margin`` times the settling time later and runs to
    the end of the segment.

    Parameters
    ----------
    experiment : Experiment
    min_duration_s : float, optional
        Shortest constant-input segment considered, s (default: 1/20 of the longest
        constant segment, at least 10 samples).  Shorter runs (single-sample transition
        values of the ECP controller) are ignored.
    smooth_s : float, optional
        Moving-average window, s (default 20 samples).
    n_sigma : float
        Tolerance in standard errors of the moving average.
    rel_floor : float
        Tolerance floor as a fraction of each output's range.
    margin : float
        Extra waiting time after settling, as a fraction of the settling time (>= 0).

    Returns
    -------
    Plateaus

    Raises
    ------
    DataError
        If the input never changes or no segment is long enough.

    Examples
    --------
    >>> from bayesmodal.data import find_data, load_experiment
    >>> p = find_data("ecp210-3dof/data_steps.mat")
    >>> plats = find_plateaus(load_experiment(p)) if p else None
    """
    e = experiment
    v = e.v_volt
    y = e.y_m
    if not (np.isfinite(n_sigma) and n_sigma > 0):
        raise DataError(f"n_sigma must be finite and > 0, got {n_sigma!r}")
    if not (np.isfinite(margin) and margin >= 0):
        raise DataError(f"margin must be finite and >= 0, got {margin!r}")
    if not (np.isfinite(rel_floor) and rel_floor >= 0):
        raise DataError(f"rel_floor must be finite and >= 0, got {rel_floor!r}")
    all_runs = _constant_segments(v, 1)
    if len(all_runs) < 2 and np.all(v == 0):
        raise DataError(f"{e.name}: the input is all zeros; there is no step to analyse")
    longest = max(b - a for a, b in all_runs)
    if min_duration_s is None:
        min_samples = max(10, longest // 20)
    else:
        if not (np.isfinite(min_duration_s) and min_duration_s > 0):
            raise DataError(f"min_duration_s must be finite and > 0 s, got {min_duration_s!r}")
        min_samples = max(3, int(round(min_duration_s / e.mean_dt)))
    # durations to sample counts by the mean step: a logger's jittered stamps too
    w = 20 if smooth_s is None else max(1, int(round(smooth_s / e.mean_dt)))
    segments = _constant_segments(v, max(min_samples, 2 * w))
    if not segments:
        raise DataError(
            f"{e.name}: no constant-input segment of at least {max(min_samples, 2 * w)} "
            f"samples (longest is {longest}); is this a step experiment?"
        )
    span = np.ptp(y, axis=0)
    rows, unsettled = [], []
    for index, (a, b) in enumerate(segments):
        seg = y[a:b]
        tail = seg[-max(3, (b - a) // 4):]
        level0 = np.median(tail, axis=0)
        s_tail = np.std(tail, axis=0, ddof=1)
        tol = np.maximum(n_sigma * s_tail / np.sqrt(w), rel_floor * span)
        tol = np.where(tol > 0, tol, np.finfo(float).tiny)
        dev = np.abs(_moving_mean(seg, w) - level0) / tol
        bad = np.flatnonzero(np.any(dev > 1.0, axis=1))
        settle = 0 if bad.size == 0 else int(bad[-1]) + w  # first sample after the transient
        start = settle + int(np.ceil(margin * settle))
        if (b - a) - start < max(3, w // 2):
            unsettled.append((a, b))
            continue
        win = y[a + start:b]
        rows.append((a + start, b, a, b, index, float(v[a]),
                     win.mean(axis=0), win.std(axis=0, ddof=1)))
    if not rows:
        return Plateaus(*(np.zeros(0, int) for _ in range(5)), np.zeros(0),
                        np.zeros((0, e.n_outputs)), np.zeros((0, e.n_outputs)),
                        tuple(unsettled))
    cols = list(zip(*rows, strict=True))
    return Plateaus(
        start=np.array(cols[0], int),
        stop=np.array(cols[1], int),
        segment_start=np.array(cols[2], int),
        segment_stop=np.array(cols[3], int),
        segment_index=np.array(cols[4], int),
        v_volt=np.array(cols[5]),
        level_m=np.array(cols[6]),
        std_m=np.array(cols[7]),
        unsettled=tuple(unsettled),
    )


# ---------------------------------------------------------------------- gains
def gains_from_levels(x_per_volt_m: np.ndarray, springs_n_m) -> tuple[np.ndarray, np.ndarray]:
    """Gain and stiffness ratios from static displacements per volt.

    Parameters
    ----------
    x_per_volt_m : ndarray, shape (..., n_carts)
        Static displacement per volt, m/V.
    springs_n_m : sequence of float, length n_carts
        Springs; only the last one (the spring to the frame) is used, N/m.

    Returns
    -------
    g_v : ndarray, shape (...)
        ``k_n x_n``, N/V.
    ratios : ndarray, shape (..., n_carts - 1)
        ``k_n / k_i = (x_i - x_{i+1}) / x_n``.

    Examples
    --------
    >>> rig = Rig()
    >>> K = rig.stiffness_matrix()
    >>> x = np.linalg.solve(K, [6.0, 0.0, 0.0])
    >>> g, r = gains_from_levels(x, rig.springs_n_m)
    >>> round(float(g), 12), np.round(r, 4).tolist()
    (6.0, [0.5116, 0.5143])
    """
    x = np.asarray(x_per_volt_m, dtype=float)
    k = np.asarray(springs_n_m, dtype=float)
    if x.shape[-1:] != k.shape:
        raise DataError(f"need {k.size} displacements per set, got shape {x.shape}")
    xn = x[..., -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = (x[..., :-1] - x[..., 1:]) / xn[..., None]
    return k[-1] * xn, ratios


def static_levels(rig: Rig, g_v: float) -> np.ndarray:
    """Static displacement per volt ``K^-1 b``, shape (n_carts,), m/V (report eq. 13)."""
    b = np.zeros(rig.n_carts)
    b[0] = g_v
    return np.linalg.solve(rig.stiffness_matrix(), b)


def _se(values: np.ndarray) -> np.ndarray:
    n = values.shape[0]
    if n < 2:
        return np.full(values.shape[1:], np.nan)
    return values.std(axis=0, ddof=1) / np.sqrt(n)


def steady_state(
    experiment: Experiment,
    *,
    rig: Rig | None = None,
    reference: str = "zero",
    nominal_g_v: float = NOMINAL_G_V,
    plateaus: Plateaus | None = None,
    **plateau_options,
) -> StaticResult:
    """Voltage-to-force gain and stiffness ratios from a step experiment.

    Parameters
    ----------
    experiment : Experiment
        A record with steps of constant voltage long enough for the carts to come to rest
        (e.g. ``data_steps``: 0.5 V, 5 s on / 5 s off).
    rig : Rig, optional
        Nominal springs (the last one is taken as known).  Default: the ECP 210 rig.
    reference : {"zero", "previous"}
        ``"zero"``: on-levels from the encoder zero (the report's convention);
        ``"previous"``: on-level minus the rest level just before the step (the first
        sample of the record if the record starts with the step).
    nominal_g_v : float
        Nominal gain for the relative error, N/V.
    plateaus : Plateaus, optional
        Precomputed plateaus; otherwise ``find_plateaus(experiment, **plateau_options)``.

    Returns
    -------
    StaticResult

    Raises
    ------
    DataError
        If no settled on-plateau is found, or the outputs do not match the rig.
    ModelError
        For an unknown ``reference``.

    Examples
    --------
    >>> from bayesmodal.data import find_data, load_experiment
    >>> p = find_data("ecp210-3dof/data_steps.mat")
    >>> res = steady_state(load_experiment(p)) if p else None
    >>> res is None or 6.0 < res.g_v < 6.1
    True
    """
    if reference not in _REFERENCES:
        raise ModelError(f"reference must be one of {_REFERENCES}, got {reference!r}")
    rig = Rig() if rig is None else rig
    chain = rig.is_chain and rig.n_carts >= 2
    e = experiment
    rig.check_record(e)
    if not chain:
        # the gain from the levels and the known springs: x / v = g_v C K^-1 d
        unknown = [s.name for s in rig.springs if not s.known]
        if unknown or not rig.drive:
            raise ModelError(
                "the static gain needs every spring known and a drive; "
                f"{'springs ' + ', '.join(unknown) + ' are unknown' if unknown else 'no drive'}"
                " (fit them with `bayesmodal lsq`, or give known = true)")
    p = find_plateaus(e, **plateau_options) if plateaus is None else plateaus
    on_idx, xs, vs = [], [], []
    for i in np.flatnonzero(p.on):
        if reference == "zero":
            x, dv = p.level_m[i], p.v_volt[i]
        else:
            prev = np.flatnonzero(p.segment_index == p.segment_index[i] - 1)
            if prev.size:
                x = p.level_m[i] - p.level_m[prev[0]]
                dv = p.v_volt[i] - p.v_volt[prev[0]]
            elif p.segment_start[i] == 0:
                # the record starts with this step: its first sample is the rest level
                x, dv = p.level_m[i] - e.y_m[0], p.v_volt[i]
            else:
                continue  # the segment before did not settle: no rest level
        if dv == 0:
            continue
        on_idx.append(int(i))
        xs.append(x)
        vs.append(dv)
    if not on_idx:
        raise DataError(
            f"{e.name}: no settled on-plateau found ({p.n_plateaus} plateaus, "
            f"{len(p.unsettled)} unsettled segments); are the steps long enough?"
        )
    x_inf = np.array(xs)
    v_inf = np.array(vs)
    x_per_volt = x_inf / v_inf[:, None]
    if chain:
        g_each, r_each = gains_from_levels(x_per_volt, rig.springs_n_m)
        g, r = gains_from_levels(x_per_volt.mean(axis=0), rig.springs_n_m)
        k = np.asarray(rig.springs_n_m)
        nominal_r = k[-1] / k[:-1]
        n = rig.n_carts
        ratio_names = tuple(f"k{n}/k{i + 1}" for i in range(n - 1))
    else:
        # least squares over the sensors of x / v = g_v a, a = C K^-1 d (m/N)
        a = rig.output_matrix() @ np.linalg.solve(rig.stiffness_matrix(), rig.input_vector())
        g_each = x_per_volt @ a / (a @ a)
        g = float(x_per_volt.mean(axis=0) @ a / (a @ a))
        r_each, r, nominal_r, ratio_names = (np.empty((len(xs), 0)), np.empty(0),
                                             np.empty(0), ())
    return StaticResult(
        experiment=e,
        plateaus=p,
        reference=reference,
        on_index=np.array(on_idx, int),
        x_inf_m=x_inf,
        v_inf_volt=v_inf,
        g_v_each=g_each,
        ratios_each=r_each,
        g_v=float(g),
        g_v_se=float(_se(g_each[:, None])[0]),
        ratios=r,
        ratios_se=_se(r_each),
        ratio_names=ratio_names,
        nominal_g_v=float(nominal_g_v),
        nominal_ratios=nominal_r,
        g_v_error_percent=float(100.0 * (g - nominal_g_v) / nominal_g_v),
        ratios_error_percent=100.0 * (r - nominal_r) / nominal_r,
    )
