"""Legends that never cover data: each legend is placed, on the drawn figure, where its box
holds none of the plotted points, line segments and annotations of its axes, or else beside
the axes.

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


def _outside(legend, ax) -> None:
    legend.set_loc("upper left")
    legend.set_bbox_to_anchor((1.02, 1.0), transform=ax.transAxes)


def place_legend(ax) -> str:
    """Put the legend of ``ax`` where it covers nothing (:data:`INSIDE`, in order), or beside
    the axes, on the right; returns where it went (``"outside"`` for beside). The figure must
    be drawn (its layout done)."""
    legend = ax.get_legend()
    found = obstacles(ax)
    for loc in INSIDE:
        legend.set_loc(loc)
        if covered(ax, legend, found) == 0:
            return loc
    _outside(legend, ax)
    return "outside"


def place_legends(fig, relayout=None) -> dict[int, str]:
    """Place every legend of ``fig`` (:func:`place_legend`), laying the figure out again with
    ``relayout`` (e.g. ``fig.tight_layout``) after a legend moved beside its axes, until no
    legend covers anything; returns the place of each axes' legend, by axes index."""
    where: dict[int, str] = {}
    for _ in range(3):  # a new layout resizes the axes: check again
        moved = False
        fig.canvas.draw()
        for i, ax in enumerate(fig.axes):
            legend = ax.get_legend()
            if legend is None or where.get(i) == "outside":
                continue
            if i in where and covered(ax, legend) == 0:
                continue
            where[i] = place_legend(ax)
            moved = True
        if not moved:
            break
        if relayout is not None:
            relayout()
    return where
