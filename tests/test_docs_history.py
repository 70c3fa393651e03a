"""The pages a user reads state facts, not history.

README.md and docs/**/*.md say what the package does, the numbers it produces and the
command that produces them.  When something was changed, and in which piece of work, is
CHANGELOG.md's business (excluded here, with the built site in docs/_build).  These tests
scan the pages for

- dated narrative: "since 25 Nov", "before (24 Nov, ...)", "on 24 Nov 2026", "Run on ",
  a day and month in prose ("24 Nov 2026"), an ISO date (2026-11-24);
- narration of the work itself: "session", "round of work", "this round", "the lead",
  "an earlier version of this page", an ordinal such as "ninth" or "12th" before
  "session", "run" or "round";

with a negative control (the patterns flag a sample that narrates and pass a clean
sentence), an explicit allow-list for legitimate matches (each with its reason), and a
check that every relative link of README.md, docs/*.md and docs/validation/*.md names an
existing file.  The stamp lines of the Validation pages' generated tables carry the date
a study's output was made, read from that output (docs/make_validation_pages.py): an
ISO date is data there, and only there.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

_MONTH = (r"(?:Jan(?:uary)?|Feb(?:ruary)?|Mar(?:ch)?|Apr(?:il)?|May|June?|July?|"
          r"Aug(?:ust)?|Sep(?:t|tember)?|Oct(?:ober)?|Nov(?:ember)?|Dec(?:ember)?)")
_ORDINAL = (r"(?:fifth|sixth|seventh|eighth|ninth|tenth|eleventh|twelfth|thirteenth|"
            r"fourteenth|fifteenth|sixteenth|seventeenth|eighteenth|nineteenth|"
            r"twentieth|\d+(?:st|nd|rd|th))")

#: name -> pattern.  Each names one way a page can narrate history.
PATTERNS: dict[str, re.Pattern] = {
    "since a date": re.compile(rf"\bsince (?:the )?\d{{1,2}} {_MONTH}\b", re.I),
    "before (a date": re.compile(rf"\bbefore \(\d{{1,2}} {_MONTH}\b", re.I),
    "on a date": re.compile(rf"\bon \d{{1,2}} {_MONTH}(?: \d{{4}})?\b", re.I),
    "Run on": re.compile(r"\bRun on\b"),
    "day and month": re.compile(rf"\b\d{{1,2}} {_MONTH}\b(?!-)"),
    "month and year": re.compile(rf"\b{_MONTH} 20\d\d\b"),
    "ISO date": re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b"),
    "session": re.compile(r"\bsessions?\b", re.I),
    "round of work": re.compile(r"\bround of work\b|\bthis round\b|\b(?:next|previous|"
                                r"last|later|earlier) round\b", re.I),
    "the lead": re.compile(r"\bthe lead(?:'s)?\b(?! (?:time|screw|of))", re.I),
    "agents": re.compile(r"\b(?:sub-?)?agents?\b", re.I),
    "earlier version": re.compile(r"\b(?:an?|the) (?:earlier|previous|old|former) "
                                  r"(?:version|revision) of\b", re.I),
    "ordinal session/run": re.compile(rf"\b{_ORDINAL}\s+(?:session|run|round)s?\b", re.I),
}

#: (page relative to the repository, pattern name, text on the line, why it is legitimate)
ALLOWED: list[tuple[str, str, str, str]] = [
    ("docs/uncertainty.md", "month and year", "December",
     "when emcee fixed its snooker move upstream (pull request #531): a fact about the "
     "dependency a user needs to judge their emcee version, not this project's history"),
]


def pages() -> list[Path]:
    """README.md and every Markdown page under docs/ except the built site."""
    out = [REPO / "README.md"]
    out += sorted(p for p in (REPO / "docs").rglob("*.md")
                  if "_build" not in p.relative_to(REPO / "docs").parts)
    return [p for p in out if p.name != "CHANGELOG.md"]


def narration(text: str) -> list[tuple[int, str, str]]:
    """(line number, pattern name, matched text) of every narrating passage of ``text``.

    A passage broken over two lines ("since 25\\nNov") is found too: each line is read
    joined with the next."""
    lines = text.splitlines()
    hits, seen = [], set()
    for n, ln in enumerate(lines, 1):
        joined = ln + " " + (lines[n].lstrip() if n < len(lines) else "")
        for name, pat in PATTERNS.items():
            for m in pat.finditer(joined):
                if m.start() >= len(ln):     # wholly on the next line: found there
                    continue
                key = (n, name, m.start())
                if key not in seen:
                    seen.add(key)
                    hits.append((n, name, m.group(0)))
    return hits


def _allowed(page: str, name: str, line: str) -> bool:
    return any(page == p and name == k and t in line for p, k, t, _ in ALLOWED)


_STAMP_LINE = re.compile(r"^Stamp(?: of [^:]+)?: date \d{4}-\d\d-\d\dT[\d:]+Z, commit ")


def _generated_stamp_lines(page: str, lines: list[str]) -> set[int]:
    """1-based numbers of the stamp lines inside generated blocks of a Validation page."""
    if not page.startswith("docs/validation/"):
        return set()
    out, inside = set(), False
    for n, ln in enumerate(lines, 1):
        if ln.startswith("<!-- generated: "):
            inside = True
        elif ln.startswith("<!-- end generated: "):
            inside = False
        elif inside and _STAMP_LINE.match(ln):
            out.add(n)
    return out


def test_pages_do_not_narrate_history():
    problems = []
    for page in pages():
        rel = page.relative_to(REPO).as_posix()
        lines = page.read_text(encoding="utf-8").splitlines()
        stamps = _generated_stamp_lines(rel, lines)
        for n, name, found in narration("\n".join(lines)):
            if _allowed(rel, name, lines[n - 1] + " " + (lines[n] if n < len(lines) else "")):
                continue
            if name == "ISO date" and n in stamps:
                continue
            problems.append(f"{rel}:{n}: {name}: {found!r}")
    assert not problems, (
        "pages narrate history (state the fact in the present tense; what changed when "
        "belongs in CHANGELOG.md):\n" + "\n".join(problems))


NARRATING = """\
Run on 24 Nov 2026 (three runs, load 3.1): 12.8x.
Since 25 Nov, the LuGre default is 4 sub-steps.
Before (24 Nov, one noise level per record) the band covered 0.62.
Measured on 23 Nov 2026 evening, then again on 2026-11-25.
The ninth session's fit and the lead's run agree.
This round of work moved the figure; a later session kept it.
In the twelfth run the chain converged.
The earlier version of this page reported +11.3.
Measured in November 2026 beside other agents' jobs.
"""

CLEAN = """\
`bayesmodal bench --json` prints the Coulomb kernel's cost: 12.8 times the linear
simulator on the rig-like input (three rounds of the bench, median of the per-round
ratios).  The default is 4 sub-steps; the first run compiles the kernels, later runs
load them from the cache.  Table 4 gives zeta to 4 decimals at 5 ms.
"""


def test_patterns_flag_narration_and_pass_a_clean_text():
    """Negative control: every narrating line of the sample is flagged, every pattern
    fires at least once, and the clean sentence passes."""
    hits = narration(NARRATING)
    flagged = {n for n, _, _ in hits}
    assert flagged == set(range(1, len(NARRATING.splitlines()) + 1)), hits
    assert {name for _, name, _ in hits} == set(PATTERNS), \
        set(PATTERNS) - {name for _, name, _ in hits}
    assert narration(CLEAN) == []


def test_only_generated_stamp_lines_may_carry_a_date():
    """A stamp line is exempt inside a Validation page's generated block, not outside it,
    and not on another page."""
    stamp = "Stamp: date 2026-01-02T03:04:05Z, commit abc1234, machine M."
    block = ["<!-- generated: x -->", "", stamp, "", "<!-- end generated: x -->"]
    assert _generated_stamp_lines("docs/validation/a.md", block) == {3}
    assert _generated_stamp_lines("docs/validation/a.md", ["", stamp]) == set()
    assert _generated_stamp_lines("docs/a.md", block) == set()
    assert _generated_stamp_lines("docs/validation/a.md",
                                  [block[0], "Measured 2026-01-02.", block[-1]]) == set()


def test_allow_list_entries_are_used():
    """Every allow-list entry still matches a line (a stale entry would hide nothing
    but mislead the reader)."""
    for page, name, text, why in ALLOWED:
        assert why, f"{page}: an allowed match needs its reason"
        hits = narration((REPO / page).read_text(encoding="utf-8"))
        lines = (REPO / page).read_text(encoding="utf-8").splitlines()
        assert any(k == name and text in lines[n - 1] + " " + (lines[n] if n < len(lines) else "")
                   for n, k, _ in hits), \
            f"{page}: allow-list entry {text!r} ({name}) matches nothing"


_LINK = re.compile(r"\]\(([^)\s#]+)(?:#[^)\s]*)?\)")


def _link_targets(text: str) -> list[tuple[int, str]]:
    """(line, path) of every relative Markdown link ``](path)`` or ``](path#anchor)``,
    outside fenced code; web and mail links are not relative."""
    out, fenced = [], False
    for n, ln in enumerate(text.splitlines(), 1):
        if ln.lstrip().startswith("```"):
            fenced = not fenced
            continue
        if fenced:
            continue
        for target in _LINK.findall(ln):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):   # https:, mailto:
                continue
            out.append((n, target))
    return out


@pytest.mark.parametrize("page", [REPO / "README.md", *sorted((REPO / "docs").glob("*.md")),
                                  *sorted((REPO / "docs" / "validation").glob("*.md"))],
                         ids=lambda p: p.relative_to(REPO).as_posix())
def test_relative_links_name_existing_files(page):
    missing = [f"{page.relative_to(REPO).as_posix()}:{n}: {t}"
               for n, t in _link_targets(page.read_text(encoding="utf-8"))
               if not (page.parent / t).exists()]
    assert not missing, "links to files that do not exist:\n" + "\n".join(missing)


def test_link_pattern_finds_links_and_cuts_anchors():
    """Negative control of the link check."""
    text = ("see [a](docs/a.md#sec), [b](b.md) and [web](https://x.org/y)\n"
            "```\n[not](in-code.md)\n```\n")
    assert _link_targets(text) == [(1, "docs/a.md"), (1, "b.md")]
