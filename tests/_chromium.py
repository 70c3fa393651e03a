"""Headless Chromium for the report tests: the browser, a page's check output and a
screenshot of its first screen (1280 x 900)."""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

WIDTH, HEIGHT = 1280, 900


def browser() -> str:
    """The Chromium executable; skips the test (with the fix) when there is none."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("chromium not installed (apt-get install chromium; .ci/run does)")


def _flags(tmp_path: Path) -> list[str]:
    return [browser(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
            f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000",
            f"--window-size={WIDTH},{HEIGHT}"]


def page_check(report: Path, check_js: str, tmp_path: Path) -> dict:
    """Load ``report`` with ``check_js`` (a script writing JSON into ``<pre
    id="bm-check">``) before ``</body>`` and return that JSON."""
    page = tmp_path / "report_check.html"
    page.write_text(report.read_text().replace("</body>", check_js))
    dom = subprocess.run([*_flags(tmp_path), "--dump-dom", page.as_uri()],
                         capture_output=True, text=True, timeout=180)
    m = re.search(r'<pre id="bm-check">(.*?)</pre>', dom.stdout, re.S)
    assert m, f"no check output from chromium: {dom.stderr[-2000:]}"
    return json.loads(html.unescape(m.group(1)))


def first_screen(report: Path, tmp_path: Path) -> np.ndarray:
    """The screenshot of ``report``'s first screen, RGB(A) floats in [0, 1], checked to be
    a page with text (not blank) and a tinted verdict box (red, amber or green)."""
    shot = tmp_path / "first_screen.png"
    subprocess.run([*_flags(tmp_path), f"--screenshot={shot}", report.as_uri()],
                   capture_output=True, timeout=180)
    assert shot.is_file() and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = matplotlib.image.imread(shot)
    assert img.shape[:2] == (HEIGHT, WIDTH)
    gray = img[..., :3].mean(axis=2)
    assert 0.005 < np.mean(gray < 0.5) < 0.5
    assert np.mean(np.ptp(img[..., :3], axis=2) > 0.03) > 0.01
    return img
