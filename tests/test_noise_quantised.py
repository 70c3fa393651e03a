"""Interval-censored likelihood of rounded readings (``inference.noise.quantised``).

Closed forms: the density of a rounded Gaussian reading is the normal probability of its
step over the step; it sums to 1 over the steps; it tends to the Gaussian density when the
noise is large and to 1/q inside the step when it is small.  Known truth: ``shift`` and
``sigma`` recovered from rounded white noise by maximum likelihood within their standard
errors, with the Gaussian model's misplaced estimate as control.
"""

import numpy as np
import pytest
from scipy import optimize
from scipy.stats import norm

from bayesmodal import DataError
from bayesmodal.data import Experiment
from bayesmodal.inference.noise import QuantisedNoise, WhiteNoise
from bayesmodal.inference.noise.quantised import log_step_probability
from bayesmodal.inference.noise_spec import parse_noise

Q = 2.2e-5  # an encoder's count, m
EPS = np.finfo(float).eps


def _model(q=(Q,)):
    return QuantisedNoise(quantum_m=np.asarray(q, float))


def test_the_density_is_the_probability_of_the_step_over_the_step():
    r = np.linspace(-3 * Q, 3 * Q, 13)[None, :, None]
    sigma, shift = 0.4 * Q, 0.2
    p = np.exp(_model().pointwise(r, np.array([[sigma, shift]])))[0, :, 0]
    c = r[0, :, 0] - shift * Q
    ref = (norm.cdf((c + Q / 2) / sigma) - norm.cdf((c - Q / 2) / sigma)) / Q
    assert np.allclose(p, ref, rtol=1e3 * EPS, atol=1e3 * EPS / Q)


def test_the_probabilities_of_all_steps_sum_to_one():
    # readings are whole steps: the residual of a fixed output x runs over k q - x
    x = 0.37 * Q
    r = (np.arange(-40, 41) * Q - x)[None, :, None]
    p = np.exp(_model().pointwise(r, np.array([[0.8 * Q, -0.3]])))[0, :, 0] * Q
    assert abs(p.sum() - 1.0) <= 1e3 * EPS


def test_limits_gaussian_for_large_noise_and_flat_step_for_small():
    rng = np.random.default_rng(0)
    r = rng.normal(size=(1, 100, 1)) * 1e-3
    big = _model().pointwise(r, np.array([[1e-3, 0.0]])).sum()
    white = WhiteNoise().pointwise(r, np.array([[1e-3]])).sum()
    # first order in (q / sigma)^2: each term differs by about (q / sigma)^2 / 24
    assert abs(big - white) <= 100 * (Q / 1e-3) ** 2
    inside = np.array([[[-0.49 * Q], [0.0], [0.49 * Q]]])
    small = np.exp(_model().pointwise(inside, np.array([[1e-9, 0.0]])))
    assert np.allclose(small * Q, 1.0, atol=1e3 * EPS)
    outside = _model().pointwise(np.array([[[0.6 * Q]]]), np.array([[1e-9, 0.0]]))
    assert outside[0, 0, 0] < -1e3  # out of the step: vanishing probability
    assert log_step_probability(np.array([-60.0]), np.array([-59.0]))[0] > -np.inf


def test_an_unrounded_output_is_gaussian():
    rng = np.random.default_rng(1)
    r = rng.normal(size=(1, 50, 2))
    p = np.array([[1.0, 2.0, 0.1, 0.0]])
    a = QuantisedNoise(quantum_m=np.array([0.0, 0.0])).pointwise(r, p)
    assert np.allclose(a, WhiteNoise().pointwise(r, p[:, :2]), rtol=1e3 * EPS)


def test_maximum_likelihood_recovers_the_shift_and_sigma_of_rounded_noise():
    """Rounded readings of a ramp (the rounding error runs over the whole step) with the
    zero at 0.3 steps and noise 0.2 steps before rounding; the Gaussian model reads the
    shift as the mean, the control."""
    rng = np.random.default_rng(2)
    n, c, sigma = 4000, 0.3, 0.2 * Q
    x = np.linspace(0.0, 300 * Q, n)
    # zeroed where the true position was c steps into a count (tests/accel_reference.py)
    y = (np.round((x + rng.normal(0, sigma, n)) / Q + c) - np.round(c)) * Q
    r = (y - x)[None, :, None]
    m = _model()

    def nll(z):
        return -m.pointwise(r, np.array([[np.exp(z[0]) * Q, z[1]]])).sum()

    z = optimize.minimize(nll, [np.log(0.5), 0.0], method="Nelder-Mead",
                          options=dict(xatol=1e-8, fatol=1e-10, maxiter=4000)).x
    d = 1e-4  # curvature by central differences
    f0 = nll(z)
    curv = [(nll(z + d * e) - 2 * f0 + nll(z - d * e)) / d**2 for e in np.eye(2)]
    se = 1.0 / np.sqrt(np.array(curv))
    assert abs(z[1] - c) <= 4 * se[1], (z, se)
    assert abs(np.exp(z[0]) * Q - sigma) <= 4 * se[0] * sigma, (z, se)
    # control: the Gaussian model, fitted to the same residuals, reads the rounding as
    # noise: its sigma is the rounding's q / sqrt(12) and more, far beyond sigma's error
    gauss_sigma = np.std(r)
    assert gauss_sigma - sigma > 10 * se[0] * sigma


def test_for_record_reads_the_steps_and_the_spec_names_it():
    t = np.arange(200) * 0.004
    y = np.column_stack([np.round(1e-3 * np.sin(t) / Q) * Q, np.sin(t)])
    e = Experiment(t, np.zeros_like(t), y)
    m = QuantisedNoise().for_record(e)
    assert np.isclose(m.quantum_m[0], Q, rtol=1e-6) and m.quantum_m[1] == 0.0
    assert parse_noise("quantised").kind == "quantised"
    with pytest.raises(DataError, match="for_record"):
        QuantisedNoise().pointwise(np.zeros((1, 3, 1)), np.array([[1.0, 0.0]]))


def test_invalid_rows_get_minus_inf():
    out = _model().pointwise(np.zeros((3, 4, 1)), np.array([[Q, 0.0], [-Q, 0.0], [Q, 0.7]]))
    assert np.all(np.isfinite(out[0])) and np.all(out[1:] == -np.inf)


def test_the_prior_reaches_zero_noise_before_the_rounding():
    """An encoder may have no noise before its count: the prior of ``sigma`` is uniform
    from zero (density falling as ``sigma`` in ``log sigma``), not log-uniform above the
    other noise models' floor of 1e-7 m, where a posterior of noise-free counts piled up.
    Control: the Gaussian models keep that floor."""
    from bayesmodal.inference.noise.base import SIGMA_PRIOR

    pri = _model().priors(1)
    tiny = np.array([[1e-3 * SIGMA_PRIOR.lo, 0.0]])  # far below the old floor
    assert np.isfinite(pri.log_prior(tiny))[0]
    assert not np.isfinite(WhiteNoise().priors(1).log_prior(tiny[:, :1]))[0]
    # sampled in log sigma: the density there falls as sigma towards zero
    z = pri.to_sampling(np.array([[1e-9, 0.0], [1e-10, 0.0]]))
    dens = pri.log_prior_z(z)
    assert np.isclose(dens[0] - dens[1], np.log(10.0), rtol=1e3 * EPS)
