"""Independent reference simulators for the model extensions (tests only).

Written from the equations of motion without importing any bayesmodal simulator: the
matrices are assembled here, and every model is integrated with
``scipy.integrate.solve_ivp`` (DOP853, tight tolerances) over the intervals where the
zero-order-hold input is constant, with terminal events for the switches of the hybrid
models (stick-slip, backlash contact).  Slow but accurate: use short records.

Parameter vectors follow the package convention: the free-damping linear parameters
``g_v, m1..mn, c1..cn, c12..`` first, then the extension's.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

RTOL = 1e-10
ATOL = 1e-13
#: Largest solver step of the event-driven friction reference, in samples: event
#: functions are checked at step ends only, so a held cart's force that went past Fs and
#: back within one solver step would be missed.
MAX_STEP_FRACTION = 0.25
V_EPS = 1e-12  # m/s, velocity below which a reversing cart counts as stopped


# ---------------------------------------------------------------------------- the rig
class RefLayout:
    """A rig assembled by hand for the references: carts ``0..n-1`` (the free ones; an end
    at a clamped cart is the frame, ``-1``), springs ``(a, b, k)``, a damper from every
    cart to the frame and one across every spring that joins two carts, the motor on cart
    ``driven`` with ``share`` (``-1``: a reversed drive) and sensors on ``outputs``.

    Parameter vector: ``g_v``, ``m_0..m_{n-1}``, the frame dampers ``c_0..c_{n-1}``, then
    the dampers across the springs joining two carts, in spring order.
    """

    def __init__(self, n, springs, *, driven=0, share=1.0, outputs=None):
        self.n = int(n)
        self.springs = [(int(a), int(b), float(k)) for a, b, k in springs]
        self.driven = int(driven)
        self.share = float(share)
        self.outputs = list(range(self.n)) if outputs is None else list(outputs)
        self.pairs = [(a, b) for a, b, _ in self.springs if a >= 0 and b >= 0]
        self.n_linear = 1 + 2 * self.n + len(self.pairs)

    @property
    def spring_ends(self):
        """``(a, b)`` of each spring; its extension is ``x_b - x_a`` (frame: 0)."""
        return [(a, b) for a, b, _ in self.springs]

    def matrices(self, theta_lin):
        n = self.n
        th = np.asarray(theta_lin, float)
        g_v, m, c_abs, c_rel = th[0], th[1 : 1 + n], th[1 + n : 1 + 2 * n], th[1 + 2 * n :]
        K = np.zeros((n, n))
        C = np.diag(c_abs).astype(float)
        for a, b, k in self.springs:
            for i in (a, b):
                if i >= 0:
                    K[i, i] += k
            if a >= 0 and b >= 0:
                K[a, b] -= k
                K[b, a] -= k
        for (a, b), c in zip(self.pairs, c_rel, strict=True):
            C[a, a] += c
            C[b, b] += c
            C[a, b] -= c
            C[b, a] -= c
        b_vec = np.zeros(n)
        b_vec[self.driven] = self.share * g_v
        return np.diag(m), C, K, b_vec


def chain_layout(springs) -> RefLayout:
    """The chain: spring i joins cart i and i + 1, the last one cart n - 1 to the frame."""
    k = np.asarray(springs, float)
    n = k.size
    return RefLayout(n, [(i, i + 1 if i < n - 1 else -1, k[i]) for i in range(n)])


def layout_of(springs) -> RefLayout:
    """A ``RefLayout`` as given, or the chain of the stiffnesses ``springs``."""
    return springs if isinstance(springs, RefLayout) else chain_layout(springs)


def rig_matrices(springs, theta_lin):
    """M, C, K (n, n) and b (n,) of the chain (or of a ``RefLayout``) with free damping.

    Cart i (0-based) is joined to cart i + 1 by spring k_i and damper c_{i,i+1}; the last
    spring joins the last cart to the frame; c_i are dampers to the frame; the motor force
    g_v v acts on cart 0.
    """
    return layout_of(springs).matrices(theta_lin)


def n_linear(springs) -> int:
    return layout_of(springs).n_linear


def driven(springs) -> int:
    """The cart the motor drives (0-based)."""
    return layout_of(springs).driven


def input_segments(u, dt, delay=0.0):
    """Intervals ``(t0, t1, value)`` of the (delayed) ZOH input up to ``(N - 1) dt``.

    ``u[k]`` holds on ``[k dt + delay, (k + 1) dt + delay)``; before ``delay`` it is zero.
    Runs of equal samples are merged.
    """
    u = np.asarray(u, float)
    t_end = (u.size - 1) * dt
    edges = np.arange(u.size + 1) * dt + delay
    vals = list(u)
    if delay > 0:
        edges = np.r_[0.0, edges]
        vals = [0.0] + vals
    segs = []
    for i, v in enumerate(vals):
        t0, t1 = edges[i], min(edges[i + 1], t_end)
        if t0 >= t_end and segs:
            break
        if t1 <= t0 and not (t0 == 0.0 and t_end == 0.0):
            continue
        if segs and segs[-1][2] == v:
            segs[-1] = (segs[-1][0], t1, v)
        else:
            segs.append((t0, t1, v))
    return segs


def integrate_smooth(rhs, z0, u, dt, *, delay=0.0, n_out):
    """Sample at ``k dt`` the solution of ``z' = rhs(z, u(t))`` with ZOH (delayed) input.

    Returns ndarray, shape (N, n_out): the first ``n_out`` states.
    """
    N = len(u)
    t_s = np.arange(N) * dt
    Y = np.empty((N, n_out))
    z = np.array(z0, float)
    Y[0] = z[:n_out]
    for t0, t1, val in input_segments(u, dt, delay):
        mask = (t_s > t0) & (t_s <= t1)
        sol = solve_ivp(lambda t, zz, v=val: rhs(zz, v), (t0, t1), z, method="DOP853",
                        dense_output=True, rtol=RTOL, atol=ATOL)
        if mask.any():
            Y[mask] = sol.sol(t_s[mask])[:n_out].T
        z = sol.y[:, -1]
    return Y


def integrate_accelerations(rhs, z0, u, dt, n):
    """Accelerations (N, n) of the carts at each sample from the right-hand side ``rhs``
    evaluated at the sampled state with the input held from the sample, m/s^2 (what an
    accelerometer reads)."""
    Z = integrate_smooth(rhs, z0, u, dt, n_out=len(z0))
    return np.array([rhs(z, v)[n : 2 * n] for z, v in zip(Z, u, strict=True)])


def _linear_rhs(M, C, K, b, extra_force=None):
    minv = 1.0 / np.diag(M)
    n = M.shape[0]

    def rhs(z, v):
        x, xd = z[:n], z[n : 2 * n]
        force = b * v - K @ x - C @ xd
        if extra_force is not None:
            force = force + extra_force(x)
        return np.r_[xd, minv * force]

    return rhs


# ---------------------------------------------------------------------------- linear
def simulate_linear_ref(springs, theta, u, dt, *, accelerations=False):
    """The plain linear model (for checking the reference itself); positions (N, n), or
    with ``accelerations`` the accelerations (N, n)."""
    M, C, K, b = rig_matrices(springs, theta)
    n = M.shape[0]
    if accelerations:
        return integrate_accelerations(_linear_rhs(M, C, K, b), np.zeros(2 * n), u, dt, n)
    return integrate_smooth(_linear_rhs(M, C, K, b), np.zeros(2 * n), u, dt, n_out=n)


# ---------------------------------------------------------------------------- extensions
def simulate_motor_lag_ref(springs, theta, u, dt):
    """Motor force ``f' = (g_v v - f) / tau`` acting on the driven cart."""
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    tau = theta[p]
    n = M.shape[0]
    minv = 1.0 / np.diag(M)
    j = driven(springs)
    g_v = b[j]  # signed by the drive's share

    def rhs(z, v):
        x, xd, f = z[:n], z[n : 2 * n], z[2 * n]
        force = -K @ x - C @ xd
        force[j] += f
        return np.r_[xd, minv * force, (g_v * v - f) / tau]

    return integrate_smooth(rhs, np.zeros(2 * n + 1), u, dt, n_out=n)


