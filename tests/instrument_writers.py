"""Write records as instrument files (for tests): UFF dataset 58 and TDMS.

Independent of the package's readers: the UFF records are written by pyuff's own writer
(``prepare_58`` and ``UFF.write_sets``), the TDMS file by npTDMS's ``TdmsWriter``.
"""

from __future__ import annotations

import gc
import warnings
from pathlib import Path

import numpy as np


def write_uff58(path: Path, dt: float, v_volt: np.ndarray, y_m: np.ndarray, *,
                units: tuple[str, ...], directions: tuple[int, ...] | None = None,
                names: tuple[str, ...] | None = None, func_type: int = 1,
                binary: int = 0) -> Path:
    """Write the input and each output as a dataset 58 record.

    Parameters
    ----------
    path : Path
    dt : float
        Sample interval, s (an even abscissa from 0).
    v_volt : ndarray, shape (N,)
        Input, V; written at node 100, direction 1, unit label ``V``.
    y_m : ndarray, shape (N, n)
        Positions, m; output ``i`` at node ``i + 1``.
    units : tuple of str
        Ordinate unit label per output: ``"m"``, ``"mm"`` or ``"counts"`` (0.0706/16000
        m per count).
    directions : tuple of int, optional
        Response direction per output (``-1``: written along -X, the values negated).
    names : tuple of str, optional
        ID line 1 per output (default ``cart1..``); the input is named ``drive``.
    func_type : int
        Dataset 58 function type (1: time response).
    binary : int
        1 for the binary variant of dataset 58.
    """
    import pyuff

    n, n_out = y_m.shape
    t = np.arange(n) * dt
    directions = directions or (1,) * n_out
    names = names or tuple(f"cart{i + 1}" for i in range(n_out))
    per_unit = {"m": 1.0, "mm": 1e-3, "counts": 0.0706 / 16000}

    def record(node, direction, name, data, unit, spec):
        return pyuff.prepare_58(
            binary=binary, func_type=func_type, rsp_node=node, rsp_dir=direction,
            ref_node=0, ref_dir=0, rsp_ent_name="rig", ref_ent_name="rig", id1=name,
            data=data, x=t, abscissa_spacing=1, abscissa_spec_data_type=17,
            abscissa_axis_units_lab="s", ordinate_spec_data_type=spec,
            ordinate_axis_units_lab=unit, orddenom_spec_data_type=0)

    sets = [record(100, 1, "drive", np.asarray(v_volt, float), "V", 1)]
    for i in range(n_out):
        values = y_m[:, i] / per_unit[units[i]] * np.sign(directions[i])
        sets.append(record(i + 1, directions[i], names[i], values, units[i], 8))
    if path.exists():
        path.unlink()
    with warnings.catch_warnings():
        # pyuff's binary writer leaves its file objects to the garbage collector
        warnings.simplefilter("ignore", ResourceWarning)
        pyuff.UFF(str(path)).write_sets(sets, "add")
        gc.collect()
    return path


def write_tdms(path: Path, dt: float, v_volt: np.ndarray, y_m: np.ndarray, *,
               units: tuple[str, ...], group: str = "rig", time_channel: bool = False,
               names: tuple[str, ...] | None = None, label_outputs: bool = True) -> Path:
    """Write the input and outputs as the channels of one TDMS group.

    Parameters
    ----------
    path : Path
    dt : float
        Sample interval, s.
    v_volt : ndarray, shape (N,)
        Input, V; channel ``drive`` in ``V``.
    y_m : ndarray, shape (N, n)
        Positions, m; channels ``cart1..`` (or ``names``) in ``units`` (``m``, ``mm``).
    units : tuple of str
    group : str
    time_channel : bool
        Write the time as a channel ``Time`` in s instead of the waveform properties
        ``wf_increment`` and ``wf_start_offset``.
    names : tuple of str, optional
    label_outputs : bool
        Write the outputs' ``unit_string`` (False: values in ``units`` with no label).
    """
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    n, n_out = y_m.shape
    names = names or tuple(f"cart{i + 1}" for i in range(n_out))
    per_unit = {"m": 1.0, "mm": 1e-3}
    wave = {} if time_channel else {"wf_increment": dt, "wf_start_offset": 0.0}
    chans = [ChannelObject(group, "drive", np.asarray(v_volt, float),
                           properties={"unit_string": "V", **wave})]
    for i in range(n_out):
        chans.append(ChannelObject(group, names[i], y_m[:, i] / per_unit[units[i]],
                                   properties={"unit_string": units[i], **wave}
                                   if label_outputs else wave))
    if time_channel:
        chans.insert(0, ChannelObject(group, "Time", np.arange(n) * dt,
                                      properties={"unit_string": "s"}))
    with TdmsWriter(str(path)) as w:
        w.write_segment([RootObject(), GroupObject(group), *chans])
    return path
