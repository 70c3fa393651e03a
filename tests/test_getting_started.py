"""docs/getting_started.md says true things about the record it fits.

The tutorial's record, ``data/two_carts.csv``, is made by ``data/make_two_carts.py``
from the rig of ``data/two_carts_rig.toml``; the page shows that description, quotes the
end of ``bayesmodal lsq``'s output and the modes ``bayesmodal modal`` prints, and says
the fit finds the parameters the record was made with.  tests/test_docs.py runs the
page's commands; this file checks what the page claims about them.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np

from bayesmodal.cli import main
from bayesmodal.data import load_experiment
from bayesmodal.fit import fit_lsq
from bayesmodal.model.rigs import load_rig
from bayesmodal.model.system import LinearModel

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "getting_started.md"
RECORD = REPO / "data" / "two_carts.csv"
RIG = REPO / "data" / "two_carts_rig.toml"


def _maker():
    spec = importlib.util.spec_from_file_location("make_two_carts",
                                                  REPO / "data" / "make_two_carts.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _fences(lang: str) -> list[tuple[int, str]]:
    """(offset in the page, body) of every ``lang`` fence of the page."""
    text = PAGE.read_text(encoding="utf-8")
    return [(m.start(), m.group(1))
            for m in re.finditer(rf"^```{lang}\n(.*?)^```$", text, re.M | re.S)]


def test_page_shows_the_rig_file():
    """The description on the page is the file the commands read."""
    shown = [body for _, body in _fences("toml")]
    assert RIG.read_text(encoding="utf-8") in shown


def test_record_is_what_its_script_makes():
    """The committed record is the script's output: the simulation's round-off (about
    1e-17 m on positions of 1e-2 m) is far below 1e-12 m, and the noise (1e-5 m) far
    above it, so a changed seed, rig or input fails."""
    made = _maker().make()
    rec = load_experiment(RECORD)
    np.testing.assert_array_equal(rec.v_volt, made.v_volt)
    np.testing.assert_allclose(rec.t_s, made.t_s, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec.y_m, made.y_m, rtol=0, atol=1e-12)


def _fit(rig):
    model = LinearModel(rig, "free")
    res = fit_lsq([load_experiment(RECORD)], model)
    truth = np.array([_maker().TRUE[n] for n in model.names])
    return res.theta - truth, res.stderr


def test_fit_finds_the_parameters_the_record_was_made_with(tmp_path):
    """The page: "the estimates are within a few standard errors of them".  The noise is
    white, so the Gauss-Newton standard errors are the estimator's own: 4 of them.
    Negative control: with spring k1 2 % stiffer than the record's rig the estimates
    move from the truth by more than 4 of those standard errors."""
    miss, se = _fit(load_rig(RIG))
    assert np.all(np.isfinite(se)) and np.all(np.abs(miss) < 4 * se), miss / se
    wrong = tmp_path / "rig.toml"
    wrong.write_text(RIG.read_text(encoding="utf-8").replace(
        "stiffness_n_m = 600.0", "stiffness_n_m = 612.0"), encoding="utf-8")
    miss_wrong, _ = _fit(load_rig(wrong))
    assert np.max(np.abs(miss_wrong) / se) > 4, miss_wrong / se


def test_quoted_output_is_what_the_commands_print(capsys):
    """The ``text`` block after the lsq command is the end of its output; the modes the
    page states are the ones ``bayesmodal modal`` prints."""
    text = PAGE.read_text(encoding="utf-8")
    at = text.index("bayesmodal lsq data/two_carts.csv --rig data/two_carts_rig.toml")
    quoted = next(body for pos, body in _fences("text") if pos > at)
    assert main(["lsq", str(RECORD), "--rig", str(RIG)]) == 0
    out = capsys.readouterr().out
    for line in quoted.splitlines():
        assert line in out.splitlines(), line
    assert main(["modal", "--rig", str(RIG), "--params",
                 "g_v=6,m1=1.6,m2=1.2,c1=3,c2=1.5,c12=0.3"]) == 0
    out = capsys.readouterr().out
    assert "11.1803   33.5410" in out and "0.6667   -2.0000" in out
    assert "11.18 and 33.54 rad/s" in text and "(1, 0.667)" in text and "(1, -2)" in text


def test_getting_started_comes_first():
    """README's "where to go next", the site's front page and its first toctree entry
    start with the tutorial."""
    for page in (REPO / "README.md", REPO / "docs" / "index.md"):
        links = [link for link in re.findall(r"\]\(([^)#\s]+)", page.read_text(encoding="utf-8"))
                 if link.endswith(".md")]  # pages, not pictures
        assert links and links[0].endswith("getting_started.md"), (page.name, links[:3])
    index = (REPO / "docs" / "index.md").read_text(encoding="utf-8")
    first = re.search(r"```\{toctree\}\n(?::.*\n)*\s*\n?(\S+)", index).group(1)
    assert first == "getting_started", first
