"""Code of the steps of the stick-slip Coulomb friction kernel (``kernels.coulomb``).

The friction decision and the state predicted with the forces held (``_coulomb_predict``),
the location and correction of each cart's events inside a step (``_coulomb_event``), the
whole-sample step that flags the lanes with an event (``_coulomb_quiet_step``), the test
of a lane at rest (``_coulomb_at_rest``) and the packed groups' event-corrected sub-step
with each cart's event code only where a lane has that cart's event
(``_split_substep``).  The physics and the event handling are described in
``kernels.coulomb.coulomb_run``.
"""

from __future__ import annotations

from ._codegen import _fma_sum, _sum

#: Safeguarded Newton steps for the break-away time of the friction kernel (a held force
#: reaching the static level, on its cubic Hermite interpolant in time).
HERMITE_NEWTON = 2

#: Newton steps from the chord for the velocity zero of the friction kernel.
REVERSAL_NEWTON = 2

#: Relative margin below the static level under which a stuck cart of the friction
#: kernel is at rest for certain over a step (rounding of the step is ~1e-16).
REST_MARGIN = 1e-9


def _rising_cubic_root(t: str, x: str, c: tuple[str, str, str, str]) -> list[str]:
    """Code locating the root ``x`` in [0, 1] of ``c0 + x (c1 + x (c2 + x c3))``, which
    is negative at 0 and not negative at 1.

    Starts from the chord (``x`` must hold it) and takes ``HERMITE_NEWTON`` Newton steps
    safeguarded by the bracket [lo, hi] (a step leaving it bisects instead).  On cubics with an
    inflection or strong curvature in the step plain Newton from the chord overshoots
    (a break-away located 0.18 of a step late on a quadratically rising force).
    """
    c0, c1, c2, c3 = c
    lines = [f"{t}lo = 0.0", f"{t}hi = 1.0"]
    for _ in range(HERMITE_NEWTON):
        lines += [
            f"{t}g = {c0} + {x} * ({c1} + {x} * ({c2} + {x} * {c3}))",
            f"{t}dg = {c1} + {x} * (2.0 * {c2} + 3.0 * {x} * {c3})",
            f"{t}hi = {x} if g > 0.0 else hi",
            f"{t}lo = lo if g > 0.0 else {x}",
            f"{t}xn = {x} - g / dg",
            f"{t}xn = xn if dg != 0.0 else -1.0",
            f"{t}xb = 0.5 * (lo + hi)",
            f"{t}{x} = xn if (xn > lo) & (xn < hi) else xb",
        ]
    return lines


def _held_force(P, n: int, i: int, fe: str, x: str) -> str:
    """Code of cart i's net force at the step end were it held at ``x`` (velocity 0):
    the end force ``fe`` without the cart's own spring and damper motion over the step."""
    s = 2 * n
    return f"{fe} + {P('G', i * s + i)} * ({x} - n{i}) - {P('G', i * s + n + i)} * n{n + i}"


def _force_rates(P, n: int, i: int) -> tuple[list, list]:
    """The products whose sums are the rates of change of cart i's net force at the step
    start and end, N/s: ``G`` times the velocities and accelerations (``x{n+j}``,
    ``A0_j``; ``V1_j``, ``A1_j``)."""
    C = range(n)
    r0 = _g_row(P, n, i, [f"x{n + j}" for j in C] + [f"A0_{j}" for j in C])
    r1 = _g_row(P, n, i, [f"V1_{j}" for j in C] + [f"A1_{j}" for j in C])
    return r0, r1


def _g_row(P, n: int, i: int, values: list[str]) -> list[tuple[str, str]]:
    """The products of row i of ``G`` with ``values`` (one per state), without the
    entries that are an exact zero in every lane (``_Rows.nonzero``: springs and dampers
    the rig does not have).  Leaving a product ``x * 0.0`` out of a sum changes no
    finite result but the sign of an exact zero sum."""
    s = 2 * n
    return [(P("G", i * s + j), v) for j, v in enumerate(values) if P.nonzero("G", i * s + j)]


def _kinetic(i: int, d: str, asym: bool) -> str:
    """Code of cart i's kinetic friction level when sliding in direction ``d`` (+-1): one
    level ``fc{i}``, or with ``asym`` ``fp{i}`` forwards and ``fn{i}`` backwards."""
    return f"(fp{i} if {d} > 0.0 else fn{i})" if asym else f"fc{i}"


