"""The linear rig driven by a per-lane input through an optional motor lag and input delay.

The input-side effects that are memoryless (offset, dead band, saturation) turn the
commanded voltage into one held input per parameter set, shape (nb, N).  The motor lag
(``tau f' = g_v v - f``) and the input delay (``v(t - D)``) are linear, so with the linear
plant the whole chain stays an exact linear recursion: the state ``(x, x', f)`` (``f`` the
lagged motor force, unused where ``tau = 0``) discretised by zero-order hold, and the delay
``D = (m + phi) dt`` split as in ``extensions.input_delay``::

    z[k+1] = e^{A dt} z[k] + B1 v[k-m-1] + B2 v[k-m],
    B1 = e^{A (1-phi) dt} Gamma(phi dt) B,   B2 = Gamma((1-phi) dt) B.

Lag and delay are both linear and time-invariant, so their order does not matter.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from ..kernels import linear_input_run, zoh
from ._linear import linear_parts, sensor_map


def split_delay(delay_s, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``D = (m + phi) dt``: whole samples ``m`` (int) and the fraction ``0 <= phi <= 1``.

    Parameters
    ----------
    delay_s : ndarray, shape (nb,)
        Delays, s (>= 0).
    dt : float
        Sample interval, s.
    """
    delay = np.asarray(delay_s, dtype=float) / dt
    m = np.floor(delay + 1e-12).astype(int)
    return m, np.clip(delay - m, 0.0, 1.0)


#: Lags below this fraction of the sample interval are simulated as instantaneous.  The
#: zero-order hold of the lag state (pole ``-1/tau``) loses accuracy as ``dt / tau``
#: grows: 6e-7 m off at ``tau`` = 1e-12 s and 1.5 mm at 1e-14 s (dt = 5 ms, 3 V pulses),
#: where a least-squares fit went and gained from the error.  At ``1e-5 dt`` the lag's
#: own effect is about ``0.55 tau`` m, below 1 % of an encoder count, and the hold is
#: accurate to well below that (``tests/test_extensions.py``).
INSTANT_LAG = 1e-5


def effective_lag(tau, dt: float):
    """``tau`` with the lags below ``INSTANT_LAG * dt`` set to 0 (instantaneous), s."""
    tau = np.asarray(tau, dtype=float)
    return np.where(tau < INSTANT_LAG * dt, 0.0, tau)


def lagged_system(rig, theta_lin: np.ndarray, tau: np.ndarray | None):
    """State matrix and input vector of ``(x, x', f)`` with the lag ``tau`` (s) per lane.

    Returns
    -------
    A : ndarray, shape (nb, s, s)
        ``s = 2n`` without a lag, ``2n + 1`` with one.
    B : ndarray, shape (nb, s)
        Per volt; lanes with ``tau = 0`` take the motor force directly (the lag state is
        then decoupled and stays at zero).
    """
    n = rig.n_carts
    p = linear_parts(rig, theta_lin)
    if tau is None:
        return p.A, p.B
    nb, s = theta_lin.shape[0], 2 * n
    A = np.zeros((nb, s + 1, s + 1))
    B = np.zeros((nb, s + 1))
    A[:, :s, :s] = p.A
    lag = tau > 0.0
    A[:, s, s] = -1.0
    B[~lag, :s] = p.B[~lag]
    A[lag, n, s] = p.inv_mass[lag, 0]  # the lagged force drives the driven cart (first)
    A[lag, s, s] = -1.0 / tau[lag]
    B[lag, s] = p.b[lag, 0] / tau[lag]
    return A, B


def linear_lanes_run(rig, theta_lin, v, dt, x0, *, tau=None, delay_s=None, outputs=None):
    """Positions (or sensors' readings) of the linear rig under per-lane inputs, with
    optional lag and delay.

    Parameters
    ----------
    rig : Rig
    theta_lin : ndarray, shape (nb, 9)
        Free-damping linear parameters.
    v : ndarray, shape (N,) or (nb, N)
        Voltage at the amplifier output, V, held over each sample.
    dt : float
        Sample interval, s.
    x0 : ndarray, shape (nb, 2n)
        Initial positions (m) and velocities (m/s); the lag state starts at zero.
    tau : ndarray, shape (nb,), optional
        Motor lag time constants, s (>= 0).
    delay_s : ndarray, shape (nb,), optional
        Input delays, s (>= 0).
    outputs : ndarray of int, shape (n_out, 2), optional
        Sensors to read (``_linear.sensor_spec``); default every cart's position.

    Returns
    -------
    ndarray, shape (nb, N, n) or (nb, N, n_out)
        Cart positions, m, in kernel order; or with ``outputs`` each sensor's reading in
        SI (m, m/s, m/s^2; an acceleration at the sample with the input held from it).
    """
    n = rig.n_carts
    nb = theta_lin.shape[0]
    A, B = lagged_system(rig, theta_lin, None if tau is None else effective_lag(tau, dt))
    s = A.shape[1]
    z0 = np.zeros((nb, s))
    z0[:, : 2 * n] = x0
    phi = None if delay_s is None else split_delay(delay_s, dt)[1]
    out_map = None if outputs is None else input_sensor_map(A, B, outputs, n, phi)
    if delay_s is None:
        Ad, Bd = zoh(A, B[..., None], dt)
        return sensors_run(Ad, np.zeros((nb, s)), Bd[..., 0], v, z0, n, out_map)
    m, phi = split_delay(delay_s, dt)
    A1, G1 = zoh(A, B[..., None], phi * dt)
    A2, G2 = zoh(A, B[..., None], (1.0 - phi) * dt)
    B1 = np.einsum("bij,bj->bi", A2, G1[..., 0])
    return sensors_run(A2 @ A1, B1, G2[..., 0], v, z0, n, out_map, shift=m)


