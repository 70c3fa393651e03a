"""Backlash of the drive (rack-pinion gap): the batched kernel with impact events."""

from __future__ import annotations

import functools

import numpy as np

from ._codegen import (
    _compile,
    _fma_sum,
    _head,
    _Rows,
    checked_columns,
    checked_outputs,
    run_batched,
    sensor_lines,
    with_sensors,
)

#: Newton steps for the impact time of the backlash kernel.
IMPACT_NEWTON = 2


def _sensors_at_sample(t: str, n: int, w: int, P, X, outputs, columns,
                       per_lane: bool) -> list[str]:
    """Code reading the sensors at the sample (``sensor_lines``) from the state there.

    An acceleration is that of the mode the drive is in once the sample's own switch
    checks are done, as the first sub-step makes them: the engaged rows (``oc``, ``od``:
    cart 1 with the motor, mass ``m1``, under ``F1 + g_v u``), and while the gap is open
    cart 1 alone, ``F1 / (m1 - m_p)``, written as the engaged row plus ``oe = 1 / m1``
    times ``fb0 = F1 m_p / (m1 - m_p) - g_v u``.  The other carts do not touch the drive:
    their rows are the same in both modes (``fb_k = 0``)."""
    s = 2 * n
    R = range(s)
    L = [f"{t}x{r} = {X('x', r)}" for r in R]
    if not any(o == 2 for _, o in outputs):
        return L + sensor_lines(t, outputs, n, s, P, [("od", "uk")], columns=columns)
    if per_lane:
        L += [f"{t}uk = u[k * {w} + b]", f"{t}uo = u[(k - 1 if k > 0 else 0) * {w} + b]"]
    else:
        L += [f"{t}uo = u_prev"]
    f1 = " + ".join(f"{P('ge', j)} * x{j}" for j in R)
    # the opening test of the sub-step (``backlash_kernel``) on the state at the sample
    L += [f"{t}half = {P('half')}",
          f"{t}side = {X('side')}",
          f"{t}fcon_prev = {X('fp')}",
          f"{t}mp = {P('mp')}",
          f"{t}mc = {P('mt')} - mp",
          f"{t}imt = {P('imt')}",
          f"{t}fm = {P('gv')} * uk",
          f"{t}F1 = {f1}",
          f"{t}fcon = (mc * fm - mp * F1) * imt",
          f"{t}fcon_o = (mc * {P('gv')} * uo - mp * F1) * imt",
          f"{t}late = half != 0.0 and side * fcon_o < 0.0 and side * fcon_prev > 0.0",
          f"{t}free = {X('eng')} == 0.0 or (half != 0.0 and (late or side * fcon < 0.0))",
          f"{t}fb0 = fma(F1 * mp, {P('imc')}, -fm) if free else 0.0"]
    L += [f"{t}fb{k} = 0.0" for k in range(1, n)]
    return L + sensor_lines(t, outputs, n, s, P, [("od", "uk")], force="fb",
                            columns=columns)


