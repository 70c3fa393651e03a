"""The generated reference pages (docs/reference/) match the package they describe.

docs/make_reference.py builds the effects catalogue, the noise models, the command line
and the run configuration keys from the registries and parsers the package runs on.
Each page is rebuilt here in memory and compared with the committed file, so a change to
an effect, a noise model, an option or a configuration key that is not regenerated fails
this test.  The generator is also checked to follow its sources (a registry entry added
in the test shows up in the page; a configuration key with no ``RunConfig`` field and a
noise spelling the configuration rejects stop it).
"""

from __future__ import annotations

import argparse
import importlib.util
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "docs" / "make_reference.py"


def _load():
    spec = importlib.util.spec_from_file_location("make_reference", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


ref = _load()


@pytest.mark.parametrize("name", sorted(ref.PAGES))
def test_committed_page_is_generated(name):
    path = REPO / "docs" / "reference" / name
    assert path.is_file(), f"docs/reference/{name} is missing: run `python docs/make_reference.py`"
    want = ref.PAGES[name]()
    got = path.read_text(encoding="utf-8")
    if got != want:
        lines = zip(got.splitlines() + [""], want.splitlines() + [""], strict=False)
        diff = next(i for i, (a, b) in enumerate(lines) if a != b)
        pytest.fail(f"docs/reference/{name} differs from what the package gives (first at "
                    f"line {diff + 1}): run `python docs/make_reference.py`")


def test_every_effect_and_parameter_is_listed():
    from bayesmodal.model.effects import EXTENSIONS
    from bayesmodal.model.rigs import load_rig

    page = ref.effects_page()
    rig = load_rig(ref.EFFECTS_PRESET)
    for name, ext in EXTENSIONS.items():
        assert f"\n## {name}\n" in page
        for p in ext.specs(rig):
            assert f"| `{p.name}` | {p.unit} |" in page, (name, p.name)


def test_every_command_and_option_is_listed():
    from bayesmodal.cli import build_parser

    page = ref.cli_page()
    sub = next(a for a in build_parser()._actions
               if isinstance(a, argparse._SubParsersAction))
    for name, parser in sub.choices.items():
        section = page.split(f"\n## bayesmodal {name}\n", 1)[1].split("\n## ", 1)[0]
        for a in parser._actions:
            for opt in a.option_strings:
                if opt not in ("-h", "--help"):
                    assert f"`{opt}" in section, (name, opt)


def test_every_configuration_key_is_listed():
    from bayesmodal.runs.config import _SCHEMA

    page = ref.config_page()
    for section, keys in _SCHEMA.items():
        body = page.split(f"\n## [{section}]\n", 1)[1].split("\n## ", 1)[0]
        for key in keys:
            assert f"| `{key}` |" in body, (section, key)


def test_every_noise_spelling_is_accepted_and_listed():
    page = ref.noise_page()
    for spelling, example in ref.NOISE_SPELLINGS:
        ref._check_spelling(example)
        assert f"\n## {spelling}\n" in page


def test_generator_follows_the_registries(monkeypatch):
    """A new effect appears in the page; a configuration key without a ``RunConfig``
    field, or a noise spelling the configuration rejects, stops the generator instead of
    writing a page that misses it."""
    from bayesmodal import ConfigError
    from bayesmodal.model.effects import EXTENSIONS
    from bayesmodal.runs.config import _SCHEMA

    monkeypatch.setitem(EXTENSIONS, "extra_effect", EXTENSIONS["motor_lag"])
    assert "\n## extra_effect\n" in ref.effects_page()
    monkeypatch.setitem(_SCHEMA["sampler"], "unmapped_key", int)
    with pytest.raises(KeyError, match="unmapped_key"):
        ref.config_page()
    with pytest.raises(ConfigError):
        ref._check_spelling("ar:none")




@pytest.mark.parametrize("name", sorted(ref.PAGES))
def test_reference_links_resolve(name):
    """Relative links name existing pages, and anchors within the page name one of its
    headings (as the site's Markdown parser forms them: lower case, spaces to hyphens,
    punctuation other than - and _ dropped)."""
    text = ref.PAGES[name]()
    anchors = {re.sub(r"[^\w\- ]", "", h.strip().lower().replace(" ", "-"))
               for h in re.findall(r"^#{1,3} (.+)$", text, re.M)}
    for m in re.finditer(r"\]\(([^)\s]+)\)", text):
        target, _, anchor = m.group(1).partition("#")
        if target:
            assert (REPO / "docs" / "reference" / target).resolve().is_file(), target
        else:
            assert anchor in anchors, anchor
