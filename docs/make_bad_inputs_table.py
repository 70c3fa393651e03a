"""Write ``docs/bad_inputs.md`` from the cases of ``tests/test_bad_inputs.py``.

Run from anywhere: ``python docs/make_bad_inputs_table.py``.  Every row is the outcome of
one case of the test module (the same code runs there and checks the committed table).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import test_bad_inputs as cases  # noqa: E402


def main() -> int:
    with tempfile.TemporaryDirectory() as d:
        text = cases.render_table(cases.all_outcomes(Path(d)))
    (HERE / "bad_inputs.md").write_text(text)
    rows = sum(ln.startswith("| ") for ln in text.splitlines()) - 1  # minus the header
    print(f"wrote {HERE / 'bad_inputs.md'} ({rows} rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
