"""Legends that never cover data: each legend is placed, on the drawn figure, where its box
holds none of the plotted points, line segments and annotations of its axes, or else below
the axes, with the figure made taller by as much, so that the axes keep their size.

The test is made in display coordinates after drawing (:func:`covered`), on what the figure
shows: markers with their size, lines sampled every couple of pixels, error bars, and the text
of annotations; reference lines spanning the axes (``axhline``) and grid lines are not data.
:func:`place_legends` is called by :func:`roughslip.analysis.plotting.save` for every figure
the package writes.
"""

from __future__ import annotations

import numpy as np

#: the places inside the axes tried, in order
INSIDE = ("upper right", "upper left", "lower right", "lower left", "upper center",
          "lower center", "center right", "center left")
#: display pixels between a legend and the nearest point it may not cover
PAD = 2.0
#: spacing of the samples along a drawn line, in display pixels
STEP = 2.0


def _data_transform(artist, ax) -> bool:
    """Whether an artist is drawn in data coordinates (not a reference line across the
    axes)."""
    try:
        return artist.get_transform().contains_branch(ax.transData)
    except (AttributeError, TypeError, ValueError):
        return False


def _sampled(xy: np.ndarray) -> np.ndarray:
    """Points every :data:`STEP` pixels along the polyline ``xy`` (display coordinates)."""
    if len(xy) < 2:
        return xy
    p0, p1 = xy[:-1], xy[1:]
    length = np.hypot(*(p1 - p0).T)
    n = np.clip(np.ceil(length / STEP), 1, 2000).astype(int)
    t = np.concatenate([np.arange(k) / k for k in n])
    start = np.repeat(p0, n, axis=0)
    step = np.repeat(p1 - p0, n, axis=0)
    return np.vstack([start + t[:, None] * step, xy[-1:]])


def obstacles(ax) -> tuple[list[tuple[np.ndarray, float]], list[tuple[float, ...]]]:
    """What a legend of ``ax`` must not cover, in display coordinates of the drawn figure:
    ``(points, radius)`` groups (markers, and lines sampled along their length) and text boxes
    ``(x0, y0, x1, y1)``, each within the axes."""
    box = ax.bbox
    inside = (box.x0, box.y0, box.x1, box.y1)
    points: list[tuple[np.ndarray, float]] = []
    dpi = ax.figure.dpi

    def keep(xy: np.ndarray, radius: float) -> None:
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        sel = ((xy[:, 0] >= inside[0]) & (xy[:, 0] <= inside[2]) & (xy[:, 1] >= inside[1])
               & (xy[:, 1] <= inside[3]))
        if sel.any():
            points.append((xy[sel], radius))

    for line in ax.get_lines():
        if not line.get_visible() or not _data_transform(line, ax):
            continue
        xy = np.asarray(line.get_transform().transform(line.get_xydata()), dtype=float)
        if xy.size == 0:
            continue
        if line.get_marker() not in (None, "None", "", " ", "none"):
            keep(xy, 0.5 * line.get_markersize() * dpi / 72.0)
        if line.get_linestyle() not in ("None", "", " ", "none"):
            ok = np.all(np.isfinite(xy), axis=1)
            for run in np.split(xy, np.flatnonzero(~ok)):  # a NaN breaks a line
                run = run[np.all(np.isfinite(run), axis=1)]
                keep(_sampled(run), 0.5 * line.get_linewidth() * dpi / 72.0)
    for coll in ax.collections:
        if not coll.get_visible():
            continue
        segments = getattr(coll, "get_segments", None)
        if segments is not None and _data_transform(coll, ax):
            for seg in segments():
                keep(_sampled(coll.get_transform().transform(np.asarray(seg, float))), 1.0)
        offsets = coll.get_offsets()
        if len(offsets) and segments is None:
            xy = coll.get_offset_transform().transform(np.asarray(offsets, float))
            sizes = coll.get_sizes()
            r = 0.5 * np.sqrt(float(sizes.max())) * dpi / 72.0 if len(sizes) else 2.0
            keep(xy, r)
    texts = []
    renderer = ax.figure.canvas.get_renderer()
    for t in ax.texts:
        if t.get_visible() and t.get_text():
            b = t.get_window_extent(renderer)
            texts.append((b.x0, b.y0, b.x1, b.y1))
    return points, texts