#: Largest condition number of a change to sensor coordinates (``sensor_coordinates``);
#: beyond it the readings are formed from the physical state instead.
MAX_SENSOR_COND = 1e4


def sensor_coordinates(C: np.ndarray, n: int):
    """A change of state ``z' = T z`` whose first states are the sensors' readings.

    The readings ``y = C z (+ D u)`` then cost a copy (a position or velocity) or one
    multiply-add and the feedthrough (an acceleration), where from ``z`` an acceleration
    takes a row of the state matrix, as many multiply-adds as states: in the linear
    recursion, whose step is ``s^2`` of them, that was 45-60 % more per acceleration
    sensor on three carts.  ``T`` is ``C`` with each row scaled to a largest entry of 1
    (``scale``), completed by unit rows, velocities first (an acceleration row is mostly
    its stiffness part, so ``T`` stays as well conditioned as the stiffness matrix).

    Parameters
    ----------
    C : ndarray, shape (nb, n_out, s)
        Output rows over the state (``_linear.sensor_map``).
    n : int
        Degrees of freedom (velocity states ``n..2n-1``).

    Returns
    -------
    T : ndarray, shape (nb, s, s), or None
        None when the readings are not independent states (more sensors than states);
        ``sensors_run`` also keeps the physical state where ``T`` is worse conditioned
        than ``MAX_SENSOR_COND`` (infinity norm) on some lane.
    scale : ndarray, shape (nb, n_out)
        ``y_o = scale_o z'_o (+ D u)``.
    """
    nb, n_out, s = C.shape
    if n_out > s:
        return None, None
    scale = np.abs(C).max(axis=2)
    if np.any(scale == 0.0):
        return None, None
    rows = C / scale[..., None]
    eye = np.eye(s)
    key = ((rows[0] != 0.0).tobytes(), n_out, s, n)
    chosen = _COMPLEMENTS.get(key)
    if chosen is None:
        chosen = _COMPLEMENTS[key] = _complement(rows[0], n)
    if n_out + len(chosen) < s:
        return None, None
    T = np.concatenate([rows, np.broadcast_to(eye[chosen], (nb, len(chosen), s))], axis=1)
    return T, scale


#: ``_complement`` of each pattern of nonzero output rows: the readings of a rig have the
#: same structure from call to call (``sensors_run`` checks each lane's ``T``).
_COMPLEMENTS: dict[tuple, list[int]] = {}


def _complement(rows: np.ndarray, n: int) -> list[int]:
    """Unit rows (state indices) that complete the output rows (n_out, s) to a basis,
    velocities first (Gram-Schmidt)."""
    s = rows.shape[1]
    eye = np.eye(s)
    Q, _ = np.linalg.qr(rows.T)
    chosen: list[int] = []
    for i in [*range(n, 2 * n), *range(n), *range(2 * n, s)]:
        if Q.shape[1] == s:
            break
        r = eye[i] - Q @ (Q.T @ eye[i])
        if np.linalg.norm(r) > 1e-6:
            Q = np.column_stack([Q, r / np.linalg.norm(r)])
            chosen.append(i)
    return chosen


def sensors_run(Ad, B1, B2, v, z0, n: int, out_map, **kw):
    """``linear_input_run`` reading the sensors of ``out_map`` (``input_sensor_map``), in
    sensor coordinates (``sensor_coordinates``) where they are independent states; the
    cart positions without ``out_map``."""
    if out_map is None:
        return linear_input_run(Ad, B1, B2, v, z0, n, **kw)
    C, D1, D2 = out_map
    T, scale = sensor_coordinates(C, n)
    if T is None:
        return linear_input_run(Ad, B1, B2, v, z0, n, out_map=out_map, **kw)
    try:
        Ti = np.linalg.inv(T)
    except np.linalg.LinAlgError:
        Ti = None
    norm = np.abs(T).sum(axis=2).max(axis=1)
    if Ti is None or not np.all(norm * np.abs(Ti).sum(axis=2).max(axis=1) < MAX_SENSOR_COND):
        return linear_input_run(Ad, B1, B2, v, z0, n, out_map=out_map, **kw)
    fed = np.any((D1 != 0.0) | (D2 != 0.0) | (scale != 1.0), axis=0)
    return linear_input_run(T @ Ad @ Ti, np.einsum("bij,bj->bi", T, B1),
                            np.einsum("bij,bj->bi", T, B2), v,
                            np.einsum("bij,bj->bi", T, z0), C.shape[1],
                            out_map=(scale[:, fed], D1[:, fed], D2[:, fed]),
                            feeds=tuple(fed), **kw)