def simulate_input_delay_ref(springs, theta, u, dt):
    """The input reaches the motor ``delay_s`` later."""
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    n = M.shape[0]
    return integrate_smooth(_linear_rhs(M, C, K, b), np.zeros(2 * n), u, dt,
                            delay=float(theta[p]), n_out=n)


def simulate_saturation_ref(springs, theta, u, dt):
    """The motor voltage is clipped at ``+-v_sat``."""
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    n = M.shape[0]
    uc = np.clip(u, -theta[p], theta[p])
    return integrate_smooth(_linear_rhs(M, C, K, b), np.zeros(2 * n), uc, dt, n_out=n)


def simulate_cubic_ref(springs, theta, u, dt, *, accelerations=False):
    """Spring i pulls with ``k_i d + k3_i d^3``, ``d`` its extension; positions (N, n), or
    with ``accelerations`` the accelerations (N, n)."""
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    k3 = np.asarray(theta[p:], float)
    n = M.shape[0]

    ends = layout_of(springs).spring_ends

    def cubic(x):
        force = np.zeros(n)
        for (a, b_end), k in zip(ends, k3, strict=True):
            # spring from a to b: extension x_b - x_a (an end at the frame does not move)
            e = (x[b_end] if b_end >= 0 else 0.0) - (x[a] if a >= 0 else 0.0)
            g = k * e**3
            if a >= 0:
                force[a] += g
            if b_end >= 0:
                force[b_end] -= g
        return force

    rhs = _linear_rhs(M, C, K, b, cubic)
    if accelerations:
        return integrate_accelerations(rhs, np.zeros(2 * n), u, dt, n)
    return integrate_smooth(rhs, np.zeros(2 * n), u, dt, n_out=n)


