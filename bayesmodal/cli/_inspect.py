"""``bayesmodal inspect``: what the reader sees in a lab file."""

from __future__ import annotations

from ..inspection import format_inspection, inspect_file
from ._common import add_data_args, print_json, reader_options


def register(sub) -> None:
    p = sub.add_parser(
        "inspect",
        help="what the reader sees in a data file",
        description="Read DATA as every command would and print what the reader sees: "
        "columns and their roles, scales, sample steps and jitter, duration, the input's "
        "events, the drive's polarity, each output's rest level before the first event "
        "and after the last, and the command line that fits the record.",
    )
    add_data_args(p)
    p.add_argument("--json", action="store_true", help="print a JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    result = inspect_file(args.data, reader_options(args))
    if args.json:
        print_json(result.as_dict())
    else:
        print(format_inspection(result))
    return 0
