"""Independent reference simulators of the new and combined effects (tests only).

Written from the equations of motion without any bayesmodal code: the chain matrices come
from ``reference_sim.rig_matrices`` (assembled by hand there), the input stages are
re-derived here in plain numpy, and the dynamics are integrated by
``scipy.integrate.solve_ivp`` over the intervals where the held input is constant (DOP853
for the smooth models, the implicit Radau method for the stiff LuGre bristles).

Parameter vectors: the free-damping linear parameters, then the effect's own.
"""

from __future__ import annotations

import numpy as np
from reference_sim import (
    ATOL,
    MAX_STEP_FRACTION,
    RTOL,
    V_EPS,
    driven,
    input_segments,
    layout_of,
    n_linear,
    rig_matrices,
    simulate_linear_ref,
)
from scipy.integrate import solve_ivp

#: Radau tolerances of the LuGre reference (stiff; the kernel under test is far coarser).
LUGRE_RTOL = 1e-9
LUGRE_ATOL = 1e-14


def deadband_ref(v, v_dead, width=0.0):
    """Dead band by cases: ``v - v_dead`` above, ``v + v_dead`` below ``-v_dead``, else 0;
    smooth: ``width * (log(1 + e^((v - vd)/width)) - log(1 + e^((-v - vd)/width)))``."""
    v = np.asarray(v, float)
    if width == 0.0:
        return np.where(v > v_dead, v - v_dead, np.where(v < -v_dead, v + v_dead, 0.0))

    def softplus(z):  # log(1 + e^z) without overflow
        return np.maximum(z, 0.0) + np.log1p(np.exp(-np.abs(z)))

    return width * (softplus((v - v_dead) / width) - softplus((-v - v_dead) / width))


def input_chain_ref(u, *, v_offset=0.0, v_dead=0.0, width=0.0, v_sat=np.inf, kappa=0.0):
    """The memoryless input stages in their physical order: offset, dead band, clip, and
    the amplitude-dependent gain ``v + kappa v |v|``."""
    v = np.asarray(u, float) + v_offset
    v = deadband_ref(v, v_dead, width)
    v = np.minimum(np.maximum(v, -v_sat), v_sat)
    return v + kappa * v * np.abs(v)


def _integrate(rhs, z0, u, dt, n_out, *, delay=0.0, method="DOP853", rtol=RTOL, atol=1e-13):
    N = len(u)
    t_s = np.arange(N) * dt
    Y = np.empty((N, n_out))
    z = np.array(z0, float)
    Y[0] = z[:n_out]
    for t0, t1, val in input_segments(u, dt, delay):
        mask = (t_s > t0) & (t_s <= t1)
        sol = solve_ivp(lambda t, zz, v=val: rhs(zz, v), (t0, t1), z, method=method,
                        dense_output=True, rtol=rtol, atol=atol)
        assert sol.success, sol.message
        if mask.any():
            Y[mask] = sol.sol(t_s[mask])[:n_out].T
        z = sol.y[:, -1]
    return Y


def simulate_linear_chain_ref(springs, theta_lin, u, dt, *, v_offset=0.0, v_dead=0.0,
                              width=0.0, v_sat=np.inf, kappa=0.0, tau=0.0, delay=0.0):
    """Linear rig behind offset, dead band, saturation, a motor lag ``tau`` and a delay.

    The lag is the state ``f`` with ``tau f' = g_v v - f`` acting on cart 1 (``tau = 0``:
    the force is ``g_v v``); the delay shifts the held input by ``delay`` seconds.
    """
    M, C, K, b = rig_matrices(springs, theta_lin)
    n = M.shape[0]
    minv = 1.0 / np.diag(M)
    j = driven(springs)
    g_v = b[j]  # signed by the drive's share
    v = input_chain_ref(u, v_offset=v_offset, v_dead=v_dead, width=width, v_sat=v_sat,
                        kappa=kappa)

    def rhs(z, vin):
        x, xd, f = z[:n], z[n : 2 * n], z[2 * n]
        force = -K @ x - C @ xd
        force[j] += f if tau > 0 else g_v * vin
        fdot = (g_v * vin - f) / tau if tau > 0 else 0.0
        return np.r_[xd, minv * force, fdot]

    return _integrate(rhs, np.zeros(2 * n + 1), v, dt, n, delay=delay)


def simulate_offset_ref(springs, theta, u, dt):
    """The motor sees ``v + v_offset`` from ``t = 0``."""
    p = n_linear(springs)
    return simulate_linear_chain_ref(springs, theta[:p], u, dt, v_offset=float(theta[p]))


def make_deadband_ref(width=0.0):
    """Reference of ``DriveDeadband(width_v=width)``."""
    def simulate_deadband_ref(springs, theta, u, dt):
        p = n_linear(springs)
        return simulate_linear_chain_ref(springs, theta[:p], u, dt, v_dead=float(theta[p]),
                                         width=width)
    return simulate_deadband_ref


