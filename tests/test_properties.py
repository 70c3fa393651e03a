"""Property-based tests (hypothesis) of the simulator and the loaders.

Each property holds for every rig, parameter set, input and record hypothesis draws:
linearity and superposition, time invariance, the static equilibrium ``x = K^-1 b v``,
energy that never increases for the damped unforced system, CSV round trips that are
exact, and loaders that answer any byte string with an Experiment or a DataError (never
another exception).  The number of examples comes from the hypothesis profile
(``tests/conftest.py``; ``ci`` by default, ``nightly`` for many more: docs/testing.md).
"""

from __future__ import annotations

import warnings

import numpy as np
from conftest import EPS, solve_tol, zoh_rtol
from hypothesis import assume, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from bayesmodal import DataError
from bayesmodal.data import ECP_M_PER_COUNT, Experiment, load_experiment, save_csv
from bayesmodal.model.simulate import simulate_linear, simulate_state_space
from bayesmodal.model.system import LinearModel, Rig

FINITE = {"allow_nan": False, "allow_infinity": False}


@st.composite
def rigs(draw, max_carts: int = 4, damping: str | None = None, min_c: float = 0.0):
    """A chain of 1..max_carts carts and a valid parameter vector for it."""
    n = draw(st.integers(1, max_carts))
    springs = draw(st.lists(st.floats(50.0, 5000.0), min_size=n, max_size=n))
    damping = damping or draw(st.sampled_from(["free", "proportional"]))
    model = LinearModel(Rig(tuple(springs)), damping)
    g = draw(st.floats(0.5, 10.0))
    masses = draw(st.lists(st.floats(0.2, 5.0), min_size=n, max_size=n))
    if damping == "free":
        c = draw(st.lists(st.floats(min_c, 5.0), min_size=2 * n - 1, max_size=2 * n - 1))
    else:
        c = [draw(st.floats(min_c, 3.0)), draw(st.floats(min_c * 1e-4, 1e-3))]
    return model, np.array([g, *masses, *c])


def inputs(n: int):
    return hnp.arrays(float, n, elements=st.floats(-5.0, 5.0, **FINITE))


DT = st.sampled_from([0.001, 0.002, 0.005, 0.01])


def _scale(*ys) -> float:
    return max(1e-300, *(float(np.abs(y).max()) for y in ys))


@given(rigs(), inputs(120), inputs(120), st.floats(-3, 3), st.floats(-3, 3), DT)
def test_linearity_and_superposition(rm, u1, u2, a, b, dt):
    model, theta = rm
    y1 = simulate_linear(model, theta, u1, dt)
    y2 = simulate_linear(model, theta, u2, dt)
    y12 = simulate_linear(model, theta, a * u1 + b * u2, dt)
    # one discretisation for all three runs: the rounding of the recursions only
    A, _ = model.state_space(theta)
    tol = 2 * zoh_rtol(A, dt, phase=False, n_steps=u1.size) * _scale(a * y1, b * y2, y12)
    np.testing.assert_allclose(y12, a * y1 + b * y2, rtol=0, atol=tol)


@given(rigs(), inputs(100), st.integers(1, 60), DT)
def test_time_invariance(rm, u, shift, dt):
    model, theta = rm
    y = simulate_linear(model, theta, u, dt)
    us = np.r_[np.zeros(shift), u[:-shift]]
    ys = simulate_linear(model, theta, us, dt)
    assert np.all(ys[:shift] == 0)  # causal: nothing before the input arrives
    A, _ = model.state_space(theta)
    tol = 2 * zoh_rtol(A, dt, phase=False, n_steps=u.size) * _scale(y)
    np.testing.assert_allclose(ys[shift:], y[:-shift], rtol=0, atol=tol)


@given(rigs(), st.floats(-5.0, 5.0).filter(lambda v: abs(v) > 1e-3), DT)
def test_static_equilibrium_is_K_inverse_b_g_v(rm, v, dt):
    # Started at x = K^-1 b v (b = g_v e_1) at rest under the constant input v, the rig
    # stays there: the static gain is K^-1 b g_v, with or without damping.
    model, theta = rm
    M, C, K, b = model.matrices(theta)
    x_static = np.linalg.solve(K, b) * v
    x0 = np.r_[x_static, np.zeros(model.n_carts)]
    y = simulate_linear(model, theta, np.full(200, v), dt, x0=x0)
    # the simulator's bound and the solve's (x0 and the static state carry it)
    A, _ = model.state_space(theta)
    tol = (zoh_rtol(A, dt, n_steps=y.shape[0]) + solve_tol(K)) * np.abs(x_static).max()
    np.testing.assert_allclose(y, np.broadcast_to(x_static, y.shape), rtol=0, atol=tol)
    # and the gain itself: the series connection of the springs for cart 1's force
    k = np.asarray(model.rig.springs_n_m)
    np.testing.assert_allclose(x_static[-1], theta[0] * v / k[-1],
                               rtol=solve_tol(K) + 4 * EPS)


