"""Command-line interface: parses arguments and calls the library, nothing more.

Each sub-command lives in its own module ``bayesmodal/cli/_<name>.py`` exposing
``register(subparsers)``; registering sets ``func(args) -> int`` on its parser.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import traceback
import warnings

from .._errors import ConfigError, DataError, ModelError, one_line
from .._version import __version__

#: Sub-command modules, in help order.
COMMANDS = ("report", "inspect", "lsq", "static", "modal", "bench", "sample", "compare", "ema",
            "diagnose", "identify", "crossval", "run", "batch", "rerun")


class CLIError(Exception):
    """An error to show the user as one line, exit code 2."""


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """States every option's default: ``(default: X)`` unless the help already says it.

    Flags (``store_true``...) and options whose default is None (their help says in words
    what happens without them) get nothing appended.
    """

    def _get_help_string(self, action):
        text = action.help or ""
        if ("default" in text or action.default is None or action.nargs == 0
                or action.default is argparse.SUPPRESS):
            return text
        return super()._get_help_string(action)


class ArgumentParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors are one line on stderr, exit code 2."""

    def error(self, message: str):
        """Print ``PROG: error: MESSAGE (see PROG --help)`` and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_args(self, args=None, namespace=None):
        """As ``argparse``, but unknown arguments are blamed on the sub-command given."""
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            command = getattr(ns, "command", None)
            prog = f"{self.prog} {command}" if command else self.prog
            self.exit(2, f"{prog}: error: unrecognized arguments: {' '.join(extra)} "
                      f"(see {prog} --help)\n")
        return ns


def build_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog="bayesmodal",
        description="Bayesian identification of vibrating mass-spring-damper rigs.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"bayesmodal {__version__}")
    parser.add_argument("--debug", action="store_true", help="show full tracebacks on error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            mod = importlib.import_module(f"{__name__}._{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"{__name__}._{name}":
                continue  # command not built yet
            raise
        mod.register(sub)
    for p in sub.choices.values():  # every sub-command states its options' defaults
        p.formatter_class = HelpFormatter
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``bayesmodal`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        with warnings.catch_warnings():  # restores showwarning on exit
            warnings.showwarning = _warning_line(args.command)
            return int(args.func(args) or 0)
    except BrokenPipeError:  # e.g. `bayesmodal modal | head`: the reader has gone
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - no flush at exit onto the pipe
        return 0
    except KeyboardInterrupt:
        print("bayesmodal: interrupted", file=sys.stderr)
        return 130
    except (DataError, ModelError, ConfigError, CLIError, OSError, ValueError) as exc:
        if args.debug:
            traceback.print_exc()
        if isinstance(exc, ConfigError):  # a configuration's problems, all of them
            msg = one_line(exc)
        else:
            msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"bayesmodal {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug: still one line, the traceback with --debug
        if args.debug:
            traceback.print_exc()
        msg = str(exc).splitlines()[0] if str(exc) else ""
        print(f"bayesmodal {args.command}: internal error: {type(exc).__name__}: {msg} "
              "(run with --debug for the traceback)", file=sys.stderr)
        return 1


def _warning_line(command: str):
    """A ``warnings.showwarning`` that prints one line per warning on stderr."""

    def show(message, category, filename, lineno, file=None, line=None):
        text = str(message).splitlines()[0] if str(message) else category.__name__
        print(f"bayesmodal {command}: warning: {text}", file=file or sys.stderr)

    return show


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
