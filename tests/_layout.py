"""Collision checks of a drawn matplotlib figure: text that overlaps, legends over data.

A figure is readable at a glance when no two pieces of its text (titles, the suptitle,
axis labels, tick labels, legends) are drawn over each other and no legend hides the
curves it explains.  :func:`layout_problems` draws the figure on its canvas (Agg in the
tests) and returns one sentence per problem found; an empty list is a clean figure.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

__all__ = ["TextBox", "text_boxes", "overlaps", "legend_cover", "legend_hides_peaks",
           "layout_problems",
           "MAX_LEGEND_SHARE", "OVERLAP_TOL_PX"]

#: Largest share of an axes' plotted data points a legend may cover.  A legend set in an
#: empty corner covers no point at all; one placed over the start of a curve covers the
#: points of the time (or lag) span under it, which is a tenth to a quarter of the axis
#: width for the legends of these figures.  2 % of the points is about the width of a
#: single tick label on a 9-inch figure: small enough that no peak can hide under a
#: legend, large enough that a curve grazing the frame's corner is not a failure.
MAX_LEGEND_SHARE = 0.02

#: Boxes that overlap by less than this many display pixels in either direction count as
#: touching, not overlapping: text extents include the font's ascent and descent, and
#: adjacent labels laid out edge to edge by the layout engine meet within a pixel.
OVERLAP_TOL_PX = 1.0


@dataclass(frozen=True)
class TextBox:
    """A piece of text (or a legend) and where it is drawn.

    Attributes
    ----------
    label : str
        What it is and where, e.g. ``"axes 2 title 'data_steps'"``.
    bbox : matplotlib.transforms.Bbox
        Display coordinates, pixels.
    """

    label: str
    bbox: object


def _visible_text(t) -> bool:
    return t is not None and t.get_visible() and bool(t.get_text().strip())


def _axis_ticks(axis):
    """Tick labels the axis draws (those inside its view interval)."""
    # ``_update_ticks`` is what ``Axis.draw`` uses to pick the ticks it draws
    for tick in axis._update_ticks():
        for lab in (tick.label1, tick.label2):
            if _visible_text(lab):
                yield lab


def text_boxes(fig, renderer=None) -> list[TextBox]:
    """Bounding boxes of the figure's text and legends.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Already drawn (``fig.canvas.draw()``).
    renderer : RendererBase, optional
        Default the figure canvas's renderer.

    Returns
    -------
    list of TextBox
    """
    r = renderer or fig.canvas.get_renderer()
    out = []
    sup = getattr(fig, "_suptitle", None)
    if _visible_text(sup):
        out.append(TextBox(f"suptitle {sup.get_text()!r}", sup.get_window_extent(r)))
    sups = [getattr(fig, n, None) for n in ("_suptitle", "_supxlabel", "_supylabel")]
    for k, t in enumerate(fig.texts):
        if _visible_text(t) and all(t is not x for x in sups):
            out.append(TextBox(f"figure text {k} {t.get_text()!r}",
                               t.get_window_extent(r)))
    for k, leg in enumerate(fig.legends):
        if leg.get_visible():
            out.append(TextBox(f"figure legend {k}", leg.get_window_extent(r)))
    for i, a in enumerate(fig.axes):
        if not a.get_visible():
            continue
        name = f"axes {i}"
        for t in (a.title, a._left_title, a._right_title):
            if _visible_text(t):
                out.append(TextBox(f"{name} title {t.get_text()!r}",
                                   t.get_window_extent(r)))
        for axis, which in ((a.xaxis, "x"), (a.yaxis, "y")):
            if _visible_text(axis.label):
                out.append(TextBox(f"{name} {which} label {axis.label.get_text()!r}",
                                   axis.label.get_window_extent(r)))
            if _visible_text(axis.offsetText):
                out.append(TextBox(f"{name} {which} offset {axis.offsetText.get_text()!r}",
                                   axis.offsetText.get_window_extent(r)))
            for lab in _axis_ticks(axis):
                out.append(TextBox(f"{name} {which} tick {lab.get_text()!r}",
                                   lab.get_window_extent(r)))
        leg = a.get_legend()
        if leg is not None and leg.get_visible():
            out.append(TextBox(f"{name} legend", leg.get_window_extent(r)))
    return out


def overlaps(a, b, tol: float = OVERLAP_TOL_PX) -> bool:
    """Whether two display boxes overlap by more than ``tol`` pixels in both directions."""
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return w > tol and h > tol


def _legends(fig) -> list[tuple[str, object]]:
    """The figure's legends and those of its axes, each with a description."""
    legends = [(f"figure legend {k}", leg) for k, leg in enumerate(fig.legends)]
    legends += [(f"axes {i} legend", a.get_legend()) for i, a in enumerate(fig.axes)
                if a.get_legend() is not None]
    return legends


