"""A layout the data cannot identify is refused before any fitting.

Two springs in parallel on one cart (one to the frame, known; one to a clamped wall,
unknown) do not fix the scale: every mass, damper and the gain scaled together, the
unknown spring absorbs the change and the motion stays the same, so a fit returns one
point of a line of equal answers (``g_v = 4.0 +- 10`` for 6.2).
``structure.check_structure`` finds the unseen direction from the rank of the
sensitivity of the transfer function (and of the free response, for estimated initial
states) and ``fit_lsq`` refuses the rig with the parameters that move together and the
fix.  The preset rigs are accepted
(negative control), except one cart with proportional damping, where ``ca`` and ``cb``
fix one damping between them.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import run_cli as _cli

from bayesmodal import ModelError
from bayesmodal.data import Experiment, save_csv
from bayesmodal.fit import fit_lsq
from bayesmodal.model.rigs import PRESETS, load_rig
from bayesmodal.model.simulate import simulate_linear
from bayesmodal.model.system import LinearModel
from bayesmodal.structure import RANK_TOL, check_structure, structure

PARALLEL = """\
name = "one cart on two springs in parallel"
clamped = ["wall"]

[[carts]]
name = "1"

[[carts]]
name = "wall"

[[springs]]
name = "k_a"
between = ["1", "frame"]
stiffness_n_m = 396.0

[[springs]]
name = "k_b"
between = ["1", "wall"]
stiffness_n_m = 300.0
known = false

[drive]
carts = ["1"]

[[sensors]]
cart = "1"
unit = "m"
"""


def _parallel(tmp_path):
    rig_path = tmp_path / "parallel.toml"
    rig_path.write_text(PARALLEL)
    model = LinearModel(load_rig(str(rig_path)), "free")
    t = np.arange(1000) * 0.005
    v = 0.5 * ((t % 2.0) < 1.0)
    y = simulate_linear(model, [6.2, 1.5, 2.0, 250.0], v, 0.005)
    save_csv(Experiment(t, v, y), tmp_path / "rec.csv")
    return rig_path, model, Experiment(t, v, y)


def test_parallel_springs_are_refused_before_any_fitting(tmp_path, monkeypatch):
    _, model, exp = _parallel(tmp_path)
    st = structure(model)
    assert st.rank == st.n_params - 1 and st.singular_values[-1] < RANK_TOL
    assert st.together == ("g_v", "m1", "c1", "k_b")

    def no_fit(*args, **kwargs):  # the refusal comes before the optimiser
        raise AssertionError("least squares was called")

    monkeypatch.setattr("bayesmodal.fit._engine.least_squares", no_fit)
    with pytest.raises(ModelError, match=r"the rig's unknowns cannot be identified from any "
                       r"record: g_v, m1, c1, k_b can change together without changing the "
                       r"motion at the sensors \(structural rank 3 of 4\); make one of them "
                       r"known in the rig"):
        fit_lsq(exp, model)
    # a free decay with its initial state estimated cannot either
    with pytest.raises(ModelError, match="structural rank"):
        check_structure(model, [Experiment(exp.t_s, 0 * exp.v_volt, exp.y_m)], "estimate")


@pytest.mark.parametrize("command", ["lsq", "sample", "crossval", "diagnose"])
def test_the_commands_refuse_it_with_one_line(tmp_path, command, monkeypatch):
    rig_path, _, _ = _parallel(tmp_path)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "rec2.csv").write_bytes((tmp_path / "rec.csv").read_bytes())
    extra = {"sample": ["--out", "out", "--steps", "20", "--walkers", "16", "--quiet",
                        "--no-plots"],
             "crossval": ["--out", "out", "--steps", "20", "--walkers", "16", "--quiet"],
             "diagnose": ["--no-posterior", "--null", "0"]}.get(command, [])
    data = ["rec.csv", "rec2.csv"] if command == "crossval" else ["rec.csv"]
    code, out, err = _cli([command, *data, "--rig", str(rig_path), *extra])
    assert code == 2 and out == "", err
    assert len(err) == 1 and err[0].startswith(f"bayesmodal {command}: error: the rig's "
                                               "unknowns cannot be identified"), err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", PRESETS)
@pytest.mark.parametrize("damping", ["free", "proportional"])
def test_the_preset_rigs_are_accepted(name, damping):
    model = LinearModel(load_rig(name), damping)
    t = np.arange(50) * 0.01
    forced = [Experiment(t, np.ones_like(t), np.ones((50, model.n_outputs)))]
    if load_rig(name).n_carts == 1 and damping == "proportional":
        # one mode: C = ca m + cb k is one damper, ca and cb cannot both be fitted
        with pytest.raises(ModelError, match=r"ca, cb can change together.*use free "
                           r"damping \(--damping free\)"):
            check_structure(model, forced)
        return
    st = structure(model, forced=True, free_records=1)
    assert st.identified and st.singular_values[-1] > 1e-3   # far from the tolerance
    check_structure(model, forced)
    check_structure(model, forced, "estimate")
