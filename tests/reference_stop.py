"""Independent reference simulators of the end stop of the driven cart (tests only).

Written from the equations of motion without bayesmodal code (the chain matrices come from
``reference_sim.rig_matrices``, assembled by hand there): the stop pushes cart 1 back with
``k_stop * max(0, side * (x_1 - side * x_stop))`` towards rest, and the dynamics are
integrated by ``scipy.integrate.solve_ivp`` (DOP853, tight tolerances) with a terminal
event at every contact and release, so that no solver step straddles the kink of the
force; with stick-slip friction every stick, reversal and break-away is an event too.

Parameter vectors: the free-damping linear parameters, then ``Fc_i, Fs_i`` (friction
cases), then ``x_stop, k_stop``.
"""

from __future__ import annotations

import numpy as np
from reference_effects import LUGRE_ATOL, LUGRE_RTOL, input_chain_ref
from reference_sim import (
    ATOL,
    MAX_STEP_FRACTION,
    RTOL,
    V_EPS,
    driven,
    input_segments,
    n_linear,
    rig_matrices,
)
from scipy.integrate import solve_ivp


def _stop_force(x1: float, side: int, x_stop: float, k_stop: float) -> float:
    """Force of the stop on cart 1, N."""
    pen = side * x1 - x_stop
    return -side * k_stop * pen if pen > 0 else 0.0


def _segment(rhs, t: float, t1: float, z, val: float, Y, t_s, **options):
    """Integrate ``rhs`` from ``t`` towards ``t1`` (up to a terminal event) and write the
    positions at the sample times it passed into ``Y``; the solver's result."""
    sol = solve_ivp(rhs, (t, t1), z, args=(val,), dense_output=True, **options)
    assert sol.success, sol.message
    take = (t_s > t) & (t_s <= sol.t[-1])
    if take.any():
        Y[take] = sol.sol(t_s[take])[: Y.shape[1]].T
    return sol


def simulate_coulomb_stop_ref(springs, theta, u, dt, *, side=1, friction=True,
                              v_offset=0.0, v_dead=0.0, states=False):
    """Stick-slip friction on every cart (``friction``) and the end stop of cart 1,
    event-driven; the input passes an offset and a sharp dead band first.

    A sliding cart in direction ``d`` feels ``-Fc d``; a stuck cart stays while its net
    force is below ``Fs``; at a velocity zero it sticks if the net force is below ``Fs``
    and otherwise slides along it.  Without ``friction`` the carts slide freely.  Returns
    the positions (N, n), or with ``states`` positions and velocities (N, 2n).
    """
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    n = M.shape[0]
    q = p + (2 * n if friction else 0)
    fc = np.asarray(theta[p : p + n], float) if friction else np.zeros(n)
    fs = np.asarray(theta[p + n : p + 2 * n], float) if friction else np.full(n, -1.0)
    x_stop, k_stop = float(theta[q]), float(theta[q + 1])
    minv = 1.0 / np.diag(M)
    v_in = input_chain_ref(u, v_offset=v_offset, v_dead=v_dead)
    t_s = np.arange(len(u)) * dt
    Y = np.empty((len(u), 2 * n if states else n))
    z = np.zeros(2 * n)
    stuck = np.ones(n, bool) if friction else np.zeros(n, bool)
    d = np.zeros(n)
    inside = [False]  # cart 1 in contact with the stop (it starts at rest, away from it)

    j = driven(springs)  # the stop is on the driven cart

    def net(z, v):
        F = b * v - K @ z[:n] - C @ z[n:]
        F[j] += _stop_force(z[j], side, x_stop, k_stop)
        return F

    def rhs(t, z, v):
        acc = minv * (net(z, v) - fc * d)
        vel = z[n:].copy()
        acc[stuck] = 0.0
        vel[stuck] = 0.0
        return np.r_[vel, acc]

    def events(v):
        out = []
        for i in range(n if friction else 0):
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

        def contact(t, z, *_):  # the kink of the stop force: restart the solver there
            return side * z[j] - x_stop
        contact.terminal = True
        contact.direction = -1.0 if inside[0] else 1.0  # the next release or contact
        return out + [contact]

    def release(z, v):
        F = net(z, v)
        for i in range(n):
            if stuck[i] and abs(F[i]) >= fs[i]:
                stuck[i], d[i] = False, np.sign(F[i])

    Y[0] = z[: Y.shape[1]]
    for t0, t1, val in input_segments(v_in, dt):
        t = t0
        release(z, val)
        while t < t1:
            sol = _segment(rhs, t, t1, z, val, Y, t_s, method="DOP853", events=events(val),
                           rtol=RTOL, atol=ATOL, max_step=MAX_STEP_FRACTION * dt)
            z = sol.y[:, -1].copy()
            if sol.status == 1:
                hit = [j for j, te in enumerate(sol.t_events) if len(te)]
                if hit[-1] == len(sol.t_events) - 1:  # a contact or a release: the next
                    inside[0] = not inside[0]         # one is the other kind
                i = hit[0]
                if friction and i < n:
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


