"""Compact PNG files of figures: an indexed palette of at most 256 colours.

Matplotlib writes 32-bit RGBA PNGs; a plot with anti-aliased lines and translucent bands
has a few thousand distinct colours, almost all of them at the edges of lines, and zlib
compresses them poorly (a trace plot of 56 walkers was 3.6 MB).  The same image in a
256-colour palette is three to four times smaller: exactly the same pixels when the
figure has at most 256 colours (median cut keeps them all), otherwise colours that
differ at the anti-aliased edges only (octree quantisation).  A figure with transparent
pixels is written as it is.
"""

from __future__ import annotations

import io
import os

__all__ = ["save_png"]

#: Largest palette of a PNG (8-bit indices).
PALETTE_COLOURS = 256


def save_png(fig, path: str | os.PathLike, *, dpi: float) -> None:
    """Write ``fig`` to ``path`` as a palette PNG (``bbox_inches="tight"``).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or path
        Output file (written directly; callers rename it into place).
    dpi : float
        Resolution, dots per inch.
    """
    import numpy as np
    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    buf.seek(0)
    with Image.open(buf) as img:
        img.load()
        rgba = img.convert("RGBA")
    if np.asarray(rgba)[..., 3].min() < 255:
        with open(path, "wb") as f:
            f.write(buf.getvalue())
        return
    rgb = rgba.convert("RGB")
    exact = rgb.getcolors(PALETTE_COLOURS) is not None
    method = Image.Quantize.MEDIANCUT if exact else Image.Quantize.FASTOCTREE
    rgb.quantize(PALETTE_COLOURS, method=method).save(path, format="PNG", optimize=True)
