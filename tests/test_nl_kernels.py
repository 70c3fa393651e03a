"""Compiled helpers of the extension simulators, and the accuracy of the nonlinear schemes
at their default sub-steps (the speed of those defaults is measured by `bayesmodal bench`)."""

import numpy as np
import pytest
from conftest import TABLE3
from reference_sim import REFERENCES
from scipy.linalg import expm

from bayesmodal._nl_kernels import expm_batched, zoh
from bayesmodal.data import ECP_M_PER_COUNT as COUNT
from bayesmodal.extensions import EXTENSIONS
from bayesmodal.extensions._base import zoh_blocks
from bayesmodal.extensions._linear import linear_parts
from bayesmodal.system import Rig

RIG = Rig()
DT = 0.005


def test_expm_batched_matches_scipy_and_is_per_matrix():
    rng = np.random.default_rng(0)
    # norms from 1e-3 to about 40: no, one and several squarings in one batch
    Z = rng.normal(size=(7, 6, 6)) * np.array([1e-3, 0.1, 0.5, 1.0, 3.0, 8.0, 15.0])[:, None, None]
    E = expm_batched(Z)
    for z, e in zip(Z, E, strict=True):
        ref = expm(z)
        np.testing.assert_allclose(e, ref, rtol=0, atol=1e-13 * np.abs(ref).max())
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
        np.testing.assert_allclose(g, w, rtol=0, atol=1e-14 * np.abs(w).max())
    # a step per system: the first one zero (identity, no input response)
    Ah, G0 = zoh(p.A, p.force_inputs, np.array([0.0, 0.001, 0.004]))
    np.testing.assert_array_equal(Ah[0], np.eye(6))
    np.testing.assert_array_equal(G0[0], 0.0)
    np.testing.assert_allclose(Ah[2], expm(p.A[2] * 0.004), atol=1e-13)


def _pulses(N=700):
    u = np.zeros(N)
    u[1:10] = 3.0
    u[200:300] = 0.4
    u[400:410] = -2.0
    return u


# effect sizes other than the ones of test_extensions: a high static level, equal levels,
# a wide and a narrow gap with heavy and light motor
@pytest.mark.parametrize(
    ("name", "effect", "tol_counts"),
    [
        ("coulomb_friction", [0.3, 0.2, 0.25, 0.3, 0.35, 0.25], 0.5),
        ("coulomb_friction", [0.05, 0.05, 0.05, 0.2, 0.2, 0.2], 0.5),
        # cart 1 with a high static level that holds it while the others move: one
        # sub-step is 1.3 counts off here (and 450 on the measured impulse input)
        ("coulomb_friction", [0.245, 0.058, 0.167, 1.405, 0.305, 0.452], 0.5),
        ("backlash", [5e-4, 0.3], 0.75),
        ("backlash", [1e-4, 0.1], 0.75),
    ],
)
def test_default_substeps_are_accurate(name, effect, tol_counts):
    """The defaults (four sub-steps for friction, two for backlash) against the event-driven
    reference: well below an encoder count, and about four times better with twice the
    sub-steps (second order), so the default is not at the edge of a breakdown."""
    ext = EXTENSIONS[name]
    theta = np.r_[TABLE3, effect]
    u = _pulses()
    y_ref = REFERENCES[name](RIG.springs_n_m, theta, u, DT)
    err = np.max(np.abs(ext.simulate(RIG, theta, u, DT) - y_ref)) / COUNT
    finer = type(ext)(n_sub=2 * ext.n_sub)
    err_fine = np.max(np.abs(finer.simulate(RIG, theta, u, DT) - y_ref)) / COUNT
    assert err < tol_counts, err
    assert err_fine < err / 2.5, (err, err_fine)


#: A posterior draw of the friction model on the measured impulses (high static level on
#: cart 1), at which one sub-step per sample flips a stick decision on that record.
HIGH_FS = np.array([5.7389, 1.5861, 1.4983, 1.1223, 1.8443, 3.1e-3, 5e-4, 0.3735, 0.109,
                    0.2449, 0.0583, 0.1665, 1.405, 0.3054, 0.4516])


def test_default_friction_substeps_on_the_measured_impulse_input():
    from conftest import measured

    e = measured("data_impulses.mat")
    ext = EXTENSIONS["coulomb_friction"]
    y_ref = REFERENCES["coulomb_friction"](RIG.springs_n_m, HIGH_FS, e.v_volt, e.dt)
    err = np.max(np.abs(ext.simulate(RIG, HIGH_FS, e.v_volt, e.dt) - y_ref)) / COUNT
    assert err < 0.5, err
    # negative control: one sub-step per sample is hundreds of counts off on this record
    one = type(ext)(n_sub=1).simulate(RIG, HIGH_FS, e.v_volt, e.dt)
    assert np.max(np.abs(one - y_ref)) / COUNT > 50
