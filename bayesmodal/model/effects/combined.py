"""Several effects at once: the linear core plus any set of effects from the catalogue.

The parameter vector is the nine free-damping linear parameters followed by each effect's
own parameters, in the order the effects are given.  Whatever that order, a simulation
follows the physical chain from the command to the carts:

    command v -> offset -> dead band -> saturation -> amplitude gain -> lag -> delay
    -> plant

The memoryless input stages (offset, dead band, saturation, amplitude gain) give one held input per
parameter set, shape (nb, N).  The plant is the linear rig, or one plant-side effect
(friction, backlash, cubic springs, LuGre friction) whose compiled kernel takes that
per-lane input.  With the linear plant the lag and the delay stay exact (one linear
recursion, ``effects._input``).  With a nonlinear plant, whose kernel takes a voltage held
over each sample, the plant is run on a grid ``n_hold`` times finer than the record's and
the delayed and lagged input is held at its exact mean over each fine interval
(``effects._input.held_average``): the impulse per interval is exact, the shape inside it
is lost, an error of second order in ``dt / n_hold`` (on 3 V pulses at 5 ms with a 2 ms
lag: 4.9 encoder counts for ``n_hold = 1``, 0.34 for the default 4; measured in
``tests/test_effects_combined_filters.py``).  Such a combination is not ``exact``.

A plant-side *force* (``plant_force``: the end stop of the driven cart) joins the one
plant kernel that takes it (``end_stop.STOP_KERNELS``: stick-slip friction, cubic
springs), or is the plant alone.

Not supported (``ModelError`` at construction): two plant-side effects together otherwise
(each has its own compiled kernel; friction and backlash in one kernel is not written).

Examples
--------
>>> from bayesmodal.model.effects import get_extension
>>> ext = get_extension("coulomb_friction+input_offset")
>>> ext.extension_names(Rig())
('Fc1', 'Fc2', 'Fc3', 'Fs1', 'Fs2', 'Fs3', 'v_offset')
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..._errors import ModelError
from ..system import Rig
from ._base import EffectLocation, Extension, ParamSpec
from ._input import held_average, linear_lanes_run
from ._linear import ALL_KINDS, linear_parts
from .end_stop import STOP_KERNELS

#: Input-side effects that are linear filters handled by the linear plant recursion.
_LINEAR_FILTERS = {3: "tau", 4: "delay_s"}

def _kernel_stage(effect: Extension) -> str | None:
    """The kernel's stage for a memoryless input effect (``Extension.kernel_stage``: a
    plant kernel with ``fuses_input_stages`` applies it to the shared input itself,
    instead of a per-lane input block), or None (the smooth dead band's softplus is left
    to numpy)."""
    kind = effect.kernel_stage
    if kind == "deadband" and getattr(effect, "width_v", 0.0) != 0.0:
        return None
    return kind


@dataclass(frozen=True)
class Combined(Extension):
    """The linear rig with several effects; ``name`` joins theirs with ``+``.

    Parameters
    ----------
    effects : tuple of Extension
        At least one; nested combinations are flattened.  At most one plant-side effect.
    n_hold : int
        With a motor lag or input delay and a nonlinear plant: plant steps per sample
        (the error falls as ``1 / n_hold^2``; the cost grows as ``n_hold``).

    Raises
    ------
    ModelError
        For an empty or unsupported combination or repeated parameter names.

    Examples
    --------
    >>> from bayesmodal.model.effects import EXTENSIONS
    >>> Combined((EXTENSIONS["input_offset"], EXTENSIONS["input_saturation"])).name
    'input_offset+input_saturation'
    """

    effects: tuple
    n_hold: int = 4

    def __post_init__(self) -> None:
        if isinstance(self.n_hold, bool) or not isinstance(self.n_hold, (int, np.integer)) \
                or self.n_hold < 1:
            raise ModelError(f"n_hold must be a positive integer, got {self.n_hold!r}")
        flat: list[Extension] = []
        for e in tuple(self.effects):
            if isinstance(e, Combined):
                flat.extend(e.effects)
            elif isinstance(e, Extension):
                flat.append(e)
            else:
                raise ModelError(f"a combination takes Extension instances, got "
                                 f"{type(e).__name__}; use get_extension(name)")
        if not flat:
            raise ModelError("a combination needs at least one effect; use the linear model "
                             "(no extension) for none")
        names = [e.name for e in flat]
        if len(set(names)) != len(names):
            raise ModelError(f"effect repeated in {names}; list each effect once")
        plant = [e for e in flat if e.side not in ("input", "output")]
        forces = [e for e in plant if getattr(e, "plant_force", False)]
        kernels = [e for e in plant if e not in forces]
        if len(kernels) > 1 or len(forces) > 1:
            raise ModelError(
                f"two plant-side effects {[e.name for e in plant]} in one model are not "
                "supported (each has its own compiled kernel); keep one of them")
        if forces and kernels and kernels[0].name not in STOP_KERNELS:
            raise ModelError(
                f"{forces[0].name} combines with {' or '.join(STOP_KERNELS)} only, not "
                f"with {kernels[0].name} (its kernel takes no stop force); keep one of them")
        stages = [e.input_stage for e in flat if e.side == "input"]
        if any(s is None for s in stages) or len(set(stages)) != len(stages):
            raise ModelError(f"input-side effects {names} need distinct stages")
        object.__setattr__(self, "effects", tuple(flat))

    # ------------------------------------------------------------------ description
    @property
    def name(self) -> str:  # type: ignore[override]
        return "+".join(e.name for e in self.effects)

    @property
    def description(self) -> str:  # type: ignore[override]
        return "; ".join(e.description for e in self.effects)

    @property
    def exact(self) -> bool:  # type: ignore[override]
        held = self.plant is not None and any(e.input_stage in _LINEAR_FILTERS
                                              for e in self.effects)
        return all(e.exact for e in self.effects) and not held

    @property
    def validity_rule(self) -> str:  # type: ignore[override]
        return "; ".join(f"{e.name}: {e.validity_rule}" for e in self.effects)

    @property
    def plant(self) -> Extension | None:
        """The plant-side effect whose kernel runs the model (a plant-side force alone
        runs its own), or None for the linear plant."""
        plant = [e for e in self.effects if e.side not in ("input", "output")]
        return next((e for e in plant if not getattr(e, "plant_force", False)),
                    plant[0] if plant else None)

    @property
    def plant_force(self) -> Extension | None:
        """A plant-side force that the plant kernel takes next to its own, or None."""
        f = next((e for e in self.effects if getattr(e, "plant_force", False)), None)
        return None if f is self.plant else f

    def transform_output(self, rig, theta_ext, y):
        """Each effect's reading of the outputs, in the order the effects are named."""
        for e, sl in zip(self.effects, self._slices(rig), strict=True):
            y = e.transform_output(rig, theta_ext[:, sl], y)
        return y

    def unsupported(self, rig: Rig) -> str | None:
        """The first of the effects' reasons not to act on ``rig``, or None."""
        return next((why for e in self.effects if (why := e.unsupported(rig))), None)

    # ------------------------------------------------------------------ parameters
    def specs(self, rig: Rig) -> tuple[ParamSpec, ...]:
        specs = tuple(p for e in self.effects for p in e.specs(rig))
        names = [p.name for p in specs]
        if len(set(names)) != len(names):
            raise ModelError(f"{self.name}: repeated parameter names {names}; these effects "
                             "cannot be combined")
        return specs

    def _slices(self, rig: Rig) -> list[slice]:
        out, i = [], 0
        for e in self.effects:
            q = len(e.specs(rig))
            out.append(slice(i, i + q))
            i += q
        return out

    def _valid_extension(self, rig, theta_lin, theta_ext):
        ok = np.ones(theta_ext.shape[:-1], bool)
        for e, sl in zip(self.effects, self._slices(rig), strict=True):
            ok &= e._valid_extension(rig, theta_lin, theta_ext[..., sl])
        return ok

    # ------------------------------------------------------------------ simulation
    @property
    def sensor_kinds(self) -> tuple[str, ...]:  # type: ignore[override]
        """The sensor kinds every one of the effects simulates."""
        return tuple(k for k in ALL_KINDS if all(k in e.sensor_kinds for e in self.effects))

    def _simulate(self, rig, theta_lin, theta_ext, u, dt, x0, outputs=None):
        own = {e.name: np.ascontiguousarray(theta_ext[:, sl])
               for e, sl in zip(self.effects, self._slices(rig), strict=True)}
        inputs = sorted((e for e in self.effects if e.side == "input"),
                        key=lambda e: e.input_stage)
        plant = self.plant
        force = self.plant_force
        extra = {} if force is None else {"stop": force.stop_args(own[force.name])}
        if outputs is not None:  # sensors of other kinds (``sensor_kinds``)
            extra["outputs"] = outputs
        kinds = [_kernel_stage(e) for e in inputs]
        if (plant is not None and getattr(plant, "fuses_input_stages", False)
                and u.ndim == 1 and None not in kinds):
            # the plant kernel applies the stages to the shared input itself (bit for bit
            # the numpy transforms below, without an (N, lanes) input block)
            stages = tuple((k, own[e.name][:, 0]) for k, e in zip(kinds, inputs, strict=True))
            return plant._simulate(rig, theta_lin, own[plant.name], u, dt, x0,
                                   input_stages=stages, **extra)
        if force is not None and getattr(plant, "stop_needs_shared_input", False):
            raise ModelError(f"{self.name}: {force.name} with {plant.name} takes the input "
                             "stages offset, sharp dead band, saturation and amplitude gain "
                             "only (its kernel needs one input for all lanes)")
        v = u
        filters: dict[str, np.ndarray] = {}
        for e in inputs:
            if e.input_stage in _LINEAR_FILTERS:
                filters[_LINEAR_FILTERS[e.input_stage]] = own[e.name][:, 0]
            else:
                v = e.transform_input(v, own[e.name])
        if v.ndim == 2:
            v = np.ascontiguousarray(np.broadcast_to(v, (theta_lin.shape[0], v.shape[-1])))
        if plant is None:
            return linear_lanes_run(rig, theta_lin, v, dt, x0, outputs=outputs, **filters)
        if not filters:
            return plant._simulate(rig, theta_lin, own[plant.name], v, dt, x0, **extra)
        n = int(self.n_hold)
        h = dt / n
        w, w0 = held_average(np.repeat(v, n, axis=-1), h, theta_lin.shape[0],
                             with_start=True, **filters)
        y = plant._simulate(rig, theta_lin, own[plant.name], w, h, x0, **extra)[:, ::n]
        if outputs is None or not np.any(outputs[:, 1] == 2):
            return y
        # an acceleration feels the lagged or delayed force at the sample, not its mean
        # over the first hold interval, which the kernel took as its input there
        feed = linear_parts(rig, theta_lin).B[:, rig.n_carts + outputs[:, 0]]  # (nb, n_out)
        jump = (w0 - w)[:, ::n]  # (nb, N)
        add = np.where(outputs[:, 1] == 2, feed, 0.0)[:, None, :] * jump[:, :, None]
        if getattr(plant, "holds_carts", False):
            # a cart held by static friction reads an exact 0 whatever the input
            add = np.where(y == 0.0, 0.0, add)
        return y + add

    # ------------------------------------------------------------------ location
    def location_of(self, rig: Rig, theta: np.ndarray) -> EffectLocation:
        """The plant-side effect's location, or the motor input."""
        theta = self.check(rig, np.asarray(theta, dtype=float))
        lin, ext = self.split(rig, theta)
        plant = self.plant
        if plant is not None:
            sl = self._slices(rig)[self.effects.index(plant)]
            return plant.location_of(rig, np.concatenate([lin, ext[sl]]))
        return EffectLocation("input", None, "motor input", np.abs(ext - self.null_values(rig)))

    # ------------------------------------------------------------------ fitting hooks
    def to_opt(self, rig, theta_ext):
        theta_ext = np.asarray(theta_ext, dtype=float)
        return np.concatenate([e.to_opt(rig, theta_ext[..., sl]) for e, sl in
                               zip(self.effects, self._slices(rig), strict=True)], axis=-1)

    def from_opt(self, rig, w):
        w = np.asarray(w, dtype=float)
        return np.concatenate([e.from_opt(rig, w[..., sl]) for e, sl in
                               zip(self.effects, self._slices(rig), strict=True)], axis=-1)

    def opt_bounds(self, rig):
        lo, hi = zip(*(e.opt_bounds(rig) for e in self.effects), strict=True)
        return np.concatenate(lo), np.concatenate(hi)

    def mode_starts(self, rig: Rig, theta_ext: np.ndarray) -> np.ndarray:
        """Each effect's alternative starts, the other effects at ``theta_ext``'s values."""
        theta_ext = np.asarray(theta_ext, dtype=float)
        rows = []
        for e, sl in zip(self.effects, self._slices(rig), strict=True):
            for g in e.mode_starts(rig, theta_ext[sl]):
                r = theta_ext.copy()
                r[sl] = g
                rows.append(r)
        return np.array(rows).reshape(len(rows), theta_ext.size)

    def start_grid(self, rig: Rig) -> np.ndarray:
        """Each effect's start grid with the other effects at their null values."""
        null = self.null_values(rig)
        rows = [null]
        for e, sl in zip(self.effects, self._slices(rig), strict=True):
            for g in e.start_grid(rig):
                r = null.copy()
                r[sl] = g
                rows.append(r)
        return np.unique(np.array(rows), axis=0)