@functools.lru_cache(maxsize=16)
def backlash_kernel(n: int, width: int, per_lane: bool = False,
                    outputs: tuple[tuple[int, int], ...] | None = None,
                    columns: tuple[tuple[int, ...], ...] | None = None):
    """Compiled backlash kernel (see ``backlash_run``); ``per_lane``: see ``_lane_inputs``;
    ``outputs``: the sensors ``(k, order)`` read at each sample (``_sensors_at_sample``:
    rows ``oc``, ``od``, ``oe`` of the acceleration sensors), default the cart positions;
    ``columns``: the states each acceleration row involves (``sensor_lines``)."""
    s, w = 2 * n, width
    R = range(s)
    rows = [("Ae", s * s), ("be", s), ("Ad", s * s), ("ge", s), ("mt", 1), ("mp", 1),
            ("imt", 1), ("imc", 1), ("imp", 1), ("gv", 1), ("half", 1)]
    if outputs is not None:
        outputs = checked_outputs(outputs, n)
        n_acc = sum(o == 2 for _, o in outputs)
        columns = None if columns is None else checked_columns(columns, n_acc, s)
        n_c = n_acc * s if columns is None else sum(map(len, columns))
        rows += [("oc", n_c), ("od", n_acc), ("oe", n_acc)] if n_acc else []
    P = _Rows("P", w, rows)
    X = _Rows("X", w, [("x", s), ("eng", 1), ("side", 1), ("xm", 1), ("vm", 1),
                       ("fp", 1)])
    if outputs is None:
        L = _head("P, X, u, n_sub, h, Y", n, w, X, per_lane)
    else:
        L = _head("P, X, u, n_sub, h, Y", len(outputs), w, X, per_lane)[: -len(outputs)]
        L += _sensors_at_sample(" " * 12, n, w, P, X, outputs, columns, per_lane)
    t = "                "
    if per_lane:
        # the last sub-step's input: the previous sample's in the first sub-step
        L[1:1] = ["    ih2 = 1.0 / (h * h)"]
        L += ["        ko = (k - 1 if k > 0 else 0) * " + str(w),
              "        for sub in range(n_sub):",
              f"            for b in range({w}):",
              f"{t}uk = u[k * {w} + b]",
              f"{t}uo = u[ko + b] if sub == 0 else uk"]
    else:
        L[1:1] = ["    u_prev = u[0]", "    ih2 = 1.0 / (h * h)"]
        L += ["        for sub in range(n_sub):",
              "            uo = u_prev",
              "            u_prev = uk",
              f"            for b in range({w}):"]
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    f1 = " + ".join(f"{P('ge', j)} * x{j}" for j in R)
    L += [f"{t}engaged = {X('eng')} != 0.0",
          f"{t}side = {X('side')}",
          f"{t}xm = {X('xm')}",
          f"{t}vm = {X('vm')}",
          f"{t}fcon_prev = {X('fp')}",
          f"{t}half = {P('half')}",
          f"{t}mp = {P('mp')}",
          f"{t}mc = {P('mt')} - mp",
          f"{t}imt = {P('imt')}",
          f"{t}imc = {P('imc')}",
          f"{t}fm = {P('gv')} * uk",
          f"{t}am = fm * {P('imp')}",
          f"{t}fo = {P('gv')} * uo",
          # engaged: the contact force on cart 1, with this and the last sub-step's input
          f"{t}F1 = {f1}",
          f"{t}fcon = (mc * fm - mp * F1) * imt",
          f"{t}fcon_o = (mc * fo - mp * F1) * imt",
          # the contact force crossed zero inside the last sub-step: since then cart 1 and
          # the motor have moved apart under that sub-step's input, second-order correction
          f"{t}late = engaged and half != 0.0 and side * fcon_o < 0.0"
          " and side * fcon_prev > 0.0",
          f"{t}pull = engaged and (late or side * fcon < 0.0)",
          f"{t}opening = pull and half != 0.0",
          f"{t}side = -side if pull and half == 0.0 else side",
          f"{t}tau = h * fcon_o / (fcon_o - fcon_prev) if late else 0.0",
          f"{t}a1e = (F1 + fo) * imt",
          f"{t}dv1 = (F1 * imc - a1e) * tau",
          f"{t}dvm = (fo * {P('imp')} - a1e) * tau",
          f"{t}xm = x0 + side * half + 0.5 * dvm * tau if opening else xm",
          f"{t}vm = x{n} + dvm if opening else vm",
          f"{t}x0 += 0.5 * dv1 * tau",
          f"{t}x{n} += dv1",
          f"{t}fcon_prev = fcon if engaged else fcon_prev",
          f"{t}engaged = engaged and not opening",
          f"{t}if engaged:"]
    for r in R:
        prods = [(P('Ae', r * s + j), f"x{j}") for j in R]
        L.append(f"{t}    y{r} = {_fma_sum(f'{P(chr(98) + chr(101), r)} * uk', prods)}")
    L += [f"{t}else:"]
    for r in R:
        prods = [(P('Ad', r * s + j), f"x{j}") for j in R]
        L.append(f"{t}    y{r} = {_fma_sum('0.0', prods)}")
    # disengaged: the motor moves freely; a plastic impact when the gap closes, located
    # on the quadratic through delta0, its slope vrel0 and delta (Newton from the chord)
    L += [f"{t}delta0 = xm - x0",
          f"{t}vrel0 = vm - x{n}",
          f"{t}xm += vm * h + 0.5 * am * h * h",
          f"{t}vm += am * h",
          f"{t}delta = xm - y0",
          f"{t}hit = not engaged and abs(delta) >= half",
          f"{t}sd = 1.0 if delta > 0.0 else -1.0",
          f"{t}e0 = delta0 - sd * half",
          f"{t}tq = h * e0 / (delta0 - delta) if delta != delta0 else h",
          f"{t}tq = 0.0 if tq < 0.0 else (h if tq > h else tq)",
          f"{t}cq = (delta - delta0 - vrel0 * h) * ih2"]
    for _ in range(IMPACT_NEWTON):
        L += [f"{t}dg = vrel0 + 2.0 * cq * tq",
              f"{t}tq = tq - (e0 + (vrel0 + cq * tq) * tq) / dg if dg != 0.0 else tq",
              f"{t}tq = 0.0 if tq < 0.0 else (h if tq > h else tq)"]
    # momentum after the impact; since the impact (tau ago) cart 1's damper acted on the
    # common velocity, and cart 1 accelerated as engaged: second-order corrections
    L += [f"{t}tau = h - tq",
          f"{t}vc = (mp * vm + mc * y{n}) * imt",
          f"{t}jump = vc - y{n}",
          f"{t}vc += {P('ge', n)} * jump * tau * imt",
          f"{t}dacc = (F1 + fm + {P('ge', n)} * jump) * imt - F1 * imc",
          # if the contact force would pull right after the impact (the motor is braked
          # harder than cart 1), the two only share their momentum and part again
          f"{t}rebound = hit and sd * fcon < 0.0",
          f"{t}a1 = F1 * imc",
          f"{t}vcs = (mp * (vm - am * tau) + mc * (y{n} - a1 * tau)) * imt",
          f"{t}js = vcs - (y{n} - a1 * tau)",
          f"{t}stay = hit and not rebound",
          f"{t}y0 = y0 + (vc - y{n}) * tau - 0.5 * dacc * tau * tau if stay else y0",
          f"{t}y0 = y0 + js * tau if rebound else y0",
          f"{t}y{n} = vc if stay else (y{n} + js if rebound else y{n})",
          f"{t}vm = vcs + am * tau if rebound else vm",
          f"{t}xm = y0 + sd * half + 0.5 * (am - a1) * tau * tau if rebound else xm",
          f"{t}side = sd if hit else side",
          # no contact-force history inside this sub-step for the next opening check
          f"{t}fcon_prev = np.nan if hit else fcon_prev",
          f"{t}engaged = engaged or stay"]
    L += [f"{t}{X('x', r)} = y{r}" for r in R]
    L += [f"{t}{X('eng')} = 1.0 if engaged else 0.0",
          f"{t}{X('side')} = side",
          f"{t}{X('xm')} = xm",
          f"{t}{X('vm')} = vm",
          f"{t}{X('fp')} = fcon_prev"]
    tag = " per-lane" if per_lane else ""
    tag += "" if outputs is None else " outputs=" + ",".join(f"{k}:{o}" for k, o in outputs)
    tag += "" if columns is None else f" columns={columns}"
    return _compile(L, f"<bayesmodal backlash n={n} w={w}{tag}>")


