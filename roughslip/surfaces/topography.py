r"""Measured topographies: instrument files, units, missing data, preparation, tiles, statistics.

Reading
    The built-in formats (``.npy``, ``.npz``, text matrices, HDF5;
    :func:`~roughslip.surfaces.synthetic.load_topography`) need nothing more; they carry no
    units or pixel size. X3P files (ISO 25178-72, the 2000 and the 2017 revision) are read by
    :func:`roughslip.surfaces.x3p.read_x3p`, with their units, pixel size and missing points,
    and need nothing more either. Every other file is
    read by SurfaceTopography (the ``topography`` extra, ``pip install 'roughslip[topography]'``),
    which recognises about 40 instrument formats by content and extension (:func:`formats`
    lists them), with their units, pixel sizes and masks of missing points. SurfaceTopography
    indexes heights ``[ix, iy]``; they are transposed to roughslip's ``[iy, ix]``.

Units
    A file with a length unit is converted to the run's unit (an error when
    the run has none); a file without one needs its unit (``unit``) when the run has one. The
    pixel size comes from the file when it has one: a pixel size given as well must agree
    (relative 1e-9) unless ``override_pixel_size``.

Preparation, in this order
    1. *Non-square pixels* are resampled onto square pixels at the finer of the two spacings,
       by linear interpolation along the coarser axis over the same physical extent (end points
       kept), which leaves the heights at the original rows or columns unchanged.
    2. *Crop* ``[y0, y1, x0, x1]`` (pixel indices of the resampled grid, end excluded).
    3. *Missing points* (NaN in built-in formats, masked points in instrument files): an error
       by default naming the file and the count; ``interpolate`` fills each from its valid
       neighbours (a harmonic fill: the discrete Laplace equation with the valid points as
       boundary values, solved directly); ``void`` keeps them as points that never touch
       (stored as NaN; during the squeeze they sit far below every other point, which in this
       model is exact: a void carries no force).
    4. *Down-sampling* by ``k``: means of ``k x k`` blocks (missing points excluded; a block
       with no valid point stays missing); the pixel size grows by ``k``.
    5. *Tiles* ``[ny, nx]``: the scan is cut into equal tiles (the remainder rows and columns at
       the high end are dropped), sample ``i`` is tile ``i`` in row-major order.
    6. *Detrending* per tile, on the valid points: ``mean``, ``tilt`` (least-squares plane) or
       ``curvature`` (least-squares quadric).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from roughslip.errors import InputError, echo, shorten
from roughslip.surfaces.limits import (
    MIN_SCAN_SIDE,
    SIDE_RULE,
    Refused,
    check_archive,
    check_scan,
)
from roughslip.surfaces.synthetic import HDF5_SUFFIXES, TEXT_SUFFIXES, load_topography
from roughslip.surfaces.x3p import read_x3p

BUILTIN_SUFFIXES = (".npy", ".npz", *TEXT_SUFFIXES, *HDF5_SUFFIXES)
EXTRA_HINT = "pip install 'roughslip[topography]'"

#: length units a run and a file can be in, in metres
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "nm": 1e-9, "pm": 1e-12}

#: unit spellings of instrument files -> LENGTH_UNITS keys (or metres per unit)
_UNIT_ALIASES: dict[str, float] = {
    **LENGTH_UNITS, "µm": 1e-6, "μm": 1e-6, "micrometer": 1e-6, "micron": 1e-6,
    "Å": 1e-10, "A": 1e-10, "angstrom": 1e-10, "km": 1e3, "cm": 1e-2, "dm": 1e-1,
}


@dataclass(frozen=True)
class RawTopography:
    """A height map as read, before preparation.

    ``heights`` are ``[iy, ix]`` with NaN at missing points; ``pixel_size`` is ``(dy, dx)`` in
    ``unit``, or None when the file gives none.
    """

    heights: np.ndarray
    pixel_size: tuple[float, float] | None
    unit: str | None
    format: str
    path: str
    channel: str | None = None


def metres_per(unit: str, where: str) -> float:
    """Metres per ``unit``; an InputError naming ``where`` for an unknown unit."""
    try:
        return _UNIT_ALIASES[unit]
    except KeyError:
        raise InputError(f"{where}: unknown length unit {echo(unit)} (known: "
                         f"{', '.join(_UNIT_ALIASES)})") from None


def formats() -> list[tuple[str, str]]:
    """``(name, file extensions)`` of every format SurfaceTopography reads (empty without the
    extra)."""
    try:
        from SurfaceTopography.IO import readers
    except ImportError:
        return []
    out = []
    for r in readers:
        exts = getattr(r, "_file_extensions", None) or []
        out.append((r.name(), ", ".join(f".{e}" for e in exts)))
    return out


def read_raw(path: str | Path, key: str | None = None) -> RawTopography:
    """Read a topography file: built-in formats directly, others through SurfaceTopography.

    Every format, for a run and for ``roughslip topography``, ends in the same check of what
    was read (:func:`~roughslip.surfaces.limits.check_scan`): at least
    :data:`~roughslip.surfaces.limits.MIN_SCAN_SIDE` pixels along each axis, a valid point,
    and heights that are not constant. Headers and archive members are checked before they
    are read (:mod:`roughslip.surfaces.limits`).

    Parameters
    ----------
    path : str or Path
        The file.
    key : str, optional
        Channel (instrument files), array (``.npz``), dataset (HDF5) or layer (X3P).

    Returns
    -------
    RawTopography

    Raises
    ------
    InputError
        One line naming the file and the rule it breaks.
    MemoryLimitError
        When the heights a file declares do not fit in the memory available.
    """
    p = Path(path)
    name = str(p)
    if p.is_dir():
        raise InputError(f"{name}: is a directory, not a topography file")
    if not p.is_file():
        raise InputError(f"{name}: no such file")
    if p.stat().st_size == 0:
        raise InputError(f"{name}: is empty (0 bytes)")
    raw = _read_any(p, key)
    check_scan(raw.heights, name)
    return raw


def _read_any(p: Path, key: str | None) -> RawTopography:
    name = str(p)
    if p.suffix.lower() == ".x3p":
        return _read_x3p(p, key)
    if p.suffix.lower() in BUILTIN_SUFFIXES:
        try:
            h = load_topography(p, key, allow_missing=True)
            return RawTopography(h, None, None, p.suffix.lower().lstrip("."), name, key)
        except Refused:
            raise  # too large, or not what it declares: no other reader may trust it
        except InputError as builtin_error:
            # an instrument file with a common extension (e.g. Zygo MetroPro .dat)?
            try:
                return _read_instrument(p, key)
            except InputError:
                raise builtin_error from None
    return _read_instrument(p, key)


def _read_x3p(p: Path, key: str | None) -> RawTopography:
    """X3P of either revision, by :func:`roughslip.surfaces.x3p.read_x3p` (no extra needed);
    ``key`` is the layer number of a multi-layer file."""
    layer = 0
    if key is not None:
        try:
            layer = int(key)
        except ValueError:
            raise InputError(f"{p}: key {echo(key)}: an X3P file's key is its layer number "
                             "(0, 1, ...)") from None
    h, pixel, _revision = read_x3p(p, layer)
    return RawTopography(h, pixel, "m", "x3p", str(p), f"layer {layer}")


def _read_instrument(p: Path, key: str | None) -> RawTopography:
    name = str(p)
    try:
        from SurfaceTopography import open_topography
    except ImportError:
        raise InputError(f"{name}: reading {p.suffix or 'this'} files needs the topography "
                         f"extra: {EXTRA_HINT}") from None
    check_archive(name, name)  # zip-based formats: every member's size and ratio
    try:
        reader = open_topography(name)
        channels = list(reader.channels)
        if key is None:
            index = reader.default_channel.index
        else:
            names = [c.name for c in channels]
            if key not in names:
                raise InputError(f"{name}: no channel {echo(key)} (it has {echo(names)})")
            index = names.index(key)
        ch = channels[index]
        if ch.dim != 2:
            raise InputError(f"{name}: channel {echo(ch.name)} is a line scan, not a 2-D map")
        t = reader.topography(channel_index=index)
        if not t.is_uniform:
            raise InputError(f"{name}: non-uniform grid; roughslip needs a uniform one")
        h = t.heights()
        if isinstance(h, np.ma.MaskedArray):
            h = h.astype(float).filled(np.nan)
        h = np.array(h, dtype=float).T  # [ix, iy] -> [iy, ix]
        sx, sy = (float(v) for v in t.pixel_size)
        unit = t.unit
        fmt = type(reader).__name__.removesuffix("Reader").lower()
    except InputError:
        raise
    except Exception as exc:  # the reader's own errors: corrupt, truncated, unknown format
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{name}: cannot read as a topography ({type(exc).__name__}: "
                         f"{shorten(msg)})") from None
    if h.ndim != 2 or h.size == 0:
        raise InputError(f"{name}: holds no 2-D height map")
    if np.isinf(h).any():
        raise InputError(f"{name}: {int(np.isinf(h).sum())} infinite height(s)")
    return RawTopography(h, (sy, sx), unit, fmt, name, ch.name)


# ----------------------------------------------------------------------------------------------
# Preparation
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PreparedTopography:
    """Heights ready for a run: ``tiles`` (one or more ``[iy, ix]`` arrays, NaN at voids), the
    square pixel size in the run's unit, and what was done."""

    tiles: list[np.ndarray]
    pixel_size: float
    provenance: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def shape(self) -> tuple[int, int]:
        return self.tiles[0].shape


