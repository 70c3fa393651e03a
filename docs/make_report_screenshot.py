"""The picture of a run report's first screen for the README (headless Chromium).

Usage::

    python docs/make_report_screenshot.py runs/records_free/report.html

renders the report at 1280 x 900 (the first screen the report tests check) and writes
``docs/figures/report_first_screen.png``, 1 280 x 900 pixels.  Needs ``chromium`` on the
path (``apt-get install chromium``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

OUT = Path(__file__).resolve().parent / "figures" / "report_first_screen.png"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report", type=Path, help="a run folder's report.html")
    ap.add_argument("--out", type=Path, default=OUT)
    a = ap.parse_args(argv)
    browser = next((shutil.which(b) for b in ("chromium", "chromium-browser",
                                               "google-chrome") if shutil.which(b)), None)
    if browser is None:
        print("chromium not found: apt-get install chromium", file=sys.stderr)
        return 2
    if not a.report.is_file():
        print(f"{a.report}: no such report; run `bash scripts/main.sh` first", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu",
                        "--hide-scrollbars", f"--user-data-dir={profile}",
                        "--virtual-time-budget=10000", "--window-size=1280,900",
                        f"--screenshot={a.out}", a.report.resolve().as_uri()],
                       capture_output=True, timeout=180, check=True)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
