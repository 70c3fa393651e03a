"""Posterior on the measured impulse record against the least-squares fit (slow).

What holds on these data, and what does not (see docs/inference.md, "Measured data"):

- posterior medians of the masses are within 2 % of LSQ for every damping and noise model;
- g_v is within 2 % of LSQ except for free damping with AR(1) noise (+2.5 %): the AR(1)
  likelihood with phi near 1 weights the data like velocities, which pulls g_v and the
  damping split away from the position-weighted LSQ optimum;
- the 90 % intervals of omega contain the LSQ frequencies only for proportional damping with
  white noise.  With AR(1) noise the intervals are narrower than the LSQ-to-posterior shift
  (the AR(1) innovations are still correlated, 0.8 at lag 1, so even this likelihood is
  overconfident); with free damping and white noise the LSQ optimum sits on the bound
  c12 = c23 = 0 while the posterior mass does not, which shifts omega_3.

The failing statements are kept as strict xfails so that a change in behaviour shows up.
"""

from __future__ import annotations

import numpy as np
import pytest

from bayesmodal.fit import fit_lsq
from bayesmodal.inference import credible_interval, propagate_modes, sample_posterior
from bayesmodal.model.system import LinearModel, Rig

pytestmark = pytest.mark.slow

COMBOS = [("free", "ar1"), ("proportional", "ar1"), ("free", "white"),
          ("proportional", "white")]
_CACHE: dict = {}


def _run(impulses, damping, noise):
    key = (damping, noise)
    if key not in _CACHE:
        model = LinearModel(Rig(), damping)
        lsq = fit_lsq(impulses, model)
        # 50 autocorrelation times after the default burn-in (a fifth): the corrected
        # snooker move's tau is 65-89 steps on these posteriors (the released move's
        # contraction made it look like 50)
        steps = 6000
        run = sample_posterior(impulses, model, noise=noise, n_walkers=32, n_steps=steps,
                               rng=1, start=lsq)
        _CACHE[key] = (model, lsq, run)
    return _CACHE[key]


def test_default_job_is_fast_and_converged(impulses):
    model, lsq, run = _run(impulses, "free", "ar1")
    assert run.chain.shape == (6000, 32, 15)
    assert run.elapsed_s < 180
    assert run.diagnostics.converged, run.diagnostics.problems
    assert run.evaluations_per_s > 32 * 6000 / 180


@pytest.mark.parametrize(("damping", "noise"), COMBOS)
def test_mass_medians_within_two_percent_of_lsq(impulses, damping, noise):
    model, lsq, run = _run(impulses, damping, noise)
    med = np.median(run.flat_draws[:, 1:4], axis=0)
    assert np.all(np.abs(med / lsq.theta[1:4] - 1) < 0.02), med / lsq.theta[1:4] - 1


@pytest.mark.parametrize(("damping", "noise"), [
    pytest.param("free", "ar1", marks=pytest.mark.xfail(
        strict=True, reason="AR(1) likelihood moves g_v +2.5 % from the LSQ optimum")),
    ("proportional", "ar1"), ("free", "white"), ("proportional", "white")])
def test_gv_median_within_two_percent_of_lsq(impulses, damping, noise):
    model, lsq, run = _run(impulses, damping, noise)
    med = np.median(run.flat_draws[:, 0])
    assert abs(med / lsq.theta[0] - 1) < 0.02, med / lsq.theta[0] - 1


_XF = pytest.mark.xfail(strict=True, reason="intervals narrower than the LSQ-posterior shift")


@pytest.mark.parametrize(("damping", "noise"), [
    pytest.param("free", "ar1", marks=_XF), pytest.param("proportional", "ar1", marks=_XF),
    pytest.param("free", "white", marks=_XF), ("proportional", "white")])
def test_omega_intervals_contain_lsq_frequencies(impulses, damping, noise):
    model, lsq, run = _run(impulses, damping, noise)
    ms = propagate_modes(model, run.flat_draws, methods=("eig",))
    ref = propagate_modes(model, lsq.theta[None], methods=("eig",)).omega_rad_s[0]
    iv = credible_interval(ms.omega_rad_s, 0.9)
    assert np.all(iv.contains(ref)), (ref, iv.lo, iv.hi)