def input_sensor_map(A, B, outputs, n: int, phi=None):
    """``(C, D1, D2)`` of ``linear_input_run`` for the sensors ``outputs``.

    The input acting just after sample ``k`` is ``v[k - m - 1]`` when the delay has a
    fraction ``phi > 0`` of a sample (the earlier input is still arriving), else
    ``v[k - m]``: the acceleration's feedthrough goes to that one.

    Parameters
    ----------
    A : ndarray, shape (nb, s, s)
    B : ndarray, shape (nb, s)
    outputs : ndarray of int, shape (n_out, 2)
        ``_linear.sensor_spec``.
    n : int
        Degrees of freedom.
    phi : ndarray, shape (nb,), optional
        Fraction of the delay beyond whole samples (``split_delay``); None: no delay.
    """
    C, D, _ = sensor_map(A, B, outputs, n)
    if phi is None:
        return C, np.zeros_like(D), D
    early = (np.asarray(phi) > 0.0)[:, None]
    return C, np.where(early, D, 0.0), np.where(early, 0.0, D)


def held_average(v: np.ndarray, dt: float, nb: int, *, tau=None, delay_s=None,
                 with_start: bool = False):
    """The delayed and lagged input as one held value per sample: its mean over each interval.

    A nonlinear plant's kernel takes an input held over each sample.  A delayed input
    changes inside an interval, and a lagged force relaxes exponentially across it; this
    gives each interval the exact mean of that signal (in volts, ``f / g_v``), so the
    impulse per interval is exact and what is lost is the signal's shape inside it, a
    second-order error in ``dt`` (``tests/test_effects_combined_filters.py`` measures the
    order against the exact linear recursion).

    With ``D = (m + phi) dt`` the delayed input's mean over ``[k dt, (k + 1) dt)`` is
    ``w[k] = phi v[k-m-1] + (1 - phi) v[k-m]`` (zero before the record).  The lag
    ``tau f' = w - f`` held over the interval gives ``f[k+1] = w[k] + (f[k] - w[k]) a`` and
    the mean ``w[k] + (f[k] - w[k]) c`` with ``a = exp(-dt / tau)``,
    ``c = tau (1 - a) / dt``; the force starts at zero.

    Parameters
    ----------
    v : ndarray, shape (N,) or (nb, N)
        Voltage held over each sample, V.
    dt : float
        Sample interval, s.
    nb : int
        Number of parameter sets (lanes).
    tau, delay_s : ndarray, shape (nb,), optional
        Lag time constants and delays, s (>= 0).
    with_start : bool
        Also return the signal just after each sample (``v[k-m-1]`` if ``phi > 0``, else
        ``v[k-m]``; the lagged force ``f[k]`` of the same recursion): what an
        acceleration at the sample feels, where the mean is what moves the carts.

    Returns
    -------
    ndarray, shape (nb, N)
        The means, V; with ``with_start`` a pair (means, values at the samples).
    """
    w = np.array(np.broadcast_to(v, (nb, np.shape(v)[-1])), dtype=float)
    start = w
    N = w.shape[1]
    if delay_s is not None:
        m, phi = split_delay(delay_s, dt)
        pad = np.concatenate([np.zeros((nb, int(m.max()) + 1)), w], axis=1)
        k = np.arange(N)
        rows = np.arange(nb)[:, None]
        first = pad.shape[1] - N  # pad[first + j] = w[j]
        late = pad[rows, first + k[None] - m[:, None]]
        early = pad[rows, first + k[None] - m[:, None] - 1]
        w = phi[:, None] * early + (1.0 - phi[:, None]) * late
        start = np.where(phi[:, None] > 0.0, early, late)
    if tau is None:
        return (w, start) if with_start else w
    tau = np.asarray(tau, dtype=float)
    out = w.copy()
    start = start.copy()
    for b in np.flatnonzero(tau > 0.0):
        a = np.exp(-dt / tau[b])
        c = tau[b] * (1.0 - a) / dt
        # f[k] before the interval: f[k+1] = a f[k] + (1 - a) w[k], f[0] = 0
        f = lfilter([0.0, 1.0 - a], [1.0, -a], w[b])
        out[b] = w[b] + (f - w[b]) * c
        start[b] = f
    return (out, start) if with_start else out
