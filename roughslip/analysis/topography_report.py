"""Reports on topographies: the statistics of a topography file or of a surface stored in a
run file, as text or as a figure (``roughslip topography``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from roughslip.analysis.summary import length_unit, pixel_size
from roughslip.errors import InputError, echo
from roughslip.surfaces.synthetic import HDF5_SUFFIXES
from roughslip.surfaces.topography import (
    LENGTH_UNITS,
    TopographyStats,
    _square,
    metres_per,
    read_raw,
    statistics,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def display_unit(rms: float, unit: str) -> tuple[str, float]:
    """The SI prefix that puts a length ``rms`` in ``unit`` between 1 and 1000 (heights of a
    scan in metres read in nm or um; its lateral size in um or mm): ``(new unit, factor)``.

    A length that is not a finite positive number (the rms of a flat map, or a NaN from
    missing points) says nothing about the prefix: ``unit`` is kept, with factor 1."""
    per = metres_per(unit, "height unit")
    if not (math.isfinite(rms) and rms > 0):
        return unit, 1.0
    metres = rms * per
    name = next((n for n in ("m", "mm", "um", "nm") if metres >= LENGTH_UNITS[n]), "pm")
    return name, per / LENGTH_UNITS[name]


def describe(path: str | Path, *, key: str | None = None, unit: str | None = None,
             sample: int | None = None, pixel: float | None = None
             ) -> tuple[TopographyStats, np.ndarray]:
    """Statistics of a topography file, or of a surface stored in a run file (``sample``:
    its rigid surface; default the first complete sample). Returns the stats and heights.

    ``unit`` and ``pixel`` (the pixel size) describe a file that carries neither (a pixel
    size in the file and a different one given is an error). Heights with a unit are shown
    in the prefix that puts their rms between 1 and 1000 (:func:`display_unit`)."""
    p = Path(path)
    if p.suffix.lower() in HDF5_SUFFIXES and key is None and _is_run_file(p):
        from roughslip.run.store import read_run

        run = read_run(p)
        done = run.sample_index[run.complete]
        if done.size == 0:
            raise InputError(f"{p}: has no complete sample")
        s = int(done[0]) if sample is None else int(sample)
        if s not in set(done.tolist()):
            raise InputError(f"{p}: sample {s} is not complete")
        h = run.surface(s)
        a, u = pixel_size(run), length_unit(run)
        st = statistics(h, a, path=f"{p} (sample {s})", fmt="roughslip run",
                        pixel_size=(a, a), unit=u)
        return st, h
    raw = read_raw(p, key)
    if raw.unit and unit and not math.isclose(metres_per(raw.unit, str(p)),
                                              metres_per(unit, "--unit"), rel_tol=1e-12):
        raise InputError(f"{p}: --unit {unit} contradicts the file's unit {echo(raw.unit)}")
    u = raw.unit or unit
    heights, ps = raw.heights, raw.pixel_size
    if ps is None and pixel is not None:
        ps = (float(pixel), float(pixel))
    elif ps is not None and pixel is not None:  # in the file's unit: --unit agrees
        if not math.isclose(float(pixel), ps[1], rel_tol=1e-9):
            raise InputError(f"{p}: --pixel-size {pixel:g} contradicts the file's "
                             f"{ps[1]:.6g} {u or ''}".rstrip())
    if u is not None and u in LENGTH_UNITS:
        finite = heights[np.isfinite(heights)]
        rms = float(np.sqrt(np.mean((finite - finite.mean()) ** 2))) if finite.size else 0.0
        if rms > 0:
            u2, f = display_unit(rms, u)
            heights = heights * f
            ps = None if ps is None else (ps[0] * f, ps[1] * f)
            u = u2
    if ps is None:
        return statistics(heights, 1.0, path=str(p), fmt=raw.format, pixel_size=None,
                          unit=u), heights
    if not math.isclose(ps[0], ps[1], rel_tol=1e-9):
        h2, sq = _square(heights, ps)
        return statistics(h2, sq[0], path=str(p), fmt=raw.format, pixel_size=ps,
                          unit=u), h2
    return statistics(heights, ps[0], path=str(p), fmt=raw.format, pixel_size=ps,
                      unit=u), heights


def _is_run_file(p: Path) -> bool:
    import h5py

    try:
        with h5py.File(p, "r") as f:
            return f.attrs.get("format") == "roughslip-run"
    except OSError:
        return False


def format_stats(st: TopographyStats) -> str:
    """Plain-text report of :class:`TopographyStats`."""
    u = st.unit or "(no unit)"
    ps = ("not in the file (1 per pixel)" if st.pixel_size is None else
          f"{st.pixel_size[1]:.6g} x {st.pixel_size[0]:.6g} {u} (x, y)")
    lines = [
        f"file:            {st.path}",
        f"format:          {st.format}",
        f"shape:           {st.shape[0]} x {st.shape[1]} (ny x nx)",
        f"pixel size:      {ps}",
        f"height unit:     {u}",
        f"missing points:  {st.missing} of {st.shape[0] * st.shape[1]}",
        f"rms height:      {st.rms_height:.6g} {st.unit or ''}".rstrip(),
        f"rms slope:       {st.rms_slope:.6g}",
        f"rms curvature:   {st.rms_curvature:.6g} per {st.unit or 'length unit'}",
        *_hurst_lines(st),
    ]
    return "\n".join(_wrap(line) for line in lines)


#: columns of the plain-text report (a 100-column terminal, and the column of the docs)
WIDTH = 88


def _wrap(line: str) -> str:
    """A report line folded at :data:`WIDTH` columns, continued under its value."""
    if len(line) <= WIDTH:
        return line
    import textwrap

    indent = " " * 17 if line.startswith(("Hurst", "  how", "file")) else "  "
    return "\n".join(textwrap.wrap(line, WIDTH, subsequent_indent=indent,
                                    break_on_hyphens=False))


def _hurst_lines(st: TopographyStats) -> list[str]:
    per = st.unit or "length unit"
    if not math.isfinite(st.hurst):
        return ["Hurst exponent:  not estimated", *(f"warning: {w}" for w in st.warnings)]
    lo, hi = st.hurst_range
    why_lo = ("4 x the lowest wavenumber, above the window's leakage and the patch size"
              if st.hurst_rolloff is None else
              f"above a roll-off found at q = {st.hurst_rolloff:.4g}")
    why_hi = ("half the Nyquist wavenumber, below the pixel-scale bend" if st.hurst_bend is None
              else f"below a bend (noise floor or pixel scale) found at q = "
                   f"{st.hurst_bend:.4g}")
    return [
        f"Hurst exponent:  {st.hurst:.3f} +- {st.hurst_std:.3f} (one standard deviation, with "
        f"the fit's systematic error: statistical {st.hurst_std_statistical:.3f}, low end of "
        f"the range {st.hurst_sys_low:.3f}, high end {st.hurst_sys_high:.3f})",
        f"  how:           radially averaged PSD, Hann window, C ~ q^-2(1+H) fitted over "
        f"q = {lo:.4g} .. {hi:.4g} rad per {per} ({st.hurst_bins} bins: from {why_lo}, to "
        f"{why_hi})",
        *(f"warning: {w}" for w in st.warnings),
    ]


def plot_stats(st: TopographyStats, h: np.ndarray, out: str | Path) -> Path:
    """Height map and PSD with the fitted power law ``C ~ q^(-2(1+H))``
    (:func:`stats_figure`), written to ``out``."""
    from roughslip.analysis.plotting import pyplot, save

    return save(pyplot(), stats_figure(st, h), out)


def stats_figure(st: TopographyStats, h: np.ndarray) -> Figure:
    """The figure of :func:`plot_stats`: the height map, in the prefix that puts the rms
    height between 1 and 1000 (:func:`display_unit` of ``st.rms_height``, which is taken over
    the valid points, so missing points do not change it; they are drawn white), and the
    radially averaged PSD with the fitted power law."""
    from roughslip.analysis.plotting import finish_axes, log_ticks, pyplot

    plt = pyplot()
    from matplotlib import colormaps

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    ax = axes[0]
    unit = st.unit or "length unit"
    if st.pixel_size is None:
        extent, xl, yl = None, "x (pixels)", "y (pixels)"
    else:
        a = min(st.pixel_size)  # non-square pixels were resampled at the finer spacing
        lat, f = (display_unit(h.shape[1] * a, st.unit) if st.unit in LENGTH_UNITS
                  else (unit, 1.0))
        extent = (0.0, h.shape[1] * a * f, 0.0, h.shape[0] * a * f)
        xl, yl = f"x ({lat})", f"y ({lat})"
    # heights in the prefix that suits them (nm for a 1e-7 m scan), not with an offset; the
    # rms of the statistics, since that of h is NaN when points are missing
    hunit, hf = (display_unit(st.rms_height, st.unit) if st.unit in LENGTH_UNITS
                 else (unit, 1.0))
    cmap = colormaps["viridis"].with_extremes(bad="white")  # missing points
    im = ax.imshow(h * hf, origin="lower", interpolation="nearest", cmap=cmap,
                   extent=extent)
    cb = fig.colorbar(im, ax=ax, fraction=0.046, label=f"height ({hunit})")
    cb.formatter.set_useOffset(False)
    cb.update_ticks()
    title = Path(st.path.split(" (")[0]).name
    if st.missing:
        title += f" ({st.missing} missing point(s), white)"
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax = axes[1]
    q, c = st.psd
    ax.loglog(q, c, "o", ms=3, label="radially averaged PSD")
    if math.isfinite(st.hurst):
        sel = (q >= st.hurst_range[0]) & (q <= st.hurst_range[1])
        if sel.sum() >= 2:
            slope = -2 * (1 + st.hurst)
            c0 = np.exp(np.mean(np.log(c[sel]) - slope * np.log(q[sel])))
            qq = q[sel]
            ax.loglog(qq, c0 * qq**slope, "-", color="C3",
                      label=f"fit: H = {st.hurst:.3f} ± {st.hurst_std:.3f}")
    for qb, what in ((st.hurst_rolloff, "roll-off"), (st.hurst_bend, "bend")):
        if qb is not None:  # left out of the fit (roughslip.surfaces.hurst)
            ax.axvline(qb, color="0.4", ls=":", lw=1, label=f"{what} found, left out")
    log_ticks(ax.xaxis)
    log_ticks(ax.yaxis)
    finish_axes(ax, f"wavenumber q (rad per {st.unit or 'length unit'})",
                f"C(q) ({st.unit or 'length unit'}$^4$)")
    return fig
