"""Known-truth checks on a two-cart rig read by accelerometers under a measured force,
and read by an encoder and an accelerometer under a voltage (mixed sensor kinds).

The data come from the independent reference simulator of ``tests/accel_reference.py``;
the full coverage study (100 replicates) is ``benchmarks/accel_coverage.py``, reported
in docs/accelerometers.md.
"""

from __future__ import annotations

import numpy as np
import pytest
from _benchmarks import load_benchmark
from accel_reference import measured_record, simulate

from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel


def _benchmark():
    return load_benchmark("accel_coverage")


def test_reference_agrees_with_the_package_simulator():
    """The two simulators agree to the reference integrator's tolerance (rtol 1e-10 per
    step, at most about a hundred DOP853 steps between hits: 1e-8 of the largest
    acceleration): a check of the reference itself before it is trusted."""
    cov = _benchmark()
    model = LinearModel(cov.rig(), "free")
    t, f, _ = measured_record(cov.TRUTH, np.random.default_rng(0), n=1000)
    ref = simulate(cov.TRUTH, f, 0.004)
    ours = simulate_linear(model, cov.TRUTH, f, 0.004)
    assert np.max(np.abs(ours - ref)) < 1e-8 * np.max(np.abs(ref))
    # negative control: a 1 % heavier cart 1 is far outside that
    off = simulate_linear(model, cov.TRUTH * np.r_[1.01, np.ones(6)], f, 0.004)
    assert np.max(np.abs(off - ref)) > 1e-3 * np.max(np.abs(ref))


def test_mixed_reference_agrees_with_the_package_simulator():
    """The encoder and accelerometer outputs of the voltage-driven rig: the package's
    simulator (sensor kinds on the linear model) against the reference before
    quantisation, to its integrator's tolerance; a 1 % lighter drive gain is far off."""
    from accel_reference import accelerations, simulate_states, voltage_pulses

    cov = _benchmark()
    model = LinearModel(cov.mixed_rig(), "free")
    v = voltage_pulses(1000, 0.004)
    f = cov.G_V * v
    states = simulate_states(cov.TRUTH, f, 0.004)
    ref = np.column_stack([states[:, 0], [accelerations(cov.TRUTH, s[:2], s[2:], fk)[1]
                                          for s, fk in zip(states, f, strict=True)]])
    theta = np.r_[cov.G_V, cov.TRUTH[:5]]
    ours = simulate_linear(model, theta, v, 0.004)
    scale = np.max(np.abs(ref), axis=0)
    assert np.all(np.max(np.abs(ours - ref), axis=0) < 1e-8 * scale)
    off = simulate_linear(model, theta * np.r_[0.99, np.ones(5)], v, 0.004)
    assert np.all(np.max(np.abs(off - ref), axis=0) > 1e-3 * scale)


@pytest.mark.parametrize("case", ["force", "mixed"])
def test_a_truth_spread_draws_the_unknowns_and_keeps_the_known_springs(case):
    """``truth_spread = 0`` is the one rig of ``TRUTH`` in every replicate, bit for bit;
    a spread draws each unknown within its factor, the known springs of the mixed case
    stay, and the record is that of the drawn rig (it differs from the fixed rig's)."""
    cov = _benchmark()
    fixed = cov.Config(case=case, n_samples=300)
    model, truth, (_, _, y0) = cov._case(fixed, 3)
    nominal = np.r_[cov.G_V, cov.TRUTH[:5]] if case == "mixed" else cov.TRUTH
    assert np.array_equal(truth, nominal)
    s = 0.05
    _, drawn, (_, _, y1) = cov._case(cov.Config(case=case, n_samples=300, truth_spread=s), 3)
    ratio = drawn / nominal
    assert np.all(np.abs(ratio - 1.0) <= s) and np.all(ratio != 1.0)
    assert drawn.size == model.n_params  # the known springs are not parameters
    assert not np.array_equal(y0, y1)
    # each seed draws its own rig
    _, other, _ = cov._case(cov.Config(case=case, n_samples=300, truth_spread=s), 4)
    assert not np.array_equal(drawn, other)
    # a truth seed keeps one drawn rig in every replicate
    one = cov.Config(case=case, n_samples=300, truth_spread=s, truth_seed=3)
    assert np.array_equal(cov._case(one, 4)[1], drawn)


@pytest.mark.slow
@pytest.mark.parametrize(("case", "noise"), [("force", None), ("mixed", None),
                                             ("mixed", "quantised")])
def test_reduced_coverage_of_the_90_percent_intervals(case, noise):
    """Ten replicates: the pooled coverage of the quantities (force: masses,
    stiffnesses, dampers, omega, zeta; mixed: the drive gain, masses, dampers, omega,
    zeta; with the case's likelihood, and the mixed records also with the rounded
    readings' one) within 3 binomial standard errors of 90 % (pooling correlated
    quantities narrows the error little, so the single-quantity error is used)."""
    cov = _benchmark()
    r = 10
    cfg = cov.Config(n_walkers=24, n_steps=1200, burn=400, case=case, noise=noise)
    res = cov.run_coverage(cfg, r, processes=1, seed0=5000)
    hits = np.concatenate([np.concatenate([np.ravel(x["hits"][k])
                                           for k in cov.CASE_GROUPS[case]]) for x in res])
    se = np.sqrt(0.9 * 0.1 / r)
    assert abs(hits.mean() - 0.9) < 3 * se, cov.tabulate(res)