@dataclass(frozen=True)
class Preparation:
    """How to prepare a measured topography (module docstring), in plain values.

    ``pixel_size`` is the spacing of a file that gives none (or of any file, with
    ``override_pixel_size``), before down-sampling; ``pixel_given`` says whether the user set
    it (then it must agree with a file that gives one); ``run_unit`` is the run's length unit.
    ``names`` says how error messages name each parameter (for a run: its configuration
    key, e.g. ``{"crop": "surface.crop"}``); a parameter not in it is named as here.
    """

    unit: str | None = None
    scale: float = 1.0
    override_pixel_size: bool = False
    missing: str = "error"
    detrend: str = "none"
    crop: list[int] | None = None
    downsample: int = 1
    tiles: list[int] | None = None
    run_unit: str | None = None
    pixel_size: float = 1.0
    pixel_given: bool = False
    names: Mapping[str, str] = field(default_factory=dict)

    def key(self, name: str) -> str:
        """How messages name parameter ``name``."""
        return self.names.get(name, name)


def prepare(raw: RawTopography, how: Preparation) -> PreparedTopography:
    """Units, resampling, crop, missing points, down-sampling, tiles and detrending (module
    docstring), each with an InputError naming the file and the parameter when impossible."""
    sc, run_unit, grid_pixel, pixel_given = how, how.run_unit, how.pixel_size, how.pixel_given
    name = raw.path
    notes: list[str] = []
    h = raw.heights
    # units: heights and pixel size to the run's unit
    file_unit = raw.unit
    if file_unit is not None and sc.unit is not None:
        if metres_per(file_unit, name) != metres_per(sc.unit, name):
            raise InputError(f"{name}: the file's unit is {echo(file_unit)}; {how.key('unit')} = "
                             f"{sc.unit!r} contradicts it (remove {how.key('unit')})")
    unit = file_unit or sc.unit
    if unit is not None and run_unit is None:
        ru = how.key("run_unit")
        raise InputError(f"{name}: heights are in {echo(unit)}; set {ru} (e.g. "
                         f"{ru} = \"um\") to say which unit the run uses")
    if unit is None and run_unit is not None:
        raise InputError(f"{name}: the file carries no unit; set {how.key('unit')} (the unit "
                         f"of its heights and pixel size)")
    factor = 1.0 if unit is None else metres_per(unit, name) / metres_per(run_unit, name)
    h = h * (factor * sc.scale)
    finite = h[np.isfinite(h)]
    height_scale = float(np.max(np.abs(finite))) if finite.size else 0.0
    pixel = None if raw.pixel_size is None else (raw.pixel_size[0] * factor,
                                                 raw.pixel_size[1] * factor)
    prov: dict[str, Any] = {"file": name, "format": raw.format, "channel": raw.channel,
                            "file_unit": unit, "file_shape": list(raw.heights.shape),
                            "file_pixel_size": None if pixel is None else list(pixel)}
    # 1. non-square pixels
    if pixel is not None and not math.isclose(pixel[0], pixel[1], rel_tol=1e-9):
        h, pixel = _square(h, pixel)
        notes.append(f"{Path(name).name}: pixels {raw.pixel_size[0]:.6g} x "
                     f"{raw.pixel_size[1]:.6g} {unit} resampled to square "
                     f"{pixel[0]:.6g} (linear interpolation), grid {list(h.shape)}")
        prov["resampled_to"] = list(h.shape)
    # the grid's pixel size against the file's
    if sc.override_pixel_size:
        if not pixel_given:
            raise InputError(f"{how.key('override_pixel_size')} needs "
                             f"{how.key('pixel_size')}")
        a = grid_pixel
        prov["pixel_size_overridden"] = True
    elif pixel is None:
        a = grid_pixel
    elif pixel_given and not math.isclose(pixel[0], grid_pixel, rel_tol=1e-9):
        px = how.key("pixel_size")
        raise InputError(f"{name}: the file's pixel size is {pixel[0]:.10g} "
                         f"{run_unit or ''}; {px} = {grid_pixel!r} contradicts it "
                         f"(remove {px}, or set {how.key('override_pixel_size')} = true)")
    else:
        a = pixel[0]
    # 2. crop
    if sc.crop is not None:
        y0, y1, x0, x1 = sc.crop
        if y1 > h.shape[0] or x1 > h.shape[1]:
            raise InputError(f"{how.key('crop')} = {sc.crop}: outside the grid of {name} "
                             f"({list(h.shape)})")
        h = h[y0:y1, x0:x1]
        if min(h.shape) < MIN_SCAN_SIDE:
            raise InputError(f"{how.key('crop')} = {sc.crop}: leaves {h.shape[0]} x "
                             f"{h.shape[1]} pixels (ny x nx) of {name}: {SIDE_RULE}")
    # 3. missing points
    missing = ~np.isfinite(h)
    n_missing = int(missing.sum())
    prov.update(missing=sc.missing, missing_points=n_missing)
    if n_missing == h.size:
        raise InputError(f"{name}: every point is missing (NaN or masked)")
    if n_missing and sc.missing == "error":
        iy, ix = (int(v) for v in np.argwhere(missing)[0])
        raise InputError(f"{name}: {n_missing} missing point(s) of {h.size} (NaN or masked), "
                         f"first at [iy, ix] = [{iy}, {ix}]; set {how.key('missing')} = "
                         f"\"interpolate\" or \"void\"")
    if n_missing and sc.missing == "interpolate":
        h = harmonic_fill(h)
        notes.append(f"{Path(name).name}: {n_missing} missing point(s) interpolated")
    elif n_missing:
        notes.append(f"{Path(name).name}: {n_missing} missing point(s) kept as voids")
    # 4. down-sampling
    k = sc.downsample
    if k > 1:
        ny, nx = (h.shape[0] // k) * k, (h.shape[1] // k) * k
        if min(ny, nx) < MIN_SCAN_SIDE * k:
            raise InputError(f"{how.key('downsample')} = {k}: leaves {h.shape[0] // k} x "
                             f"{h.shape[1] // k} pixels (ny x nx) of the {list(h.shape)} grid "
                             f"of {name}: {SIDE_RULE}")
        blocks = h[:ny, :nx].reshape(ny // k, k, nx // k, k)
        valid = np.isfinite(blocks)
        count = valid.sum(axis=(1, 3))
        with np.errstate(invalid="ignore", divide="ignore"):
            h = np.where(valid, blocks, 0.0).sum(axis=(1, 3)) / count
        h[count == 0] = np.nan
        a = a * k
    # 5. tiles
    ty, tx = sc.tiles or (1, 1)
    sy, sx = h.shape[0] // ty, h.shape[1] // tx
    if min(sy, sx) < MIN_SCAN_SIDE:  # (without tiles the steps above ensure the size)
        raise InputError(f"{how.key('tiles')} = {sc.tiles}: tiles of {sy} x {sx} pixels "
                         f"(ny x nx) from the {list(h.shape)} grid of {name}: "
                         f"{SIDE_RULE.replace('a scan', 'a tile')}; use fewer tiles")
    tiles = [h[i * sy:(i + 1) * sy, j * sx:(j + 1) * sx].copy()
             for i in range(ty) for j in range(tx)]
    for i, t in enumerate(tiles):
        if not np.isfinite(t).any():
            raise InputError(f"{name}: tile {i} has no valid point")
    # 6. detrending
    if sc.detrend != "none":
        tiles = [detrend(t, sc.detrend) for t in tiles]
    # none may be flat: measured against the file's heights, so that a trend removed down to
    # rounding, or a crop of a flat region, is seen
    steps = [how.key(s) for s, done in (("crop", sc.crop is not None), ("downsample", k > 1),
                                        ("tiles", sc.tiles is not None),
                                        ("detrend", sc.detrend != "none")) if done]
    for i, t in enumerate(tiles):
        piece = f"tile {i}" if len(tiles) > 1 else "the prepared grid"
        check_scan(t, f"{name}: {piece} (after {', '.join(steps)})" if steps else name,
                   scale=height_scale)
    prov.update(pixel_size=a, unit=run_unit, crop=sc.crop, downsample=k, tiles=[ty, tx],
                tile_shape=[sy, sx], detrend=sc.detrend)
    return PreparedTopography(tiles, a, prov, notes)


def _square(h: np.ndarray, pixel: tuple[float, float]) -> tuple[np.ndarray, tuple[float, float]]:
    """Linear interpolation along the coarser axis onto the finer spacing (same extent)."""
    dy, dx = pixel
    fine = min(dy, dx)
    axis = 0 if dy > dx else 1
    n = h.shape[axis]
    length = (n - 1) * max(dy, dx)
    m = math.floor(length / fine + 1e-9) + 1
    old = np.arange(n) * max(dy, dx)
    new = np.arange(m) * fine
    hh = np.moveaxis(h, axis, 0)
    out = np.empty((m, hh.shape[1]))
    for c in range(hh.shape[1]):
        col = hh[:, c]
        ok = np.isfinite(col)
        out[:, c] = np.interp(new, old[ok], col[ok]) if ok.sum() >= 2 else np.nan
        # a new point next to a missing old one is missing too
        near = np.clip(np.searchsorted(old, new, side="right") - 1, 0, n - 2)
        bad = ~(ok[near] & ok[np.minimum(near + 1, n - 1)])
        out[bad, c] = np.nan
    return np.moveaxis(out, 0, axis), (fine, fine)


def harmonic_fill(h: np.ndarray) -> np.ndarray:
    """Fill NaN points by solving the 5-point discrete Laplace equation on them, with the valid
    points as boundary values (grid edges: zero normal derivative)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    miss = ~np.isfinite(h)
    ny, nx = h.shape
    idx = -np.ones(h.shape, dtype=np.int64)
    idx[miss] = np.arange(int(miss.sum()))
    rows, cols, vals = [], [], []
    rhs = np.zeros(int(miss.sum()))
    ys, xs = np.nonzero(miss)
    for r, (y, x) in enumerate(zip(ys, xs, strict=True)):
        deg = 0
        for yy, xx in ((y - 1, x), (y + 1, x), (y, x - 1), (y, x + 1)):
            if not (0 <= yy < ny and 0 <= xx < nx):
                continue
            deg += 1
            if miss[yy, xx]:
                rows.append(r)
                cols.append(idx[yy, xx])
                vals.append(-1.0)
            else:
                rhs[r] += h[yy, xx]
        rows.append(r)
        cols.append(r)
        vals.append(float(deg))
    A = sp.csr_matrix((vals, (rows, cols)), shape=(rhs.size, rhs.size))
    out = h.copy()
    out[miss] = np.atleast_1d(spsolve(A, rhs))
    return out


def detrend(h: np.ndarray, mode: str) -> np.ndarray:
    """Subtract the least-squares mean, plane or quadric fitted to the finite points."""
    if mode == "none":
        return h
    ny, nx = h.shape
    y, x = np.mgrid[0:ny, 0:nx].astype(float)
    y, x = y - (ny - 1) / 2, x - (nx - 1) / 2
    terms = [np.ones_like(x)]
    if mode in ("tilt", "curvature"):
        terms += [x, y]
    if mode == "curvature":
        terms += [x * x, x * y, y * y]
    if mode not in ("mean", "tilt", "curvature"):
        raise InputError(f"detrend = {mode!r}: must be none, mean, tilt or curvature")
    ok = np.isfinite(h)
    A = np.stack([t[ok] for t in terms], axis=1)
    coef, *_ = np.linalg.lstsq(A, h[ok], rcond=None)
    return h - sum(c * t for c, t in zip(coef, terms, strict=True))


# ----------------------------------------------------------------------------------------------
# Statistics (`roughslip topography`)
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TopographyStats:
    """What a user checks before a run.

    The Hurst exponent comes from :func:`~roughslip.surfaces.hurst.fit_hurst`: ``hurst_std``
    is one standard deviation including the fit's systematic error,
    ``hurst_std_statistical``, ``hurst_sys_low`` and ``hurst_sys_high`` its parts, and
    ``hurst_rolloff`` and ``hurst_bend`` the wavenumbers of a roll-off and of a noise floor
    or pixel-scale bend detected in the spectrum and left out of the fit (None: none).
    """

    path: str
    format: str
    shape: tuple[int, int]
    pixel_size: tuple[float, float] | None
    unit: str | None
    missing: int
    rms_height: float
    rms_slope: float
    rms_curvature: float
    hurst: float
    hurst_range: tuple[float, float]  # wavenumbers of the fit (rad per length unit)
    psd: tuple[np.ndarray, np.ndarray] = field(repr=False)
    hurst_std: float = math.nan
    hurst_std_statistical: float = math.nan
    hurst_sys_low: float = math.nan
    hurst_sys_high: float = math.nan
    hurst_rolloff: float | None = None
    hurst_bend: float | None = None
    hurst_bins: int = 0  # wavenumber bins in the fit
    warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in ("path", "format", "shape", "pixel_size", "unit",
                                           "missing", "rms_height", "rms_slope",
                                           "rms_curvature", "hurst", "hurst_std",
                                           "hurst_std_statistical", "hurst_sys_low",
                                           "hurst_sys_high", "hurst_bins", "hurst_range",
                                           "hurst_rolloff", "hurst_bend")}
        d["warnings"] = list(self.warnings)
        d["shape"] = list(self.shape)
        return d


#: fewest wavenumber bins in the Hurst fit before the report warns: 2.5 octaves at the 4 bins
#: per octave of :func:`~roughslip.surfaces.hurst.spectrum_bins`
HURST_MIN_BINS = 10


def statistics(h: np.ndarray, a: float = 1.0, *, path: str = "", fmt: str = "",
               pixel_size: tuple[float, float] | None = None, unit: str | None = None
               ) -> TopographyStats:
    r"""rms height, slope (:func:`~roughslip.surfaces.synthetic.rms_slope_of`), curvature
    (:math:`\sqrt{\langle(\nabla^2 h/2)^2\rangle}` by central differences inside the grid) and
    the Hurst exponent with one standard deviation that includes the fit's systematic error,
    from the radially averaged PSD over a range chosen from the spectrum
    (:func:`~roughslip.surfaces.hurst.fit_hurst`), with warnings when the exponent leaves
    (0, 1), the range holds fewer than :data:`HURST_MIN_BINS` bins or the standard
    deviation exceeds 0.1. Missing points are filled harmonically first (and counted)."""
    from roughslip.surfaces.hurst import fit_hurst, spectrum_bins
    from roughslip.surfaces.synthetic import rms_height_of, rms_slope_of

    miss = int((~np.isfinite(h)).sum())
    if miss == h.size:
        raise InputError(f"{path}: every point is missing")
    hh = harmonic_fill(h) if miss else h
    lap = (hh[2:, 1:-1] + hh[:-2, 1:-1] + hh[1:-1, 2:] + hh[1:-1, :-2]
           - 4 * hh[1:-1, 1:-1]) / a**2 if min(h.shape) >= 3 else np.zeros(1)
    ny, nx = h.shape
    warnings = []
    try:
        fit = fit_hurst(hh, a)
    except InputError as exc:
        fit = None
        warnings.append(f"no Hurst exponent: {exc}")
    if fit is None:
        q, c, _ = spectrum_bins(hh, a)
        hurst_kw: dict[str, Any] = {"hurst": math.nan, "hurst_range": (math.nan, math.nan),
                                    "psd": (q, c)}
    else:
        hurst_kw = {"hurst": fit.hurst, "hurst_range": (fit.qmin, fit.qmax),
                    "psd": fit.psd[:2], "hurst_std": fit.std,
                    "hurst_std_statistical": fit.std_statistical,
                    "hurst_sys_low": fit.sys_low, "hurst_sys_high": fit.sys_high,
                    "hurst_rolloff": fit.rolloff, "hurst_bend": fit.bend,
                    "hurst_bins": fit.bins}
        if not 0 < fit.hurst < 1:
            warnings.append(f"the Hurst exponent {fit.hurst:.3f} lies outside (0, 1): the "
                            "surface is not self-affine over the fitted wavenumbers (a trend, "
                            "a form or a filter?)")
        if fit.bins < HURST_MIN_BINS:
            warnings.append(f"the fit range holds only {fit.bins} wavenumber bins (fewer "
                            f"than {HURST_MIN_BINS}): too short for a reliable exponent")
        if fit.std > 0.1:
            warnings.append(f"the exponent is uncertain on a {ny} x {nx} grid "
                            f"(+- {fit.std:.2f})")
    return TopographyStats(path, fmt, (ny, nx), pixel_size, unit, miss, rms_height_of(hh),
                           rms_slope_of(hh, a), float(np.sqrt(np.mean((lap / 2) ** 2))),
                           warnings=tuple(warnings), **hurst_kw)
