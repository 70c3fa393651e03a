"""The FRF of an ``Experiment``, its estimator chosen from what the input holds.

- a pulse train (short pulses on a zero background): each pulse-to-pulse segment is a
  complete transient and one average (:func:`~.frf.pulse_frf`);
- steps: the same on the record's increments, each step an impulse
  (:func:`~.excitation.step_increments`);
- a hammer test, an input that is a measured force holding isolated hits
  (:func:`~.excitation.is_impact_train`): the hits found, the force windowed around them
  and each hit-to-hit segment one average (:func:`~.impact.impact_frf`).  The load cell's
  noise between the hits leaves the force nowhere exactly zero, so such a record is no
  pulse train, and Welch's Hann window over it would smear each hit's ringing (a damping
  ratio twice the truth, docs/ema.md);
- anything else (a sweep, random or periodic excitation): Welch averaging
  (:func:`~.frf.welch_frf`).
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError
from .excitation import is_impact_train, is_pulse_train, is_step_input, step_increments
from .forms import form_units
from .frf import FRF, pulse_frf, welch_frf
from .impact import impact_frf

__all__ = ["FRF_METHODS", "INPUT_KINDS", "choose_frf_method", "frf_from_experiment"]

#: FRF estimates of an Experiment (``frf_from_experiment``, ``bayesmodal ema --frf``).
FRF_METHODS = ("auto", "pulse", "step", "impact", "welch", "transient")

#: What the input of a record is: a motor voltage or a measured force (``Rig.input``).
INPUT_KINDS = ("voltage", "force")


def _check_input_kind(input_kind: str) -> None:
    if input_kind not in INPUT_KINDS:
        raise DataError(f"input_kind must be one of {INPUT_KINDS}, got {input_kind!r}; a "
                        "rig's input is Rig.input")


def choose_frf_method(u, *, input_kind: str = "voltage") -> str:
    """The FRF estimate ``method="auto"`` takes for an input.

    Parameters
    ----------
    u : ndarray, shape (N,)
        The record's input, V or N.
    input_kind : {"voltage", "force"}
        What the input is.  Only a measured force can be a hammer test.

    Returns
    -------
    str
        ``"impact"`` for a force of isolated hits (:func:`~.excitation.is_impact_train`),
        else ``"pulse"`` for a pulse train, ``"step"`` for steps, ``"welch"`` otherwise.

    Examples
    --------
    >>> f = np.random.default_rng(0).normal(0.0, 0.02, 3000); f[100:103] += 60.0
    >>> choose_frf_method(f, input_kind="force"), choose_frf_method(f)
    ('impact', 'welch')
    """
    _check_input_kind(input_kind)
    u = np.asarray(u, dtype=float)
    if input_kind == "force" and is_impact_train(u):
        return "impact"
    return "pulse" if is_pulse_train(u) else "step" if is_step_input(u) else "welch"


def frf_from_experiment(experiment, *, method: str = "auto", input_kind: str = "voltage",
                        **kwargs) -> FRF:
    """FRF of an Experiment (cart positions per motor volt, m/V, unless told otherwise).

    Parameters
    ----------
    experiment : bayesmodal.data.Experiment
    method : {"auto", "pulse", "step", "impact", "welch", "transient"}
        ``"pulse"``: segment a pulse train (``pulse_frf``); ``"step"``: the same on the
        increments of a step record (``step_increments``: each step an impulse, each
        segment from one step to the next); ``"impact"``: a hammer test (``impact_frf``:
        the force windowed around each hit, no exponential window); ``"welch"``: Welch
        averaging; ``"transient"``: one segment spanning the whole record (increments when
        the input ends at another level than it starts, e.g. a single step);
        ``"auto"``: :func:`choose_frf_method`.
    input_kind : {"voltage", "force"}
        What the input is (``Rig.input``): ``"auto"`` takes ``"impact"`` only for a
        force, and the FRF's units are per V or per N.
    **kwargs
        Passed to ``pulse_frf``, ``impact_frf`` or ``welch_frf``.

    Returns
    -------
    FRF
        In ``m/V`` or ``m/N`` unless ``units`` is given; ``identify`` sets the sensors'
        form.

    Raises
    ------
    DataError
        An unknown method or input kind, or the estimator's own refusal (a double
        impact for ``"impact"``).
    """
    if method not in FRF_METHODS:
        raise DataError(f"FRF method must be one of {FRF_METHODS}, got {method!r}")
    _check_input_kind(input_kind)
    u, y, dt = experiment.v_volt, experiment.y_m, experiment.dt
    if method == "auto":
        method = choose_frf_method(u, input_kind=input_kind)
    kwargs.setdefault("units", form_units(0, input_kind))
    if method == "pulse":
        return pulse_frf(u, y, dt, **kwargs)
    if method == "impact":
        return impact_frf(u, y, dt, **kwargs)
    if method == "step":
        du, dy = step_increments(u, y)
        kwargs.setdefault("baseline", False)
        return pulse_frf(du, dy, dt, **kwargs)
    if method == "transient":
        if u[-1] != u[0]:
            u, y = step_increments(u, y)
            kwargs.setdefault("baseline", False)
        return pulse_frf(u, y, dt, segments=np.array([[0, u.size]]), **kwargs)
    return welch_frf(u, y, dt, **kwargs)