def simulate_lugre_ref(springs, theta, u, dt, *, v_offset=0.0, v_dead=0.0):
    """LuGre friction on every cart, bristles relaxed at the start.

    ``z_i' = v_i - sigma0 |v_i| z_i / g_i(v_i)``,
    ``g_i(v) = Fc_i + (Fs_i - Fc_i) exp(-(v / vs)^2)``, friction
    ``-(sigma0 z_i + sigma1 z_i')`` on cart i; the input passes offset and dead band first.
    """
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    n = M.shape[0]
    minv = 1.0 / np.diag(M)
    fc, fs = np.asarray(theta[p : p + n]), np.asarray(theta[p + n : p + 2 * n])
    s0, s1, vs = theta[p + 2 * n], theta[p + 2 * n + 1], theta[p + 2 * n + 2]
    v_in = input_chain_ref(u, v_offset=v_offset, v_dead=v_dead)

    def rhs(z, vin):
        x, xd, zb = z[:n], z[n : 2 * n], z[2 * n :]
        g = fc + (fs - fc) * np.exp(-((xd / vs) ** 2))
        with np.errstate(divide="ignore", invalid="ignore"):
            relax = np.where(g > 0, s0 * np.abs(xd) * zb / g, 0.0)
        zdot = xd - relax
        friction = s0 * zb + s1 * zdot
        force = b * vin - K @ x - C @ xd - friction
        return np.r_[xd, minv * force, zdot]

    return _integrate(rhs, np.zeros(3 * n), v_in, dt, n, method="Radau", rtol=LUGRE_RTOL,
                      atol=LUGRE_ATOL)


def simulate_directional_coulomb_ref(springs, theta, u, dt):
    """Stick-slip friction with a kinetic level by direction, event-driven.

    Parameters after the linear ones: ``Fcp_i`` (sliding forwards), ``Fcn_i`` (backwards),
    ``Fs_i``.  A sliding cart in direction ``d`` feels ``-Fc(d) d``; a stuck cart stays
    while ``|F| < Fs``; at a velocity zero it sticks if ``|F| < Fs`` and otherwise slides
    along ``F``.  Events are located by ``solve_ivp`` (DOP853, terminal events).
    """
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    n = M.shape[0]
    fcp = np.asarray(theta[p : p + n], float)
    fcn = np.asarray(theta[p + n : p + 2 * n], float)
    fs = np.asarray(theta[p + 2 * n : p + 3 * n], float)
    minv = 1.0 / np.diag(M)
    t_s = np.arange(len(u)) * dt
    Y = np.empty((len(u), n))
    z = np.zeros(2 * n)
    stuck = np.ones(n, bool)
    d = np.zeros(n)

    def net(z, v):
        return b * v - K @ z[:n] - C @ z[n:]

    def rhs(t, z, v):
        level = np.where(d > 0, fcp, fcn)
        acc = minv * (net(z, v) - level * d)
        vel = z[n:].copy()
        acc[stuck] = 0.0
        vel[stuck] = 0.0
        return np.r_[vel, acc]

    def events(v):
        out = []
        for i in range(n):
            if stuck[i]:
                def e(t, z, *_, i=i):
                    return abs(net(z, v)[i]) - fs[i]
                e.direction = 1.0
            else:
                def e(t, z, *_, i=i):
                    return d[i] * z[n + i] + V_EPS
                e.direction = -1.0
            e.terminal = True
            out.append(e)
        return out

    def release(z, v):
        F = net(z, v)
        for i in range(n):
            if stuck[i] and abs(F[i]) >= fs[i]:
                stuck[i], d[i] = False, np.sign(F[i])

    Y[0] = z[:n]
    for t0, t1, val in input_segments(u, dt):
        t = t0
        release(z, val)
        while t < t1:
            sol = solve_ivp(rhs, (t, t1), z, method="DOP853", args=(val,), events=events(val),
                            dense_output=True, rtol=RTOL, atol=ATOL,
                            max_step=MAX_STEP_FRACTION * dt)
            take = (t_s > t) & (t_s <= sol.t[-1])
            if take.any():
                Y[take] = sol.sol(t_s[take])[:n].T
            z = sol.y[:, -1].copy()
            if sol.status == 1:
                i = next(j for j, te in enumerate(sol.t_events) if len(te))
                F = net(z, val)
                if stuck[i]:
                    stuck[i], d[i] = False, np.sign(F[i])
                else:
                    z[n + i] = 0.0
                    if abs(F[i]) < fs[i]:
                        stuck[i], d[i] = True, 0.0
                    else:
                        d[i] = np.sign(F[i])
                release(z, val)
                z[n:][stuck] = 0.0
            t = sol.t[-1]
    return Y


def simulate_amplitude_gain_ref(springs, theta, u, dt):
    """The motor sees ``v (1 + kappa |v|)``."""
    p = n_linear(springs)
    return simulate_linear_chain_ref(springs, theta[:p], u, dt, kappa=float(theta[p]))


def simulate_sensor_gain_ref(springs, theta, u, dt):
    """The linear rig read by sensors whose scales, after the first, are ``s_j``."""
    p = n_linear(springs)
    y = simulate_linear_ref(springs, theta[:p], u, dt)
    outputs = layout_of(springs).outputs
    for j, s in enumerate(theta[p:], start=1):
        y[:, outputs[j]] *= s
    return y


#: References of the new registered effects, by name (same signature as reference_sim's).
NEW_REFERENCES = {
    "input_offset": simulate_offset_ref,
    "drive_deadband": make_deadband_ref(0.0),
    "lugre_friction": simulate_lugre_ref,
    "coulomb_directional": simulate_directional_coulomb_ref,
    "amplitude_gain": simulate_amplitude_gain_ref,
    "sensor_gain": simulate_sensor_gain_ref,
}