# ---------------------------------------------------------------------------- stick-slip
def simulate_coulomb_ref(springs, theta, u, dt, *, states=False):
    """Stick-slip friction, event-driven.

    Modes per cart: stuck (x' = 0 held while |F| < Fs) or sliding in direction d
    (friction -Fc d).  Events: a sliding cart's velocity reaching zero (then stick if
    |F| < Fs, else reverse) and a stuck cart's |F| reaching Fs (break away along F).
    Returns the positions (N, n), or with ``states`` positions and velocities (N, 2n)
    (a held cart's velocity is exactly 0).
    """
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    n = M.shape[0]
    fc = np.asarray(theta[p : p + n], float)
    fs = np.asarray(theta[p + n : p + 2 * n], float)
    minv = 1.0 / np.diag(M)
    N = len(u)
    t_s = np.arange(N) * dt
    n_out = 2 * n if states else n
    Y = np.empty((N, n_out))
    z = np.zeros(2 * n)
    stuck = np.ones(n, bool)
    d = np.zeros(n)

    def net(z, v):
        return b * v - K @ z[:n] - C @ z[n:]

    def rhs(t, z, v):
        F = net(z, v)
        a = minv * (F - fc * d)
        xd = z[n:].copy()
        a[stuck] = 0.0
        xd[stuck] = 0.0
        return np.r_[xd, a]

    def make_events(v):
        evs = []
        for i in range(n):
            if stuck[i]:
                def e(t, z, *_, i=i):
                    return abs(net(z, v)[i]) - fs[i]
                e.direction = 1.0
            else:
                # offset: a just-released cart starts at v = 0 exactly, which the event
                # finder would otherwise report again at once
                def e(t, z, *_, i=i):
                    return d[i] * z[n + i] + V_EPS
                e.direction = -1.0
            e.terminal = True
            evs.append(e)
        return evs

    def update_modes(z, v):
        # at a segment start and after every event: stuck carts whose force exceeds Fs
        # break away
        F = net(z, v)
        for i in range(n):
            if stuck[i] and abs(F[i]) >= fs[i]:
                stuck[i] = False
                d[i] = np.sign(F[i])

    Y[0] = z[:n_out]
    for t0, t1, val in input_segments(u, dt):
        t = t0
        update_modes(z, val)
        while t < t1:
            mask = (t_s > t) & (t_s <= t1)
            sol = solve_ivp(rhs, (t, t1), z, method="DOP853", args=(val,),
                            events=make_events(val), dense_output=True,
                            rtol=RTOL, atol=ATOL, max_step=MAX_STEP_FRACTION * dt)
            t_stop = sol.t[-1]
            take = mask & (t_s <= t_stop)
            if take.any():
                Y[take] = sol.sol(t_s[take])[:n_out].T
            z = sol.y[:, -1].copy()
            if sol.status == 1:  # an event
                i = next(j for j, te in enumerate(sol.t_events) if len(te))
                F = net(z, val)
                if stuck[i]:
                    stuck[i] = False
                    d[i] = np.sign(F[i])
                else:
                    z[n + i] = 0.0
                    if abs(F[i]) < fs[i]:
                        stuck[i] = True
                        d[i] = 0.0
                    else:
                        d[i] = np.sign(F[i])
                # a held cart whose force went past Fs at this event (the event
                # functions only see upward crossings) breaks away now
                update_modes(z, val)
                for j in range(n):
                    if stuck[j]:
                        z[n + j] = 0.0
            t = t_stop
    return Y if states else Y[:, :n]