def _coulomb_load(t, P, X, n, asym=False) -> list[str]:
    """Code loading a lane's state and friction parameters into scalars."""
    s = 2 * n
    R, C = range(s), range(n)
    L: list[str] = []
    L += [f"{t}x{r} = {X('x', r)}" for r in R]
    for i in C:
        L += [f"{t}st{i} = {X('st', i)} != 0.0", f"{t}d{i} = {X('d', i)}",
              f"{t}xs{i} = {X('xs', i)}", f"{t}fc{i} = {P('fc', i)}", f"{t}fs{i} = {P('fs', i)}",
              f"{t}gb{i} = {P('gb', i)}", f"{t}mi{i} = {P('mi', i)}"]
        if asym:
            L += [f"{t}fp{i} = fc{i}", f"{t}fn{i} = {P('fn', i)}"]
    return L


def _coulomb_predict(t, P, n, mats, asym=False, held=True) -> list[str]:
    """Code of the friction decision at the step start and the state predicted with it
    held over the step (matrices ``mats = (A, B, F, R)`` of the step: input, held and
    ramped force responses), the net forces at the end (``Fe``) and the velocities and
    accelerations at both ends.

    ``held=False``: for lanes none of whose carts is stuck at the step start, without the
    ramp correction of held carts.  Its force differences are then ``0.0 * (...)`` and
    the correction adds an exact zero to each state, so for a finite state the result
    is the same bit for bit."""
    s = 2 * n
    R, C = range(s), range(n)
    L: list[str] = []
    # friction over the sub-step: stuck carts hold the net force (or break away at once
    # when the input jumped past Fs), sliding carts get -Fc dir; written as selects (no
    # nested branches) so that the compiler vectorises across lanes
    for i in C:
        gz = _sum(_g_row(P, n, i, [f"x{j}" for j in R]))
        L += [f"{t}F{i} = gb{i} * uk + {gz}",
              f"{t}aF{i} = abs(F{i})",
              f"{t}hold = st{i} & (aF{i} < fs{i})",
              f"{t}d{i} = math.copysign(1.0, F{i}) if st{i} != hold else d{i}",
              f"{t}f{i} = -F{i} if hold else -{_kinetic(i, f'd{i}', asym)} * d{i}",
              f"{t}st{i} = hold"]
    for r in R:
        prods = [(P(mats[0], r * s + j), f"x{j}") for j in R]
        prods += [(P(mats[2], r * n + j), f"f{j}") for j in C]
        L.append(f"{t}n{r} = {P(mats[1], r)} * uk + {_sum(prods)}")

    def end_force(i):
        return f"{t}Fe{i} = gb{i} * uk + {_sum(_g_row(P, n, i, [f'n{j}' for j in R]))}"

    # net forces at the end; a held cart's force changed over the step, and holding it
    # with its start value would let it drift and pull on its neighbours: hold it with
    # the force ramping to its end value instead (one correction with the ramp response)
    for i in C if held else ():
        # (a product with 1 or 0, not a branch: the compiler would sink the end force
        # into the branch and not vectorise the loop)
        L += [end_force(i),
              f"{t}df{i} = (1.0 if st{i} else 0.0) * (F{i} -"
              f" ({_held_force(P, n, i, f'Fe{i}', f'xs{i}')}))"]
    for r in R if held else ():
        prods = [(P(mats[3], r * n + j), f"df{j}") for j in C]
        L.append(f"{t}n{r} = {_fma_sum(f'n{r}', prods)}")
    # net forces at the end again, and the rates of change of the net force at both ends
    # (G times velocities and accelerations; held carts neither move nor accelerate)
    for i in C:
        L += [end_force(i),
              f"{t}A0_{i} = (F{i} + f{i}) * mi{i}",
              f"{t}A1_{i} = 0.0 if st{i} else (Fe{i} + f{i}) * mi{i}",
              f"{t}V1_{i} = 0.0 if st{i} else n{n + i}"]
    return L


def _coulomb_events(t, P, n, asym=False) -> list[str]:
    """Code locating and correcting the events inside a step (see ``coulomb_run``)."""
    return [line for i in range(n) for line in _coulomb_event(t, P, n, i, asym)]


