"""Explanations the records cannot tell apart: friction on a driven cart and a drive offset.

On a cart the motor drives with share ``s`` (force ``s g_v v``), a drive offset ``v0``
adds the constant force ``s g_v v0``.  While the cart slides, Coulomb friction of equal
levels ``Fc`` with that offset pushes it with ``-Fc + s g_v v0`` forwards and
``Fc + s g_v v0`` backwards: exactly directional friction of levels

    Fcp = Fc - s g_v v0,    Fcn = Fc + s g_v v0,

without an offset.  The two models differ only in the breakaway thresholds of the held
cart (the offset moves them to ``+-Fs - s g_v v0``, directional friction keeps them
symmetric), and a step or a pulse of the input carries the force across either pair of
thresholds within one sample: records of steps and pulses give one motion under both
readings (to rounding, ``tests/test_diagnose_equivalence.py``), while a slow ramp or sine,
whose force reaches the thresholds gradually, tells them apart.  On a one-cart rig,
the layouts benchmark's record ``coulomb_friction+input_offset`` seed 20002 is fitted by
both to the same cost within 4e-7 nats (global searches of each model,
``fit_extension_global``), and ``diagnose`` names directional friction there.
``equivalent_readings`` says so in the diagnosis' notes, with the other reading's values.
"""

from __future__ import annotations

import numpy as np

from ...model.system import Rig

__all__ = ["equivalent_readings", "has_slow_drive"]

#: Effects that shape the drive's voltage after the offset (a dead band or a saturation of
#: ``v + v0`` is not that of ``v`` plus a constant) or act in the drive itself: with any of
#: them the equivalence does not hold.
_HOW = ("only the breakaway force tells them apart, which steps and pulses cross within a "
        "sample under either reading: add a slow ramp or sine of the drive to tell them apart")
_SLOW = ("only the breakaway force tells them apart, which the records' slow drive reaches "
         "gradually: the records chose this reading")

#: A record drives slowly when at least this share of its samples change the input by a
#: nonzero amount of at most ``SLOW_STEP`` of its range (a ramp or a sine; steps and
#: pulses change it only at their edges).
SLOW_SHARE = 0.05
SLOW_STEP = 0.01


def has_slow_drive(v) -> bool:
    """Whether the input ``v`` (N,), V, holds a slow drive (``SLOW_SHARE``, ``SLOW_STEP``).

    Parameters
    ----------
    v : array_like, shape (N,)
        A record's input, V.

    Returns
    -------
    bool

    Examples
    --------
    >>> t = np.arange(2000) * 0.005
    >>> has_slow_drive(np.sin(2 * np.pi * 0.2 * t)), has_slow_drive(np.sign(np.sin(t)))
    (True, False)
    """
    v = np.asarray(v, dtype=float)
    dv = np.abs(np.diff(v))
    span = float(np.ptp(v)) if v.size else 0.0
    if dv.size == 0 or span == 0.0:
        return False
    return bool(np.mean((dv > 0.0) & (dv <= SLOW_STEP * span)) >= SLOW_SHARE)
_SHAPING = frozenset({"drive_deadband", "input_saturation", "amplitude_gain", "backlash"})


def equivalent_readings(effects, params: dict[str, float], rig: Rig,
                        inputs=()) -> list[str]:
    """One note for each driven cart whose friction the records cannot tell from an offset.

    Parameters
    ----------
    effects : sequence of str
        The final model's effects.
    params : dict
        Its fitted parameters by name (``g_v`` and the friction levels ``Fc<i>`` or
        ``Fcp<i>``, ``Fcn<i>``, N; the offset ``v_offset``, V).
    rig : Rig
    inputs : sequence of array_like, optional
        The records' inputs, V: where one of them drives slowly (``has_slow_drive``) the
        note says that the records chose the reading, else how to tell them apart.

    Returns
    -------
    list of str
        Empty unless the model holds directional friction on a driven cart without an
        offset, or equal friction on a driven cart with an offset, and nothing that
        shapes the drive's voltage (``_SHAPING``).

    Examples
    --------
    >>> from bayesmodal.model.rigs import load_rig
    >>> rig = load_rig("ecp210-1cart")
    >>> p = {"g_v": 6.4, "Fcp1": 1.1354, "Fcn1": 0.6166, "Fs1": 1.15}
    >>> note = equivalent_readings(["coulomb_directional"], p, rig)[0]
    >>> print(note[:73])
    cart 1 (driven): directional friction Fcp 1.135 N, Fcn 0.617 N acts while
    >>> print(note[74:157])
    the cart slides exactly as equal levels Fc 0.876 N with a drive offset of -0.0405 V
    """
    if set(effects) & _SHAPING:
        return []
    how = _SLOW if any(has_slow_drive(v) for v in inputs) else _HOW
    shares = rig.input_vector()
    g_v = float(params.get("g_v", 1.0))
    out = []
    for i in np.flatnonzero(shares):
        k, s = i + 1, float(shares[i]) * g_v
        if "coulomb_directional" in effects and "input_offset" not in effects:
            fcp, fcn = params.get(f"Fcp{k}", 0.0), params.get(f"Fcn{k}", 0.0)
            if fcp == fcn:
                continue
            out.append(
                f"cart {k} (driven): directional friction Fcp {fcp:.3f} N, Fcn {fcn:.3f} N "
                f"acts while the cart slides exactly as equal levels Fc {(fcp + fcn) / 2:.3f} N "
                f"with a drive offset of {(fcn - fcp) / (2 * s):+.4f} V; {how}")
        elif "coulomb_friction" in effects and "input_offset" in effects:
            fc, v0 = params.get(f"Fc{k}", 0.0), params.get("v_offset", 0.0)
            if fc == 0.0 or v0 == 0.0:
                continue
            out.append(
                f"cart {k} (driven): friction Fc {fc:.3f} N with the drive offset "
                f"{v0:+.4f} V acts while the cart slides exactly as directional levels Fcp "
                f"{fc - s * v0:.3f} N, Fcn {fc + s * v0:.3f} N without an offset; {how}")
    return out
