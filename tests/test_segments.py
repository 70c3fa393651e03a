"""Records cut where the rig rests (``bayesmodal.segments``, ``diagnose --split-at-rest``)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import TABLE3, measured

from bayesmodal import ConfigError
from bayesmodal.cli import main
from bayesmodal.data import ECP_M_PER_COUNT, Experiment, save_csv
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel, Rig
from bayesmodal.segments import rest_mask, split_at_rest, split_records

DT = 0.005
#: Pulse onsets, samples: 3 V for 10 samples, then 12 s without drive.
ONSETS = (0, 2400, 4800)


def _pulses(n=7200, onsets=ONSETS, name="pulses") -> Experiment:
    """Three 3 V pulses on the linear rig, read by an encoder (positions in whole counts):
    once the motion has decayed below half a count the readout is still."""
    u = np.zeros(n)
    for k in onsets:
        u[k:k + 10] = 3.0
    theta = TABLE3.copy()
    theta[4:] *= 4.0  # dampers four times the report's: the carts settle within 8 s
    y = simulate_linear(LinearModel(Rig(), "free"), theta, u, DT)
    y = np.round(y / ECP_M_PER_COUNT) * ECP_M_PER_COUNT
    return Experiment(np.arange(n) * DT, u, y, name=name)


def test_pulses_are_cut_where_the_next_drive_starts():
    e = _pulses()
    parts = split_at_rest(e)
    assert [p.name for p in parts] == ["pulses[1]", "pulses[2]", "pulses[3]"]
    rest = rest_mask(e)
    starts = [0]
    for p in parts:
        a = starts[-1]
        n = p.t_s.size
        np.testing.assert_array_equal(p.y_m, e.y_m[a:a + n])
        np.testing.assert_array_equal(p.v_volt, e.v_volt[a:a + n])
        np.testing.assert_allclose(p.t_s, np.arange(n) * DT, rtol=0, atol=1e-12)
        starts.append(a + n - 1)  # the next part starts with this one's last sample
    assert starts[-1] == e.t_s.size - 1  # the parts cover the record
    for k, a in enumerate(starts[1:-1], 1):
        # each cut is the last rest sample before a pulse: still, undriven, then driven
        assert rest[a] and a + 1 == ONSETS[k]
        assert np.all(rest[a - int(1.0 / DT) + 1 : a + 1])
    for p in parts:  # one pulse each
        assert np.count_nonzero(np.diff((p.v_volt != 0).astype(int)) == 1) <= 1
        assert np.any(p.v_volt != 0)


def test_no_cut_without_a_long_enough_rest_or_before_the_first_drive():
    # negative controls: a sweep never rests; rests shorter than min_rest_s do not cut;
    # a rest before the first drive does not make a part without drive
    t = np.arange(4000) * DT
    u = 0.2 * np.sin(2 * np.pi * (0.5 + 0.2 * t) * t)
    y = simulate_linear(LinearModel(Rig(), "free"), TABLE3, u, DT)
    sweep = Experiment(t, u, y, name="sweep")
    assert split_at_rest(sweep) == (sweep,)
    e = _pulses()
    gap_s = (ONSETS[1] - ONSETS[0]) * DT
    assert split_at_rest(e, min_rest_s=gap_s) == (e,)
    late = _pulses(onsets=(1200, 3600), name="late")
    parts = split_at_rest(late)
    assert len(parts) == 2 and parts[0].t_s.size - 1 == 3599
    assert not np.any(rest_mask(late)[:1]) and np.all(rest_mask(late)[1:1200])


def test_tolerance_counts_small_changes_as_rest():
    e = _pulses()
    jitter = e.y_m.copy()
    jitter[1::2] += ECP_M_PER_COUNT  # one count of flicker everywhere
    noisy = Experiment(e.t_s, e.v_volt, jitter, name="noisy")
    assert split_at_rest(noisy) == (noisy,)  # never still at tol 0
    assert len(split_at_rest(noisy, tol_m=1.5 * ECP_M_PER_COUNT)) == 3


def test_split_records_keeps_training_and_held_out_parts_apart():
    a, b = _pulses(name="a"), _pulses(name="b")
    exps, train = split_records([a, b], which=[0], train=[0])
    assert [e.name for e in exps] == ["a[1]", "a[2]", "a[3]", "b"] and train == [0, 1, 2]
    exps, train = split_records([a, b], which=[0, 1], train=[1])
    assert len(exps) == 6 and train == [3, 4, 5]


def test_bad_arguments_name_the_fix():
    e = _pulses()
    with pytest.raises(ConfigError, match="min_rest_s must be > 0"):
        split_at_rest(e, min_rest_s=0.0)
    with pytest.raises(ConfigError, match="tol_m must be >= 0"):
        split_at_rest(e, tol_m=-1.0)
    with pytest.raises(ConfigError, match="out of range"):
        split_records([e], which=[1], train=[0])
    t = np.arange(300) * DT
    moving = Experiment(t, np.ones(300), np.c_[t, t, t], name="moving")
    with pytest.raises(ConfigError, match="moving: no rest of 1.0 s"):
        split_records([moving], which=[0], train=[0])


def test_cli_refuses_a_record_without_rest_in_one_line(tmp_path, capsys):
    t = np.arange(300) * DT
    path = tmp_path / "moving.csv"
    save_csv(Experiment(t, np.ones(300), np.c_[t, t, t] * 1e-3, name="moving"), path)
    assert main(["diagnose", str(path), "--split-at-rest", "0", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no rest of 1.0 s" in err[0]


def test_the_measured_impulses_are_cut_into_their_four_pulses():
    imp = measured("data_impulses.mat")
    parts = split_at_rest(imp)
    assert len(parts) == 4
    for p in parts:  # each part: one 3 V pulse from rest, at its start
        on = np.flatnonzero(p.v_volt != 0)
        assert on.size and on[0] <= 1 and np.all(np.diff(on) == 1)
        assert np.max(np.abs(p.y_m[0])) < 1e-3  # rests within a millimetre of zero