def _coulomb_event(t, P, n, i, asym=False) -> list[str]:
    """Code locating and correcting cart i's events inside a step (``_coulomb_events``).

    It reads the step's prediction (``_coulomb_predict``) and cart i's own state, and
    writes only cart i's: the carts' corrections are independent within a step."""
    L: list[str] = []
    v = n + i
    r0, r1 = (_sum(r) for r in _force_rates(P, n, i))
    L += [f"{t}Fe = Fe{i}",
          # stuck: did the net force on the held cart reach Fs inside the step?
          # (on its cubic Hermite interpolant in time, Newton from the chord)
          f"{t}Fh = {_held_force(P, n, i, 'Fe', f'xs{i}')}",
          f"{t}aE = abs(Fh)",
          f"{t}slip = st{i} & (aE >= fs{i})",
          f"{t}db = math.copysign(1.0, Fh)",
          f"{t}ab = (fs{i} - aF{i}) / (aE - aF{i})",
          f"{t}ab = ab if slip & (aE > aF{i}) else 0.0",
          f"{t}ab = (0.0 if ab < 0.0 else (1.0 if ab > 1.0 else ab))",
          f"{t}q0 = db * F{i}",
          f"{t}q1 = db * Fh",
          f"{t}k0 = db * h * ({r0})",
          f"{t}k1 = db * h * ({r1})",
          # q(s) = q0 + s (k0 + s (c2 + s c3)), the Hermite cubic in power form
          f"{t}c2 = 3.0 * (q1 - q0) - 2.0 * k0 - k1",
          f"{t}c3 = 2.0 * (q0 - q1) + k0 + k1",
          f"{t}qs = q0 - fs{i}"]
    L += _rising_cubic_root(t, "ab", ("qs", "k0", "c2", "c3"))
    L += [f"{t}ab = ab if slip else 0.0",
          # velocity and displacement gained from the break-away to the end of the
          # step under the net force q(s) less the kinetic level: integrals of
          # (q - Fc) and (1 - s)(q - Fc) over [ab, 1] (antiderivatives J1 and J2)
          f"{t}p0 = q0 - {_kinetic(i, 'db', asym)}",
          f"{t}j1 = ab * (p0 + ab * (0.5 * k0 + ab * ({1 / 3!r} * c2 + 0.25 * ab * c3)))",
          f"{t}j2 = ab * ab * (0.5 * p0 + ab * ({1 / 3!r} * k0 + ab * (0.25 * c2"
          f" + 0.2 * ab * c3)))",
          f"{t}i0 = p0 + 0.5 * k0 + {1 / 3!r} * c2 + 0.25 * c3 - j1",
          f"{t}i1 = 0.5 * p0 + {1 / 3!r} * k0 + 0.25 * c2 + 0.2 * c3 - j2",
          f"{t}dvb = db * mi{i} * h * i0",
          f"{t}dxb = db * mi{i} * h * h * (i0 - i1)",
          # sliding: a velocity reversal inside the step, located on the cubic Hermite
          # interpolant of the velocity (end values and accelerations)
          f"{t}v0 = x{v}",
          f"{t}v1 = n{v}",
          f"{t}rev = (not st{i}) & (d{i} * v1 < 0.0)",
          f"{t}a = v0 / (v0 - v1)",
          f"{t}a = a if v0 != v1 else 0.0",
          f"{t}a = (0.0 if a < 0.0 else (1.0 if a > 1.0 else a))",
          f"{t}m0 = (F{i} + f{i}) * mi{i} * h",
          f"{t}m1 = (Fe + f{i}) * mi{i} * h",
          # v(s) = v0 + s (m0 + s (e2 + s e3))
          f"{t}e2 = 3.0 * (v1 - v0) - 2.0 * m0 - m1",
          f"{t}e3 = 2.0 * (v0 - v1) + m0 + m1"]
    for _ in range(REVERSAL_NEWTON):
        L += [f"{t}g = v0 + a * (m0 + a * (e2 + a * e3))",
              f"{t}dg = m0 + a * (2.0 * e2 + 3.0 * a * e3)",
              f"{t}an = a - g / dg",
              f"{t}a = an if dg != 0.0 else a",
              f"{t}a = (0.0 if a < 0.0 else (1.0 if a > 1.0 else a))"]
    L += [f"{t}tau = (1.0 - a) * h",
          # stick if the net force at the crossing is below Fs, else slide back
          f"{t}stick = rev & (abs(F{i} + a * (Fe - F{i})) < fs{i})",
          f"{t}flip = rev != stick",
          # the friction after the crossing, fc(-d) d, instead of -fc(d) d
          f"{t}dv = {_reversal_levels(i, asym)} * d{i} * mi{i} * tau",
          f"{t}dv = dv if flip else 0.0",
          # distance travelled after the crossing: integral of the interpolant
          f"{t}after = h * (v0 + 0.5 * m0 + {1 / 3!r} * e2 + 0.25 * e3"
          f" - a * (v0 + a * (0.5 * m0 + a * ({1 / 3!r} * e2 + 0.25 * a * e3))))",
          f"{t}pa = n{i} - after",
          f"{t}pb = n{i} + 0.5 * dv * tau",
          f"{t}p = pa if stick else pb",
          # stuck at the crossing, but the held net force reaches Fs again before
          # the end of the step: break away there (linear in time from the crossing)
          f"{t}Fk = {_held_force(P, n, i, 'Fe', 'p')}",
          f"{t}aK = abs(Fk)",
          f"{t}brk = stick & (aK >= fs{i})",
          f"{t}dk = math.copysign(1.0, Fk)",
          f"{t}qx = dk * (F{i} + a * (Fe - F{i}))",
          f"{t}ak = a + (1.0 - a) * (fs{i} - qx) / (aK - qx)",
          f"{t}ak = ak if brk & (aK > qx) else 1.0",
          f"{t}ak = (a if ak < a else (1.0 if ak > 1.0 else ak))",
          f"{t}tk = (1.0 - ak) * h",
          f"{t}dvk = dk * (0.5 * (aK + fs{i}) - {_kinetic(i, 'dk', asym)}) * mi{i} * tk",
          f"{t}dxk = dk * mi{i} * tk * tk * ({1 / 6!r} * aK + {1 / 3!r} * fs{i}"
          f" - 0.5 * {_kinetic(i, 'dk', asym)})",
          f"{t}pk = p + dxk",
          f"{t}p = pk if brk else p",
          f"{t}xb = xs{i} + dxb",
          f"{t}xh = xb if slip else xs{i}",
          f"{t}n{i} = xh if st{i} else p",
          f"{t}vh = dvb if slip else 0.0",
          f"{t}vk = dvk if brk else 0.0",
          f"{t}vf = v1 + dv",
          f"{t}vs = vk if stick else vf",
          f"{t}n{v} = vh if st{i} else vs",
          f"{t}xs{i} = p if stick else xs{i}",
          f"{t}dr = -d{i} if flip else d{i}",
          f"{t}dr = dk if brk else dr",
          f"{t}d{i} = db if slip else dr",
          f"{t}st{i} = (st{i} != slip) | (stick != brk)"]
    return L


