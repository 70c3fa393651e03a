"""What every model extension is: named parameters on top of the free-damping linear model.

A parameter vector of an extension is ``(theta_linear, theta_extension)``: the nine
``LinearModel(rig, "free")`` parameters ``g_v, m1.., c1.., c12..`` first, then the
extension's own.  With the extension parameters at their ``null`` values every extension
reduces to the linear model (and its simulator to ``simulate_linear``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ..._errors import DataError, ModelError
from ..system import LinearModel, Rig
from ._linear import kernel_order, outputs_from_kernel, sensor_spec, state_to_kernel

__all__ = ["ParamSpec", "EffectLocation", "Extension", "cart_numbers"]


@dataclass(frozen=True)
class ParamSpec:
    """One extension parameter.

    Attributes
    ----------
    name : str
        Name in the parameter vector (e.g. ``"Fc1"``, ``"tau_s"``).
    unit : str
        SI unit (``"N"``, ``"s"``, ``"m"``, ``"kg"``, ``"N/m^3"``, ``"V"``).
    bounds : tuple of float
        Default prior ``(lo, hi)`` for a uniform prior, in ``unit``.
    null : float
        Value at which the effect vanishes (the linear model), in ``unit``.
    meaning : str
        Physical meaning, one sentence.
    scale : float
        Typical size, in ``unit``: the optimiser's unit step and finite-difference scale.
    """

    name: str
    unit: str
    bounds: tuple[float, float]
    null: float
    meaning: str
    scale: float


@dataclass(frozen=True)
class EffectLocation:
    """Where on the rig an extension acts.

    Attributes
    ----------
    kind : {"cart", "spring", "input", "drive"}
        Element type: a cart (friction), a spring (cubic stiffness), the motor input
        (lag, delay, saturation) or the rack-pinion drive of cart 1 (backlash).
    index : int or None
        0-based index of the strongest cart or spring; None for the input.
    label : str
        Human-readable, e.g. ``"cart 2"`` or ``"spring 1 (cart 1 - cart 2)"``.
    strength : ndarray, shape (n_elements,)
        Size of the effect at each element, in the extension's unit (e.g. ``Fs_i``, N).
    """

    kind: str
    index: int | None
    label: str
    strength: np.ndarray


def cart_numbers(rig: Rig) -> tuple[int, ...]:
    """The 1-based cart number of each degree of freedom (``m<i>``, ``Fc<i>``), in order.

    On a rig with clamped carts the numbers skip them: cart 2 clamped of three gives
    ``(1, 3)``.
    """
    return tuple(rig.cart_index(c) for c in rig.free_carts)


def check_input(u: np.ndarray, dt: float) -> tuple[np.ndarray, float]:
    """Validate a ZOH input ``u`` (N,) V and a sample interval ``dt`` s."""
    u = np.ascontiguousarray(u, dtype=float)
    if u.ndim != 1 or u.size < 1:
        raise DataError(f"input u must be a non-empty 1-D array of volts, got shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise DataError("input u contains NaN or inf")
    if not (np.isfinite(dt) and dt > 0):
        raise DataError(f"sample interval dt must be finite and > 0 s, got {dt!r}")
    return u, float(dt)


class Extension(ABC):
    """A named nonlinear or augmented simulator on top of ``LinearModel(rig, "free")``.

    Subclasses define ``name``, ``description``, ``exact`` (True when the simulation is
    exact, i.e. linear in the state), ``specs`` and ``_simulate``; they may refine the
    validity rule, the optimiser coordinates, the start grid of the least-squares fit and
    ``location_of``.  Instances are immutable and hold only numerical settings.

    Examples
    --------
    >>> from bayesmodal.model.effects import EXTENSIONS
    >>> ext = EXTENSIONS["motor_lag"]
    >>> ext.names(Rig())[-1]
    'tau_s'
    """

    name: str = ""
    description: str = ""
    exact: bool = False
    validity_rule: str = "linear part admissible, extension parameters finite and >= 0"
    #: ``"plant"`` (acts on the carts: friction, backlash, springs), ``"input"`` (acts on
    #: the voltage before the motor force: offset, dead band, saturation, lag, delay) or
    #: ``"output"`` (acts on the sensors' readings: ``transform_output``).
    side: str = "plant"
    #: Place of an input-side effect in the physical chain offset (0) -> dead band (1) ->
    #: saturation (2) -> amplitude gain (2.5) -> lag (3) -> delay (4); None for plant-side
    #: effects.
    input_stage: float | None = None

    #: The memoryless input stage a fused plant kernel applies itself to the shared input
    #: (``kernels.coulomb.INPUT_STAGES``: ``"offset"``, ``"deadband"``, ``"saturation"``,
    #: ``"gain"``), or None.
    kernel_stage: str | None = None
    #: In the catalogue ``diagnose`` tries by default (``DEFAULT_CANDIDATES``).
    default_candidate: bool = True
    #: A change of the simulator that changes its numbers: part of a run's hash
    #: (``model.effects.EXTENSION_REVISIONS``); empty for the first version.
    revision: str = ""
    #: Residual signatures that point to the effect: tags of the checks of
    #: ``bayesmodal.discrepancy.checks`` (``"stick"``, ``"decay"``, ``"bias"``, ...,
    #: ``suggested_by``).
    signatures: tuple[str, ...] = ()
    #: Parameters of a realistic size on the three-cart rig ``Rig()`` (benchmarks and
    #: tests), in ``extension_names`` order.
    typical: tuple[float, ...] = ()
    #: The effect a posterior samples in this one's place, when this one's likelihood is
    #: too rough for a sampler (stick-slip friction's has narrow spikes that trap walkers):
    #: a registry name with the same parameters and more, or None (sampled as it is).
    sampled_as: str | None = None

    #: What the effect needs on the rig: ``""`` (any rig), ``"drive"`` (a motor on at least
    #: one cart: every input-side effect needs one) or ``"one_drive"`` (a motor on exactly one cart:
    #: the effects at the driven cart, its end stop, backlash and lagged motor force).
    needs: str = ""
    #: Sensor kinds the simulator reads (``Rig.output_kinds``): ``_simulate`` takes
    #: ``outputs`` (``_linear.sensor_spec``) when it reads more than positions.
    sensor_kinds: tuple[str, ...] = ("position",)

    def unsupported(self, rig: Rig) -> str | None:
        """Why the effect cannot act on ``rig`` (one line with the fix), None if it can."""
        kinds = sorted(set(rig.output_kinds) - set(self.sensor_kinds))
        if kinds:
            return (f"{self.name}: simulates position sensors only (m, mm, count), this "
                    f"rig has {' and '.join(kinds)} sensors; the input-side effects, "
                    "cubic_stiffness, end_stop, coulomb_friction and coulomb_directional "
                    "simulate every sensor kind, as does the linear model (fit_lsq, "
                    "sample_posterior)")
        driven = [d.cart for d in rig.drive if d.share != 0.0]
        if (self.needs == "drive" or self.side == "input") and not driven:
            return (f"{self.name} acts on the motor input, and this rig has no drive; "
                    "describe the motor in [drive] or leave the effect out")
        if self.needs == "one_drive" and len(driven) != 1:
            return (f"{self.name} acts at the driven cart, and this rig's motor drives "
                    f"{'no cart' if not driven else 'carts ' + ', '.join(driven)}; "
                    "describe a rig whose [drive] has exactly one cart, or leave it out")
        return None

    def transform_input(self, v: np.ndarray, theta_ext: np.ndarray) -> np.ndarray:
        """The voltage after a memoryless input-side effect, one row per parameter set.

        Parameters
        ----------
        v : ndarray, shape (N,) or (nb, N)
            Voltage before the effect, V, held over each sample.
        theta_ext : ndarray, shape (nb, n_ext)
            The effect's own parameters.

        Returns
        -------
        ndarray, shape (nb, N)
            Voltage after the effect, V.
        """
        raise NotImplementedError(f"{self.name} is not a memoryless input-side effect")

    # ------------------------------------------------------------------ parameters
    @staticmethod
    def linear_model(rig: Rig) -> LinearModel:
        """The underlying free-damping linear model."""
        return LinearModel(rig, "free")

    @abstractmethod
    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        """The extension's own parameters, in vector order after the linear ones."""

    def extension_names(self, rig: Rig) -> tuple[str, ...]:
        """Names of the extension parameters only."""
        return tuple(p.name for p in self.specs(rig))

    def names(self, rig: Rig) -> tuple[str, ...]:
        """All parameter names: the linear free-damping ones, then the extension's."""
        return self.linear_model(rig).names + self.extension_names(rig)

    def n_params(self, rig: Rig) -> int:
        """Length of the full parameter vector."""
        return len(self.names(rig))

    def default_bounds(self, rig: Rig) -> np.ndarray:
        """Default prior bounds of the extension parameters, shape (n_ext, 2), SI units."""
        return np.array([p.bounds for p in self.specs(rig)], dtype=float)

    def null_values(self, rig: Rig) -> np.ndarray:
        """Extension parameters at which the model is linear, shape (n_ext,)."""
        return np.array([p.null for p in self.specs(rig)], dtype=float)

    def null_theta(self, rig: Rig, theta_linear: np.ndarray) -> np.ndarray:
        """Full vector(s) ``(theta_linear, null_values)``, shape (..., n_params)."""
        theta_linear = np.asarray(theta_linear, dtype=float)
        null = self.null_values(rig)
        null = np.broadcast_to(null, theta_linear.shape[:-1] + null.shape)
        return np.concatenate([theta_linear, null], axis=-1)

    def split(self, rig: Rig, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(theta_linear, theta_extension)`` views of a vector of shape (..., n_params)."""
        p = self.linear_model(rig).n_params
        return theta[..., :p], theta[..., p:]

    def as_dict(self, rig: Rig, theta: np.ndarray) -> dict[str, float]:
        """Name-to-value mapping of one full parameter vector."""
        theta = np.asarray(theta, dtype=float)
        return {n: float(v) for n, v in zip(self.names(rig), theta, strict=True)}

    def _valid_extension(self, rig: Rig, theta_lin, theta_ext) -> np.ndarray:
        """Extra validity rule on the extension parameters (default: finite and >= 0)."""
        return np.all(np.isfinite(theta_ext) & (theta_ext >= 0), axis=-1)

    def valid(self, rig: Rig, theta: np.ndarray) -> np.ndarray:
        """Boolean mask, shape (...,), of admissible full parameter vectors."""
        theta = np.asarray(theta, dtype=float)
        lin, ext = self.split(rig, theta)
        return self.linear_model(rig).valid(lin) & self._valid_extension(rig, lin, ext)

    def check(self, rig: Rig, theta: np.ndarray) -> np.ndarray:
        """Validate and return theta as a float array of shape (..., n_params)."""
        theta = np.asarray(theta, dtype=float)
        names = self.names(rig)
        if theta.shape[-1:] != (len(names),):
            raise ModelError(
                f"{self.name}: parameter vector must have length {len(names)} {names}, "
                f"got shape {theta.shape}"
            )
        bad = ~self.valid(rig, theta)
        if np.any(bad):
            first = theta[bad][0] if theta.ndim > 1 else theta
            raise ModelError(
                f"{self.name}: impossible parameters ({self.validity_rule}): "
                f"{self.as_dict(rig, first)}"
            )
        return theta

    # ------------------------------------------------------------------ simulation
    def simulate(
        self,
        rig: Rig,
        theta: np.ndarray,
        u: np.ndarray,
        dt: float,
        x0: np.ndarray | None = None,
    ) -> np.ndarray:
        """Cart positions for one or many parameter sets.

        Parameters
        ----------
        rig : Rig
        theta : ndarray, shape (n_params,) or (nb, n_params)
            Full parameter vectors in ``names(rig)`` order.
        u : ndarray, shape (N,)
            Motor voltage, V, held over each sample interval.
        dt : float
            Sample interval, s.
        x0 : ndarray, shape (2n,) or (nb, 2n), optional
            Initial cart positions (m) and velocities (m/s); at rest by default.  Internal
            states of the extension (motor force, motor position, delayed input) start at
            rest.

        Returns
        -------
        y : ndarray, shape (N, n_outputs) or (nb, N, n_outputs)
            What each sensor reads (``rig.sensors``), in SI along +x as
            ``simulate_linear``: position m, velocity m/s, acceleration m/s^2 (at the
            sample, with the input held from it and the nonlinear forces at the sample's
            state: their feedthrough included).

        Raises
        ------
        ModelError
            If any parameter set is impossible.
        DataError
            If the input or x0 is malformed.
        """
        theta = np.asarray(theta, dtype=float)
        single = theta.ndim == 1
        theta = np.atleast_2d(theta)
        if theta.ndim != 2:
            raise ModelError(
                f"theta must have shape (n_params,) or (nb, n_params), got {theta.shape}"
            )
        why = self.unsupported(rig)
        if why:
            raise ModelError(why)
        theta = self.check(rig, theta)
        u, dt = check_input(u, dt)
        nb = theta.shape[0]
        s = 2 * rig.n_carts
        if x0 is None:
            x0b = np.zeros((nb, s))
        else:
            x0 = np.asarray(x0, dtype=float)
            if x0.shape not in ((s,), (nb, s)):
                raise DataError(f"x0 must have shape ({s},) or ({nb}, {s}), got {x0.shape}")
            x0b = np.ascontiguousarray(np.broadcast_to(x0, (nb, s)))
        lin, ext = self.split(rig, theta)
        order = kernel_order(rig)
        args = (rig, np.ascontiguousarray(lin), np.ascontiguousarray(ext), u, dt,
                state_to_kernel(order, x0b))
        spec = sensor_spec(rig)
        if spec is None:
            y = outputs_from_kernel(order, self._simulate(*args))
        else:  # velocity or acceleration sensors: each read in the kernel, sensor order
            y = self._simulate(*args, outputs=spec)
        y = self.transform_output(rig, ext, y)
        return y[0] if single else y

    def transform_output(self, rig: Rig, theta_ext: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The sensors' readings of the simulated outputs (default: as simulated).

        Parameters
        ----------
        rig : Rig
        theta_ext : ndarray, shape (nb, n_ext)
            The effect's own parameters.
        y : ndarray, shape (nb, N, n_outputs)
            Simulated outputs, m (possibly a view of a kernel's buffer: not to be written).

        Returns
        -------
        ndarray, shape (nb, N, n_outputs)
        """
        return y

    @abstractmethod
    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0) -> np.ndarray:
        """Batched simulation; validated inputs, returns shape (nb, N, n).

        ``x0`` and the returned positions are in the kernels' order of the degrees of
        freedom (``_linear.kernel_order``: the driven cart first), ``theta_lin`` and
        ``theta_ext`` in the rig's; per-cart parameters are reordered with
        ``_linear.to_kernel``.  An effect whose ``sensor_kinds`` go beyond positions also
        takes ``outputs`` (``_linear.sensor_spec``, kernel degrees of freedom) and then
        returns each sensor's reading, shape (nb, N, n_outputs), in sensor order.
        """

    # ------------------------------------------------------------------ location
    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """Where the effect acts for one full parameter vector (default: the input)."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        _, ext = self.split(rig, theta)
        return EffectLocation("input", None, "motor input", np.abs(ext - self.null_values(rig)))

    # ------------------------------------------------------------------ fitting hooks
    def to_opt(self, rig: Rig, theta_ext: np.ndarray) -> np.ndarray:
        """Optimiser coordinates of the extension parameters (default: identity)."""
        return np.array(theta_ext, dtype=float)

    def from_opt(self, rig: Rig, w: np.ndarray) -> np.ndarray:
        """Inverse of ``to_opt``."""
        return np.array(w, dtype=float)

    def opt_bounds(self, rig: Rig) -> tuple[np.ndarray, np.ndarray]:
        """Hard bounds ``(lo, hi)`` in optimiser coordinates (default: ``[0, inf)``)."""
        q = len(self.specs(rig))
        return np.zeros(q), np.full(q, np.inf)

    def mode_starts(self, rig: Rig, theta_ext: np.ndarray) -> np.ndarray:
        """Alternative starts of the posterior-mode search around a fit, shape (k, n_ext).

        For parameters that do nothing on a face of the parameter space where a fit may
        end (``bayesmodal.inference.mode``).  Default: none.
        """
        return np.empty((0, len(self.specs(rig))))

    def start_grid(self, rig: Rig) -> np.ndarray:
        """Candidate starting values of the extension parameters, shape (n_grid, n_ext).

        The least-squares fit evaluates all of them (with the linear fit) in one batch and
        starts from the best.  Default: the null values and points spread over the prior.
        """
        specs = self.specs(rig)
        lo = np.array([p.bounds[0] for p in specs])
        hi = np.array([p.bounds[1] for p in specs])
        null = self.null_values(rig)
        fractions = np.array([0.05, 0.15, 0.3, 0.6])
        grid = [np.where(np.isfinite(null), null, hi)]
        grid += [lo + f * (hi - lo) for f in fractions]
        return np.array(grid)