def backlash_run(Ae, Be, Adis, Ge, m1, m_p, g_v, gap, u, n_sub, h, x0, outputs=None,
                 out_map=None, columns=None):
    """Rack-pinion backlash with a plastic contact (see ``extensions.backlash``).

    Engaged (``|delta| = gap / 2`` on side ``side``): motor and cart 1 move together; the
    exact linear step ``(Ae, Be)`` applies.  The contact force on cart 1 is
    ``Fcon = ((m1 - m_p) g_v u - m_p F1) / m1`` with ``F1 = Ge z`` the other forces on
    cart 1; the contact opens when ``side * Fcon < 0``, with the motion since the zero
    crossing of ``Fcon`` inside the last sub-step (under that sub-step's input) added to
    cart 1 and the motor.  Disengaged: the carts follow the exact unforced step ``Adis``
    (cart 1 without the motor mass) and the motor is a free mass ``m_p`` under ``g_v u``;
    when ``|delta|`` reaches ``gap / 2`` the contact closes with a plastic impact that
    conserves momentum.  The impact time is the root of the quadratic through ``delta``,
    its slope at the start and its end value (two Newton steps from the chord), and for
    the ``tau`` since the impact cart 1 is corrected to second order: it moved with the
    engaged acceleration, and its damper acted on the common velocity.  If the contact
    force would pull right after the impact, the two only exchange momentum and stay
    apart.  With ``gap = 0`` the contact never opens (it only changes side) and the scheme
    is the linear simulator.  The error is second order in the sub-step.

    Parameters
    ----------
    Ae, Adis : ndarray, shape (nb, s, s)
        One sub-step engaged and disengaged.
    Be : ndarray, shape (nb, s)
        Engaged response to the input held over a sub-step.
    Ge : ndarray, shape (nb, s)
        Spring and damper force on cart 1 from the state, N.
    m1, m_p, g_v, gap : ndarray, shape (nb,)
        Cart 1 mass with the motor (kg), motor mass (kg), gain (N/V), gap (m).
    u : ndarray, shape (N,)
    n_sub : int
    h : float
        Sub-step, s.
    x0 : ndarray, shape (nb, s)
    outputs : ndarray of int, shape (n_out, 2), optional
        Sensors ``(k, order)`` to read (``effects._linear.sensor_spec``), with
    out_map : tuple of ndarray
        ``(C, D, E)`` of the engaged rig (shapes (nb, n_out, s), (nb, n_out), (nb, n_out,
        n); ``effects._linear.sensor_map``): engaged, the readings are ``C x[k] + D
        u[k]``; with the gap open an acceleration of cart 1 is ``F1 / (m1 - m_p)``
        (``_sensors_at_sample``).  Default: the cart positions.
    columns : tuple of tuple of int, optional
        The states each acceleration sensor's row of ``C`` can involve; default all.

    Returns
    -------
    ndarray, shape (nb, N, n) or (nb, N, n_out)
    """
    nb, s = x0.shape
    n = s // 2
    engaged = (gap == 0.0).astype(float)
    # at rest with the pinion in the middle of the gap
    state = [x0, engaged, np.ones(nb), x0[:, 0], x0[:, n], np.zeros(nb)]
    mc = m1 - m_p
    params = [Ae, Be, Adis, Ge, m1, m_p, 1.0 / m1, 1.0 / mc, 1.0 / m_p, g_v, 0.5 * gap]
    kernel = functools.partial(backlash_kernel, n)
    kernel, params, n_out = with_sensors(kernel, params, outputs, out_map, columns, n)
    return run_batched(kernel, params, state, u, n_out, int(n_sub), float(h))