def _reversal_levels(i: int, asym: bool) -> str:
    """Code of ``fc(d) + fc(-d)`` for cart i sliding in direction ``d{i}``."""
    return f"(fp{i} + fn{i})" if asym else f"2.0 * fc{i}"


def _coulomb_store(t, X, n) -> list[str]:
    """Code storing a lane's state."""
    s = 2 * n
    R, C = range(s), range(n)
    L: list[str] = []
    L += [f"{t}{X('x', r)} = n{r}" for r in R]
    for i in C:
        L += [f"{t}{X('st', i)} = 1.0 if st{i} else 0.0", f"{t}{X('d', i)} = d{i}",
              f"{t}{X('xs', i)} = xs{i}"]
    return L


def _coulomb_quiet_step(t, P, X, n, mats, step, asym=False, stop=False,
                        held=True) -> list[str]:
    """Code of a step without event corrections that counts the lanes needing them.

    Saves the lane's state in ``S``, takes the step with the matrices ``mats`` (of length
    ``step``) and keeps held carts in place.  The lane's flag (the last row of ``S``) is
    set, and ``ev`` counts it, if any cart had or may have had an event in the step: the
    velocity of a sliding cart or the held force of a stuck one tested at the end, at the
    midpoint of its cubic Hermite interpolant and on the linear extrapolations from both
    ends (a velocity dipping through zero and back, or a held force peaking past ``Fs``
    inside the step, which the end values alone would hide).  With ``stop`` a lane is
    also flagged where its driven cart is in contact with the end stop or can reach it
    within the step (``nq_``, set by ``kernels.stop.stop_input_lines``): the stop force
    is held at its mid-step value, accurate in sub-steps.  ``held=False``: the step of
    lanes without a stuck cart (``_coulomb_predict``), which tests the sliding carts
    only.
    """
    C, w = range(n), X.width
    L = [f"{t}S[{r * w} + b] = {X.array}[{r * w} + b]" for r in range(X.size)]
    L += _coulomb_load(t, P, X, n, asym)
    L += _coulomb_predict(t, P, n, mats, asym, held)
    flags = []
    for i in C:
        v = n + i
        r0, r1 = (_fma_sum("0.0", r) for r in _force_rates(P, n, i))
        # (a stuck cart's test: not needed where no cart is stuck)
        L += [f"{t}q1 = {_held_force(P, n, i, f'Fe{i}', f'xs{i}')}",
              f"{t}k0 = {step} * ({r0})",
              f"{t}k1 = {step} * ({r1})",
              f"{t}qm = 0.5 * (F{i} + q1) + 0.125 * (k0 - k1)",
              f"{t}hit = ((abs(q1) >= fs{i}) | (abs(qm) >= fs{i}) | (abs(F{i} + k0) >= fs{i})"
              f" | (abs(q1 - k1) >= fs{i}))"] if held else []
        L += [f"{t}m0 = A0_{i} * {step}",
              f"{t}m1 = A1_{i} * {step}",
              f"{t}vm = 0.5 * (x{v} + n{v}) + 0.125 * (m0 - m1)",
              f"{t}turn = ((d{i} * n{v} < 0.0) | (d{i} * vm < 0.0) | (d{i} * (x{v} + m0) < 0.0)"
              f" | (d{i} * (n{v} - m1) < 0.0))",
              f"{t}ev{i} = hit if st{i} else turn" if held else f"{t}ev{i} = turn",
              f"{t}n{i} = xs{i} if st{i} else n{i}",
              f"{t}n{v} = 0.0 if st{i} else n{v}"]
        flags.append(f"ev{i}")
    if stop:
        flags.append("nq_")
    L += [f"{t}e = {' | '.join(flags)}",
          f"{t}S[{X.size * w} + b] = 1.0 if e else 0.0",
          f"{t}ev += 1 if e else 0"]
    return L + _coulomb_store(t, X, n)


