"""``bayesmodal modal``: springs shown and overridable, one-line errors naming the parameter."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.linalg import eigh

from bayesmodal.cli import main
from bayesmodal.model.system import Rig

EPS = np.finfo(float).eps
MASSES = np.array([1.565, 1.461, 1.146])  # report Table 3


def _omega(springs):
    """Undamped natural frequencies, rad/s, of the three-cart chain (independent of the
    package: the generalized symmetric eigenproblem K u = w^2 M u)."""
    k1, k2, k3 = springs
    K = np.array([[k1, -k1, 0], [-k1, k1 + k2, -k2], [0, -k2, k2 + k3]])
    w2, _ = eigh(K, np.diag(MASSES))
    return np.sqrt(w2), np.linalg.cond(K)


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_springs_are_shown_and_can_be_overridden(capsys):
    default = list(Rig().springs_n_m)
    out = _json(capsys, ["modal", "--json"])
    assert out["springs_n_m"] == default
    w0, cond0 = _omega(default)
    np.testing.assert_allclose(out["methods"]["eigen"]["omega_rad_s"], w0,
                               rtol=100 * cond0 * EPS)
    springs = [default[0], 900.0, default[2]]
    out = _json(capsys, ["modal", "--params", "k2=900", "--json"])
    assert out["springs_n_m"] == springs
    w, cond = _omega(springs)
    np.testing.assert_allclose(out["methods"]["eigen"]["omega_rad_s"], w,
                               rtol=100 * cond * EPS)
    assert not np.allclose(w, w0, rtol=1e-3)  # negative control: k2 changed the modes
    assert main(["modal", "--params", "k2=900"]) == 0
    text = capsys.readouterr().out
    assert f"springs: k1 = {default[0]:.4g} N/m, k2 = 900 N/m, k3 = {default[2]:.4g} N/m" in text


@pytest.mark.parametrize("params,name", [("m1=-1", "m1"), ("k3=0", "k3"), ("c12=nan", "c12"),
                                         ("g_v=-6", "g_v")])
def test_impossible_value_is_one_line_naming_the_parameter(capsys, params, name):
    assert main(["modal", "--params", params]) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and cap.out == ""
    assert lines[0].startswith(f"bayesmodal modal: error: parameter {name} = ")
    assert "{" not in lines[0]  # not the whole parameter dictionary
    assert f"the default is {name}=" in lines[0]


def test_unknown_name_lists_the_springs_too(capsys):
    assert main(["modal", "--params", "k4=100"]) == 2
    err = capsys.readouterr().err
    assert "k1, k2, k3" in err and len(err.strip().splitlines()) == 1
