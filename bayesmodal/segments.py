"""Records cut where the rig rests, so that the parts of one record can be held out.

A leave-one-record-out test cannot judge an effect that only one record exercises (the
end stop that only the 3 V pulses of the impulse record reach, docs/discrepancy.md
section 7): no other record can place it.  Cut that record where the rig rests, with no
drive and every cart still, and each part is a record that starts at rest, as a model
simulated from the zero state expects; its parts can then predict each other.

Examples
--------
>>> import numpy as np
>>> from bayesmodal.data import Experiment
>>> t = np.arange(40) * 0.1
>>> v = np.where((t < 0.3) | ((t >= 2.0) & (t < 2.3)), 1.0, 0.0)  # two pulses
>>> y = np.zeros((40, 1))
>>> y[:12, 0] = np.sin(np.linspace(0, np.pi, 12))        # moves, then rests
>>> y[20:32, 0] = np.sin(np.linspace(0, np.pi, 12))
>>> [p.name for p in split_at_rest(Experiment(t, v, y, name="rec"), min_rest_s=0.5)]
['rec[1]', 'rec[2]']
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._errors import ConfigError
from .data import Experiment


def rest_mask(experiment: Experiment, tol_m: float = 0.0) -> np.ndarray:
    """Samples at rest: no drive, and every position within ``tol_m`` of the sample before.

    Parameters
    ----------
    experiment : Experiment
    tol_m : float
        Largest change of a position between two samples still counted as rest, m
        (0: positions unchanged, as an encoder at rest reads).

    Returns
    -------
    ndarray of bool, shape (N,)
        False for the first sample (nothing before it to compare).
    """
    y, v = experiment.y_m, experiment.v_volt
    still = np.zeros(v.size, bool)
    still[1:] = np.all(np.abs(np.diff(y, axis=0)) <= tol_m, axis=1)
    return still & (v == 0.0)


def split_at_rest(experiment: Experiment, *, min_rest_s: float = 1.0,
                  tol_m: float = 0.0) -> tuple[Experiment, ...]:
    """The record cut where the drive starts again after a rest of at least ``min_rest_s``.

    Each part after the first starts with the last sample of such a rest (no drive, carts
    still; ``rest_mask``) and runs to the last sample of the next, with its time
    starting at 0 and its positions as measured (a cart held off its zero by friction
    keeps that small offset).  Every part holds some drive: a rest before the first
    drive of the record does not cut it.  A record without such a rest (a sweep) is
    returned whole.

    Parameters
    ----------
    experiment : Experiment
    min_rest_s : float
        Shortest rest that ends a part, s (> 0).
    tol_m : float
        Largest change of a position between samples still counted as rest, m (>= 0).

    Returns
    -------
    tuple of Experiment
        The parts in time order, named ``"<name>[k]"`` (k from 1), or ``(experiment,)``.

    Raises
    ------
    ConfigError
        For ``min_rest_s <= 0`` or ``tol_m < 0``.
    """
    if not np.isfinite(min_rest_s) or min_rest_s <= 0:
        raise ConfigError(f"min_rest_s must be > 0 s, got {min_rest_s}; pass the shortest "
                          "rest, in seconds, that separates two parts")
    if not np.isfinite(tol_m) or tol_m < 0:
        raise ConfigError(f"tol_m must be >= 0 m, got {tol_m}; pass 0 for positions that "
                          "do not change at rest")
    rest = rest_mask(experiment, tol_m)
    n_min = max(1, int(np.ceil(min_rest_s / experiment.dt - 1e-9)))
    # runs of rest samples: [start, stop)
    edges = np.diff(np.r_[0, rest.astype(np.int8), 0])
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    N = experiment.t_s.size
    v = experiment.v_volt
    cuts: list[int] = []
    last = 0  # where the part being closed starts
    for a, b in zip(starts, stops, strict=True):
        # the last sample of a long rest that the drive ends, if the part it closes was
        # driven (a rest before the first drive, or a cart creeping a count, cuts nothing)
        if b - a >= n_min and b < N and v[b] != 0.0 and np.any(v[last:b]):
            last = int(b) - 1
            cuts.append(last)
    if not cuts:
        return (experiment,)
    bounds = [0, *cuts, N]
    parts = []
    for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:], strict=True), 1):
        end = b + 1 if b < N else N  # each part ends with the rest sample the next starts
        sl = slice(a, end)
        parts.append(Experiment(experiment.t_s[sl] - experiment.t_s[a],
                                experiment.v_volt[sl], experiment.y_m[sl],
                                name=f"{experiment.name}[{k}]",
                                source=f"{experiment.source or experiment.name}, samples "
                                f"{a}-{end - 1}"))
    return tuple(parts)


def split_records(experiments: Sequence[Experiment], which: Sequence[int],
                  train: Sequence[int], *, min_rest_s: float = 1.0
                  ) -> tuple[list[Experiment], list[int]]:
    """Records ``which`` cut at rest (``split_at_rest``), and the training indices remapped.

    The parts of a training record are all training records; those of a held-out record
    are all held out.

    Parameters
    ----------
    experiments : sequence of Experiment
    which : sequence of int
        Indices of the records to cut.
    train : sequence of int
        Indices of the training records among ``experiments``.
    min_rest_s : float
        Shortest rest that ends a part, s.

    Returns
    -------
    experiments : list of Experiment
        The records in order, each cut one replaced by its parts.
    train : list of int
        The training indices among them.

    Raises
    ------
    ConfigError
        For an index out of range, or a record to cut that has no rest to cut it at.
    """
    n = len(experiments)
    bad = [k for k in list(which) + list(train) if not 0 <= k < n]
    if bad:
        count = ("there is 1 record (index 0)" if n == 1
                 else f"there are {n} records (indices 0 to {n - 1})")
        raise ConfigError(f"record index {bad[0]} is out of range: {count}")
    out: list[Experiment] = []
    new_train: list[int] = []
    for k, e in enumerate(experiments):
        parts = split_at_rest(e, min_rest_s=min_rest_s) if k in which else (e,)
        if k in which and len(parts) == 1:
            raise ConfigError(f"{e.name}: no rest of {min_rest_s} s (no drive, carts still) "
                              "to cut it at; do not split this record")
        if k in train:
            new_train += range(len(out), len(out) + len(parts))
        out += parts
    return out, new_train