def _coulomb_at_rest(t, P, X, n) -> list[str]:
    """Code adding 1 to ``nq`` for a lane at rest over the coming step.

    A lane is at rest when every cart is stuck and each one's net force at the step start
    is below its static level by more than ``REST_MARGIN`` times the size of the terms
    it sums.  Over a step with the input held, such a lane's state does not change: the
    quick step would return it bit for bit (held carts are put back where they stuck,
    with velocity 0, and no held force can reach ``Fs``: the rounding of the quick step
    is ~1e-16 of the same terms), so the kernel skips the step for a group of lanes all
    at rest.  The test depends on the lane's own state only, and skipping changes no
    result: the output is the same whatever the batch.
    """
    L: list[str] = [f"{t}rest = True"]
    for i in range(n):
        # positions only: a lane can be at rest only if every cart is stuck, and a stuck
        # cart's velocity is a zero (the steps set it so), whose products would change
        # the sums at most by the sign of a zero
        terms = [f"{P('gb', i)} * uk"] + [f"{g} * {x}" for g, x in _g_row(
            P, n, i, [X("x", j) for j in range(n)])]
        L += [f"{t}Fq = {' + '.join(terms)}",
              f"{t}mq = {' + '.join(f'abs({term})' for term in terms)}",
              f"{t}rest = rest & ({X('st', i)} != 0.0)"
              f" & (abs(Fq) + {REST_MARGIN!r} * mq < {P('fs', i)})"]
    return L + [f"{t}nq += 1 if rest else 0"]


