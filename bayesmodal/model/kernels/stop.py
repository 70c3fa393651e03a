"""Code of a soft end stop on the driven cart, for the kernels that take one.

A one-sided elastic stop at ``x_stop`` (m) on cart 1 (index 0: the cart the motor drives,
see ``effects.end_stop``) pushes back with ``k_stop * max(0, side * (x_1 - x_stop))``
(N), ``side = +1`` for a stop beyond positive travel, ``-1`` beyond negative travel.  It is
a memoryless function of the cart's position, so each kernel treats it as it treats its
other position-dependent forces:

- the cubic-spring kernel (ETD2RK: the force at both ends of a sub-step) adds it to the
  spring forces (:func:`stop_force_lines`);
- the stick-slip friction kernel holds every force over a step, the motor's too; the stop
  acts on the driven cart, where it is the motor force of the voltage
  ``-side * (k_stop / g_v) * max(0, ...)``, so it is added to the lane's input ``uk``
  (:func:`stop_input_lines`), evaluated at the step's predicted mid-point ``x_1 + v_1 h /
  2`` (second order away from the contact's onset), and a lane in contact, or able to
  reach it within the step, takes the step again in sub-steps
  (``kernels.coulomb._coulomb_quiet_step``);
- the LuGre kernel holds the friction force over each sub-step; the stop's force at
  cart 1's mid-step position joins cart 1's friction force there (:func:`stop_depth_lines`).

Parameter rows: ``xq`` (``x_stop``, m) and ``kq`` (``k_stop``, N/m, or ``k_stop / g_v``,
V/m, in the friction kernel).  With ``kq = 0`` the stop adds an exact zero.
"""

from __future__ import annotations

#: Sides a stop can be on (compile-time constants of the generated code).
STOP_SIDES = (1, -1)


def checked_side(side) -> int:
    """``side`` as +1 or -1 (only these integers reach generated source)."""
    if side not in STOP_SIDES or isinstance(side, bool):
        raise ValueError(f"stop side must be +1 or -1, got {side!r}")
    return int(side)


def stop_depth_lines(t: str, x1: str, side: int, xq: str) -> list[str]:
    """Code setting ``pq`` to the depth (m) of cart 1 in the stop, ``max(0, side * (x1 -
    xq))``, at the position (code) ``x1``."""
    side = checked_side(side)
    return [f"{t}pq = {side:+d}.0 * ({x1} - {xq})",
            f"{t}pq = pq if pq > 0.0 else 0.0"]


def stop_force_lines(t: str, src: str, dst: str, side: int, xq: str, kq: str) -> list[str]:
    """Code adding the stop force on cart 1 at the positions ``{src}0..`` to ``{dst}0``."""
    side = checked_side(side)
    return stop_depth_lines(t, f"{src}0", side, xq) + [
        f"{t}{dst}0 = {dst}0 - {side:+d}.0 * {kq} * pq"]


def stop_input_lines(t: str, x: str, v: str, step: str, side: int, xq: str, kq: str
                     ) -> list[str]:
    """Code adding the stop force, as a voltage, to the lane's input ``uk``, and setting
    ``nq_`` where the cart is in contact or can reach it within the step.

    ``x``, ``v``: the lane's position and velocity of cart 1 at the step start; ``step``:
    the step length (s); ``kq``: ``k_stop / g_v`` (V/m)."""
    side = checked_side(side)
    return stop_depth_lines(t, f"{x} + 0.5 * {step} * {v}", side, xq) + [
        f"{t}uk = uk - {side:+d}.0 * {kq} * pq",
        f"{t}nq_ = ({kq} > 0.0) & ({side:+d}.0 * ({x} - {xq}) + {step} * abs({v}) > 0.0)"]
