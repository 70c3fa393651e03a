"""Compiled helpers of the extension simulators, and the accuracy of the nonlinear schemes
at their default sub-steps (the speed of those defaults is measured by `bayesmodal bench`)."""

import numpy as np
import pytest
from conftest import EPS, TABLE3
from reference_sim import REFERENCES
from scipy.linalg import expm

from bayesmodal.data import ECP_M_PER_COUNT as COUNT
from bayesmodal.model.effects import EXTENSIONS
from bayesmodal.model.effects._linear import linear_parts
from bayesmodal.model.kernels import expm_batched, zoh
from bayesmodal.model.system import Rig

RIG = Rig()
DT = 0.005


def zoh_blocks(A, inputs, h, *, ramp=False):
    """Reference for the compiled ``zoh``: the Van Loan block exponential by scipy's expm.

    For ``w`` held constant over the step (zero-order hold), ``z(h) = Ah z(0) + G0 w`` with
    ``Ah = e^{A h}`` and ``G0 = int_0^h e^{A s} ds inputs``.  With ``ramp=True`` also the
    response ``G1 = int_0^h e^{A (h - s)} (s / h) ds inputs`` to the unit ramp ``s / h``,
    taken from the top-right block of ``expm([[A h, inputs h, 0], [0, 0, I], [0, 0, 0]])``
    (Van Loan).

    Parameters
    ----------
    A : ndarray, shape (nb, s, s)
    inputs : ndarray, shape (nb, s, m)
    h : float
        Step, s.
    ramp : bool

    Returns
    -------
    Ah : ndarray, shape (nb, s, s)
    G0 : ndarray, shape (nb, s, m)
    G1 : ndarray, shape (nb, s, m)
        Only with ``ramp=True``.
    """
    nb, s, _ = A.shape
    m = inputs.shape[-1]
    size = s + m + (m if ramp else 0)
    Z = np.zeros((nb, size, size))
    Z[:, :s, :s] = A * h
    Z[:, :s, s : s + m] = inputs * h
    if ramp:
        Z[:, s : s + m, s + m :] = np.eye(m)
    E = expm(Z)
    Ah = E[:, :s, :s]
    G0 = E[:, :s, s : s + m]
    if ramp:
        return Ah, G0, E[:, :s, s + m :]
    return Ah, G0


def expm_atol(Z, ref):
    """Bound on the difference of two backward-stable matrix exponentials of Z (n, n) or a
    stack: each n eps (1 + ||Z||) relative to the largest entry of the result."""
    Z = np.asarray(Z)
    norm = float(np.max(np.linalg.norm(Z, 2, axis=(-2, -1))))
    return 2 * Z.shape[-1] * EPS * (1 + norm) * np.abs(ref).max()


def test_expm_batched_matches_scipy_and_is_per_matrix():
    rng = np.random.default_rng(0)
    # norms from 1e-3 to about 40: no, one and several squarings in one batch
    Z = rng.normal(size=(7, 6, 6)) * np.array([1e-3, 0.1, 0.5, 1.0, 3.0, 8.0, 15.0])[:, None, None]
    E = expm_batched(Z)
    for z, e in zip(Z, E, strict=True):
        ref = expm(z)
        # both backward stable up to n eps of Z; expm's condition number is about ||Z||
        # (exactly for normal Z), and each result carries its own rounding
        np.testing.assert_allclose(e, ref, rtol=0, atol=expm_atol(z, ref))
    # each matrix is scaled by its own norm: the result does not depend on the batch
    np.testing.assert_array_equal(expm_batched(Z[:1]), E[:1])
    np.testing.assert_array_equal(expm_batched(np.zeros((2, 3, 3))), [np.eye(3)] * 2)
    with pytest.raises(ValueError, match="non-finite"):
        expm_batched(np.full((1, 2, 2), np.nan))


@pytest.mark.parametrize("ramp", [False, True])
def test_zoh_matches_van_loan_blocks(ramp):
    theta = TABLE3 * np.array([[1.0], [1.1], [0.9]])
    p = linear_parts(RIG, theta)
    got = zoh(p.A, p.force_inputs, 0.0025, ramp=ramp)
    want = zoh_blocks(p.A, p.force_inputs, 0.0025, ramp=ramp)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_allclose(g, w, rtol=0, atol=expm_atol(p.A * 0.0025, w))
    # a step per system: the first one zero (identity, no input response)
    Ah, G0 = zoh(p.A, p.force_inputs, np.array([0.0, 0.001, 0.004]))
    np.testing.assert_array_equal(Ah[0], np.eye(6))
    np.testing.assert_array_equal(G0[0], 0.0)
    ref = expm(p.A[2] * 0.004)
    np.testing.assert_allclose(Ah[2], ref, rtol=0, atol=expm_atol(p.A[2] * 0.004, ref))


