"""The rig description: ``Rig``, the layout of carts, springs, dampers, drive and sensors.

A ``Rig`` joins the elements of ``bayesmodal.model.elements`` into a rectilinear layout,
checks that they fit together (``bayesmodal.model._rig_checks``, one step each) and
assembles what the linear model needs from the layout alone: the stiffness matrix at the
nominal springs, the unit pattern of each two-node element, the drive's input vector and
the sensors' output matrix.  ``Rig(springs_n_m=...)`` is the chain shorthand (``Rig()``
the ECP Model 210 three-cart rig).  The TOML form is in ``bayesmodal.model.rigs``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._errors import DataError, ModelError
from ._rig_checks import (
    as_tuple,
    check_grounded,
    checked_clamps,
    checked_drive,
    checked_sensors,
    input_gain,
    named_springs,
    ordered_dampers,
    tie_groups,
)
from .elements import ECP_M_PER_COUNT, FRAME, Cart, Damper, Drive, Sensor, Spring

__all__ = ["Rig", "chain_matrix", "DAMPING_MODELS", "ECP210_SPRINGS_N_M"]

#: Nominal springs of the ECP Model 210 three-cart rig, N/m (report Table 1).
ECP210_SPRINGS_N_M = (774.0, 770.0, 396.0)

DAMPING_MODELS = ("free", "proportional")


def _chain_elements(springs_n_m, springs, drive, sensors) -> tuple:
    """Carts, springs, drive and sensors of the chain shorthand ``Rig(springs_n_m=...)``:
    spring ``i`` joins cart ``i`` and ``i + 1``, the last one the last cart and the frame;
    the motor on cart 1 and an encoder on every cart unless ``drive`` and ``sensors`` are
    given."""
    k = np.asarray(ECP210_SPRINGS_N_M if springs_n_m is None else springs_n_m, dtype=float)
    if k.ndim != 1 or k.size < 1:
        raise ModelError(
            f"springs_n_m must be a non-empty 1-D sequence, got {springs_n_m!r}"
        )
    if not np.all(np.isfinite(k)) or np.any(k <= 0):
        raise ModelError(
            f"every spring stiffness must be finite and > 0 N/m, got {k.tolist()}")
    if springs:
        raise ModelError("springs given without carts; list the carts too")
    n = k.size
    names = [str(i + 1) for i in range(n)]
    carts = tuple(Cart(c) for c in names)
    springs = tuple(
        Spring(names[i], names[i + 1] if i + 1 < n else FRAME, float(k[i]),
               name=f"k{i + 1}") for i in range(n))
    if drive is None:
        drive = (Drive("1"),)
    if sensors is None:
        sensors = tuple(Sensor(c, "count", ECP_M_PER_COUNT) for c in names)
    return carts, springs, drive, sensors


@dataclass(frozen=True)
class Rig:
    """Layout of a rectilinear rig: carts, springs, dampers, drive, sensors, clamps.

    ``Rig()`` is the ECP Model 210 three-cart chain; ``Rig(springs_n_m=(...))`` a chain of
    ``len(springs_n_m)`` carts (spring ``i`` joins cart ``i`` and ``i + 1``, the last one
    joins the last cart to the frame, the motor drives cart 1, an encoder on every cart).
    Any other layout gives ``carts`` and ``springs`` (and optionally the rest); see
    docs/rigs.md and ``bayesmodal.model.rigs.load_rig`` for the TOML form.

    Parameters
    ----------
    springs_n_m : tuple of float, optional
        Chain shorthand: spring stiffnesses, N/m.  Give either this or ``carts``.  After
        construction it holds the nominal stiffness of every spring in ``springs`` order.
    carts : tuple of Cart
        Carts in order; cart ``i`` (1-based) has the parameters ``m<i>`` and ``c<i>``.
    springs : tuple of Spring
    dampers : tuple of Damper, optional
        Dampers of the free damping model; default: one from every unclamped cart to the
        frame and one across every spring joining two unclamped carts.
    drive : tuple of Drive
        Carts the motor pushes; empty for a rig with no input (free decays only).
    sensors : tuple of Sensor, optional
        Measured carts in the order of the record's columns; default every unclamped cart.
    clamped : tuple of str
        Carts fixed to the frame (not degrees of freedom).
    gain_n_v : float, optional
        Known input gain, N/V (then ``g_v`` is not a parameter); default estimated.  A
        force input holds it at 1.
    input : {"voltage", "force"}
        What the record's input column holds: the motor's command voltage, V, through
        the drive gain ``g_v``; or the measured force on the driven carts, N (a load cell
        on a shaker, an instrumented hammer), with the gain fixed at 1 and not a
        parameter.  The force sensor's own noise is not modelled (docs/accelerometers.md
        gives the bias that leaves).  ``[drive] input = "force"`` in TOML.
    damping : {"free", "proportional"}, optional
        The damping model the description declares (``[dampers] proportional = true`` or
        ``false`` in TOML); ``LinearModel`` refuses another one.  None (default): not
        declared, chosen with the model.
    ties : tuple of tuple of str
        Groups of unknown parameters of one kind that share one value (``(("k1", "k2"),)``
        for "you may assume k1 = k2", ``(("m1", "m2"),)`` for equal masses); the first
        name of a group is the parameter, the others follow it.  ``ties = [["k1", "k2"]]``
        in TOML.
    name : str
        Free-text label.

    Examples
    --------
    >>> rig = Rig()
    >>> rig.n_carts
    3
    >>> float(rig.stiffness_matrix()[2, 2])
    1166.0
    >>> two = Rig(carts=(Cart("1"), Cart("2")),
    ...           springs=(Spring("1", "frame", 770.0), Spring("1", "2", 396.0)),
    ...           drive=(Drive("1"),))
    >>> two.stiffness_matrix().tolist()
    [[1166.0, -396.0], [-396.0, 396.0]]
    """

    springs_n_m: tuple[float, ...] | None = None
    carts: tuple[Cart, ...] = ()
    springs: tuple[Spring, ...] = ()
    dampers: tuple[Damper, ...] | None = None
    drive: tuple[Drive, ...] | None = None
    sensors: tuple[Sensor, ...] | None = None
    clamped: tuple[str, ...] = ()
    gain_n_v: float | None = None
    input: str = "voltage"
    damping: str | None = None
    ties: tuple[tuple[str, ...], ...] = ()
    name: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if self.damping is not None and self.damping not in DAMPING_MODELS:
            raise ModelError(f"rig damping must be one of {DAMPING_MODELS} or None (not "
                             f"declared), got {self.damping!r}")
        carts, springs, drive, sensors = self.carts, self.springs, self.drive, self.sensors
        if not self.carts:
            carts, springs, drive, sensors = _chain_elements(self.springs_n_m, self.springs,
                                                             self.drive, self.sensors)
        elif self.springs_n_m is not None and tuple(float(k) for k in self.springs_n_m) != tuple(
                float(s.stiffness_n_m) for s in self.springs):
            # (equal values come from dataclasses.replace of a built rig)
            raise ModelError("give either springs_n_m (a chain) or carts and springs, not both "
                             "(with dataclasses.replace of springs pass springs_n_m=None)")
        carts = as_tuple(carts, Cart, "carts")
        springs = as_tuple(springs, Spring, "springs")
        cart_names = [c.name for c in carts]
        clamped, free = checked_clamps(cart_names, self.clamped)
        springs = named_springs(springs, cart_names)
        check_grounded(springs, free, clamped)
        dampers = ordered_dampers(self.dampers, springs, free, clamped, cart_names)
        drive = checked_drive(drive, cart_names, clamped)
        sensors = checked_sensors(sensors, free, cart_names, clamped)
        set_(self, "gain_n_v", input_gain(self.input, self.gain_n_v, drive))
        set_(self, "ties", tie_groups(self.ties))
        set_(self, "carts", carts)
        set_(self, "springs", springs)
        set_(self, "dampers", dampers)
        set_(self, "drive", drive)
        set_(self, "sensors", sensors)
        set_(self, "clamped", clamped)
        set_(self, "springs_n_m", tuple(s.stiffness_n_m for s in springs))

    # ------------------------------------------------------------------ layout
    @property
    def free_carts(self) -> tuple[str, ...]:
        """Names of the carts that move (the degrees of freedom), in order."""
        return tuple(c.name for c in self.carts if c.name not in self.clamped)

    @property
    def n_carts(self) -> int:
        """Number of degrees of freedom (unclamped carts)."""
        return len(self.free_carts)

    @property
    def n_outputs(self) -> int:
        """Number of measured outputs (sensors)."""
        return len(self.sensors)

    def check_record(self, experiment) -> None:
        """Refuse a record whose number of output columns is not this rig's sensors'.

        Parameters
        ----------
        experiment : Experiment
            A record (its ``n_outputs`` and ``source`` or ``name`` are read).

        Raises
        ------
        DataError
            One line naming the record, both counts and the fix: a record with one
            column per sensor, or a rig description (``--rig FILE``) with its sensors.
        """
        if experiment.n_outputs == self.n_outputs:
            return
        what = "cart" if self.is_chain else "sensor"
        name = experiment.source or experiment.name
        raise DataError(
            f"{name}: {experiment.n_outputs} outputs but the rig has {self.n_outputs} "
            f"{what}s; give a record with one position column per {what}, or describe "
            "the rig that made it (--rig FILE, e.g. --rig ecp210-1cart for one cart; "
            "docs/rigs.md)")

    @property
    def is_chain(self) -> bool:
        """True for the chain layout ``Rig(springs_n_m=...)`` describes (any sensor units).

        The chain has carts ``"1".."n"`` of unknown mass, spring ``i`` between cart ``i`` and
        ``i + 1`` (the last to the frame), all known, the default dampers, the motor on
        cart 1 with share 1 and unknown gain, a sensor on every cart in order, no clamps.
        """
        cached = self.__dict__.get("_is_chain")
        if cached is None:
            cached = self._chain_layout()
            object.__setattr__(self, "_is_chain", cached)  # not a field: eq and hash ignore it
        return cached

    def _chain_layout(self) -> bool:
        n = len(self.carts)
        names = [str(i + 1) for i in range(n)]
        chain = Rig(springs_n_m=self.springs_n_m) if len(self.springs) == n else None
        return (
            chain is not None
            and [c.name for c in self.carts] == names
            and all(c.mass == "unknown" for c in self.carts)
            and all(s.known for s in self.springs)
            and [(s.a, s.b) for s in self.springs] == [(s.a, s.b) for s in chain.springs]
            and self.dampers == chain.dampers
            and self.drive == chain.drive
            and [s.cart for s in self.sensors] == names
            and all(s.kind == "position" for s in self.sensors)
            and not self.clamped
            and self.gain_n_v is None
            and not self.ties
        )

    @property
    def per_unit_gain(self) -> bool:
        """True when nothing absolute is known (no known mass, spring or input gain) and a
        motor drives the rig: the model then fixes the gain at 1 and every mass, damper
        and spring is identified per unit of drive gain (kg per N/V = V s^2/m, N s/m per
        N/V = V s/m, N/m per N/V = V/m).  Frequencies, damping ratios and mode shapes do
        not depend on the scale."""
        free = self.free_carts
        known_mass = any(c.mass == "known" for c in self.carts if c.name in free)
        known_spring = any(s.known and (s.a in free or s.b in free) for s in self.springs)
        return bool(self.drive) and self.gain_n_v is None and not (known_mass or known_spring)

    def require_chain(self, what: str) -> None:
        """Raise ModelError unless the rig is the chain driven at cart 1 (``is_chain``).

        Parameters
        ----------
        what : str
            What needs the chain, for the message (e.g. ``"the coulomb_friction extension"``).
        """
        if not self.is_chain:
            raise ModelError(
                f"{what}: needs the chain rig (spring i joins cart i to i+1, the last to the "
                "frame, all known; motor on cart 1; a sensor on every cart; no clamps); this "
                "rig is not one, use the linear model (fit_lsq, sample_posterior) instead")

    def cart_index(self, name: str) -> int:
        """1-based position of a cart in ``carts`` (its parameter number)."""
        return [c.name for c in self.carts].index(name) + 1

    @property
    def sensor_dofs(self) -> np.ndarray:
        """Degree of freedom each sensor measures, shape (n_outputs,), in sensor order."""
        free = self.free_carts
        return np.array([free.index(s.cart) for s in self.sensors])

    def output_matrix(self) -> np.ndarray:
        """Which cart each sensor reads, shape (n_outputs, n_carts): ``y = C_out x`` for
        position sensors (m), ``C_out x'`` for velocity and ``C_out x''`` for acceleration
        sensors."""
        free = self.free_carts
        out = np.zeros((self.n_outputs, self.n_carts))
        for i, s in enumerate(self.sensors):
            out[i, free.index(s.cart)] = 1.0
        return out

    @property
    def output_kinds(self) -> tuple[str, ...]:
        """Kind of each sensor in record order: ``"position"``, ``"velocity"`` or
        ``"acceleration"``."""
        return tuple(s.kind for s in self.sensors)

    @property
    def positions_only(self) -> bool:
        """True when every sensor measures a position."""
        return all(s.kind == "position" for s in self.sensors)

    def require_positions(self, what: str) -> None:
        """Raise ModelError unless every sensor measures a position.

        Parameters
        ----------
        what : str
            What needs position outputs, for the message (e.g. ``"the cubic_spring
            extension"``).
        """
        if not self.positions_only:
            kinds = sorted({k for k in self.output_kinds if k != "position"})
            raise ModelError(
                f"{what}: needs position sensors only (m, mm, count), this rig has "
                f"{' and '.join(kinds)} sensors; fit the linear model (fit_lsq, "
                "sample_posterior), which simulates every sensor kind")

    def input_vector(self) -> np.ndarray:
        """Drive shares per degree of freedom, shape (n_carts,); ``b = g_v * input_vector``."""
        free = self.free_carts
        d = np.zeros(self.n_carts)
        for dr in self.drive:
            d[free.index(dr.cart)] = dr.share
        return d

    def stiffness_matrix(self) -> np.ndarray:
        """Stiffness matrix K, shape (n, n), N/m (unknown springs at their nominal value)."""
        if self.is_chain:
            return chain_matrix(np.asarray(self.springs_n_m), grounded_last=True)
        return sum(s.stiffness_n_m * self.element_pattern(s.a, s.b) for s in self.springs)

    def element_pattern(self, a: str, b: str) -> np.ndarray:
        """Unit matrix of a two-node element, shape (n_carts, n_carts).

        ``+1`` on the diagonal of each free end, ``-1`` off the diagonal when both ends are
        free; an end at the frame or at a clamped cart contributes nothing.
        """
        free = self.free_carts
        idx = [free.index(e) for e in (a, b) if e in free]
        out = np.zeros((self.n_carts, self.n_carts))
        for i in idx:
            out[i, i] += 1.0
        if len(idx) == 2:
            out[idx[0], idx[1]] -= 1.0
            out[idx[1], idx[0]] -= 1.0
        return out



def chain_matrix(elements: np.ndarray, *, grounded_last: bool) -> np.ndarray:
    """Assemble the matrix of a chain of two-node elements.

    Parameters
    ----------
    elements : ndarray, shape (..., m)
        Element values; element ``i`` (0-based) joins node ``i`` and ``i + 1``.  If
        ``grounded_last`` the last element joins the last node to ground, so that the chain
        has ``m`` nodes; otherwise it has ``m + 1`` nodes.
    grounded_last : bool
        Whether the last element joins the last node to ground.

    Returns
    -------
    ndarray, shape (..., n, n)
    """
    e = np.asarray(elements, dtype=float)
    m = e.shape[-1]
    n = m if grounded_last else m + 1
    out = np.zeros(e.shape[:-1] + (n, n))
    n_links = n - 1
    for i in range(n_links):
        k = e[..., i]
        out[..., i, i] += k
        out[..., i + 1, i + 1] += k
        out[..., i, i + 1] -= k
        out[..., i + 1, i] -= k
    if grounded_last:
        out[..., n - 1, n - 1] += e[..., m - 1]
    return out
