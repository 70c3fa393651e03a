"""Progress display of long computations: a tqdm bar on a terminal, plain lines elsewhere.

A tqdm bar redraws itself with carriage returns and escape codes, which turn a log file
into noise.  So the bar is drawn only when its stream is a terminal; otherwise
:func:`progress_bar` writes one plain line each time another tenth of the work is done
(and one at the end), e.g. ``sampling: 600/3000 steps (20 %), 12 s``.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["announce", "progress_bar"]


class _Silent:
    """The progress interface doing nothing (progress disabled)."""

    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, text: str) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _Lines(_Silent):
    """Plain progress lines at every tenth of ``total`` (for logs and pipes)."""

    def __init__(self, total: int, desc: str, unit: str, file: TextIO) -> None:
        self.total, self.desc, self.unit, self.file = max(int(total), 0), desc, unit, file
        self.n = 0
        self.tenths = 0  # tenths of the total already reported
        self.postfix = ""
        self.t0 = time.perf_counter()

    def set_postfix_str(self, text: str) -> None:
        self.postfix = text

    def update(self, n: int = 1) -> None:
        self.n += n
        tenths = 10 * self.n // self.total if self.total else 10
        if tenths > self.tenths:
            self.tenths = tenths
            self._line()

    def _line(self) -> None:
        pct = 100 * self.n / self.total if self.total else 100.0
        extra = f", {self.postfix}" if self.postfix else ""
        self.file.write(f"{self.desc}: {self.n}/{self.total} {self.unit}s ({pct:.0f} %), "
                        f"{time.perf_counter() - self.t0:.0f} s{extra}\n")
        self.file.flush()


def progress_bar(total: int, *, desc: str, unit: str = "step", enabled: bool = True,
                 file: TextIO | None = None, leave: bool = True):
    """A progress display over ``total`` units of work.

    Parameters
    ----------
    total : int
        Units of work.
    desc : str
        What is being done (the line's or the bar's prefix).
    unit : str
        Name of one unit, singular.
    enabled : bool
        False gives an object that shows nothing.
    file : text stream, optional
        Where to write (default ``sys.stderr`` at call time).
    leave : bool
        Keep the tqdm bar on screen when done.

    Returns
    -------
    object
        With ``update(n=1)``, ``set_postfix_str(text)``, ``close()``; a context manager.
        A ``tqdm`` bar when ``file`` is a terminal, else plain lines every 10 %.

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> with progress_bar(4, desc="fits", unit="fit", file=out) as bar:
    ...     for _ in range(4):
    ...         bar.update()
    >>> out.getvalue().splitlines()[0].startswith("fits: 1/4 fits (25 %)")
    True
    """
    if not enabled:
        return _Silent()
    file = sys.stderr if file is None else file
    isatty = getattr(file, "isatty", None)
    if callable(isatty) and isatty():
        from tqdm.auto import tqdm

        return tqdm(total=total, desc=desc, unit=unit, file=file, leave=leave)
    return _Lines(total, desc, unit, file)


def announce(text: str, *, enabled: bool = True, file: TextIO | None = None) -> None:
    """Write one progress line (the start of a stage) when ``enabled``.

    Parameters
    ----------
    text : str
        The line, without newline.
    enabled : bool
        False writes nothing.
    file : text stream, optional
        Default ``sys.stderr`` at call time.
    """
    if enabled:
        file = sys.stderr if file is None else file
        file.write(text + "\n")
        file.flush()
