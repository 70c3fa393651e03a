"""The fits' threads (``bayesmodal.fit._threads``) give the numbers of one thread.

The parts a diagnosis runs side by side (local searches from several starts, the
generations of the global search, the folds of a leave-one-record-out gain) must give
every number bit for bit as in turn: the thread count is not part of a result.  Data:
records hiding Coulomb friction on one cart from the independent reference simulator
(tests/hidden_layouts.py).  Negative controls: a different start is not taken from the
fold cache, and a worker that fails raises in the caller.
"""

import json

import numpy as np
import pytest
from hidden_layouts import layout_rig, make_layout_case

from bayesmodal import ConfigError
from bayesmodal.data import Experiment
from bayesmodal.discrepancy.diagnosis import DiagnoseSpec, diagnose, gains
from bayesmodal.fit import fit_lsq
from bayesmodal.fit._global_start import member_cost, search_box
from bayesmodal.fit._threads import fit_threads, split_rows, thread_count, thread_map
from bayesmodal.model.effects import get_extension

RIG = layout_rig("one_cart")
FRICTION = get_extension("coulomb_friction")


@pytest.fixture(scope="module")
def records():
    """Two records of one rig hiding friction: one case cut in halves."""
    e = make_layout_case("one_cart", "coulomb_friction", 2, n_samples=1200).experiment
    h = e.n_samples // 2
    return [Experiment(e.t_s[:h], e.v_volt[:h], e.y_m[:h], name="a"),
            Experiment(e.t_s[h:] - e.t_s[h], e.v_volt[h:], e.y_m[h:], name="b")]


@pytest.fixture(scope="module")
def linear(records):
    return fit_lsq(records, RIG)


def test_thread_map_keeps_order_error_state_and_does_not_nest():
    with fit_threads(3), np.errstate(divide="ignore"):
        out = thread_map(lambda x: (np.float64(1.0) / x, thread_count()), [0.0, 2.0, 4.0])
    assert [v for v, _ in out] == [np.inf, 0.5, 0.25]
    assert {n for _, n in out} == {1}  # the workers run their parts in one thread
    assert thread_count() == 1  # outside the block


def test_a_failing_call_raises_in_the_caller():
    def fail(x):
        if x == 2:
            raise ValueError("boom")
        return x

    with fit_threads(2), pytest.raises(ValueError, match="boom"):
        thread_map(fail, [1, 2, 3])


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_bad_thread_counts_are_refused(bad):
    with pytest.raises(ConfigError, match="positive integer"), fit_threads(bad):
        pass


def test_split_rows_is_the_whole_call():
    rows = np.arange(70.0).reshape(35, 2)
    with fit_threads(2):
        assert np.array_equal(split_rows(lambda r: r.sum(axis=1), rows, min_rows=8),
                              rows.sum(axis=1))


def test_a_generation_costs_the_same_on_two_threads(records, linear):
    """A generation of 120 members on a one-output rig: on two threads each block is one
    chunk of lanes, whose residuals come lanes-first, unlike the whole generation's; each
    member's cost is still its one-thread cost bit for bit, and its cost alone."""
    box = search_box(FRICTION, RIG, linear.theta)
    x = (box[:, :1] + np.random.default_rng(4).random((box.shape[0], 120))
         * (box[:, 1:] - box[:, :1]))
    cost = member_cost(FRICTION, RIG, records, None)
    one = cost(x)
    with fit_threads(2):
        two = cost(x)
    assert np.array_equal(one, two)
    assert np.array_equal(one[:1], cost(x[:, :1]))


def test_a_global_fit_is_the_same_on_two_threads(records, linear):
    """Differential evolution (its generations split over threads) and the polish from the
    pruned starts (side by side): bit for bit the one-thread fit.  A population of 100
    (20 per parameter) is cut into two blocks of one chunk of lanes each, whose residuals
    of one output come lanes-first, unlike the whole population's: the sums must not
    depend on that."""
    kw = dict(extension=FRICTION, search="global", linear=linear, generations=3, popsize=20,
              max_samples=600, max_nfev=8)
    one = fit_lsq(records, RIG, rng=np.random.default_rng(5), **kw)
    with fit_threads(2):
        two = fit_lsq(records, RIG, rng=np.random.default_rng(5), **kw)
    assert np.array_equal(one.theta, two.theta)
    assert one.cost == two.cost


def test_held_out_folds_are_the_same_on_two_threads_and_cached(records, linear, monkeypatch):
    theta = fit_lsq(records, RIG, extension=FRICTION, linear=linear, max_nfev=8).theta
    args = (records, RIG, None, linear.theta, FRICTION, theta, linear, 6)
    one = gains.loro_gain(*args)
    refits = []
    real = gains._refit

    def counted(ext, *a, **k):
        refits.append(ext)
        return real(ext, *a, **k)

    monkeypatch.setattr(gains, "_refit", counted)
    cache = {}
    with fit_threads(2):
        two = gains.loro_gain(*args, cache=cache)
        again = gains.loro_gain(*args, cache=cache)
    assert json.dumps(one, sort_keys=True) == json.dumps(two, sort_keys=True)
    assert json.dumps(one, sort_keys=True) == json.dumps(again, sort_keys=True)
    # the second call refitted the new model only: the current model's folds came from
    # the cache
    assert refits.count(None) == len(records) and refits.count(FRICTION) == 2 * len(records)
    # negative control: another current start is refitted, not read from the cache
    gains.loro_gain(records, RIG, None, linear.theta * 1.01, FRICTION, theta, linear, 6,
                    cache=cache)
    assert refits.count(None) == 2 * len(records)


def test_a_diagnosis_is_the_same_on_two_threads(records):
    spec = DiagnoseSpec(posterior=False, n_null=19, max_effects=2, n_starts=2,
                        candidates=("coulomb_friction", "input_offset", "drive_deadband"))
    one = diagnose(records, spec, rig=RIG, train=(0, 1), rng=3)
    two = diagnose(records, spec, rig=RIG, train=(0, 1), rng=3, threads=2)
    assert one.cause == "coulomb_friction"
    assert json.dumps(one.as_dict(), sort_keys=True, default=str) == json.dumps(
        two.as_dict(), sort_keys=True, default=str)