def simulate_stop_ref(springs, theta, u, dt, *, side=1, states=False):
    """The linear rig with the end stop of cart 1 (no friction)."""
    return simulate_coulomb_stop_ref(springs, theta, u, dt, side=side, friction=False,
                                     states=states)


def simulate_lugre_stop_ref(springs, theta, u, dt, *, side=1):
    """LuGre friction on every cart (bristles relaxed at the start) and the end stop of
    cart 1: Radau (stiff bristles) with a restart at every contact and release.

    ``z_i' = v_i - sigma0 |v_i| z_i / g_i(v_i)``, ``g_i(v) = Fc_i + (Fs_i - Fc_i)
    exp(-(v / vs)^2)``, friction ``-(sigma0 z_i + sigma1 z_i')`` on cart i.  Parameters
    after the linear ones: ``Fc_i, Fs_i, sigma0, sigma1, v_stribeck, x_stop, k_stop``.
    """
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    n = M.shape[0]
    minv = 1.0 / np.diag(M)
    fc, fs = np.asarray(theta[p : p + n], float), np.asarray(theta[p + n : p + 2 * n], float)
    s0, s1, vs = (float(theta[p + 2 * n + j]) for j in range(3))
    x_stop, k_stop = float(theta[p + 2 * n + 3]), float(theta[p + 2 * n + 4])
    j = driven(springs)  # the stop is on the driven cart

    def rhs(t, z, v):
        x, xd, zb = z[:n], z[n : 2 * n], z[2 * n :]
        g = fc + (fs - fc) * np.exp(-((xd / vs) ** 2))
        with np.errstate(divide="ignore", invalid="ignore"):
            relax = np.where(g > 0, s0 * np.abs(xd) * zb / g, 0.0)
        zdot = xd - relax
        force = b * v - K @ x - C @ xd - (s0 * zb + s1 * zdot)
        force[j] += _stop_force(x[j], side, x_stop, k_stop)
        return np.r_[xd, minv * force, zdot]

    inside = [False]

    def contact(t, z, *_):
        return side * z[j] - x_stop

    t_s = np.arange(len(u)) * dt
    Y = np.empty((len(u), n))
    z = np.zeros(3 * n)
    Y[0] = z[:n]
    for t0, t1, val in input_segments(u, dt):
        t = t0
        while t < t1:
            contact.terminal = True
            contact.direction = -1.0 if inside[0] else 1.0
            sol = _segment(rhs, t, t1, z, val, Y, t_s, method="Radau", events=[contact],
                           rtol=LUGRE_RTOL, atol=LUGRE_ATOL)
            z = sol.y[:, -1].copy()
            if sol.status == 1:
                inside[0] = not inside[0]
            t = sol.t[-1]
    return Y