# ---------------------------------------------------------------------------- backlash
def simulate_backlash_ref(springs, theta, u, dt, tau=0.0):
    """Rack-pinion backlash between a motor of mass m_p and cart 1, plastic contact.

    With ``tau > 0`` the motor force lags the voltage, ``tau f' = g_v v - f`` (an extra
    state, continuous through the contact events), and ``f`` replaces ``g_v v`` below.

    Engaged on side s (delta = x_m - x_1 = s gap/2): motor and cart 1 move together
    (total mass m1); the contact force on cart 1 is g_v v - m_p a_1 and the contact opens
    when s * force < 0.  Disengaged: cart 1 has mass m1 - m_p and no motor force, the motor
    accelerates at g_v v / m_p; at |delta| = gap/2 a plastic impact gives both the
    momentum-weighted mean velocity.
    """
    p = n_linear(springs)
    M, C, K, b = rig_matrices(springs, theta[:p])
    gap, m_p = float(theta[p]), float(theta[p + 1])
    n = M.shape[0]
    m = np.diag(M).copy()
    j = driven(springs)
    g_v = b[j]  # signed by the drive's share
    N = len(u)
    t_s = np.arange(N) * dt
    Y = np.empty((N, n))
    half = gap / 2
    state = {"engaged": False, "side": 1.0}
    lag = tau > 0.0
    z = np.zeros(2 * n + 2 + lag)  # x, x', x_m, x_m' (and the lagged force f)

    def drive(z, v):
        return z[2 * n + 2] if lag else g_v * v

    def accel_engaged(z, v):
        F = -K @ z[:n] - C @ z[n : 2 * n]
        F[j] += drive(z, v)
        return F / m

    def contact_force(z, v):
        return drive(z, v) - m_p * accel_engaged(z, v)[j]

    def rhs(t, z, v):
        x, xd = z[:n], z[n : 2 * n]
        if state["engaged"]:
            a = accel_engaged(z, v)
            out = np.r_[xd, a, xd[j], a[j]]
        else:
            F = -K @ x - C @ xd
            mm = m.copy()
            mm[j] -= m_p
            out = np.r_[xd, F / mm, z[2 * n + 1], drive(z, v) / m_p]
        return np.r_[out, (g_v * v - z[2 * n + 2]) / tau] if lag else out

    def events(v):
        if state["engaged"]:
            def opened(t, z, *_):
                return state["side"] * contact_force(z, v)
            opened.terminal, opened.direction = True, -1.0
            return [opened]

        def hit_pos(t, z, *_):
            return z[2 * n] - z[j] - half

        def hit_neg(t, z, *_):
            return z[2 * n] - z[j] + half
        hit_pos.terminal, hit_pos.direction = True, 1.0
        hit_neg.terminal, hit_neg.direction = True, -1.0
        return [hit_pos, hit_neg]

    def maybe_open(z, v):
        if state["engaged"] and state["side"] * contact_force(z, v) < 0:
            state["engaged"] = False

    Y[0] = z[:n]
    for t0, t1, val in input_segments(u, dt):
        t = t0
        maybe_open(z, val)
        while t < t1:
            mask = (t_s > t) & (t_s <= t1)
            sol = solve_ivp(rhs, (t, t1), z, method="DOP853", args=(val,), events=events(val),
                            dense_output=True, rtol=RTOL, atol=ATOL)
            t_stop = sol.t[-1]
            take = mask & (t_s <= t_stop)
            if take.any():
                Y[take] = sol.sol(t_s[take])[:n].T
            z = sol.y[:, -1].copy()
            if sol.status == 1:
                if state["engaged"]:
                    state["engaged"] = False
                else:
                    hit = 0 if len(sol.t_events[0]) else 1
                    state["side"] = 1.0 if hit == 0 else -1.0
                    vc = (m_p * z[2 * n + 1] + (m[j] - m_p) * z[n + j]) / m[j]
                    z[n + j] = vc
                    z[2 * n + 1] = vc
                    z[2 * n] = z[j] + state["side"] * half
                    state["engaged"] = True
                    maybe_open(z, val)
            t = t_stop
    return Y


REFERENCES = {
    "coulomb_friction": simulate_coulomb_ref,
    "motor_lag": simulate_motor_lag_ref,
    "input_delay": simulate_input_delay_ref,
    "backlash": simulate_backlash_ref,
    "cubic_stiffness": simulate_cubic_ref,
    "input_saturation": simulate_saturation_ref,
}
