"""Every sub-command and option explains itself; usage errors are one line."""

import argparse

import pytest

from bayesmodal.cli import ArgumentParser, HelpFormatter, build_parser, main

FLAGS = (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse._HelpAction,
         argparse._VersionAction, argparse._StoreConstAction)


def _subparsers():
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return parser, sub.choices


def _options():
    _, choices = _subparsers()
    for name, p in choices.items():
        fmt = p._get_formatter()
        for a in p._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            yield name, a, fmt


def test_every_command_is_registered_and_described():
    parser, choices = _subparsers()
    assert set(choices) == set(__import__("bayesmodal.cli", fromlist=["COMMANDS"]).COMMANDS)
    missing = [n for n, p in choices.items() if not (p.description or "").strip()]
    assert missing == []


def _problem(name, action, fmt):
    """What is wrong with one option's help, or None."""
    if not (action.help or "").strip():
        return f"{name} {action.dest}: no help"
    if isinstance(action, FLAGS) or not action.option_strings:
        return None  # flags and positionals have no default to state
    text = " ".join(fmt._format_action(action).split())
    if "default" not in text:
        return f"{name} {action.option_strings}: help does not state a default"
    if action.default is not None and "%(default)." not in action.help \
            and str(action.default) not in text:
        return f"{name} {action.option_strings}: default {action.default} not shown"
    return None


@pytest.mark.parametrize("name,action,fmt", list(_options()),
                         ids=lambda x: x if isinstance(x, str) else
                         getattr(x, "dest", None) if isinstance(x, argparse.Action) else "")
def test_every_option_has_help_stating_its_default(name, action, fmt):
    assert _problem(name, action, fmt) is None


def test_negative_control_bad_options_are_caught():
    p = ArgumentParser(prog="x", formatter_class=HelpFormatter)
    fmt = p._get_formatter()
    bare = p.add_argument("--bare", type=int, default=3)
    silent = p.add_argument("--out", default=None, help="output folder")
    wrong = p.add_argument("--n", type=int, default=7, help="count (default 5)")
    good = p.add_argument("--m", type=int, default=7, help="count")
    assert "no help" in _problem("x", bare, fmt)
    assert "does not state a default" in _problem("x", silent, fmt)
    assert "default 7 not shown" in _problem("x", wrong, fmt)
    assert _problem("x", good, fmt) is None


@pytest.mark.parametrize("argv,prog", [
    (["lsq", "--damping", "viscous", "x.csv"], "bayesmodal lsq"),
    (["modal", "--bogus"], "bayesmodal modal"),
    (["no-such-command"], "bayesmodal"),
])
def test_usage_error_is_one_line(capsys, argv, prog):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1, cap.err
    assert lines[0].startswith(f"{prog}: error: ")
    assert lines[0].endswith(f"(see {prog} --help)")
    assert "usage:" not in cap.err


RIG_COMMANDS = ("lsq", "sample", "static", "ema", "diagnose", "modal", "crossval")
DATA_OPTIONS = ("--columns", "--input-scale", "--time-scale", "--m-per-count")


def test_rig_and_column_options_are_documented_on_every_command_that_reads_a_rig():
    # issue 17: every command takes --rig; every one that reads records takes the column map
    # and the scales, each with help (the test above checks the help text itself).
    _, choices = _subparsers()
    for name in RIG_COMMANDS:
        opts = {o: a for a in choices[name]._actions for o in a.option_strings}
        wanted = ("--rig",) + (DATA_OPTIONS if name != "modal" else ())
        missing = [o for o in wanted if o not in opts or not (opts[o].help or "").strip()]
        assert missing == [], f"{name}: {missing}"
        assert "--rig" in choices[name].format_help()
