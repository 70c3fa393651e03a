"""The likelihoods' fast path (kept simulator buffers, shared modal forms and step
responses, residual sums read from the buffers) gives the numbers of the straightforward
computation, bit for bit: simulate each record with ``simulate_linear``, form the residual
sums with ``ar1_sums`` / ``ar1_sums_affine``, and turn them into the log-likelihood."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from bayesmodal.data import Experiment
from bayesmodal.inference.likelihood import Likelihood, loglik_from_sums
from bayesmodal.inference.record_layout import DEFAULT_LAYOUT, RecordLayout
from bayesmodal.inference.records import RecordsLikelihood
from bayesmodal.model._resid_kernels import ar1_sums, ar1_sums_affine, ar1_sums_lanes
from bayesmodal.model.simulate import LinearSimulator, simulate_linear
from bayesmodal.model.system import LinearModel, Rig

MODEL = LinearModel(Rig(), "free")
THETA = np.array([5.5, 1.5, 1.45, 1.15, 3.0, 2.0, 1.5, 0.5, 0.5])


def _records(lengths=(900, 700, 1100), dts=(0.005, 0.005, 0.005), seed=0):
    """Records of different lengths (the step response of the longest serves all)."""
    rng = np.random.default_rng(seed)
    out = []
    for k, (n, dt) in enumerate(zip(lengths, dts, strict=True)):
        t = np.arange(n) * dt
        v = 3.0 * ((t % 1.5) < 0.05) if k % 2 == 0 else 0.5 * np.sin(t * (2 + k))
        th = THETA.copy()
        th[0] = 5.0 + 0.5 * k
        y = simulate_linear(MODEL, th, v + 0.01 * k, dt)
        out.append(Experiment(t, v, y + 1e-5 * rng.standard_normal(y.shape), name=f"r{k}"))
    return out


def _rows(lik, nb, seed):
    """Parameter rows near a plausible point: shared physics, per-record values, noise."""
    rng = np.random.default_rng(seed)
    x = np.empty((nb, lik.n_params))
    for i, nm in enumerate(lik.names):
        base = nm.split("[")[0]
        if base in MODEL.names:
            x[:, i] = THETA[MODEL.names.index(base)] * (1 + 0.01 * rng.standard_normal(nb))
        elif base.startswith("mu_"):
            x[:, i] = THETA[MODEL.names.index(base[3:])]
        elif base.startswith("tau_"):
            x[:, i] = 0.1
        elif base == "v0":
            x[:, i] = 0.01 * rng.standard_normal(nb)
        elif base.startswith("sigma"):
            x[:, i] = 1e-5 * (1 + 0.1 * rng.random(nb))
        elif base.startswith("phi"):
            x[:, i] = 0.5 + 0.4 * rng.random(nb)
        else:
            raise AssertionError(nm)
    return x


def _reference_records(lik, theta):
    """The straightforward computation, record by record (fresh simulations)."""
    n_mech = len(lik.mech_names)
    out = np.empty((theta.shape[0], lik.n_records))
    for r, e in enumerate(lik.experiments):
        full, v0 = lik.record_theta(theta, r)
        mech = full[:, :n_mech]
        if np.any(v0):
            unit = mech.copy()
            unit[:, 0] = 1.0
            a = simulate_linear(MODEL, unit, e.v_volt, e.dt)
            b = simulate_linear(MODEL, unit, np.ones(e.n_samples), e.dt)
            sums = ar1_sums_affine(e.y_m, a, b, mech[:, 0], v0)
        else:
            sums = ar1_sums(e.y_m, simulate_linear(MODEL, mech, e.v_volt, e.dt))
        out[:, r] = loglik_from_sums(*sums, e.n_samples, *lik.sigma_phi(full[:, n_mech:]))
    return out


@pytest.mark.parametrize("nb", [1, 5, 16, 20, 40])
def test_lane_sums_equal_the_array_sums_bit_for_bit(nb):
    rng = np.random.default_rng(nb)
    n, dt = 800, 0.005
    u = np.sin(np.arange(n) * dt * 7)
    th = THETA * (1 + 0.01 * rng.standard_normal((nb, THETA.size)))
    M, C, K, b = MODEL.matrices(th)
    masses = np.diagonal(M, axis1=1, axis2=2)
    sim, step = LinearSimulator(u, dt, 3), LinearSimulator(np.ones(n + 37), dt, 3)
    prep = sim.prepare_second_order(masses, C, K, b)
    a = np.array(sim.run_prepared(prep))
    bb = np.array(step.run_prepared(prep))[:, :n]
    y = a[0] + 1e-6 * rng.standard_normal((n, 3))
    g, v0 = rng.uniform(5, 6, nb), 0.01 * rng.standard_normal(nb)
    A = sim.run_prepared(prep, lanes_last=True)
    B = step.run_prepared(prep, lanes_last=True)
    for new, old in [(ar1_sums_lanes(y, A, nb), ar1_sums(y, a)),
                     (ar1_sums_lanes(y, A, nb, B, g, v0), ar1_sums_affine(y, a, bb, g, v0))]:
        for p, q in zip(new, old, strict=True):
            np.testing.assert_array_equal(p, q)
    # the prepared form reproduces simulate_linear
    np.testing.assert_array_equal(a, simulate_linear(MODEL, th, u, dt))


@pytest.mark.parametrize("layout", [DEFAULT_LAYOUT, RecordLayout({}),
                                    RecordLayout({"g_v": "independent"}),
                                    RecordLayout({"g_v": "hierarchical", "v0": "independent",
                                                  "m2": "hierarchical"})],
                         ids=["default", "shared", "gain", "gain_offset_mass"])
@pytest.mark.parametrize("noise", ["ar1", "white"])
def test_records_likelihood_is_the_straightforward_computation(layout, noise):
    lik = RecordsLikelihood(MODEL, _records(), noise, layout=layout)
    for nb, seed in [(12, 1), (5, 2), (12, 3)]:  # sizes change: buffers are re-made
        th = _rows(lik, nb, seed)
        np.testing.assert_array_equal(lik.record_loglik(th), _reference_records(lik, th))


def test_records_with_two_sample_intervals():
    lik = RecordsLikelihood(MODEL, _records(dts=(0.005, 0.004, 0.005)), "ar1")
    th = _rows(lik, 8, 4)
    np.testing.assert_array_equal(lik.record_loglik(th), _reference_records(lik, th))


def test_single_record_likelihood_is_the_straightforward_computation():
    exps = _records()
    lik = Likelihood(MODEL, exps, "ar1")
    for nb, seed in [(16, 5), (3, 6)]:
        rng = np.random.default_rng(seed)
        th = np.c_[THETA * (1 + 0.01 * rng.standard_normal((nb, THETA.size))),
                   np.full((nb, 3), 1e-5), np.full((nb, 3), 0.8)]
        ref = sum(loglik_from_sums(*ar1_sums(e.y_m, simulate_linear(MODEL, th[:, :9],
                                                                    e.v_volt, e.dt)),
                                   e.n_samples, th[:, 9:12], th[:, 12:])
                  for e in exps)
        np.testing.assert_array_equal(lik(th), ref)


def test_a_pickled_likelihood_rebuilds_its_buffers():
    lik = RecordsLikelihood(MODEL, _records(), "ar1")
    th = _rows(lik, 6, 7)
    before = lik(th)
    clone = pickle.loads(pickle.dumps(lik))
    np.testing.assert_array_equal(clone(th), before)


@pytest.mark.parametrize("nb, overdamped", [(1, False), (16, False), (20, True)])
def test_sums_inside_the_recursion_equal_the_stored_prediction_bit_for_bit(nb, overdamped):
    rng = np.random.default_rng(nb)
    n, dt = 600, 0.005
    u = 3.0 * ((np.arange(n) * dt % 1.0) < 0.05)
    th = THETA * (1 + 0.01 * rng.standard_normal((nb, THETA.size)))
    if overdamped:  # a lane the modal form refuses: its chunk runs the full-state kernel
        th[nb // 2, 4:] = [200.0, 200.0, 200.0, 0.0, 0.0]
    M, C, K, b = MODEL.matrices(th)
    sim = LinearSimulator(u, dt, 3)
    prep = sim.prepare_second_order(np.diagonal(M, axis1=1, axis2=2), C, K, b)
    ok = prep[3]  # (time key, outputs, output key, lanes with a modal form, ...)
    assert bool(np.all(ok)) is not overdamped
    yh = simulate_linear(MODEL, th, u, dt)
    y = yh[0] + 1e-6 * rng.standard_normal((n, 3))
    for p, q in zip(sim.residual_sums(prep, y), ar1_sums(y, yh), strict=True):
        np.testing.assert_array_equal(p, q)


@pytest.mark.parametrize("nb, overdamped", [(3, False), (20, True)])
def test_affine_sums_inside_the_recursion_bit_for_bit(nb, overdamped):
    rng = np.random.default_rng(10 + nb)
    n, dt = 500, 0.005
    u = 0.5 * np.sin(np.arange(n) * dt * 9)
    th = THETA * (1 + 0.01 * rng.standard_normal((nb, THETA.size)))
    th[:, 0] = 1.0
    if overdamped:
        th[nb // 2, 4:] = [200.0, 200.0, 200.0, 0.0, 0.0]
    M, C, K, b = MODEL.matrices(th)
    sim = LinearSimulator(u, dt, 3)
    prep = sim.prepare_second_order(np.diagonal(M, axis1=1, axis2=2), C, K, b)
    a = simulate_linear(MODEL, th, u, dt)
    bb = simulate_linear(MODEL, th, np.ones(n), dt)
    g, v0 = rng.uniform(5, 6, nb), 0.01 * rng.standard_normal(nb)
    y = 5.5 * a[0] + 1e-6 * rng.standard_normal((n, 3))
    for p, q in zip(sim.residual_sums(prep, y, g, v0), ar1_sums_affine(y, a, bb, g, v0),
                    strict=True):
        np.testing.assert_array_equal(p, q)
