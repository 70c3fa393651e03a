"""The rig model: carts on a rail joined by springs and dampers, driven by a motor.

The default rig is a chain: spring ``i`` joins cart ``i`` and cart ``i + 1``; the last spring
joins cart ``n`` to the frame; the motor drives cart 1.  For three carts with
``k = (k1, k2, k3)`` the equations of motion are (report eq. 3, with errata 1 and 2)::

    m1 x1'' = k1 (x2 - x1) + c12 (x2' - x1') - c1 x1' + g_v v
    m2 x2'' = k1 (x1 - x2) + k2 (x3 - x2) + c12 (x1' - x2') + c23 (x3' - x2') - c2 x2'
    m3 x3'' = k2 (x2 - x3) + c23 (x2' - x3') - c3 x3' - k3 x3

so that ``M x'' + C x' + K x = b v`` with ``K[n-1, n-1] = k_{n-1} + k_n`` and
``b = (g_v, 0, ..., 0)``.  The state is ``(x, x')`` and

    A = [[0, I], [-M^-1 K, -M^-1 C]],   B = [0; M^-1 b].

Any other rectilinear layout is described by a ``Rig`` with explicit ``carts``, ``springs``,
``dampers``, ``drive``, ``sensors`` and ``clamped`` carts (see docs/rigs.md and
``bayesmodal.model.rigs`` for the TOML form).  Every two-node element between carts ``i`` and
``j`` with value ``k`` adds ``k`` to ``K[i, i]`` and ``K[j, j]`` and ``-k`` to ``K[i, j]``
and ``K[j, i]``; an element to the frame (or to a clamped cart) adds only ``K[i, i]``.
Clamped carts are not degrees of freedom.  Unknown springs are parameters ``k*`` appended
after the damping parameters; carts of known mass drop out of the parameter vector, as does
``g_v`` when the input gain is known.

Two damping models are supported: ``"free"`` (a damper from each listed cart to the frame,
``c1..cn``, and one across each listed pair, ``c12, c23, ...``; by default every cart and
every spring between two carts) and ``"proportional"`` (``C = ca M + cb K``).

The module holds the linear model; the rig it is built on is defined in ``rig`` (the
layout, checked by ``_rig_checks``) and ``elements`` (carts, springs, dampers, drive,
sensors), and re-exported here.  Where each parameter of a general rig goes in the
matrices is ``_param_layout``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from .._errors import ModelError
from ._param_layout import _layout
from .elements import (
    ECP_M_PER_COUNT,
    FRAME,
    INPUT_KINDS,
    MASS_KINDS,
    SENSOR_KINDS,
    SENSOR_ORDERS,  # noqa: F401  (re-exported: defined in elements)
    SENSOR_UNITS,
    STANDARD_GRAVITY_M_S2,
    Cart,
    Damper,
    Drive,
    Sensor,
    Spring,
)
from .rig import DAMPING_MODELS, ECP210_SPRINGS_N_M, Rig, chain_matrix

# The rig and its elements (defined in ``rig`` and ``elements``) are re-exported here,
# where the package has always imported them from.
__all__ = [
    "default_start",
    "ECP_M_PER_COUNT",
    "Rig",
    "Cart",
    "Spring",
    "Damper",
    "Drive",
    "Sensor",
    "LinearModel",
    "DAMPING_MODELS",
    "ECP210_SPRINGS_N_M",
    "FRAME",
    "MASS_KINDS",
    "SENSOR_UNITS",
    "SENSOR_KINDS",
    "STANDARD_GRAVITY_M_S2",
    "INPUT_KINDS",
]


def _pair_name(i: int, n: int) -> str:
    # 1-based indices of the relative damper between cart i and cart i+1
    return f"c{i}{i + 1}" if n < 10 else f"c{i}_{i + 1}"



def _check_scale(rig: Rig) -> None:
    # Scaling every mass, damper and spring by a factor a scales the motion by 1/a under a
    # fixed force, and leaves a free decay unchanged: something absolute must be known.
    free = rig.free_carts
    known_mass = any(c.mass == "known" for c in rig.carts if c.name in free)
    known_spring = any(s.known and (s.a in free or s.b in free) for s in rig.springs)
    known_gain = rig.gain_n_v is not None and bool(rig.drive)
    if not (known_mass or known_spring or known_gain or rig.per_unit_gain):
        raise ModelError(
            "masses, springs and input gain cannot be separated (all unknown: scaling them "
            "together gives the same motion); add a known mass (mass = \"known\", mass_kg), "
            "a known spring (known = true) or the input gain from a static-gain record "
            "(gain_n_v, see `bayesmodal static`)")


@dataclass(frozen=True)
class LinearModel:
    """Linear rig model with a chosen damping model.

    Parameters
    ----------
    rig : Rig
        Layout, known masses and springs.
    damping : {"free", "proportional"}
        Damping model.

    Attributes
    ----------
    names : tuple of str
        Parameter names in vector order: ``g_v`` (unless the gain is known), the unknown
        masses ``m<i>``, the damping (``c<i>`` to the frame, then ``c<i><j>`` across pairs;
        or ``ca, cb``), then the unknown springs.  For ``Rig()``: ``("g_v", "m1", "m2",
        "m3", "c1", "c2", "c3", "c12", "c23")`` or ``("g_v", "m1", "m2", "m3", "ca",
        "cb")``.  Units: g_v N/V, masses kg, c* N s/m, ca 1/s, cb s, k* N/m.

    Raises
    ------
    ModelError
        For an unknown damping model, or a rig whose masses, springs and gain are all
        unknown (see ``docs/rigs.md``).

    Examples
    --------
    >>> model = LinearModel(Rig(), "proportional")
    >>> model.names
    ('g_v', 'm1', 'm2', 'm3', 'ca', 'cb')
    """

    rig: Rig = field(default_factory=Rig)
    damping: str = "free"

    def __post_init__(self) -> None:
        if self.damping not in DAMPING_MODELS:
            raise ModelError(f"damping must be one of {DAMPING_MODELS}, got {self.damping!r}")
        if not isinstance(self.rig, Rig):
            raise ModelError(f"rig must be a Rig, got {type(self.rig).__name__}")
        if self.rig.damping is not None and self.rig.damping != self.damping:
            raise ModelError(
                f"the rig declares {self.rig.damping} damping ([dampers] proportional = "
                f"{str(self.rig.damping == 'proportional').lower()}) but {self.damping} "
                "damping was asked for; drop one of the two")
        _check_scale(self.rig)
        chain = self.rig.is_chain
        object.__setattr__(self, "_chain", chain)
        object.__setattr__(self, "_layout", None if chain else _layout(self.rig, self.damping))

    @property
    def n_carts(self) -> int:
        """Number of degrees of freedom (unclamped carts)."""
        return self.rig.n_carts

    @property
    def n_outputs(self) -> int:
        """Number of measured outputs (the rig's sensors)."""
        return self.rig.n_outputs

    @property
    def output_index(self) -> np.ndarray | None:
        """Degree of freedom of each output, shape (n_outputs,); None for all, in order."""
        return None if self._chain else self._layout.outputs

    @functools.cached_property
    def output_spec(self) -> np.ndarray | None:
        """Degree of freedom and time derivative (0 position, 1 velocity, 2 acceleration)
        of each output, shape (n_outputs, 2) int; None when every sensor reads a position
        (the outputs are then the positions ``output_index`` picks)."""
        if self.rig.positions_only:
            return None
        free = self.rig.free_carts
        return np.array([(free.index(s.cart), s.order) for s in self.rig.sensors],
                        dtype=np.int64)

    @property
    def n_states(self) -> int:
        return 2 * self.rig.n_carts

    @functools.cached_property  # (read on every likelihood call: built once)
    def names(self) -> tuple[str, ...]:
        if not self._chain:
            return self._layout.names
        n = self.rig.n_carts
        masses = tuple(f"m{i + 1}" for i in range(n))
        if self.damping == "proportional":
            return ("g_v",) + masses + ("ca", "cb")
        absolute = tuple(f"c{i + 1}" for i in range(n))
        relative = tuple(_pair_name(i + 1, n) for i in range(n - 1))
        return ("g_v",) + masses + absolute + relative

    @property
    def n_params(self) -> int:
        return len(self.names)

    @property
    def scale(self) -> str:
        """``"absolute"``, or ``"per_unit_gain"`` when nothing absolute is known
        (``Rig.per_unit_gain``: masses in V s^2/m, dampers in V s/m, springs in V/m)."""
        return "per_unit_gain" if self.rig.per_unit_gain else "absolute"

    @property
    def tied(self) -> dict[str, str]:
        """Each tied parameter that follows another: ``{"k2": "k1"}`` for ``ties =
        [["k1", "k2"]]``."""
        return {x: g[0] for g in self.rig.ties for x in g[1:]}

    def as_vector(self, params: dict[str, float]) -> np.ndarray:
        """Parameter vector, shape (n_params,), from a name-to-value mapping.

        Raises
        ------
        ModelError
            If a name is missing or unknown.
        """
        missing = [n for n in self.names if n not in params]
        unknown = [n for n in params if n not in self.names]
        if missing or unknown:
            raise ModelError(
                f"parameters for damping={self.damping!r}: missing {missing}, unknown {unknown}"
            )
        return np.array([float(params[n]) for n in self.names])

    def as_dict(self, theta: np.ndarray) -> dict[str, float]:
        """Name-to-value mapping of a parameter vector of shape (n_params,)."""
        theta = np.asarray(theta, dtype=float)
        return {n: float(v) for n, v in zip(self.names, theta, strict=True)}

    # ------------------------------------------------------------------ validity
    def valid(self, theta: np.ndarray) -> np.ndarray:
        """Boolean mask, shape (...,), of physically admissible parameter sets.

        Admissible: finite, g_v > 0, masses > 0, unknown springs > 0, every damping
        coefficient >= 0.  For proportional damping ``ca >= 0`` and ``cb >= 0`` (which
        makes C positive semi-definite and the system stable).
        """
        theta = np.asarray(theta, dtype=float)
        ok = np.all(np.isfinite(theta), axis=-1)
        if not self._chain:
            pos = self._layout.positive
            ok &= np.all(theta[..., pos] > 0, axis=-1)
            ok &= np.all(theta[..., ~pos] >= 0, axis=-1)
            return ok
        n = self.rig.n_carts
        ok &= theta[..., 0] > 0
        ok &= np.all(theta[..., 1 : 1 + n] > 0, axis=-1)
        ok &= np.all(theta[..., 1 + n :] >= 0, axis=-1)
        return ok

    def check(self, theta: np.ndarray) -> np.ndarray:
        """Validate and return theta as a float array of shape (..., n_params)."""
        theta = np.asarray(theta, dtype=float)
        if theta.shape[-1:] != (self.n_params,):
            raise ModelError(
                f"parameter vector must have length {self.n_params} {self.names}, "
                f"got shape {theta.shape}"
            )
        bad = ~self.valid(theta)
        if np.any(bad):
            first = theta[bad][0] if theta.ndim > 1 else theta
            springs = "" if self._chain else ", springs > 0"
            raise ModelError(
                "impossible parameters (need finite values, g_v > 0, masses > 0, damping >= 0"
                f"{springs}): {self.as_dict(first)}"
            )
        return theta

    def check_record(self, experiment) -> None:
        """Refuse a record whose number of output columns is not this model's
        (:meth:`Rig.check_record`)."""
        self.rig.check_record(experiment)

    # ------------------------------------------------------------------ matrices
    def matrices(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Mass, damping, stiffness matrices and input vector.

        Parameters
        ----------
        theta : ndarray, shape (..., n_params)

        Returns
        -------
        M, C, K : ndarray, shape (..., n, n)
            kg, N s/m, N/m, over the degrees of freedom (unclamped carts).
        b : ndarray, shape (..., n)
            Force per volt at each cart, N/V.
        """
        theta = np.asarray(theta, dtype=float)
        if not self._chain:
            return self._general_matrices(theta)
        n = self.rig.n_carts
        batch = theta.shape[:-1]
        masses = theta[..., 1 : 1 + n]
        M = masses[..., :, None] * np.eye(n)
        K = np.broadcast_to(self.rig.stiffness_matrix(), batch + (n, n)).copy()
        if self.damping == "proportional":
            ca = theta[..., 1 + n]
            cb = theta[..., 2 + n]
            C = ca[..., None, None] * M + cb[..., None, None] * K
        else:
            absolute = theta[..., 1 + n : 1 + 2 * n]
            relative = theta[..., 1 + 2 * n :]
            C = chain_matrix(relative, grounded_last=False) if n > 1 else np.zeros(batch + (1, 1))
            C = C + absolute[..., :, None] * np.eye(n)
        b = np.zeros(batch + (n,))
        b[..., 0] = theta[..., 0]
        return M, C, K, b

    def _general_matrices(self, theta: np.ndarray):
        lay = self._layout
        n = self.rig.n_carts
        batch = theta.shape[:-1]
        masses = np.broadcast_to(lay.masses0, batch + (n,)).copy()
        masses[..., lay.mass_dof] = theta[..., lay.mass_idx]
        M = masses[..., :, None] * np.eye(n)
        K = lay.K0 + np.einsum("...j,jab->...ab", theta[..., lay.k_idx], lay.k_pat)
        if self.damping == "proportional":
            ia = self.names.index("ca")
            C = theta[..., ia, None, None] * M + theta[..., ia + 1, None, None] * K
        else:
            C = np.einsum("...j,jab->...ab", theta[..., lay.c_idx], lay.c_pat)
        if lay.gain is not None:
            g = theta[..., lay.gain]
        elif self.rig.per_unit_gain:
            g = np.ones(batch)  # everything per unit of drive gain
        else:
            g = np.full(batch, self.rig.gain_n_v if self.rig.gain_n_v is not None else 0.0)
        b = g[..., None] * self.rig.input_vector()
        return M, C, K, b

    def state_space(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Continuous state-space matrices for state ``(x, x')`` and input v.

        Returns
        -------
        A : ndarray, shape (..., 2n, 2n), 1/s and 1/s^2 blocks
        B : ndarray, shape (..., 2n), m/(V s^2) in the acceleration block
        """
        return state_space_from(*self.matrices(theta))


def state_space_from(M, C, K, b) -> tuple[np.ndarray, np.ndarray]:
    """State-space matrices of ``M x'' + C x' + K x = b v`` for state ``(x, x')``.

    Parameters
    ----------
    M, C, K : ndarray, shape (..., n, n)
        Mass (diagonal, kg), damping (N s/m) and stiffness (N/m) matrices.
    b : ndarray, shape (..., n)
        Force per volt, N/V.

    Returns
    -------
    A : ndarray, shape (..., 2n, 2n), 1/s and 1/s^2 blocks
    B : ndarray, shape (..., 2n), m/(V s^2) in the acceleration block
    """
    n = M.shape[-1]
    inv_m = 1.0 / np.diagonal(M, axis1=-2, axis2=-1)  # M is diagonal
    batch = M.shape[:-2]
    A = np.zeros(batch + (2 * n, 2 * n))
    A[..., :n, n:] = np.eye(n)
    A[..., n:, :n] = -inv_m[..., :, None] * K
    A[..., n:, n:] = -inv_m[..., :, None] * C
    B = np.zeros(batch + (2 * n,))
    B[..., n:] = inv_m * b
    return A, B


def param_kinds(model: LinearModel) -> tuple[str, ...]:
    """Kind of each parameter: gain, mass, ground (damper), pair (damper), ca, cb, spring."""
    out = []
    for name in model.names:
        if name == "g_v":
            out.append("gain")
        elif name in ("ca", "cb"):
            out.append(name)
        elif name[0] == "m" and name[1:].isdigit():
            out.append("mass")
        elif name[0] == "c" and name[1:].isdigit() and int(name[1:]) <= len(model.rig.carts):
            out.append("ground")
        elif name[0] == "c":
            out.append("pair")
        else:
            out.append("spring")
    return tuple(out)


def log_scale_mask(model: LinearModel) -> np.ndarray:
    """Parameters a fit moves on a log scale, shape (n_params,) bool: the positive scale
    parameters (gain, masses, dampers to the frame, ``ca``, springs); the dampers across
    two carts and ``cb``, which may vanish, stay linear."""
    return np.array([k in ("gain", "mass", "ground", "ca", "spring")
                     for k in param_kinds(model)])


def damper_mask(model: LinearModel) -> np.ndarray:
    """The free damping model's dampers (to the frame and across two carts), shape
    (n_params,) bool."""
    return np.array([k in ("ground", "pair") for k in param_kinds(model)])


#: Damping ratio a damper at a cart of given mass starts from (``default_start``).
START_DAMPING_RATIO = 0.05


def default_start(model: LinearModel) -> np.ndarray:
    """A neutral starting point: g_v 5.25 N/V (nominal), masses 1 kg, small damping.

    Carts of nominal mass start at their mass and unknown springs at their nominal stiffness;
    a damper to the frame at a cart of given mass ``m`` (diagonal stiffness ``k``) starts
    at ``2 START_DAMPING_RATIO sqrt(m k)``, one across a pair at a tenth of that.  On a rig
    identified per unit of drive gain (``Rig.per_unit_gain``) masses, dampers and springs
    start at these values divided by the nominal gain.

    Parameters
    ----------
    model : LinearModel

    Returns
    -------
    ndarray, shape (n_params,)
        In ``model.names`` order.
    """
    n = model.n_carts
    if model.rig.is_chain:
        if model.damping == "proportional":
            tail = [1.0, 1e-4]
        else:
            tail = [1.0] * n + [0.1] * (n - 1)
        return np.array([5.25] + [1.0] * n + tail)
    rig = model.rig
    nominal_mass = {f"m{rig.cart_index(c.name)}": c.mass_kg for c in rig.carts
                    if c.mass_kg is not None}
    springs = {s.name: s.stiffness_n_m for s in rig.springs}
    base = {"gain": 5.25, "ground": 1.0, "pair": 0.1, "ca": 1.0, "cb": 1e-4}
    # per unit of drive gain: the nominal values divided by the nominal gain (the
    # natural frequencies of the start are the nominal ones)
    per_unit = 1.0 / base["gain"] if rig.per_unit_gain else 1.0
    # the dampers' starts are a 1 kg cart's; a damper at a cart whose mass is given starts
    # at a damping ratio of START_DAMPING_RATIO, c = 2 zeta sqrt(m k) (a torsional disk of
    # 2e-3 kg m^2 on 5.3 N m/rad starts at 0.01 N m s/rad, not at a damping ratio of 7,
    # from which the fit does not find its way)
    ratio = {}
    if model.damping == "free":
        diag = np.diag(rig.stiffness_matrix())
        mass = {c.name: c.mass_kg for c in rig.carts if c.mass_kg is not None}
        free = rig.free_carts
        for name, d in zip([n for n, k in zip(model.names, param_kinds(model), strict=True)
                            if k in ("ground", "pair")], rig.dampers, strict=True):
            ends = [e for e in (d.a, d.b) if e in mass]
            if ends:
                c = 2 * START_DAMPING_RATIO * np.sqrt(mass[ends[0]] * diag[free.index(ends[0])])
                ratio[name] = c / base["ground"]
    out = []
    for name, kind in zip(model.names, param_kinds(model), strict=True):
        if kind == "mass":
            out.append(nominal_mass.get(name, 1.0) * per_unit)
        elif kind == "spring":
            out.append(springs[name] * per_unit)
        elif kind in ("ground", "pair"):
            out.append(base[kind] * ratio.get(name, 1.0) * per_unit)
        else:
            out.append(base[kind])
    return np.array(out)
