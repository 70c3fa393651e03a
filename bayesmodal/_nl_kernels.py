"""Compiled inner loops (numba) for the model extensions.

Every nonlinear extension is written as the *exact* zero-order-hold discretisation of the
linear rig over a sub-step ``h = dt / n_sub`` plus extra force inputs ``f`` acting on the
carts (friction, cubic spring forces) or a switch between two exactly discretised linear
systems (backlash).  The linear part is therefore integrated without error and the only
approximation is in how ``f`` varies within a sub-step; with the extension switched off
``f = 0`` and the kernels reproduce the linear simulator to rounding error.

Layouts (float64, C order; ``s = 2 n`` states ``(x, x')``, ``n`` carts, ``nb`` lanes):

- ``Ah (nb, s, s)``, ``Bh (nb, s)``: one sub-step of the linear system;
- ``Fh (nb, s, n)``: response to a force held constant on each cart over the sub-step;
- ``G (nb, n, s)``, ``gb (nb, n)``: net non-friction force on each cart,
  ``F = G z + gb u`` with ``G = [-K, -C]`` and ``gb = b`` (N);
- ``Y (nb, N, n)`` output positions, ``Y[:, k]`` is the state at ``t = k dt``.

The per-lane loops keep the parameter set outermost: lanes branch differently (stick,
slip, contact) so there is nothing to gain from vectorising across them.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "boundscheck": False, "error_model": "numpy"}


# ---------------------------------------------------------------------------------------
# linear recursion with a different input sequence in each lane (delay, saturation)
MAX_WIDTH = 64


def _padded_width(nb: int) -> int:
    w = 1
    while w < min(nb, MAX_WIDTH):
        w *= 2
    return w


def _compile(lines: list[str], label: str, **globals_):
    namespace: dict = dict(globals_)
    exec(compile("\n".join(lines), label, "exec"), namespace)  # noqa: S102 - integers only
    return njit(nogil=True, boundscheck=False, error_model="numpy")(namespace["kernel"])


@functools.lru_cache(maxsize=32)
def _per_lane_kernel(n_states: int, n_out: int, width: int):
    """Compiled ``kernel(P, U, X, Y)`` for ``x[k+1] = Ad x[k] + Bd U[k]``, lanes innermost.

    Flat layouts: ``P (s*s + s, width)`` with ``Ad[i, j]`` in row ``i*s + j`` and ``Bd[i]``
    in row ``s*s + i``; ``U (N, width)``; ``X (s, width)`` updated in place;
    ``Y (N, n_out, width)``.  The batch index is innermost and the widths are constants so
    that the compiler vectorises across parameter sets.
    """
    s, w = n_states, width
    lines = [
        "def kernel(P, U, X, Y):",
        "    for k in range(U.shape[0] // " + str(w) + "):",
        f"        uo = k * {w}",
        f"        yo = k * {n_out * w}",
        f"        for b in range({w}):",
        "            uk = U[uo + b]",
    ]
    lines += [f"            x{i} = X[{i * w} + b]" for i in range(s)]
    lines += [f"            Y[yo + {i * w} + b] = x{i}" for i in range(n_out)]
    for i in range(s):
        terms = " + ".join(f"P[{(i * s + j) * w} + b] * x{j}" for j in range(s))
        lines.append(f"            X[{i * w} + b] = P[{(s * s + i) * w} + b] * uk + {terms}")
    return _compile(lines, f"<bayesmodal per-lane recursion s={s} o={n_out} w={w}>")


def run_per_lane(Ad: np.ndarray, Bd: np.ndarray, U: np.ndarray, x0: np.ndarray, n_out: int):
    """Batched ``x[k+1] = Ad x[k] + Bd U[b, k]`` with one input sequence per lane.

    Parameters
    ----------
    Ad : ndarray, shape (nb, s, s)
    Bd : ndarray, shape (nb, s)
    U : ndarray, shape (nb, N)
    x0 : ndarray, shape (nb, s)
    n_out : int
        Number of leading states returned.

    Returns
    -------
    ndarray, shape (nb, N, n_out)
    """
    nb, s, _ = Ad.shape
    N = U.shape[1]
    width = _padded_width(nb)
    n_chunks = -(-nb // width)
    kernel = _per_lane_kernel(s, n_out, width)
    Y = np.empty((n_chunks, N, n_out, width))
    for c in range(n_chunks):
        lanes = np.arange(c * width, (c + 1) * width)
        lanes = np.where(lanes < nb, lanes, nb - 1)  # pad with a repeated valid lane
        P = np.empty((s * s + s, width))
        P[: s * s] = Ad[lanes].reshape(width, s * s).T
        P[s * s :] = Bd[lanes].T
        Uc = np.ascontiguousarray(U[lanes].T)
        X = np.ascontiguousarray(x0[lanes].T)
        kernel(P.ravel(), Uc.ravel(), X.ravel(), Y[c].reshape(-1))
    y = Y.transpose(0, 3, 1, 2).reshape(n_chunks * width, N, n_out)[:nb]
    return np.ascontiguousarray(y)


# ---------------------------------------------------------------------------------------
# Coulomb friction with stick-slip
@njit(**_JIT)
def _sgn(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@functools.lru_cache(maxsize=16)
def coulomb_kernel(n: int):
    """Compiled stick-slip Coulomb friction kernel for ``n`` carts (see ``coulomb_run``)."""
    s = 2 * n
    R = range(s)
    C = range(n)
    L = ["def kernel(Ah, Bh, Fh, G, gb, minv, Fc, Fs, u, n_sub, h, X0, Y):",
         "    nb = Ah.shape[0]",
         "    N = u.shape[0]",
         "    for b in range(nb):"]
    w = "        "
    L += [f"{w}a{r}_{j} = Ah[b, {r}, {j}]" for r in R for j in R]
    L += [f"{w}bh{r} = Bh[b, {r}]" for r in R]
    L += [f"{w}fh{r}_{j} = Fh[b, {r}, {j}]" for r in R for j in C]
    L += [f"{w}g{i}_{j} = G[b, {i}, {j}]" for i in C for j in R]
    for i in C:
        L += [f"{w}gb{i} = gb[b, {i}]", f"{w}mi{i} = minv[b, {i}]",
              f"{w}fc{i} = Fc[b, {i}]", f"{w}fs{i} = Fs[b, {i}]"]
    L += [f"{w}x{r} = X0[b, {r}]" for r in R]
    for i in C:
        v = f"x{n + i}"
        L += [f"{w}st{i} = {v} == 0.0",
              f"{w}d{i} = 1.0 if {v} > 0.0 else (-1.0 if {v} < 0.0 else 0.0)",
              f"{w}xs{i} = x{i}",
              f"{w}gzp{i} = np.nan",
              f"{w}f{i} = 0.0"]
    L += [f"{w}u_prev = u[0]",
          f"{w}for k in range(N):"]
    w = "            "
    L += [f"{w}Y[b, k, {i}] = x{i}" for i in C]
    L += [f"{w}uk = u[k]", f"{w}for sub in range(n_sub):"]
    w = "                "
    L += [f"{w}same = uk == u_prev", f"{w}u_prev = uk"]
    for i in C:
        gz = " + ".join(f"g{i}_{j} * x{j}" for j in R)
        L += [f"{w}gz{i} = {gz}",
              f"{w}F{i} = gz{i} + gb{i} * uk",
              f"{w}Fp{i} = gzp{i} + gb{i} * uk",
              f"{w}gzp{i} = gz{i}"]
    for i in C:
        L += [f"{w}if st{i}:",
              f"{w}    if abs(F{i}) < fs{i}:",
              f"{w}        f{i} = -F{i}",
              f"{w}    else:",
              f"{w}        st{i} = False",
              f"{w}        d{i} = 1.0 if F{i} > 0.0 else (-1.0 if F{i} < 0.0 else 0.0)",
              f"{w}        f{i} = -fc{i} * d{i}",
              f"{w}        aF = abs(F{i})",
              f"{w}        aFp = abs(Fp{i})",
              f"{w}        if same and aFp < fs{i} and aF > aFp:",
              f"{w}            tau = h * (aF - fs{i}) / (aF - aFp)",
              f"{w}            dv = d{i} * (0.5 * (aF + fs{i}) - fc{i}) * mi{i} * tau",
              f"{w}            x{n + i} += dv",
              f"{w}            x{i} += 0.5 * dv * tau",
              f"{w}else:",
              f"{w}    f{i} = -fc{i} * d{i}"]
    for r in R:
        terms = " + ".join([f"a{r}_{j} * x{j}" for j in R] + [f"fh{r}_{j} * f{j}" for j in C])
        L.append(f"{w}n{r} = bh{r} * uk + {terms}")
    for i in C:
        fe = " + ".join(f"g{i}_{j} * n{j}" for j in R)
        L += [f"{w}if st{i}:",
              f"{w}    n{i} = xs{i}",
              f"{w}    n{n + i} = 0.0",
              f"{w}elif d{i} * n{n + i} < 0.0:",
              f"{w}    v0 = x{n + i}",
              f"{w}    v1 = n{n + i}",
              f"{w}    a = v0 / (v0 - v1) if v0 != v1 else 0.0",
              f"{w}    a = min(max(a, 0.0), 1.0)",
              f"{w}    tau = (1.0 - a) * h",
              f"{w}    Fe = gb{i} * uk + {fe}",
              f"{w}    Fx = F{i} + a * (Fe - F{i})",
              f"{w}    if abs(Fx) < fs{i}:",
              f"{w}        st{i} = True",
              f"{w}        n{i} -= 0.5 * v1 * tau",
              f"{w}        n{n + i} = 0.0",
              f"{w}        xs{i} = n{i}",
              f"{w}    else:",
              f"{w}        dv = 2.0 * fc{i} * d{i} * mi{i} * tau",
              f"{w}        n{n + i} += dv",
              f"{w}        n{i} += 0.5 * dv * tau",
              f"{w}        d{i} = -d{i}"]
    L += [f"{w}x{r} = n{r}" for r in R]
    return _compile(L, f"<bayesmodal coulomb n={n}>", np=np)


def coulomb_run(Ah, Bh, Fh, G, gb, minv, Fc, Fs, u, n_sub, h, x0, Y):
    """Stick-slip Coulomb friction on every cart (see ``extensions.coulomb``).

    Per sub-step: the friction force of each cart is decided at the start (stuck carts
    hold the net force exactly, ``f = -F``, while ``|F| < Fs``; sliding carts get
    ``f = -Fc dir``), the state is advanced exactly with that force held, and the events
    inside the step are then corrected to second order:

    - a sliding cart whose velocity changed sign crossed zero at the fraction
      ``a = v0 / (v0 - v1)`` of the step.  If the net force there is below ``Fs`` it sticks
      (velocity set to zero, position moved back by the distance travelled after the
      crossing, ``v1 tau / 2``); otherwise friction reverses and the wrong force over the
      remaining ``tau = (1 - a) h`` is undone: ``dv = 2 Fc dir tau / m``,
      ``dx = dv tau / 2``;
    - a stuck cart whose net force passed ``Fs`` during the previous sub-step (same input)
      started slipping ``tau = h (|F| - Fs) / (|F| - |F_prev|)`` ago; it gets the velocity
      and displacement of that interval under the mean net force.

    The state loop is generated for the number of carts and unrolled into scalars.
    """
    n = Fc.shape[1]
    coulomb_kernel(n)(Ah, Bh, Fh, G, gb, minv, Fc, Fs, u, int(n_sub), float(h), x0, Y)
    return Y


# ---------------------------------------------------------------------------------------
# cubic spring stiffness
def _cubic_force_lines(w: str, n: int, src: str, dst: str) -> list[str]:
    # spring i joins cart i and i + 1 (the last one joins cart n - 1 to the frame); its
    # extension is d_i = x_{i+1} - x_i (or -x_{n-1}) and it pulls cart i with k3_i d_i^3
    # and cart i + 1 with -k3_i d_i^3
    lines = []
    for i in range(n):
        d = f"({src}{i + 1} - {src}{i})" if i < n - 1 else f"(-{src}{i})"
        lines += [f"{w}e{i} = {d}", f"{w}c{i} = k3_{i} * e{i} * e{i} * e{i}"]
    for i in range(n):
        lines.append(f"{w}{dst}{i} = c{i}" + (f" - c{i - 1}" if i > 0 else ""))
    return lines


@functools.lru_cache(maxsize=16)
def cubic_kernel(n: int):
    """Compiled cubic-spring kernel for ``n`` carts (see ``cubic_run``)."""
    s = 2 * n
    R, C = range(s), range(n)
    L = ["def kernel(Ah, Bh, F0h, F1h, k3, u, n_sub, X0, Y):",
         "    nb = Ah.shape[0]",
         "    N = u.shape[0]",
         "    for b in range(nb):"]
    w = "        "
    L += [f"{w}a{r}_{j} = Ah[b, {r}, {j}]" for r in R for j in R]
    L += [f"{w}bh{r} = Bh[b, {r}]" for r in R]
    L += [f"{w}p{r}_{j} = F0h[b, {r}, {j}]" for r in R for j in C]
    L += [f"{w}q{r}_{j} = F1h[b, {r}, {j}]" for r in R for j in C]
    L += [f"{w}k3_{i} = k3[b, {i}]" for i in C]
    L += [f"{w}x{r} = X0[b, {r}]" for r in R]
    L += [f"{w}for k in range(N):"]
    w = "            "
    L += [f"{w}Y[b, k, {i}] = x{i}" for i in C]
    L += [f"{w}uk = u[k]", f"{w}for sub in range(n_sub):"]
    w = "                "
    L += _cubic_force_lines(w, n, "x", "f")
    for r in R:
        terms = " + ".join([f"a{r}_{j} * x{j}" for j in R] + [f"p{r}_{j} * f{j}" for j in C])
        L.append(f"{w}y{r} = bh{r} * uk + {terms}")
    L += _cubic_force_lines(w, n, "y", "g")
    for r in R:
        terms = " + ".join(f"q{r}_{j} * (g{j} - f{j})" for j in C)
        L.append(f"{w}x{r} = y{r} + {terms}")
    return _compile(L, f"<bayesmodal cubic n={n}>")


def cubic_run(Ah, Bh, F0h, F1h, k3, u, n_sub, x0, Y):
    """Cubic spring forces ``k3_i d_i^3`` by the exponential Runge-Kutta scheme ETD2RK.

    Predictor with the force held over the sub-step (``F0h``), corrector with the force
    ramped linearly between its values at both ends (``F1h``, the response to the unit
    ramp ``s / h``); second-order in the nonlinear part, exact in the linear part.
    """
    cubic_kernel(k3.shape[1])(Ah, Bh, F0h, F1h, k3, u, int(n_sub), x0, Y)
    return Y


# ---------------------------------------------------------------------------------------
# backlash between the motor and cart 1
@functools.lru_cache(maxsize=16)
def backlash_kernel(n: int):
    """Compiled backlash kernel for ``n`` carts (see ``backlash_run``)."""
    s = 2 * n
    R = range(s)
    L = ["def kernel(Ae, Be, Adis, Ge, m1, m_p, g_v, gap, u, n_sub, h, X0, Y):",
         "    nb = Ae.shape[0]",
         "    N = u.shape[0]",
         "    for b in range(nb):"]
    w = "        "
    L += [f"{w}a{r}_{j} = Ae[b, {r}, {j}]" for r in R for j in R]
    L += [f"{w}e{r}_{j} = Adis[b, {r}, {j}]" for r in R for j in R]
    L += [f"{w}be{r} = Be[b, {r}]" for r in R]
    L += [f"{w}ge{j} = Ge[b, {j}]" for j in R]
    L += [f"{w}x{r} = X0[b, {r}]" for r in R]
    L += [f"{w}half = 0.5 * gap[b]",
          f"{w}mp = m_p[b]",
          f"{w}mt = m1[b]",
          f"{w}mc = mt - mp",
          f"{w}gv = g_v[b]",
          f"{w}engaged = half == 0.0",
          f"{w}side = 1.0",
          f"{w}xm = x0",
          f"{w}vm = x{n}",
          f"{w}fcon_prev = 0.0",
          f"{w}u_prev = u[0]",
          f"{w}for k in range(N):"]
    w = "            "
    L += [f"{w}Y[b, k, {i}] = x{i}" for i in range(n)]
    L += [f"{w}uk = u[k]", f"{w}fm = gv * uk", f"{w}am = fm / mp",
          f"{w}for sub in range(n_sub):"]
    w = "                "
    f1 = " + ".join(f"ge{j} * x{j}" for j in R)
    L += [f"{w}same = uk == u_prev",
          f"{w}u_prev = uk",
          f"{w}if engaged:",
          f"{w}    F1 = {f1}",
          f"{w}    fcon = (mc * fm - mp * F1) / mt",
          f"{w}    if side * fcon < 0.0:",
          f"{w}        if half == 0.0:",
          f"{w}            side = -side",
          f"{w}        else:",
          f"{w}            engaged = False",
          f"{w}            xm = x0 + side * half",
          f"{w}            vm = x{n}",
          # the contact force crossed zero inside the last sub-step (same input): since
          # then cart 1 and the motor have moved apart, second-order correction
          f"{w}            if same and side * fcon_prev > 0.0:",
          f"{w}                tau = h * fcon / (fcon - fcon_prev)",
          f"{w}                a1e = (F1 + fm) / mt",
          f"{w}                dv1 = (F1 / mc - a1e) * tau",
          f"{w}                dvm = (am - a1e) * tau",
          f"{w}                x0 += 0.5 * dv1 * tau",
          f"{w}                x{n} += dv1",
          f"{w}                xm += 0.5 * dvm * tau",
          f"{w}                vm += dvm",
          f"{w}    fcon_prev = fcon",
          f"{w}if engaged:"]
    for r in R:
        terms = " + ".join(f"a{r}_{j} * x{j}" for j in R)
        L.append(f"{w}    y{r} = be{r} * uk + {terms}")
    L += [f"{w}else:"]
    for r in R:
        terms = " + ".join(f"e{r}_{j} * x{j}" for j in R)
        L.append(f"{w}    y{r} = {terms}")
    L += [f"{w}    delta0 = xm - x0",
          f"{w}    xm += vm * h + 0.5 * am * h * h",
          f"{w}    vm += am * h",
          f"{w}    delta = xm - y0",
          f"{w}    if abs(delta) >= half:",
          # plastic impact: momentum is right whenever it happened; the position of cart 1
          # is corrected for the time since the impact
          f"{w}        side = 1.0 if delta > 0.0 else -1.0",
          f"{w}        a = (side * half - delta0) / (delta - delta0) if delta != delta0 else 1.0",
          f"{w}        a = min(max(a, 0.0), 1.0)",
          f"{w}        vc = (mp * vm + mc * y{n}) / mt",
          f"{w}        y0 += (vc - y{n}) * (1.0 - a) * h",
          f"{w}        y{n} = vc",
          f"{w}        engaged = True"]
    L += [f"{w}x{r} = y{r}" for r in R]
    return _compile(L, f"<bayesmodal backlash n={n}>")


def backlash_run(Ae, Be, Adis, Ge, m1, m_p, g_v, gap, u, n_sub, h, x0, Y):
    """Rack-pinion backlash with a plastic contact (see ``extensions.backlash``).

    Engaged (``|delta| = gap / 2`` on side ``side``): motor and cart 1 move together; the
    exact linear step ``(Ae, Be)`` applies.  The contact force on cart 1 is
    ``Fcon = ((m1 - m_p) g_v u - m_p F1) / m1`` with ``F1 = Ge z`` the other forces on
    cart 1; the contact opens when ``side * Fcon < 0`` (with the motion since the zero
    crossing of ``Fcon`` inside the last sub-step added to cart 1 and the motor).
    Disengaged: the carts follow the exact unforced step ``Adis`` (cart 1 without the motor
    mass) and the motor is a free mass ``m_p`` under ``g_v u``; when ``|delta|`` reaches
    ``gap / 2`` the contact closes with a plastic impact that conserves momentum, and cart
    1's position is corrected for the part of the sub-step after the impact.  With
    ``gap = 0`` the contact never opens (it only changes side) and the scheme is the linear
    simulator.
    """
    n = Ae.shape[1] // 2
    backlash_kernel(n)(Ae, Be, Adis, Ge, m1, m_p, g_v, gap, u, int(n_sub), float(h), x0, Y)
    return Y
