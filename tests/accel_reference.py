"""An independent reference simulator of a two-cart rig read by accelerometers under a
measured force, for the known-truth studies (``benchmarks/accel_coverage.py``).

Nothing of the package is used: the equations of motion are written from the free-body
diagrams of cart 1 - k1 - cart 2 - k2 - frame with dampers c1, c2 to the frame and c12
across, driven by the force ``f`` on cart 1 held over each sample interval; they are
integrated with ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-10) over each stretch of
constant force, and the accelerations are the right-hand side at each sample with the
force held from it.  The record is then measured: white accelerometer noise and a
logger's quantisation of both the force and the accelerations.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

#: (m1, m2 kg, c1, c2, c12 N s/m, k1, k2 N/m): the names of the rig with both springs
#: unknown, in the package's parameter order.
NAMES = ("m1", "m2", "c1", "c2", "c12", "k1", "k2")
#: The rig of the known-truth studies (``benchmarks/accel_coverage.py``,
#: ``benchmarks/ema_errors.py``), in NAMES order.
TRUTH = (1.5, 1.2, 1.2, 0.8, 0.3, 600.0, 450.0)


def accelerations(p, x, xd, f):
    """Accelerations of the two carts, m/s^2, for parameters ``p`` (NAMES order)."""
    m1, m2, c1, c2, c12, k1, k2 = p
    a1 = (k1 * (x[1] - x[0]) + c12 * (xd[1] - xd[0]) - c1 * xd[0] + f) / m1
    a2 = (k1 * (x[0] - x[1]) - k2 * x[1] + c12 * (xd[0] - xd[1]) - c2 * xd[1]) / m2
    return np.array([a1, a2])


def simulate(p, f, dt):
    """Noise-free accelerations, shape (N, 2), m/s^2, of the force ``f`` (N,) N."""
    states = simulate_states(p, f, dt)
    return np.array([accelerations(p, s[:2], s[2:], fk) for s, fk in zip(states, f,
                                                                           strict=True)])


def simulate_states(p, f, dt):
    """Positions (m) and velocities (m/s) of both carts, shape (N, 4), from rest under
    the force ``f`` (N,) N held over each sample interval."""
    n = f.size
    state = np.zeros(4)
    states = np.empty((n, 4))
    states[0] = state
    edges = np.r_[0, np.flatnonzero(np.diff(f)) + 1, n]
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        level = f[a]

        def rhs(_t, s, level=level):
            return np.r_[s[2:], accelerations(p, s[:2], s[2:], level)]

        t_eval = dt * np.arange(a, min(b, n - 1) + 1)
        if t_eval.size < 2:
            continue
        sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), state, method="DOP853",
                        t_eval=t_eval, rtol=1e-10, atol=1e-13)
        states[a + 1 : a + t_eval.size] = sol.y[:, 1:].T
        state = sol.y[:, -1]
    return states


def hammer_force(n, dt, *, peak=60.0, every_s=4.0):
    """Half-sine hits of 12 ms (three samples at 4 ms), N."""
    f = np.zeros(n)
    width = max(int(round(0.012 / dt)), 1)
    pulse = peak * np.sin(np.pi * (np.arange(width) + 0.5) / width)
    for k0 in range(int(0.1 / dt), n - width, int(every_s / dt)):
        f[k0 : k0 + width] = pulse
    return f


def measured_record(p, rng, *, n=2000, dt=0.004, sigma_acc=0.05, step_acc=5e-3,
                    step_force=1e-2):
    """``(t, f, y)``: a hammer test's force (quantised, N) and accelerations (noise and
    quantisation, m/s^2); the rig moves under the quantised force, as recorded."""
    f = np.round(hammer_force(n, dt) / step_force) * step_force
    y = simulate(p, f, dt) + rng.normal(0.0, sigma_acc, (n, 2))
    return np.arange(n) * dt, f, np.round(y / step_acc) * step_acc


def voltage_pulses(n, dt, *, volts=2.0, width_s=0.05, every_s=4.0):
    """Rectangular drive pulses of ``volts`` V, ``width_s`` long, every ``every_s``, V."""
    v = np.zeros(n)
    width = max(int(round(width_s / dt)), 1)
    for k0 in range(int(0.1 / dt), n - width, int(every_s / dt)):
        v[k0 : k0 + width] = volts
    return v


def mixed_record(p, g_v, rng, *, n=2000, dt=0.004, m_per_count=2.2e-5, sigma_acc=0.05,
                 step_acc=5e-3, every_s=4.0):
    """``(t, v, y)`` of a voltage-driven rig read by an encoder on cart 1 and an
    accelerometer on cart 2: the drive's force is ``g_v v`` (N/V times V) on cart 1, ``v``
    2 V pulses ``every_s`` apart;
    ``y[:, 0]`` the encoder's position (m, quantised to ``m_per_count``: the count is
    zeroed at the start, where cart 1 rests at a random fraction of a count, so that the
    quantisation error differs from record to record), ``y[:, 1]`` cart 2's acceleration
    (m/s^2, white noise and quantisation)."""
    v = voltage_pulses(n, dt, every_s=every_s)
    f = g_v * v
    states = simulate_states(p, f, dt)
    acc = np.array([accelerations(p, s[:2], s[2:], fk)[1] for s, fk in zip(states, f,
                                                                          strict=True)])
    rest = rng.uniform(0.0, 1.0)  # where cart 1 rests within a count
    x1 = (np.round(states[:, 0] / m_per_count + rest) - np.round(rest)) * m_per_count
    a2 = np.round((acc + rng.normal(0.0, sigma_acc, n)) / step_acc) * step_acc
    return np.arange(n) * dt, v, np.column_stack([x1, a2])