@given(rigs(min_c=0.05), hnp.arrays(float, 8, elements=st.floats(-1.0, 1.0, **FINITE)), DT)
def test_energy_never_increases_without_input(rm, x0_raw, dt):
    model, theta = rm
    n = model.n_carts
    x0 = x0_raw[: 2 * n] * np.r_[np.full(n, 0.01), np.full(n, 0.1)]
    assume(np.max(np.abs(x0_raw[: 2 * n])) > 1e-3)  # energies far above underflow
    M, C, K, b = model.matrices(theta)
    A, B = model.state_space(theta)
    states = simulate_state_space(A, B, np.zeros(400), dt, 2 * n, x0=x0)[0]
    x, xd = states[:, :n], states[:, n:]
    energy = 0.5 * np.einsum("ki,ij,kj->k", xd, M, xd) + 0.5 * np.einsum("ki,ij,kj->k", x, K, x)
    assert np.all(np.diff(energy) <= 1e-9 * energy[0] + 1e-300)
    assert energy[-1] < energy[0]  # and damping removes some
    # the fast second-order path: its potential energy never exceeds the initial total
    y = simulate_linear(model, theta, np.zeros(400), dt, x0=x0)
    potential = 0.5 * np.einsum("ki,ij,kj->k", y, K, y)
    assert np.all(potential <= energy[0] * (1 + 1e-9))
    # two kernels, each within its bound of the exact answer
    np.testing.assert_allclose(y, x, rtol=0,
                               atol=2 * zoh_rtol(A, dt, n_steps=400) * np.abs(x).max())


@st.composite
def experiments(draw):
    n = draw(st.integers(3, 40))
    n_out = draw(st.integers(1, 5))
    dt = draw(st.sampled_from([0.001, 0.005, 0.01, 0.02]))
    t0 = draw(st.sampled_from([0.0, 0.5, 12.25]))
    v = draw(hnp.arrays(float, n, elements=st.floats(-10, 10, **FINITE)))
    y = draw(hnp.arrays(float, (n, n_out), elements=st.floats(-0.1, 0.1, **FINITE)))
    return Experiment(t0 + np.arange(n) * dt, v, y, name="rt")


@given(experiments())
def test_csv_round_trip_is_exact(tmp_path_factory, exp):
    p = tmp_path_factory.mktemp("rt") / "rt.csv"
    save_csv(exp, p)
    back = load_experiment(p)
    np.testing.assert_array_equal(back.t_s, exp.t_s)
    np.testing.assert_array_equal(back.v_volt, exp.v_volt)
    np.testing.assert_array_equal(back.y_m, exp.y_m)
    assert back.name == "rt" and len(back.sha256) == 64


@given(st.integers(3, 40), st.integers(1, 4), st.data())
def test_ecp_txt_counts_round_trip(tmp_path_factory, n, n_out, data):
    counts = data.draw(hnp.arrays(np.int64, (n, n_out), elements=st.integers(-20000, 20000)))
    v = data.draw(hnp.arrays(float, n, elements=st.floats(-5, 5, **FINITE)))
    t = np.arange(n) * 0.005
    p = tmp_path_factory.mktemp("ecp") / "rec.txt"
    np.savetxt(p, np.column_stack([t, counts, v]), delimiter="\t", fmt="%.17g")
    e = load_experiment(p)
    np.testing.assert_array_equal(e.y_m, counts * ECP_M_PER_COUNT)
    np.testing.assert_array_equal(e.v_volt, v)


CSV_ALPHABET = "0123456789.,-+eE \t\nnaifNAItvx"


@given(st.one_of(st.binary(max_size=600),
                 st.text(CSV_ALPHABET, max_size=300).map(str.encode),
                 st.text(CSV_ALPHABET, max_size=300).map(lambda s: b"t,v,x1\n" + s.encode())),
       st.sampled_from(["csv", "txt", "mat"]))
def test_loaders_answer_any_bytes_with_an_experiment_or_a_data_error(tmp_path_factory, raw,
                                                                      ext):
    p = tmp_path_factory.mktemp("fuzz") / f"f.{ext}"
    p.write_bytes(raw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # implausible amplitudes are fine here
        try:
            e = load_experiment(p)
        except DataError as exc:
            assert str(p) in str(exc) or p.stem in str(exc)
            return
    # accepted: then it is a valid record
    assert e.n_samples >= 3 and np.all(np.isfinite(e.y_m)) and np.all(np.diff(e.t_s) > 0)


def _valid_mat(compressed: bool) -> bytes:
    import io

    import scipy.io

    t = np.arange(200)[:, None] * 0.005
    buf = io.BytesIO()
    scipy.io.savemat(buf, {"t": t, "x1": t * 100, "x2": t * 50, "x3": t, "v": t * 0 + 1},
                     do_compression=compressed)
    return buf.getvalue()


_MATS = {False: _valid_mat(False), True: _valid_mat(True)}


@given(st.booleans(), st.lists(st.tuples(st.floats(0, 1, exclude_max=True),
                                         st.integers(0, 255)), min_size=1, max_size=6))
def test_corrupted_mat_files_give_an_experiment_or_a_data_error(tmp_path_factory, compressed,
                                                                flips):
    # a real MATLAB file with a few bytes overwritten reaches deeper into scipy's reader
    # than random bytes do
    raw = bytearray(_MATS[compressed])
    for where, value in flips:
        raw[int(where * len(raw))] = value
    p = tmp_path_factory.mktemp("flip") / "f.mat"
    p.write_bytes(bytes(raw))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        try:
            e = load_experiment(p)
        except DataError as exc:
            assert str(p) in str(exc) or p.stem in str(exc)
            return
    assert e.n_samples >= 3 and np.all(np.isfinite(e.y_m)) and np.all(np.diff(e.t_s) > 0)
