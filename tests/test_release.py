"""A hand-released free decay (``--release auto``, ``--rest-offset final``).

The truth: one cart on a known spring, pushed by hand to 10 mm, held, released between
two samples, decaying freely; every position read 1.5 mm off (the rest offset dry
friction leaves, or an encoder zeroed away from equilibrium), with seeded white noise.
The release is found within one sample step and ``bayesmodal lsq`` recovers the mass and
damper within the fit's standard errors.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest
import scipy.linalg

from bayesmodal import ConfigError, DataError
from bayesmodal._release import final_rest, find_release
from bayesmodal.cli import main
from bayesmodal.data import Experiment, load_experiment, save_csv
from bayesmodal.model.system import Cart, Drive, LinearModel, Rig, Spring
from bayesmodal.reading import ReadOptions

K1 = 396.0
GAIN = 6.2
TRUTH = {"m1": 1.5, "c1": 5.0}
DT = 0.005
N = 1800
T_RELEASE = 1.7345   # between samples 346 and 347
HELD_M = 0.010
OFFSET_M = 0.0015
SIGMA_M = 2e-5
K_SE = 4.0

RIG_TOML = f"""name = "one cart, hand-released"
[[carts]]
name = "1"
[[springs]]
name = "k1"
between = ["1", "frame"]
stiffness_n_m = {K1}
[drive]
carts = ["1"]
gain_n_v = {GAIN}
"""


def _decay(*, push: bool = True, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and positions (m, shape (N, 1)) of the push, hold, release and decay.

    The free response after the release is the exact ``expm(A tau) [h, 0]`` at the
    samples' own delays ``tau = t - T_RELEASE``; the push is a smooth step from 0.5 to
    1 s (or, without it, the record starts held).
    """
    rig = Rig(carts=(Cart("1"),), springs=(Spring("1", "frame", K1),), drive=(Drive("1"),),
              gain_n_v=GAIN)
    a = LinearModel(rig, "free").state_space(np.array([TRUTH["m1"], TRUTH["c1"]]))[0]
    t = np.arange(N) * DT
    u = np.clip((t - 0.5) / 0.5, 0.0, 1.0) if push else np.ones(N)
    x = HELD_M * u**2 * (3 - 2 * u)
    after = t > T_RELEASE
    step = scipy.linalg.expm(a * DT)
    state = scipy.linalg.expm(a * (t[after][0] - T_RELEASE)) @ [HELD_M, 0.0]
    for k in np.flatnonzero(after):
        x[k] = state[0]
        state = step @ state
    rng = np.random.default_rng(seed)
    return t, x[:, None] + OFFSET_M + SIGMA_M * rng.standard_normal((N, 1))


@pytest.mark.parametrize("push", [True, False])
def test_the_release_is_found_within_one_step(push):
    for seed in range(5):
        t, y = _decay(push=push, seed=seed)
        k0 = find_release("rec", y)
        assert abs(t[k0] - T_RELEASE) <= DT, (seed, k0)


def test_the_final_rest_is_the_offset():
    t, y = _decay()
    k0 = find_release("rec", y)
    # the mean of the last 10 % of the samples: within 4 of its standard errors
    n = round(0.1 * (N - k0))
    assert abs(final_rest("rec", y[k0:])[0] - OFFSET_M) < K_SE * SIGMA_M / np.sqrt(n)
    with pytest.raises(DataError, match=r"rec: output 1 still moves over the last 10% of "
                       r"the record .* record until the carts stop, or drop --rest-offset"):
        final_rest("rec", y[: int(T_RELEASE / DT) + 200])


def _lsq(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["lsq", *argv, "--json"])
    assert code == 0, err.getvalue()
    return json.loads(out.getvalue())


def test_lsq_of_a_hand_released_decay_recovers_the_truth(tmp_path):
    t, y = _decay(seed=11)
    path = tmp_path / "decay.csv"
    save_csv(Experiment(t, np.zeros(N), y, name="decay"), path)
    rig = tmp_path / "rig.toml"
    rig.write_text(RIG_TOML)
    js = _lsq(str(path), "--rig", str(rig), "--release", "auto", "--rest-offset", "final")
    assert js["identified"] is True, js["reason"]
    for name, value in TRUTH.items():
        assert abs(js["parameters"][name] - value) < K_SE * js["stderr"][name], (name, js)
    # the residual is the noise: a chi-square of n samples has a relative spread sqrt(2/n)
    n = N - int(T_RELEASE / DT)
    assert abs(js["sigma_m"][0] / SIGMA_M - 1) < K_SE * np.sqrt(0.5 / n)
    # negative control: the offset left in, the linear model cannot reach it, and lsq
    # says the fit is no answer
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["lsq", str(path), "--rig", str(rig), "--release", "auto", "--json"])
    assert code == 2
    assert "decay.csv: not identified: the model explains less than" in err.getvalue()
    assert json.loads(out.getvalue())["sigma_m"][0] > 0.5 * OFFSET_M


def test_the_cut_record_starts_at_the_release(tmp_path):
    t, y = _decay()
    path = tmp_path / "decay.csv"
    save_csv(Experiment(t, np.zeros(N), y, name="decay"), path)
    e = load_experiment(path, options=ReadOptions(release="auto", rest_offset="final"))
    assert abs(e.t_s[0] - T_RELEASE) <= DT
    assert abs(e.y_m[0, 0] - HELD_M) < 5 * SIGMA_M
    # a window first, then the release within it
    w = load_experiment(path, options=ReadOptions(t_start=1.0, t_end=6.0, release="auto"))
    assert w.t_s[0] == e.t_s[0] and w.t_s[-1] == pytest.approx(6.0)


def test_a_driven_record_or_no_hold_is_refused(tmp_path):
    t, y = _decay()
    path = tmp_path / "driven.csv"
    save_csv(Experiment(t, 0.5 * (t > 1), y, name="driven"), path)
    with pytest.raises(DataError, match=r"driven.csv: the input is not zero \(up to 0.5 V\); "
                       r"--release auto is for a cart released by hand with no input"):
        load_experiment(path, options=ReadOptions(release="auto"))
    swing = tmp_path / "swing.csv"
    save_csv(Experiment(t[400:], np.zeros(N - 400), y[400:], name="swing"), swing)
    with pytest.raises(DataError, match=r"swing.csv: output 1 is held for \d+ samples before "
                       r"it moves; --release auto needs a hold of at least 12 samples"):
        load_experiment(swing, options=ReadOptions(release="auto"))


def test_options_are_checked():
    with pytest.raises(ConfigError, match="release must be 'auto'"):
        ReadOptions(release="yes")
    with pytest.raises(ConfigError, match=r"rest_offset must be one of \('none', 'initial'"):
        ReadOptions(rest_offset="first")