#: Scratch rows of a packed sub-step (``_split_substep``): what the event code of a cart
#: reads from the prediction (start velocities, predicted end state, forces, rates).
_SCRATCH = ("xv", "nx", "F", "aF", "f", "Fe", "A0", "A1", "V1")


def _scratch_rows(n: int) -> list[tuple[str, int]]:
    return [(name, 2 * n if name == "nx" else n) for name in _SCRATCH]


def _split_substep(t, PP, XX, SC, n, g, asym=False) -> list[str]:
    """Code of an event-corrected sub-step of a packed group of ``g`` lanes, each cart's
    event code only where a lane of the group has an event of that cart.

    A first lane loop predicts the step (``_coulomb_predict``), keeps what the event code
    reads in the scratch rows ``SC``, counts per cart the lanes whose cart slipped (stuck,
    held force at ``Fs`` by the end) or reversed (sliding, velocity of the other sign at
    the end), and stores the state with every cart put back as the event code leaves a
    cart without either: a stuck cart at ``xs`` with velocity 0, a sliding one where it
    is (``+ 0.0``, as the event code adds its zero corrections).  Then, for each cart
    with an event in some lane, a lane loop runs that cart's event code
    (``_coulomb_event``) from the scratch rows and stores the cart's state.  The carts'
    corrections are independent within a step, so for a finite state this is the
    one-loop step bit for bit; in a packed sub-step of the rig-like input 0.9 carts of
    three have an event in some lane of the group on average (docs/performance.md)."""
    s = 2 * n
    R, C = range(s), range(n)
    tl = t + "    "
    L = [f"{t}nev{i} = 0" for i in C] + [f"{t}for b in range({g}):"]
    L += _coulomb_load(tl, PP, XX, n, asym)
    L += _coulomb_predict(tl, PP, n, ("A", "bh", "fh", "rh"), asym)
    L += [f"{tl}{SC('xv', i)} = x{n + i}" for i in C]
    L += [f"{tl}{SC('nx', r)} = n{r}" for r in R]
    for name in ("F", "aF", "f", "Fe"):
        L += [f"{tl}{SC(name, i)} = {name}{i}" for i in C]
    for name in ("A0", "A1", "V1"):
        L += [f"{tl}{SC(name, i)} = {name}_{i}" for i in C]
    for i in C:
        v = n + i
        L += [f"{tl}Fh = {_held_force(PP, n, i, f'Fe{i}', f'xs{i}')}",
              f"{tl}e = (st{i} & (abs(Fh) >= fs{i})) | ((not st{i}) & (d{i} * n{v} < 0.0))",
              f"{tl}nev{i} += 1 if e else 0",
              f"{tl}n{i} = xs{i} if st{i} else n{i} + 0.0",
              f"{tl}n{v} = 0.0 if st{i} else n{v} + 0.0"]
    L += _coulomb_store(tl, XX, n)
    tb = tl + "    "
    for i in C:
        v = n + i
        L += [f"{t}if nev{i} > 0:", f"{tl}for b in range({g}):"]
        L += [f"{tb}x{n + j} = {SC('xv', j)}" for j in C]
        L += [f"{tb}n{i} = {SC('nx', i)}", f"{tb}n{v} = {SC('nx', v)}"]
        L += [f"{tb}{name}{i} = {SC(name, i)}" for name in ("F", "aF", "f", "Fe")]
        L += [f"{tb}{name}_{j} = {SC(name, j)}" for name in ("A0", "A1", "V1") for j in C]
        L += [f"{tb}st{i} = {XX('st', i)} != 0.0", f"{tb}d{i} = {XX('d', i)}",
              f"{tb}xs{i} = {XX('xs', i)}", f"{tb}fc{i} = {PP('fc', i)}",
              f"{tb}fs{i} = {PP('fs', i)}", f"{tb}mi{i} = {PP('mi', i)}"]
        if asym:
            L += [f"{tb}fp{i} = fc{i}", f"{tb}fn{i} = {PP('fn', i)}"]
        L += _coulomb_event(tb, PP, n, i, asym)
        L += [f"{tb}{XX('x', i)} = n{i}", f"{tb}{XX('x', v)} = n{v}",
              f"{tb}{XX('st', i)} = 1.0 if st{i} else 0.0", f"{tb}{XX('d', i)} = d{i}",
              f"{tb}{XX('xs', i)} = xs{i}"]
    return L



