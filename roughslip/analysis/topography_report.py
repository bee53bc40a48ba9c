"""Reports on topographies: the statistics of a topography file or of a surface stored in a
run file, as text or as a figure (``roughslip topography``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from roughslip.errors import InputError
from roughslip.surfaces.synthetic import HDF5_SUFFIXES
from roughslip.surfaces.topography import TopographyStats, _square, read_raw, statistics


def describe(path: str | Path, *, key: str | None = None, unit: str | None = None,
             sample: int | None = None) -> tuple[TopographyStats, np.ndarray]:
    """Statistics of a topography file, or of a surface stored in a run file (``sample``:
    its rigid surface; default the first complete sample). Returns the stats and heights."""
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
        cfg = run.config_dict()
        a = float(run.attrs.get("pixel_size", cfg.get("grid", {}).get("pixel_size", 1.0)))
        u = cfg.get("units", {}).get("length")
        st = statistics(h, a, path=f"{p} (sample {s})", fmt="roughslip run",
                        pixel_size=(a, a), unit=u)
        return st, h
    raw = read_raw(p, key)
    u = raw.unit or unit
    if raw.pixel_size is None:
        a, ps = 1.0, None
    else:
        ps = raw.pixel_size
        if not math.isclose(ps[0], ps[1], rel_tol=1e-9):
            h2, sq = _square(raw.heights, ps)
            return statistics(h2, sq[0], path=str(p), fmt=raw.format, pixel_size=ps,
                              unit=u), h2
        a = ps[0]
    return statistics(raw.heights, a, path=str(p), fmt=raw.format, pixel_size=ps,
                      unit=u), raw.heights


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
        f"Hurst exponent:  {st.hurst:.3f} (radially averaged PSD, Hann window, fit over "
        f"q = {st.hurst_range[0]:.4g} .. {st.hurst_range[1]:.4g} rad per "
        f"{st.unit or 'length unit'})",
    ]
    return "\n".join(lines)


def plot_stats(st: TopographyStats, h: np.ndarray, out: str | Path) -> Path:
    """Height map and PSD with the fitted power law ``C ~ q^(-2(1+H))``."""
    from roughslip.analysis.plotting import finish_axes, pyplot, save

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    ax = axes[0]
    im = ax.imshow(h, origin="lower", interpolation="nearest", cmap="viridis")
    fig.colorbar(im, ax=ax, fraction=0.046, label=f"height ({st.unit or 'length unit'})")
    ax.set_title(Path(st.path.split(" (")[0]).name, fontsize=9)
    ax.set_xlabel("ix")
    ax.set_ylabel("iy")
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
                      label=f"fit: H = {st.hurst:.3f}")
    finish_axes(ax, f"wavenumber q (rad per {st.unit or 'length unit'})", "C(q)")
    return save(plt, fig, out)