def _inside(p: np.ndarray, box) -> np.ndarray:
    """Which display points ``p`` (shape (n, 2)) lie in the bounding box ``box``."""
    return ((p[:, 0] >= box.x0) & (p[:, 0] <= box.x1)
            & (p[:, 1] >= box.y0) & (p[:, 1] <= box.y1))


def legend_cover(fig, renderer=None) -> list[tuple[str, int, float]]:
    """Share of each axes' data points that each legend covers.

    The points are the vertices of the axes' visible ``Line2D`` artists, transformed to
    display coordinates, that lie inside the axes (points outside are not drawn).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Already drawn.
    renderer : RendererBase, optional

    Returns
    -------
    list of (str, int, float)
        Legend description, index of the axes in ``fig.axes`` and the share of its points
        inside the legend's box, for every legend and axes whose boxes meet.
    """
    r = renderer or fig.canvas.get_renderer()
    legends = _legends(fig)
    out = []
    for i, a in enumerate(fig.axes):
        if not a.get_visible():
            continue
        frame = a.get_window_extent(r)
        pts = [ln.get_transform().transform(np.asarray(ln.get_xydata(), float))
               for ln in a.get_lines() if ln.get_visible() and len(ln.get_xydata())]
        if not pts:
            continue
        p = np.concatenate(pts)
        p = p[np.all(np.isfinite(p), axis=1)]
        p = p[(p[:, 0] >= frame.x0) & (p[:, 0] <= frame.x1)
              & (p[:, 1] >= frame.y0) & (p[:, 1] <= frame.y1)]
        if not len(p):
            continue
        for name, leg in legends:
            if not leg.get_visible():
                continue
            box = leg.get_window_extent(r)
            if not overlaps(box, frame, 0.0):
                continue
            out.append((name, i, float(np.mean(_inside(p, box)))))
    return out


def legend_hides_peaks(fig, renderer=None) -> list[tuple[str, int]]:
    """Legends drawn over the largest or smallest value of a curve.

    The share of :func:`legend_cover` bounds how much of the curves a legend hides; the
    extremes are the points a reader looks at first (the peaks of a response, the value
    at lag 0 of an autocorrelation), and a legend must not hide them however few points
    it covers.  Curves of fewer than 10 points (reference lines, markers) are left out.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Already drawn.
    renderer : RendererBase, optional

    Returns
    -------
    list of (str, int)
        Legend description and index of the axes in ``fig.axes`` whose curve it covers.
    """
    r = renderer or fig.canvas.get_renderer()
    legends = _legends(fig)
    out = []
    for i, a in enumerate(fig.axes):
        if not a.get_visible():
            continue
        peaks = []
        for ln in a.get_lines():
            xy = np.asarray(ln.get_xydata(), float)
            xy = xy[np.all(np.isfinite(xy), axis=1)]
            if ln.get_visible() and len(xy) >= 10:
                peaks.append(ln.get_transform().transform(
                    xy[[np.argmax(xy[:, 1]), np.argmin(xy[:, 1])]]))
        if not peaks:
            continue
        p = np.concatenate(peaks)
        for name, leg in legends:
            box = leg.get_window_extent(r)
            if leg.get_visible() and np.any(_inside(p, box)):
                out.append((name, i))
    return out


def layout_problems(fig, *, max_legend_share: float = MAX_LEGEND_SHARE) -> list[str]:
    """Everything that makes a figure hard to read: overlapping text, legends over data.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Drawn here with ``fig.canvas.draw()`` (layout engines run on draw).
    max_legend_share : float
        Largest share of an axes' data points a legend may cover.

    Returns
    -------
    list of str
        One sentence per problem; empty for a clean figure.
    """
    if not hasattr(fig.canvas, "get_renderer"):  # closed by pyplot: draw it on Agg
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    boxes, seen = [], set()
    for b in text_boxes(fig, r):
        # twin axes draw the shared axis's tick labels twice at one place: one text
        key = (b.label.split(" ", 2)[-1], tuple(np.round(b.bbox.extents, 1)))
        if key not in seen:
            seen.add(key)
            boxes.append(b)
    problems = []
    for b1, b2 in itertools.combinations(boxes, 2):
        if overlaps(b1.bbox, b2.bbox):
            problems.append(f"{b1.label} overlaps {b2.label}")
    for name, i, share in legend_cover(fig, r):
        if share > max_legend_share:
            problems.append(f"{name} covers {100 * share:.1f} % of the data points of "
                            f"axes {i} (limit {100 * max_legend_share:.0f} %)")
    for name, i in legend_hides_peaks(fig, r):
        problems.append(f"{name} hides the largest or smallest value of a curve of axes {i}")
    return problems