def _pulses(N=700):
    u = np.zeros(N)
    u[1:10] = 3.0
    u[200:300] = 0.4
    u[400:410] = -2.0
    return u


# effect sizes other than the ones of test_extensions: a high static level, equal levels,
# a wide and a narrow gap with heavy and light motor
FRICTION_CASES = [
    [0.3, 0.2, 0.25, 0.3, 0.35, 0.25],
    [0.05, 0.05, 0.05, 0.2, 0.2, 0.2],
    # cart 1 with a high static level that holds it while the others move
    [0.245, 0.058, 0.167, 1.405, 0.305, 0.452],
]


@pytest.mark.parametrize("effect", FRICTION_CASES)
def test_default_friction_is_accurate_with_margin(effect):
    """The default (four sub-steps where events are) against the event-driven reference:
    well below an encoder count, and still so with half the sub-steps, so that the default
    is not at the edge of a breakdown."""
    ext = EXTENSIONS["coulomb_friction"]
    theta = np.r_[TABLE3, effect]
    u = _pulses()
    y_ref = REFERENCES["coulomb_friction"](RIG.springs_n_m, theta, u, DT)
    err = np.max(np.abs(ext.simulate(RIG, theta, u, DT) - y_ref)) / COUNT
    half = type(ext)(n_sub=ext.n_sub // 2).simulate(RIG, theta, u, DT)
    err_half = np.max(np.abs(half - y_ref)) / COUNT
    assert err < 0.1, err
    assert err_half < 0.5, err_half


@pytest.mark.parametrize(("effect", "tol_counts"), [([5e-4, 0.3], 0.75), ([1e-4, 0.1], 0.75)])
def test_default_backlash_substeps_are_accurate(effect, tol_counts):
    """The default (two sub-steps) against the event-driven reference: below an encoder
    count, and about four times better with twice the sub-steps (second order), so the
    default is not at the edge of a breakdown."""
    ext = EXTENSIONS["backlash"]
    theta = np.r_[TABLE3, effect]
    u = _pulses()
    y_ref = REFERENCES["backlash"](RIG.springs_n_m, theta, u, DT)
    err = np.max(np.abs(ext.simulate(RIG, theta, u, DT) - y_ref)) / COUNT
    finer = type(ext)(n_sub=2 * ext.n_sub)
    err_fine = np.max(np.abs(finer.simulate(RIG, theta, u, DT) - y_ref)) / COUNT
    assert err < tol_counts, err
    assert err_fine < err / 2.5, (err, err_fine)


#: A posterior draw of the friction model on the measured impulses (high static level on
#: cart 1), at which one sub-step per sample used to flip a stick decision on that record
#: (a cart sticking and breaking away again within one step was held to the step's end).
HIGH_FS = np.array([5.7389, 1.5861, 1.4983, 1.1223, 1.8443, 3.1e-3, 5e-4, 0.3735, 0.109,
                    0.2449, 0.0583, 0.1665, 1.405, 0.3054, 0.4516])


def test_default_friction_substeps_on_the_measured_impulse_input():
    from conftest import measured

    e = measured("data_impulses.mat")
    ext = EXTENSIONS["coulomb_friction"]
    y_ref = REFERENCES["coulomb_friction"](RIG.springs_n_m, HIGH_FS, e.v_volt, e.dt)
    y = ext.simulate(RIG, HIGH_FS, e.v_volt, e.dt)
    assert np.max(np.abs(y - y_ref)) / COUNT < 0.1
    # negative control: the comparison sees a 2 % change of cart 1's static level
    other = HIGH_FS.copy()
    other[12] *= 1.02
    y_other = REFERENCES["coulomb_friction"](RIG.springs_n_m, other, e.v_volt, e.dt)
    assert np.max(np.abs(y_other - y_ref)) / COUNT > 5


#: A draw at which a stuck cart's force passes its static level while another cart
#: reverses (measured impulses, near sample 2266).  The reference used to miss the
#: break-away there (its event functions only see upward crossings, and it did not check
#: the stuck carts again after another cart's event): 423 counts off the kernel.
HELD_PAST_FS = np.array([6.270499, 1.515944, 1.422741, 1.117235, 3.20796, 1.853952, 2.071799,
                         0.002135, 0.00001, 0.049189, 0.020692, 0.340077, 0.049189, 1.195213,
                         1.33248])


def test_reference_releases_a_held_cart_after_another_carts_event():
    from conftest import measured

    e = measured("data_impulses.mat")
    u = e.v_volt[:2400]
    y_ref = REFERENCES["coulomb_friction"](RIG.springs_n_m, HELD_PAST_FS, u, e.dt)
    y = EXTENSIONS["coulomb_friction"].simulate(RIG, HELD_PAST_FS, u, e.dt)
    assert np.max(np.abs(y - y_ref)) / COUNT < 0.5
    # the reference's released cart 2 moves on after sample 2266 (it stayed put before)
    assert abs(y_ref[2300, 1] - y_ref[2267, 1]) / COUNT > 50


def _friction_draws(n, rng):
    """Linear parameters within 10 % of Table 3, friction levels up to 1.6 N."""
    lin = TABLE3 * (1 + 0.1 * rng.uniform(-1, 1, (n, TABLE3.size)))
    fc = rng.uniform(0.0, 0.4, (n, 3))
    fs = fc + rng.uniform(0.0, 1.2, (n, 3)) * (rng.random((n, 3)) < 0.7)
    return np.concatenate([lin, fc, fs], axis=1)


def _count_kernel_calls(monkeypatch) -> list:
    """Patch the friction kernel to record what each call returns: (packed groups that
    took a sample again in sub-steps, samples a group at rest skipped)."""
    import bayesmodal.model.kernels.coulomb as nk

    returned = []
    compiled = nk.coulomb_kernel

    def counting(n, width, adaptive=True, **kw):
        kernel = compiled(n, width, adaptive, **kw)
        return lambda *args: returned.append(kernel(*args))

    monkeypatch.setattr(nk, "coulomb_kernel", counting)
    return returned


@pytest.mark.parametrize(("record", "most_retaken"),
                         [("data_impulses.mat", 0.35), ("data_sine_sweep_fast.mat", 0.75)])
def test_adaptive_friction_matches_corrected_sub_steps_everywhere(record, most_retaken,
                                                                   monkeypatch):
    """Taking quiet samples in one step changes the result by hundredths of a count
    against corrected sub-steps in every sample, and lane groups take only part of the
    samples again in sub-steps (a quarter of them on the impulses, half on the fast
    sweep, for this spread-out cloud of parameters); each lane's result does not depend
    on the rest of its batch."""
    from conftest import measured

    e = measured(record)
    u = e.v_volt[:3000]
    theta = _friction_draws(32, np.random.default_rng(5))
    ext = EXTENSIONS["coulomb_friction"]
    fixed = type(ext)(adaptive=False).simulate(RIG, theta, u, e.dt)
    retaken = _count_kernel_calls(monkeypatch)
    y = ext.simulate(RIG, theta, u, e.dt)
    monkeypatch.undo()
    # different paths, the same answer: hundredths of a count, up to the accuracy of
    # either where a stick-or-reverse decision is marginal
    diff = np.max(np.abs(y - fixed), axis=(1, 2)) / COUNT
    assert 0 < np.median(diff) < 0.02 and np.max(diff) < 0.5, diff
    for i in (0, 17, 31):
        np.testing.assert_array_equal(y[i], ext.simulate(RIG, theta[i], u, e.dt))
    # 32 lanes: at most two packed groups of 16 per sample
    share = retaken[0][0] / (2 * u.size)
    assert 0.0 < share < most_retaken, share


def test_friction_groups_at_rest_skip_samples_and_change_nothing(monkeypatch):
    """A group of lanes whose carts are all stuck below their static levels skips the
    sample; the output of a lane is bit for bit the same whether its group skips (16
    friction lanes together, or the lane alone) or cannot (a lane without friction in its
    group, which never rests)."""
    from conftest import measured

    e = measured("data_impulses.mat")
    u = e.v_volt[:4000]  # two pulses and the rest after them
    theta = _friction_draws(16, np.random.default_rng(8))
    no_friction = theta[:1].copy()
    no_friction[:, 9:] = 0.0
    counts = _count_kernel_calls(monkeypatch)
    ext = EXTENSIONS["coulomb_friction"]
    together = ext.simulate(RIG, theta, u, e.dt)
    mixed = ext.simulate(RIG, np.concatenate([no_friction, theta[:15]]), u, e.dt)
    alone = [ext.simulate(RIG, theta[i], u, e.dt) for i in (0, 6, 14)]
    monkeypatch.undo()
    rests = [c[1] for c in counts]
    # the friction group rests for part of the record, the group with a frictionless
    # lane never does, a lane alone rests at least as often as its group
    assert 0 < rests[0] < u.size and rests[1] == 0 and min(rests[2:]) >= rests[0], rests
    np.testing.assert_array_equal(together[:15], mixed[1:])
    for i, y in zip((0, 6, 14), alone, strict=True):
        np.testing.assert_array_equal(together[i], y)
    # at rest the positions do not move at all
    still = np.all(np.diff(together, axis=1) == 0.0, axis=(0, 2))
    assert still.sum() >= rests[0] - 1


@pytest.mark.slow
def test_friction_accuracy_over_random_levels_on_measured_inputs():
    """Random friction levels (up to 1.6 N) and linear parameters on three measured
    inputs: the default stays below half a count of the event-driven reference; one
    sub-step per sample (negative control) is not."""
    from conftest import measured

    theta = _friction_draws(6, np.random.default_rng(11))
    ext = EXTENSIONS["coulomb_friction"]
    worst_one = 0.0
    for record in ("data_impulses.mat", "data_steps.mat", "data_sine_sweep_fast.mat"):
        e = measured(record)
        u = e.v_volt[:2500]
        y = ext.simulate(RIG, theta, u, e.dt)
        y1 = type(ext)(n_sub=1).simulate(RIG, theta, u, e.dt)
        for i, th in enumerate(theta):
            y_ref = REFERENCES["coulomb_friction"](RIG.springs_n_m, th, u, e.dt)
            err = np.max(np.abs(y[i] - y_ref)) / COUNT
            assert err < 0.5, (record, i, err)
            worst_one = max(worst_one, np.max(np.abs(y1[i] - y_ref)) / COUNT)
    assert worst_one > 1.0, worst_one


def test_friction_kernel_leaves_out_the_rigs_absent_springs_bit_for_bit(monkeypatch):
    """On the three-cart chain carts 1 and 3 share no spring or damper: the four entries of
    ``G = [-K, -C]`` joining them are zero in every lane and the kernel leaves their
    products out, with the output bit for bit that of the kernel summing them all; leaving
    out an entry that is not zero (negative control) changes it."""
    import bayesmodal.model.kernels.coulomb as nk
    from bayesmodal.bench import rig_input

    theta = _friction_draws(16, np.random.default_rng(11))
    n, s = 3, 6
    joined = {(0, 2), (2, 0)}
    expected = sorted(i * s + j + off for i, j in joined for off in (0, n))
    u = rig_input(3000, DT)
    ext = EXTENSIONS["coulomb_friction"]
    seen = []
    real = nk.structural_zeros

    def spy(G):
        seen.append(real(G))
        return seen[-1]

    monkeypatch.setattr(nk, "structural_zeros", spy)
    left_out = ext.simulate(RIG, theta, u, DT)
    assert seen and seen[-1] == tuple(expected), seen
    monkeypatch.setattr(nk, "structural_zeros", lambda G: ())
    summed = ext.simulate(RIG, theta, u, DT)
    assert left_out.tobytes() == summed.tobytes()
    monkeypatch.setattr(nk, "structural_zeros", lambda G: (1,))  # k2 on cart 1: not zero
    wrong = ext.simulate(RIG, theta, u, DT)
    assert not np.array_equal(wrong, summed)
    with pytest.raises(ValueError, match="off-diagonal"):
        nk.coulomb_kernel(n, 16, g_zeros=(0,))


def test_friction_groups_without_a_stuck_cart_take_the_sliding_step_bit_for_bit(monkeypatch):
    """A group of lanes none of whose carts is stuck takes the whole-sample step without
    the held carts' ramp correction and tests (``GROUP_STEPS``): the output is bit for
    bit that of the kernel taking the full step everywhere; taking the sliding step in
    every group, stuck carts included (negative control), changes it."""
    import bayesmodal.model.kernels.coulomb as nk
    from bayesmodal.bench import rig_input
    from bayesmodal.model.rigs import load_rig

    # two carts (smaller kernels to compile than the chain's): 16 lanes, friction up to
    # 1.6 N on each cart
    rng = np.random.default_rng(12)
    two = load_rig("ecp210-2cart-frame-at-drive")
    base = np.array([6.223, 1.565, 1.461, 2.923, 1.806, 0.3])
    lin = base * rng.uniform(0.9, 1.1, (16, base.size))
    fc = rng.uniform(0.1, 0.8, (16, 2))
    theta = np.concatenate([lin, fc, fc + rng.uniform(0.0, 0.8, (16, 2))], axis=1)
    u = rig_input(3000, DT)
    ext = EXTENSIONS["coulomb_friction"]
    out = {}
    for steps in (("sliding", "held"), ("held",), ("sliding",)):
        monkeypatch.setattr(nk, "GROUP_STEPS", steps)
        nk.coulomb_kernel.cache_clear()
        out[steps] = ext.simulate(two, theta, u, DT)
    nk.coulomb_kernel.cache_clear()
    assert out[("sliding", "held")].tobytes() == out[("held",)].tobytes()
    assert not np.array_equal(out[("sliding",)], out[("held",)])
