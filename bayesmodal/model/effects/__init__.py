"""Model extensions: named simulators of effects the linear rig model leaves out.

Each extension adds its own parameters after the free-damping linear parameters and
reduces to the linear model at its ``null`` values.  Every extension works on every rig
description: per-cart parameters for each free cart, per-spring ones for each spring
with a free end, and the effects at the driven cart (backlash, end stop, motor lag)
where the motor drives exactly one cart (``Extension.unsupported`` says why not).  The
registry ``EXTENSIONS`` maps a name to a ready-to-use instance:

============================  ===============================  =====================
name                          parameters (after the linear)    acts at
============================  ===============================  =====================
``coulomb_friction``          ``Fc1..Fcn, Fs1..Fsn`` (N)       each cart
``motor_lag``                 ``tau_s`` (s)                    motor input
``input_delay``               ``delay_s`` (s)                  motor input
``backlash``                  ``gap_m`` (m), ``m_p`` (kg)      the driven cart
``cubic_stiffness``           ``k3_1..k3_n`` (N/m^3)           each spring
``input_saturation``          ``v_sat`` (V)                    motor input
``input_offset``              ``v_offset`` (V)                 motor input
``drive_deadband``            ``v_dead`` (V)                   motor input
``lugre_friction``            ``Fc1..Fcn, Fs1..Fsn`` (N),      each cart
                              ``sigma0`` (N/m), ``sigma1``
                              (N s/m), ``v_stribeck`` (m/s)
``coulomb_directional``       ``Fcp_i, Fcn_i, Fs_i`` (N)       each cart
``amplitude_gain``            ``kappa_per_V`` (1/V)            motor input
``end_stop``                  ``x_stop`` (m), ``k_stop``       the driven cart
                              (N/m)
``sensor_gain``               ``s_2..s_n`` (1)                 each sensor after
                                                               the first
============================  ===============================  =====================

Effects combine: ``get_extension("coulomb_friction+input_offset")`` (or a list of names)
is a ``Combined`` model, the linear core with all of them (see ``extensions.combined``).

Examples
--------
>>> import numpy as np
>>> from bayesmodal.model.system import Rig
>>> ext = EXTENSIONS["coulomb_friction"]
>>> rig = Rig()
>>> theta = ext.null_theta(rig, np.array([6.2, 1.56, 1.46, 1.15, 2.9, 1.8, 2.0, 0.0, 0.0]))
>>> ext.simulate(rig, theta, np.r_[np.full(10, 3.0), np.zeros(90)], 0.005).shape
(100, 3)
"""

from __future__ import annotations

from ..._errors import ModelError
from ._base import EffectLocation, Extension, ParamSpec
from .amplitude_gain import AmplitudeGain
from .backlash import Backlash
from .combined import Combined
from .coulomb import CoulombFriction
from .coulomb_directional import DirectionalCoulombFriction
from .cubic import CubicStiffness
from .deadband import DriveDeadband
from .end_stop import EndStop
from .input_delay import InputDelay
from .input_offset import InputOffset
from .lugre import LuGreFriction
from .motor_lag import MotorLag
from .saturation import InputSaturation
from .sensor_gain import SensorGain

__all__ = [
    "resolve_extension",
    "EXTENSION_REVISIONS",
    "extension_revisions",
    "EXTENSIONS",
    "AmplitudeGain",
    "EffectLocation",
    "Extension",
    "ParamSpec",
    "Backlash",
    "Combined",
    "CoulombFriction",
    "CubicStiffness",
    "DirectionalCoulombFriction",
    "DriveDeadband",
    "EndStop",
    "InputDelay",
    "InputOffset",
    "InputSaturation",
    "LuGreFriction",
    "MotorLag",
    "SensorGain",
    "get_extension",
    "suggested_by",
    "default_candidates",
]

#: Registry of the extensions with their default numerical settings.
EXTENSIONS: dict[str, Extension] = {
    ext.name: ext
    for ext in (
        CoulombFriction(),
        MotorLag(),
        InputDelay(),
        Backlash(),
        CubicStiffness(),
        InputSaturation(),
        InputOffset(),
        DriveDeadband(),
        LuGreFriction(),
        DirectionalCoulombFriction(),
        AmplitudeGain(),
        EndStop(),
        SensorGain(),
    )
}


