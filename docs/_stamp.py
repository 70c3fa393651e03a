"""When, at which commit and on which machine a study's output was made.

The scripts ``docs/make_*.py`` add ``stamp()`` to what they write (key ``"stamp"``), so
that the Validation pages (``docs/validation/``, written by
``docs/make_validation_pages.py``) take the date, the commit and the machine from the
stored output, never from prose.  An output written before its script stamped has no
``"stamp"``: its page says "not recorded".
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _commit() -> str | None:
    """Short hash of HEAD, with ``+changes`` when the work tree differs from it."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=ROOT, capture_output=True, text=True,
                               check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("+changes" if dirty else "")


def _machine() -> str:
    """Operating system, architecture, processor model, cores and the 1-minute load."""
    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        load = f", load {os.getloadavg()[0]:.1f}"
    except OSError:
        load = ""
    parts = [f"{platform.system()} {platform.machine()}", cpu, f"{os.cpu_count()} cores"]
    return ", ".join(p for p in parts if p) + load


def stamp() -> dict:
    """``{"date": UTC time to the second, "commit": short hash or None, "machine": ...}``."""
    now = _dt.datetime.now(_dt.UTC).replace(microsecond=0)
    return {"date": now.isoformat().replace("+00:00", "Z"), "commit": _commit(),
            "machine": _machine()}