def covered(ax, legend=None, found=None) -> int:
    """How many obstacles (:func:`obstacles`, or ``found``) the legend's box covers on the
    drawn figure (call ``figure.canvas.draw()`` first); 0 when the axes has no legend."""
    legend = legend or ax.get_legend()
    if legend is None:
        return 0
    b = legend.get_window_extent(ax.figure.canvas.get_renderer())
    points, texts = found or obstacles(ax)
    n = 0
    for xy, r in points:
        pad = r + PAD
        n += int(np.sum((xy[:, 0] > b.x0 - pad) & (xy[:, 0] < b.x1 + pad)
                        & (xy[:, 1] > b.y0 - pad) & (xy[:, 1] < b.y1 + pad)))
    for x0, y0, x1, y1 in texts:
        n += int(x0 < b.x1 and x1 > b.x0 and y0 < b.y1 and y1 > b.y0)
    return n


def _below(legend, ax) -> bool:
    """Anchor ``legend`` under ``ax``, below its tick labels and axis label, centred; whether
    the anchor moved (by more than a pixel)."""
    renderer = ax.figure.canvas.get_renderer()
    legend.set_visible(False)  # the axes' extent without the legend
    try:
        box = ax.get_tightbbox(renderer)
    finally:
        legend.set_visible(True)
    height = max(ax.bbox.height, 1.0)
    y = (box.y0 - ax.bbox.y0 - PAD) / height
    old = legend.get_bbox_to_anchor()
    moved = legend._loc != legend.codes["upper center"] or \
        abs(old.y0 - ax.transAxes.transform((0.5, y))[1]) > 1.0
    legend.set_loc("upper center")
    legend.set_bbox_to_anchor((0.5, y), transform=ax.transAxes)
    return moved


def place_legend(ax) -> str:
    """Put the legend of ``ax`` where it covers nothing (:data:`INSIDE`, in order), or below
    the axes; returns where it went (``"below"``). The figure must be drawn (its layout
    done)."""
    legend = ax.get_legend()
    found = obstacles(ax)
    for loc in INSIDE:
        legend.set_loc(loc)
        if covered(ax, legend, found) == 0:
            return loc
    _below(legend, ax)
    return "below"


def _grow(fig, legends: list) -> None:
    """Make ``fig`` taller by the height of the legends just put below their axes (the
    tallest of each row of axes), so that the layout keeps the axes' size."""
    renderer = fig.canvas.get_renderer()
    rows: dict[int, float] = {}
    for ax, legend in legends:
        row = round(ax.bbox.y0)
        # the legend, its gap below the axes' label and its pad from the anchor
        gap = legend.borderaxespad * legend._fontsize * fig.dpi / 72.0
        height = legend.get_window_extent(renderer).height + gap + 2 * PAD
        rows[row] = max(rows.get(row, 0.0), height)
    if rows:
        w, h = fig.get_size_inches()
        fig.set_size_inches(w, h + sum(rows.values()) / fig.dpi)


def place_legends(fig, relayout=None) -> dict[int, str]:
    """Place every legend of ``fig`` (:func:`place_legend`): inside its axes where it covers
    nothing, else below them, the figure grown to keep the axes' size (:func:`_grow`) and
    laid out again with ``relayout`` (e.g. ``fig.tight_layout``; a figure with a layout
    engine lays itself out), until no legend covers anything; returns the place of each axes'
    legend, by axes index."""
    where: dict[int, str] = {}
    fig.canvas.draw()
    size = {i: ax.bbox.height for i, ax in enumerate(fig.axes)}  # to keep
    for _ in range(4):  # a new layout resizes the axes: check again
        moved = False
        fig.canvas.draw()
        below = []
        # what the layout took from axes with a legend below them, given back (once a row)
        short = {round(ax.bbox.y0): size[i] - ax.bbox.height for i, ax in enumerate(fig.axes)
                 if where.get(i) == "below" and i in size}
        if short and max(abs(s) for s in short.values()) > 1.0:
            w, h = fig.get_size_inches()
            fig.set_size_inches(w, h + sum(short.values()) / fig.dpi)
            moved = True
        for i, ax in enumerate(fig.axes):
            legend = ax.get_legend()
            if legend is None:
                continue
            if where.get(i) == "below":
                moved |= _below(legend, ax)  # follow the axes' new size
                continue
            if i in where and covered(ax, legend) == 0:
                continue
            where[i] = place_legend(ax)
            moved = True
            if where[i] == "below":
                below.append((ax, legend))
        _grow(fig, below)
        if not moved:
            break
        if relayout is not None:
            relayout()
    return where
