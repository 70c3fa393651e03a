"""``bayesmodal report``: reproduce the reference report's tables and figures."""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..reproduce import format_tables, reproduce_report, save_report_plots
from ._common import print_json, to_jsonable


def register(sub) -> None:
    p = sub.add_parser(
        "report",
        help="reproduce the report's tables (2-9) and figures from the ECP data",
        description="Run the report's analysis end to end: steady state (Table 2), LSQ fits "
        "(Tables 3-5), modal analysis (Tables 6-9), Bode plots and predictions.",
    )
    p.add_argument("--data-dir", metavar="DIR",
                   help="folder with data_impulses, data_steps (and the sine sweeps) as .mat "
                        "or .txt (default: $BAYESMODAL_DATA/ecp210-3dof or the shared folder)")
    p.add_argument("--out", metavar="DIR",
                   help="write the figures, tables.txt and report.json into DIR "
                        "(default: nothing written)")
    p.add_argument("--json", action="store_true", help="print a JSON object, not tables")
    p.set_defaults(func=run)


def _write_text(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def run(args) -> int:
    tables = reproduce_report(args.data_dir)
    text = format_tables(tables)
    summary = tables.as_dict()
    if args.out:
        import matplotlib

        matplotlib.use("Agg")
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        save_report_plots(tables, out)
        _write_text(out / "tables.txt", text)
        _write_text(out / "report.json", json.dumps(to_jsonable(summary), indent=2) + "\n")
    if args.json:
        print_json(summary)
    else:
        print(text, end="")
        if args.out:
            print(f"figures, tables.txt and report.json written to {args.out}")
    return 0
