"""Write a record the way the ECP Executive's "export raw data" does (for tests).

Independent of the package's reader: the layout is spelled out here from the
Executive's own files (a header row of column names, a blank line, then the rows as a
MATLAB matrix literal, the time printed to three decimals, positions in whole counts).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: The ECP 210's servo sample period, s (not a whole number of milliseconds).
ECP_DT = 0.008854

#: Metres per encoder count of the ECP 210.
M_PER_COUNT = 0.0706 / 16000


def write_export(path: Path, v_volt: np.ndarray, y_m: np.ndarray, *, dt: float = ECP_DT,
                 commanded: bool = True, commanded_m: np.ndarray | None = None,
                 per_count: float = M_PER_COUNT) -> Path:
    """Write ``v`` (V) and the cart positions ``y`` (m) as an Executive export.

    Parameters
    ----------
    path : Path
    v_volt : ndarray, shape (N,)
        Control effort, V.
    y_m : ndarray, shape (N, n_encoders)
        Positions, m (rad for a torsional plant); written as whole encoder counts.
    dt : float
        Sample period, s; the time column is ``k dt`` printed to 1 ms.
    commanded : bool
        Write a ``Commanded Pos`` column (zeros: open loop).
    commanded_m : ndarray, shape (N,), optional
        The commanded position of a closed loop, m; written as whole counts (default
        zeros).
    per_count : float
        Position per encoder count: m for the rectilinear plant (default), rad for the
        torsional one (``2 pi / 16000``).

    Returns
    -------
    Path
    """
    n, m = y_m.shape
    counts = np.round(y_m / per_count).astype(int)
    ref = (np.zeros(n, int) if commanded_m is None
           else np.round(np.asarray(commanded_m) / per_count).astype(int))
    names = ["Sample", "Time"] + (["Commanded Pos"] if commanded else []) + [
        f"Encoder {i + 1} Pos" for i in range(m)] + ["Control Effort"]
    lines = [" " + "   ".join(names), ""]
    for k in range(n):
        cells = [f"{k:5d}", f"{k * dt:8.3f}"] + ([f"{ref[k]:6d}"] if commanded else []) + [
            f"{c:6d}" for c in counts[k]] + [f"{v_volt[k]:9.4f}"]
        row = " ".join(cells)
        opener = "[" if k == 0 else " "
        closer = "]" if k == n - 1 else ";"
        lines.append(f"{opener}{row}{closer}")
    path.write_text("\n".join(lines) + "\n")
    return path
