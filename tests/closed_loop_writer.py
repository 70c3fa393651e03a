"""Write a closed-loop record: a PID controller's control effort as the recorded input.

Independent of the package's simulator: the three-cart chain of report eq. 3 is built
here from its masses, springs and dampers, discretised with its zero-order hold by
``scipy.linalg.expm`` of the augmented matrix, and run in closed loop sample by sample.
At each servo sample the controller reads cart 1's encoder (whole counts of the noisy
position), computes the effort ``kp e + ki sum(e) dt + kd (e - e_prev) / dt`` of the
error ``e`` to the commanded position, clips it to the amplifier's +-3 V and holds it
until the next sample; the effort, printed to 0.1 mV as the ECP Executive prints it, is
what drove the carts.  The file is the Executive's export with the commanded position,
the three encoders and the control effort (``tests/ecp_export_writer.py``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from ecp_export_writer import ECP_DT, M_PER_COUNT, write_export
from scipy.linalg import expm

#: The truth, in ``LinearModel(Rig(), "free").names`` order: g_v N/V, m1..m3 kg,
#: c1..c3, c12, c23 N s/m.
THETA = np.array([6.2, 1.57, 1.46, 1.14, 2.9, 1.8, 2.0, 0.01, 0.01])

#: The ECP 210's springs, N/m (cart 1 - cart 2, cart 2 - cart 3, cart 3 - frame).
SPRINGS_N_M = (774.0, 770.0, 396.0)

#: PID gains: V/m, V/(m s), V s/m.
PID = (300.0, 100.0, 5.0)

#: The amplifier's limit, V.
SATURATION_V = 3.0


def _discrete_plant(theta: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``x[k+1] = Ad x[k] + Bd v[k]`` for the state (x1..x3, x1'..x3'), m and m/s."""
    g, m1, m2, m3, c1, c2, c3, c12, c23 = theta
    k1, k2, k3 = SPRINGS_N_M
    stiff = np.array([[k1, -k1, 0], [-k1, k1 + k2, -k2], [0, -k2, k2 + k3]])
    damp = np.array([[c1 + c12, -c12, 0], [-c12, c2 + c12 + c23, -c23],
                     [0, -c23, c3 + c23]])
    inv_m = np.diag(1 / np.array([m1, m2, m3]))
    aug = np.zeros((7, 7))
    aug[:3, 3:6] = np.eye(3)
    aug[3:6, :3] = -inv_m @ stiff
    aug[3:6, 3:6] = -inv_m @ damp
    aug[3, 6] = g / m1
    e = expm(aug * dt)
    return e[:6, :6], e[:6, 6]


def closed_loop(n: int, *, seed: int, noise_counts: float = 2.0, step_counts: int = 800,
                period_s: float = 4.0, dt: float = ECP_DT, theta: np.ndarray = THETA):
    """Run the PID loop on cart 1 for ``n`` samples.

    Parameters
    ----------
    n : int
        Samples.
    seed : int
        Seed of the measurement noise (``numpy.random.default_rng``).
    noise_counts : float
        Standard deviation of each encoder's white noise, counts.
    step_counts : int
        Commanded position: a square wave of this height, counts, from 0.2 s.
    period_s : float
        Its period, s.
    dt : float
        Servo sample period, s.
    theta : ndarray, shape (9,)
        The truth.

    Returns
    -------
    v_volt : ndarray, shape (n,)
        Control effort, V (printed to 0.1 mV).
    y_m : ndarray, shape (n, 3)
        Measured positions (truth plus noise), m.
    r_m : ndarray, shape (n,)
        Commanded position, m.
    """
    ad, bd = _discrete_plant(np.asarray(theta, float), dt)
    kp, ki, kd = PID
    rng = np.random.default_rng(seed)
    x = np.zeros(6)
    integral, previous = 0.0, 0.0
    v = np.zeros(n)
    y = np.zeros((n, 3))
    t = np.arange(n) * dt
    r = step_counts * M_PER_COUNT * (((t % period_s) < period_s / 2) & (t > 0.2))
    for k in range(n):
        y[k] = x[:3] + noise_counts * M_PER_COUNT * rng.standard_normal(3)
        error = r[k] - np.round(y[k, 0] / M_PER_COUNT) * M_PER_COUNT
        integral += error * dt
        derivative = (error - previous) / dt if k else 0.0
        previous = error
        effort = kp * error + ki * integral + kd * derivative
        v[k] = np.round(np.clip(effort, -SATURATION_V, SATURATION_V), 4)
        x = ad @ x + bd * v[k]
    return v, y, r


def write_closed_loop(path: Path, n: int = 1200, *, seed: int = 11, dt: float = ECP_DT,
                      **kw) -> Path:
    """Write a closed-loop record as an ECP Executive export, sample period ``dt`` in s
    (other keywords: ``closed_loop``)."""
    v, y, r = closed_loop(n, seed=seed, dt=dt, **kw)
    return write_export(Path(path), v, y, dt=dt, commanded_m=r)
