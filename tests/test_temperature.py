"""Temperature calibration by held-out coverage, against a conjugate model whose right
temperature is known in closed form.

Records ``r = 1..R`` of ``n`` samples each, ``y_rk = beta + b_r + e_rk`` with
``e ~ N(0, sigma^2)`` and a record offset ``b_r ~ N(0, s^2)`` (records that disagree).  The
model says ``y_rk = beta + e``, ``e ~ N(0, sigma0^2)`` with ``sigma0`` known and a flat prior.
Its tempered posterior on the ``m = (R - 1) n`` training samples of a fold is
``beta ~ N(ybar, T sigma0^2 / m)``, and a held-out sample's predictive is
``N(ybar, sigma0^2 (T / m + 1))``.  The held-out error ``y - ybar`` has variance
``c = sigma^2 + s^2 + (sigma^2 / n + s^2) / (R - 1)``, so the 90 % band is calibrated at

    T* = m (c / sigma0^2 - 1),

which is 1 for the well-specified model (``s = 0``, ``sigma = sigma0``).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from bayesmodal._errors import ConfigError
from bayesmodal.inference.temperature import calibrate, solve_temperature

Z90 = float(stats.norm.ppf(0.95))
R, N, SIGMA0 = 4, 5, 1.0
M = (R - 1) * N


def _data(sigma, s, n_rep, seed):
    rng = np.random.default_rng(seed)
    return (s * rng.standard_normal((n_rep, R, 1))
            + sigma * rng.standard_normal((n_rep, R, N)))


def _loro(data, t):
    """Coverage of the 90 % band per replicate and held-out record, shape (n_rep, R)."""
    tot = data.sum(axis=2)
    sd = SIGMA0 * np.sqrt(t / M + 1.0)
    cov = np.empty(tot.shape)
    for r in range(R):
        mean = (tot.sum(axis=1) - tot[:, r]) / M
        cov[:, r] = np.mean(np.abs(data[:, r, :] - mean[:, None]) <= Z90 * sd, axis=1)
    return cov


def _truth(sigma, s):
    c = sigma**2 + s**2 + (sigma**2 / N + s**2) / (R - 1)
    return c, M * (c / SIGMA0**2 - 1.0)


def _closed_form_coverage(t, c):
    return 2 * stats.norm.cdf(Z90 * np.sqrt(SIGMA0**2 * (t / M + 1.0) / c)) - 1


GRID = np.geomspace(0.25, 16.0, 19)


@pytest.mark.parametrize("sigma, s", [(1.0, 0.0), (1.0, 0.3), (1.1, 0.0)],
                         ids=["well_specified", "records_disagree", "noise_sd_too_small"])
def test_calibrated_temperature_matches_the_closed_form(sigma, s):
    c, t_star = _truth(sigma, s)
    data = _data(sigma, s, 20000, seed=int(100 * sigma + 10 * s))
    per_rep = {}

    def evaluate(t):
        per_rep[t] = _loro(data, t)
        cov = per_rep[t].mean(axis=0)[:, None]
        return cov, np.full_like(cov, 2 * Z90 * SIGMA0 * np.sqrt(t / M + 1) / np.sqrt(c))

    cal = calibrate(evaluate, GRID, target=0.9, criterion="mean", refine=True)
    assert cal.status == "bracketed"
    # Monte Carlo error of the mean coverage (replicates are independent), carried to T
    # through the closed-form slope dC/dT at T*; plus the error of interpolating the exact
    # curve on the same grid
    cov_rep = per_rep[cal.temperature].mean(axis=1)
    se_cov = cov_rep.std(ddof=1) / np.sqrt(cov_rep.size)
    slope = stats.norm.pdf(Z90) * Z90 * SIGMA0**2 / (M * c)
    interp, _ = solve_temperature(GRID, _closed_form_coverage(GRID, c), 0.9)
    tol = 4 * se_cov / slope + abs(interp - t_star)
    assert abs(cal.temperature - t_star) < tol, (cal.temperature, t_star, tol)
    # the coverage measured at the chosen temperature is nominal within its error
    assert abs(cov_rep.mean() - 0.9) < 4 * se_cov + slope * abs(interp - t_star)
    json.dumps(cal.to_dict())  # serialisable as it is written into crossval.json
    assert "chosen" in cal.table()


def test_negative_control_excludes_the_misspecified_answer():
    """The well-specified records do not give the temperature of disagreeing records."""
    c, _ = _truth(1.0, 0.0)
    _, t_bad = _truth(1.0, 0.3)
    data = _data(1.0, 0.0, 20000, seed=7)
    cal = calibrate(lambda t: (_loro(data, t).mean(axis=0)[:, None],) * 2, GRID,
                    refine=False)
    slope = stats.norm.pdf(Z90) * Z90 * SIGMA0**2 / (M * c)
    se_cov = _loro(data, 1.0).mean(axis=1).std(ddof=1) / np.sqrt(data.shape[0])
    assert abs(cal.temperature - t_bad) > 4 * se_cov / slope


def test_solver_statuses_and_first_crossing():
    assert solve_temperature([1, 10], [0.95, 0.97]) == (1.0, "above")
    assert solve_temperature([1, 10], [0.5, 0.6]) == (10.0, "below")
    # never reached and falling (tempered noise parameters narrowing the band): the best
    assert solve_temperature([1, 10, 100], [0.83, 0.86, 0.80]) == (10.0, "below")
    # a dip: the first crossing, between the neighbours that bracket the target
    t, st = solve_temperature([1, 10, 100], [0.85, 0.80, 0.95], 0.9)
    assert st == "bracketed"
    assert t == pytest.approx(10 ** (1 + (0.9 - 0.80) / (0.95 - 0.80)), rel=1e-12)


def test_worst_criterion_follows_the_lowest_record():
    # record 0 reaches 0.9 only at T = 100, record 1 is always above
    cov = {1.0: [[0.6], [0.99]], 10.0: [[0.8], [0.99]], 100.0: [[0.9], [0.99]]}

    def ev(t):
        return np.array(cov[t]), np.ones((2, 1))

    mean = calibrate(ev, list(cov), criterion="mean", refine=False)
    worst = calibrate(ev, list(cov), criterion="worst", refine=False)
    assert mean.temperature == pytest.approx(10 ** (1 + (0.9 - 0.895) / (0.945 - 0.895)))
    assert worst.temperature == pytest.approx(100.0)


@pytest.mark.parametrize("kw, match", [
    ({"temperatures": [0.0, 1.0]}, "temperatures must be finite and > 0"),
    ({"target": 1.5}, "target coverage must be in"),
    ({"criterion": "median"}, "criterion must be one of"),
])
def test_bad_settings_name_the_fix(kw, match):
    args = {"temperatures": [1.0, 10.0], **kw}
    with pytest.raises(ConfigError, match=match):
        calibrate(lambda t: (np.ones((1, 1)), np.ones((1, 1))), **args)