def suggested_by(signature: str) -> tuple[str, ...]:
    """The registered effects whose ``signatures`` hold ``signature`` (a residual check's
    tag), in registry order; ``(signature,)`` when none does (a cause outside the
    catalogue, e.g. ``"unmodelled_mode"``).

    Parameters
    ----------
    signature : str
        A residual check's tag (``"stick"``, ``"decay"``, ``"bias"``, ``"lag"``, ...).

    Returns
    -------
    tuple of str

    Examples
    --------
    >>> suggested_by("lag")
    ('motor_lag', 'input_delay')
    """
    found = tuple(n for n, e in EXTENSIONS.items() if signature in e.signatures)
    return found or (signature,)


def default_candidates() -> tuple[str, ...]:
    """The effects ``diagnose`` tries by default (``Extension.default_candidate``), in
    registry order."""
    return tuple(n for n, e in EXTENSIONS.items() if e.default_candidate)


#: Effects whose numerics changed the result: a run naming one hashes with its revision,
#: so a run sampled before the change does not resume (``Extension.revision``: LuGre
#: friction steps with 4 sub-steps per sample, not 8).
EXTENSION_REVISIONS = {n: e.revision for n, e in EXTENSIONS.items() if e.revision}


def extension_revisions(names) -> dict:
    """The :data:`EXTENSION_REVISIONS` of the effects named in ``names``.

    Parameters
    ----------
    names : str or sequence of str
        Effect names, or one name with ``+`` between effects.

    Returns
    -------
    dict
        ``{name: revision}``; empty when none changed.
    """
    parts = names.split("+") if isinstance(names, str) else list(names)
    return {e: r for e, r in EXTENSION_REVISIONS.items() if e in parts}


def resolve_extension(extension, model) -> Extension | None:
    """The ``Extension`` instance for a name, an instance or None, checked against a model.

    Parameters
    ----------
    extension : str, sequence of str, Extension or None
        A registry name (or several, combined), an instance, or None (the linear model).
    model : LinearModel
        The model it extends.

    Returns
    -------
    Extension or None

    Raises
    ------
    ModelError
        For an unknown name, an object that is not an ``Extension``, a model whose
        damping is not free (every extension is built on ``LinearModel(rig, "free")``), or
        an effect the rig cannot carry (``Extension.unsupported``: e.g. backlash on a rig
        whose motor drives two carts).
    """
    if extension is None:
        return None
    ext = (get_extension(extension) if isinstance(extension, (str, list, tuple))
           else extension)
    if not isinstance(ext, Extension):
        raise ModelError(
            "extension must be a name in bayesmodal.model.effects.EXTENSIONS or an "
            f"Extension, got {type(extension).__name__}")
    if model.damping != "free":
        raise ModelError(
            f"the {ext.name} extension is built on the free-damping model; got "
            f"{model.damping!r} damping (use LinearModel(rig, 'free'))")
    why = ext.unsupported(model.rig)
    if why:
        raise ModelError(why)
    return ext


def get_extension(name) -> Extension:
    """The registered extension called ``name``, or a combination of several.

    Parameters
    ----------
    name : str or sequence of str
        A name in ``EXTENSIONS``; names joined by ``+`` or a list of names give a
        ``Combined`` model (one name alone gives that extension).

    Raises
    ------
    ModelError
        For an unknown name (the message lists the known ones) or an unsupported
        combination.

    Examples
    --------
    >>> get_extension(["coulomb_friction", "input_offset"]).name
    'coulomb_friction+input_offset'
    """

    names = name.split("+") if isinstance(name, str) else list(name)
    effects = []
    for n in names:
        try:
            effects.append(EXTENSIONS[str(n).strip()])
        except KeyError:
            raise ModelError(
                f"unknown model extension {n!r}; known: {sorted(EXTENSIONS)}"
            ) from None
    if len(effects) == 1:
        return effects[0]
    return Combined(tuple(effects))