def _coulomb_rates(t, P, X, n, width, asym=False, stop=0) -> list[str]:
    """Code writing a lane's positions, velocities and accelerations at the sample into
    the scratch rows ``Z[(order * n + i) * width + b]`` (``order`` 0, 1, 2; cart ``i``).

    Read from the lane's state at the sample, before any step: the positions and the
    velocities are the states (a stuck cart's velocity is the exact zero the steps set),
    the acceleration is ``(F_i + f_i) / m_i`` with ``F_i`` the net force with the input
    held from the sample, ``uk``, and ``f_i`` the friction of that state: a stuck cart
    whose ``|F_i|`` is below ``Fs_i`` is held (an exact 0), one at or past it breaks away
    at the sample (``-Fc`` in the direction of ``F_i``), a sliding cart feels ``-Fc_i
    dir_i``.  With ``stop`` (+1 or -1) the stop force enters ``uk`` at the step's
    mid-point (``kernels.stop.stop_input_lines``): it is replaced by its value at the
    driven cart's position at the sample.
    """
    s, w = 2 * n, width
    R, C = range(s), range(n)
    L = [f"{t}x{r} = {X('x', r)}" for r in R]
    if stop:
        L += [f"{t}uk = uk + {stop:+d}.0 * {P('kq')} * pq",
              f"{t}pq = {stop:+d}.0 * (x0 - {P('xq')})",
              f"{t}pq = pq if pq > 0.0 else 0.0",
              f"{t}uk = uk - {stop:+d}.0 * {P('kq')} * pq"]
    for i in C:
        gz = _sum(_g_row(P, n, i, [f"x{j}" for j in R]))
        L += [f"{t}fc{i} = {P('fc', i)}"]
        if asym:
            L += [f"{t}fp{i} = fc{i}", f"{t}fn{i} = {P('fn', i)}"]
        L += [f"{t}F{i} = {P('gb', i)} * uk + {gz}",
              f"{t}st{i} = {X('st', i)} != 0.0",
              f"{t}hold = st{i} & (abs(F{i}) < {P('fs', i)})",
              f"{t}d{i} = math.copysign(1.0, F{i}) if st{i} else {X('d', i)}",
              f"{t}Z[{i * w} + b] = x{i}",
              f"{t}Z[{(n + i) * w} + b] = x{n + i}",
              f"{t}Z[{(s + i) * w} + b] = 0.0 if hold else"
              f" (F{i} - {_kinetic(i, f'd{i}', asym)} * d{i}) * {P('mi', i)}"]
    return L


def _coulomb_read(P, X, n, width, group=0, asym=False, stop=0) -> list[str]:
    """Code of a sample's reading of every lane in the sample loop: its ``3 n`` rates
    (``_coulomb_rates``) into the scratch rows ``Z``, then the sensors' rows ``cols``
    (an array given at run time: one compiled variant for any set of sensors) copied to
    the output ``Y[yo + o * width + b]``.

    With ``group`` (the adaptive kernel, after its ``same`` and ``rested`` are set) a
    group of lanes that the kernel will skip at rest (all stuck and held over the last
    sample, the input the same) reads what it read at the last sample: the same state,
    input and forces, so the same numbers, copied instead of computed again.
    """
    t, w = " " * 8, width
    copy = [f"{t}    for o in range(n_out):",
            f"{t}        for lane in range(g0, g0 + {group or w}):",
            f"{t}            Y[yo + o * {w} + lane] = Z[cols[o] * {w} + lane]"]
    if not group:
        return ([f"{t}for b in range({w}):"] + _coulomb_rates(t + "    ", P, X, n, w, asym, stop)
                + [f"{t}g0 = 0"] + [line[4:] for line in copy])
    return [f"{t}for g0 in range(0, {w}, {group}):",
            f"{t}    if same and rested[g0 // {group}]:",
            f"{t}        for o in range(n_out):",
            f"{t}            for lane in range(g0, g0 + {group}):",
            f"{t}                Y[yo + o * {w} + lane] = Y[yo - n_out * {w} + o * {w} + lane]",
            f"{t}        continue",
            f"{t}    for b in range(g0, g0 + {group}):",
            *_coulomb_rates(t + "        ", P, X, n, w, asym, stop), *copy]
