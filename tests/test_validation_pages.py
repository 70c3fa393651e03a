"""The Validation pages (docs/validation/) quote the studies' stored outputs exactly.

Every table of a Validation page sits between marker comments and is written by
docs/make_validation_pages.py from the outputs the studies store in docs/figures/, with
the studies' own rendering functions.  Here each table is rendered again from the stored
output and compared with the page, so a study rerun without regenerating the page, or a
number edited by hand, fails.  The studies themselves are not run (they take minutes to an
hour on the measured data); their outputs are committed files, so nothing here needs the
measured data.
"""

from __future__ import annotations

import ast
import importlib
import re
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
RUN = "run `python docs/make_validation_pages.py` and commit the pages"

sys.path.insert(0, str(DOCS))
gen = importlib.import_module("make_validation_pages")


def _page(name: str) -> str:
    return (DOCS / "validation" / name).read_text(encoding="utf-8")


@pytest.mark.parametrize("name", sorted(gen.BLOCKS))
def test_block_matches_the_stored_output(name):
    block = gen.BLOCKS[name]
    found = gen.blocks_in(_page(block.page))
    assert name in found, f"docs/validation/{block.page} has no block {name!r}: {RUN}"
    want = "\n" + block.render().rstrip() + "\n\n"
    assert found[name] == want, (
        f"docs/validation/{block.page}, block {name!r}, differs from "
        f"{', '.join(block.sources)}: {RUN}")


@pytest.mark.parametrize("page", sorted(p.name for p in (DOCS / "validation").glob("*.md")))
def test_every_marker_is_a_known_block_of_that_page(page):
    text = _page(page)
    opened = re.findall(r"<!-- generated: ([\w-]+) -->", text)
    closed = re.findall(r"<!-- end generated: ([\w-]+) -->", text)
    assert opened == closed, f"{page}: unbalanced markers {opened} / {closed}"
    assert len(opened) == len(set(opened)), f"{page}: a block appears twice"
    for name in opened:
        assert name in gen.BLOCKS, f"{page}: unknown block {name!r}"
        assert gen.BLOCKS[name].page == page, f"{page}: block {name!r} belongs elsewhere"


def test_sources_are_committed_outputs():
    for name, block in gen.BLOCKS.items():
        for src in block.sources:
            assert (DOCS / "figures" / src).is_file(), f"{name}: docs/figures/{src} missing"


def test_a_changed_number_is_caught():
    """Negative control: a page whose table differs from the stored output is rewritten
    by the generator, so the comparison above would fail on it."""
    name = "target-front"
    text = _page(gen.BLOCKS[name].page)
    body = gen.blocks_in(text)[name]
    m = re.search(r"\d+\.\d", body)
    assert m, "the block quotes no number"
    tampered = text.replace(body, body[:m.start()] + "0.0" + body[m.end():], 1)
    assert tampered != text
    assert gen.blocks_in(tampered)[name] != "\n" + gen.BLOCKS[name].render().rstrip() + "\n\n"
    assert gen.render_page(tampered) == text


def test_stamp_line_reports_a_stamp_or_says_not_recorded():
    s = {"date": "D", "commit": "abc1234", "machine": "M"}
    assert gen.stamp_line(s) == "Stamp: date D, commit abc1234, machine M."
    assert "not recorded" in gen.stamp_line(None)
    assert "commit not recorded" in gen.stamp_line({"date": "D", "commit": None,
                                                    "machine": "M"})


def test_stamp_has_date_commit_and_machine():
    stamp = importlib.import_module("_stamp").stamp()
    assert set(stamp) == {"date", "commit", "machine"}
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", stamp["date"])
    assert stamp["machine"]


#: the study scripts whose outputs the pages quote (docs/make_reference.py and
#: docs/make_bad_inputs_table.py write pages, docs/make_report_screenshot.py the README's
#: picture, not study outputs)
STUDIES = sorted(p.name for p in DOCS.glob("make_*.py")
                 if p.name not in {"make_reference.py", "make_bad_inputs_table.py",
                                   "make_validation_pages.py", "make_report_screenshot.py"})


@pytest.mark.parametrize("script", STUDIES)
def test_study_is_on_a_validation_page_and_stamps_its_output(script):
    pages = "".join(_page(p.name) for p in (DOCS / "validation").glob("*.md"))
    assert f"docs/{script}" in pages, f"no Validation page names docs/{script}"
    if script == "make_misfit_shares.py" or script in {
            "make_calibration_table.py", "make_noise_scale_table.py"}:
        # misfit shares only print; the leave-one-out studies stamp in docs/_measured.py
        src = (DOCS / ("_measured.py" if script != "make_misfit_shares.py" else script))
    else:
        src = DOCS / script
    calls = [n for n in ast.walk(ast.parse(src.read_text(encoding="utf-8")))
             if isinstance(n, ast.Call) and getattr(n.func, "id", None) == "stamp"]
    assert calls, f"{src.name} writes its output without stamp()"
