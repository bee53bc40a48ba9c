r"""Topographies: self-affine random surfaces, analytic shapes, measured files, statistics.

Heights are 2-D arrays indexed ``[iy, ix]``; pixel centres sit at ``x = ix a``, ``y = iy a``.
Positive heights protrude toward the other body (docs/theory/squeeze.rst#squeeze-problem).

Self-affine surfaces ([Report2003] §4.3)
    White noise is Fourier filtered by :math:`|k|^{-(H+1)}` (signed frequencies, :math:`k=0`
    term zero), so that the isotropic power spectrum is :math:`C(q)\propto q^{-2(1+H)}`. Below an
    optional roll-off wavenumber the filter is flat; above an optional cut-off it is zero. The
    result is shifted to zero mean and scaled to the requested rms height or rms slope. With
    ``oversample = m`` the surface is generated on an ``m``-times larger periodic grid and
    cropped, so that an open-boundary study does not inherit periodicity.

All randomness comes from the generator passed in; :func:`sample_rng` derives sample ``i`` of a
run from ``SeedSequence(seed).spawn``, independently of how samples are distributed to workers.
"""

from __future__ import annotations

import io
import math
import zipfile
from pathlib import Path
from typing import IO

import numpy as np

from roughslip.errors import InputError, echo, shorten
from roughslip.surfaces.limits import (
    MAX_COMPRESSION_RATIO,
    MAX_SCAN_POINTS,
    Refused,
    check_array,
    read_exactly,
    read_member,
)


def sample_rng(seed: int, index: int) -> np.random.Generator:
    """Generator of sample ``index``: child ``index`` of ``SeedSequence(seed).spawn``."""
    if int(seed) < 0 or int(index) < 0:
        raise InputError(f"seed = {seed}, sample index = {index}: must be >= 0")
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(index),)))


def coordinates(shape: tuple[int, int], a: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre coordinates ``x`` (shape ``(1, nx)``) and ``y`` (shape ``(ny, 1)``)."""
    ny, nx = shape
    return (np.arange(nx) * a)[None, :], (np.arange(ny) * a)[:, None]


def _grid_center(shape: tuple[int, int], a: float) -> tuple[float, float]:
    ny, nx = shape
    return 0.5 * (nx - 1) * a, 0.5 * (ny - 1) * a


# --------------------------------------------------------------------------------------------
# Self-affine
# --------------------------------------------------------------------------------------------


def self_affine(
    shape: tuple[int, int],
    *,
    hurst: float,
    rng: np.random.Generator,
    a: float = 1.0,
    rms_height: float | None = None,
    rms_slope: float | None = None,
    rolloff_wavelength: float | None = None,
    cutoff_wavelength: float | None = None,
    oversample: int = 1,
    anisotropy: float = 1.0,
) -> np.ndarray:
    r"""Random self-affine surface by Fourier filtering ([Report2003] §4.3).

    Parameters
    ----------
    shape : (ny, nx)
    hurst : float
        Hurst exponent, :math:`0 < H < 1`.
    rng : numpy.random.Generator
        Source of the white noise (see :func:`sample_rng`).
    a : float
        Pixel side.
    rms_height, rms_slope : float
        Exactly one: the rms height :math:`\sqrt{\langle h^2\rangle}` or the rms slope
        :math:`\sqrt{\langle|\nabla h|^2\rangle}` (forward differences inside the grid).
    rolloff_wavelength, cutoff_wavelength : float, optional
        The spectrum is flat for wavelengths longer than the roll-off and zero for wavelengths
        shorter than the cut-off.
    oversample : int
        Generate on an ``oversample``-times larger periodic grid and crop the top-left corner.
    anisotropy : float
        :math:`\gamma = \xi_y/\xi_x > 0`, the ratio of the lengths over which the heights are
        correlated along y and along x. The filter is that of the isotropic surface evaluated
        at :math:`\mathbf q' = (q_x, \gamma q_y)`, so the surface is the isotropic one
        stretched by :math:`\gamma` along y (its roll-off and cut-off wavelengths too, along
        y): ridges run along y for :math:`\gamma > 1`, along x for :math:`\gamma < 1`
        (the Peklenik number of tribology). 1: isotropic.

    Returns
    -------
    ndarray
        Zero-mean heights, scaled exactly to the requested rms.
    """
    ny, nx = _check_shape(shape)
    if not 0.0 < hurst < 1.0:
        raise InputError(f"hurst = {hurst!r}: must be in (0, 1)")
    if (rms_height is None) == (rms_slope is None):
        raise InputError("give exactly one of rms_height and rms_slope")
    target = rms_height if rms_height is not None else rms_slope
    if not (math.isfinite(target) and target > 0):
        raise InputError(f"rms = {target!r}: must be a finite number > 0")
    m = int(oversample)
    if m < 1:
        raise InputError(f"oversample = {oversample!r}: must be >= 1")
    if not (math.isfinite(anisotropy) and anisotropy > 0):
        raise InputError(f"anisotropy = {anisotropy!r}: must be a finite number > 0")
    my, mx = ny * m, nx * m
    noise = rng.standard_normal((my, mx))
    spec = np.fft.rfft2(noise)
    ky = np.fft.fftfreq(my, d=a)[:, None]
    kx = np.fft.rfftfreq(mx, d=a)[None, :]
    k = np.hypot(kx, ky if anisotropy == 1.0 else anisotropy * ky)
    kk = k.copy()
    if rolloff_wavelength is not None:
        kk = np.maximum(kk, 1.0 / rolloff_wavelength)
    kk[0, 0] = 1.0
    filt = kk ** (-(hurst + 1.0))
    filt[0, 0] = 0.0
    if cutoff_wavelength is not None:
        filt[k > 1.0 / cutoff_wavelength] = 0.0
    h = np.fft.irfft2(spec * filt, s=(my, mx))[:ny, :nx]
    h = h - h.mean()
    cur = rms_height_of(h) if rms_height is not None else rms_slope_of(h, a)
    if not cur > 0:
        raise InputError(
            "the filtered surface is flat (is the cut-off wavelength shorter than the grid "
            "allows, or the grid too small?)"
        )
    return h * (target / cur)


def _check_shape(shape) -> tuple[int, int]:
    try:
        ny, nx = (int(s) for s in shape)
    except (TypeError, ValueError):
        raise InputError(f"shape {shape!r}: must be (ny, nx)") from None
    if ny < 1 or nx < 1:
        raise InputError(f"shape {shape!r}: both lengths must be >= 1")
    return ny, nx


# --------------------------------------------------------------------------------------------
# Analytic shapes
# --------------------------------------------------------------------------------------------


def sphere(shape, *, radius: float, a: float = 1.0, center=None) -> np.ndarray:
    r"""Paraboloid :math:`h = -((x-x_0)^2+(y-y_0)^2)/(2R)`, apex height 0.

    The default apex is the grid centre: a pixel corner for even sizes, a pixel centre for odd.
    """
    shape = _check_shape(shape)
    if not radius > 0:
        raise InputError(f"radius = {radius!r}: must be > 0")
    x0, y0 = _grid_center(shape, a) if center is None else center
    x, y = coordinates(shape, a)
    return -((x - x0) ** 2 + (y - y0) ** 2) / (2.0 * radius)


def punch(shape, *, radius: float, a: float = 1.0, center=None, step: float | None = None
          ) -> np.ndarray:
    """Flat circular punch: 0 on pixels whose centre lies inside ``radius``, ``-step`` outside.

    ``step`` defaults to the grid's larger side; sites outside never touch while the depth is
    smaller than the step.
    """
    shape = _check_shape(shape)
    if not radius > 0:
        raise InputError(f"radius = {radius!r}: must be > 0")
    step = max(shape) * a if step is None else step
    if not step > 0:
        raise InputError(f"step = {step!r}: must be > 0")
    x0, y0 = _grid_center(shape, a) if center is None else center
    x, y = coordinates(shape, a)
    inside = (x - x0) ** 2 + (y - y0) ** 2 < radius**2
    if not inside.any():
        raise InputError(f"punch radius {radius:g} contains no pixel centre")
    return np.where(inside, 0.0, -float(step))


def sinusoid(shape, *, amplitude: float, wavelength: float, a: float = 1.0,
             direction: str = "x", phase: float = 0.0) -> np.ndarray:
    r"""1-D sinusoid :math:`h = \Delta\cos(2\pi x/\lambda + \phi)` extruded along the other axis."""
    shape = _check_shape(shape)
    if direction not in ("x", "y"):
        raise InputError(f"direction = {direction!r}: must be 'x' or 'y'")
    x, y = coordinates(shape, a)
    s = x if direction == "x" else y
    return np.broadcast_to(amplitude * np.cos(2 * np.pi * s / wavelength + phase), shape).copy()


def plane(shape, *, a: float = 1.0, slope=(0.0, 0.0)) -> np.ndarray:
    """Plane ``h = sx x + sy y`` (flat by default)."""
    shape = _check_shape(shape)
    x, y = coordinates(shape, a)
    return np.broadcast_to(slope[0] * x + slope[1] * y, shape).astype(float)


# --------------------------------------------------------------------------------------------
# Measured topographies
# --------------------------------------------------------------------------------------------

TEXT_SUFFIXES = (".txt", ".csv", ".dat", ".asc")
HDF5_SUFFIXES = (".h5", ".hdf5", ".hdf")


def load_topography(path: str | Path, key: str | None = None, scale: float = 1.0,
                    allow_missing: bool = False) -> np.ndarray:
    """Read a 2-D height map; never executes code from the file.

    Supported: ``.npy`` (never pickled data), ``.npz`` (array ``key``, or the only one),
    text matrices (``.txt``, ``.dat``, ``.asc`` whitespace- and ``.csv`` comma-separated), HDF5
    (dataset ``key``, or the only dataset). Empty, 1-D, ragged or non-numeric input, infinite
    values, and NaN (missing points) unless ``allow_missing``, are rejected with an
    :class:`InputError` naming the file. The header of an array (``.npy``, an ``.npz`` member,
    an HDF5 dataset) is checked before its data is read: the shape and data type against the
    data the file holds, :data:`~roughslip.surfaces.limits.MAX_SCAN_POINTS` and the memory
    available, and an ``.npz`` member's size and compression ratio
    (:mod:`roughslip.surfaces.limits`). Instrument formats:
    :mod:`roughslip.surfaces.topography`.
    """
    p = Path(path)
    name = str(p)
    if not p.is_file():
        raise InputError(f"{name}: no such file")
    suffix = p.suffix.lower()
    try:
        if suffix == ".npy":
            with p.open("rb") as fh:
                arr = _read_npy(fh, p.stat().st_size, name)
        elif suffix == ".npz":
            arr = _load_npz(p, key)
        elif suffix in TEXT_SUFFIXES:
            arr = _load_text(p, "," if suffix == ".csv" else None)
        elif suffix in HDF5_SUFFIXES:
            arr = _load_hdf5(p, key)
        else:
            raise InputError(
                f"{name}: unknown topography format {echo(suffix)} (built in: .npy, .npz, "
                f"{', '.join(TEXT_SUFFIXES)}, {', '.join(HDF5_SUFFIXES)}; instrument formats "
                "through roughslip.surfaces.topography)"
            )
    except InputError:
        raise
    except (ValueError, zipfile.BadZipFile, EOFError) as exc:
        msg = str(exc)
        if "pickle" in msg.lower():
            msg = "holds Python objects (pickled data is never loaded)"
        raise InputError(f"{name}: cannot read heights ({shorten(msg)})") from None
    except OSError as exc:
        raise InputError(f"{name}: cannot read ({shorten(str(exc))})") from None
    return _validate(np.asarray(arr), name, allow_missing) * float(scale)


def _read_npy(fh: IO[bytes], size: int, where: str) -> np.ndarray:
    """An array in the ``.npy`` format from ``fh`` (at its start; ``size`` bytes in all), its
    header checked before the data is read (:func:`~roughslip.surfaces.limits.check_array`)."""
    from numpy.lib import format as npy

    try:
        version = npy.read_magic(fh)
        # 3.0 differs from 2.0 only in UTF-8 field names, which a height map has none of
        read = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
        shape, fortran, dtype = read(fh)
    except ValueError as exc:
        raise InputError(f"{where}: not a .npy array ({shorten(str(exc))})") from None
    check_array(shape, dtype, size - fh.tell(), where)
    data = read_exactly(fh, math.prod(shape) * dtype.itemsize, where)
    arr = np.frombuffer(data, dtype=dtype)
    return arr.reshape(shape[::-1]).T if fortran else arr.reshape(shape)


def _load_npz(p: Path, key: str | None) -> np.ndarray:
    """Array ``key`` (or the only one) of an ``.npz`` archive, its member's declared size and
    compression ratio, and its header, checked before its data is read."""
    name = str(p)
    with zipfile.ZipFile(p) as z:
        members = {n.removesuffix(".npy"): n for n in z.namelist()}  # as numpy names them
        names = list(members)
        if key is None:
            if len(names) != 1:
                raise InputError(f"{name}: holds arrays {echo(names)}; set surface.key")
            key = names[0]
        if key not in members:
            raise InputError(f"{name}: no array {echo(key)} (it has {echo(names)})")
        info = z.getinfo(members[key])
        header = 2**16  # the largest .npy header numpy reads, and more
        data = read_member(z, info.filename, name,
                           limit=8 * MAX_SCAN_POINTS + header)
    return _read_npy(io.BytesIO(data), len(data), f"{name} (array {echo(key)})")


def _load_text(p: Path, delimiter: str | None) -> np.ndarray:
    """A text matrix, one row per line: each row held as float64 as it is read, and the
    points counted against :data:`~roughslip.surfaces.limits.MAX_SCAN_POINTS`, so that a huge
    file is refused before it fills the memory."""
    from roughslip.surfaces.limits import MAX_SCAN_POINTS

    rows: list[np.ndarray] = []
    points = 0
    with p.open("r", encoding="utf-8", errors="strict") as fh:
        for lineno, line in enumerate(fh, 1):
            s = line.split("#", 1)[0].strip()
            if not s:
                continue
            parts = s.split(delimiter) if delimiter else s.split()
            try:
                rows.append(np.array([float(v) for v in parts]))
            except ValueError:
                raise InputError(f"{p}: line {lineno}: not a row of numbers") from None
            if len(rows[-1]) != len(rows[0]):
                raise InputError(
                    f"{p}: ragged rows (line {lineno} has {len(rows[-1])} values, the first "
                    f"row {len(rows[0])})"
                )
            points += rows[-1].size
            if points > MAX_SCAN_POINTS:
                raise InputError(f"{p}: more than {MAX_SCAN_POINTS} points by line {lineno}: "
                                 f"a height map may have at most {MAX_SCAN_POINTS} (2^30)")
    if not rows:
        raise InputError(f"{p}: is empty")
    return np.array(rows)


def _load_hdf5(p: Path, key: str | None) -> np.ndarray:
    import h5py

    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        raise InputError(f"{p}: not a readable HDF5 file ({shorten(str(exc))})") from None
    with f:
        if key is None:
            names: list[str] = []
            f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
            if len(names) != 1:
                raise InputError(f"{p}: holds datasets {echo(names)}; set surface.key")
            key = names[0]
        if key not in f or not isinstance(f[key], h5py.Dataset):
            raise InputError(f"{p}: no dataset {echo(key)}")
        d = f[key]
        where = f"{p} (dataset {echo(key)})"
        check_array(d.shape, d.dtype, None, where)
        stored = d.id.get_storage_size()
        ratio = d.nbytes / max(stored, 1)
        if ratio > MAX_COMPRESSION_RATIO:
            raise Refused(f"{where}: declares {d.nbytes} bytes stored in {stored} (ratio "
                          f"{ratio:.0f}:1): a dataset may be compressed at most "
                          f"{MAX_COMPRESSION_RATIO}:1")
        return d[()]


def _validate(arr: np.ndarray, name: str, allow_missing: bool = False) -> np.ndarray:
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number)) or np.iscomplexobj(arr):
        raise InputError(f"{name}: heights must be real numbers (got dtype {arr.dtype})")
    if arr.ndim != 2:
        raise InputError(f"{name}: heights must be a 2-D array (got {arr.ndim}-D, shape "
                         f"{arr.shape})")
    if arr.size == 0:
        raise InputError(f"{name}: is empty")
    arr = arr.astype(float)
    bad = np.isinf(arr) if allow_missing else ~np.isfinite(arr)
    if allow_missing and np.isnan(arr).all():
        raise InputError(f"{name}: every height is missing (NaN)")
    if bad.any():
        iy, ix = np.argwhere(bad)[0]
        raise InputError(f"{name}: {int(bad.sum())} non-finite height(s), first at [iy, ix] = "
                         f"[{iy}, {ix}] ({arr[iy, ix]})")
    return arr


# --------------------------------------------------------------------------------------------
# Statistics
# --------------------------------------------------------------------------------------------


def rms_height_of(h: np.ndarray) -> float:
    r"""Root mean square of ``h - mean(h)`` over the valid points.

    .. math:: h_\mathrm{rms} = \sqrt{\langle (h - \langle h\rangle)^2\rangle}

    Missing points (NaN, as a scan read with ``allow_missing`` holds them) are left out of
    both means; a map without a valid point gives NaN.
    """
    ok = np.isfinite(h)
    v = h if ok.all() else h[ok]
    if v.size == 0:
        return math.nan
    return float(np.sqrt(np.mean((v - v.mean()) ** 2)))


def rms_slope_of(h: np.ndarray, a: float = 1.0) -> float:
    r""":math:`\sqrt{\langle (\partial_x h)^2\rangle + \langle (\partial_y h)^2\rangle}` by forward
    differences inside the grid (an axis of length 1 contributes nothing).

    A difference with a missing point (NaN) at either end is left out of its mean; an axis
    with no valid difference contributes nothing.
    """
    s = 0.0
    for axis in (1, 0):
        if h.shape[axis] > 1:
            d = np.diff(h, axis=axis)
            d = d[np.isfinite(d)]
            if d.size:
                s += float(np.mean(d**2))
    return math.sqrt(s) / a


def radial_psd(h: np.ndarray, a: float = 1.0, window: str | None = None, nbins: int | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    r"""Radially averaged power spectrum :math:`C(q)` of a topography.

    Parameters
    ----------
    window : {None, "hann"}
        Apply a 2-D Hann window first (use it for non-periodic surfaces to limit leakage).
    nbins : int, optional
        Number of logarithmic wavenumber bins (default about ``2 log2(min(ny, nx))``).

    Returns
    -------
    q, C, count : ndarray
        Bin centres (angular wavenumber), the mean of :math:`|\hat h|^2 a^2/(n_y n_x)` in
        each non-empty bin, and the number of Fourier modes in it.

    Raises
    ------
    InputError
        When a height is missing (NaN): fill missing points first
        (:func:`roughslip.surfaces.topography.harmonic_fill`).
    """
    ny, nx = h.shape
    if not np.isfinite(h).all():
        raise InputError(f"{int((~np.isfinite(h)).sum())} missing (non-finite) height(s): "
                         "a spectrum needs every point; fill them first "
                         "(roughslip.surfaces.topography.harmonic_fill)")
    hh = h - h.mean()
    if window == "hann":
        w = np.outer(np.hanning(ny), np.hanning(nx))
        hh = hh * w / np.sqrt(np.mean(w**2))
    elif window is not None:
        raise InputError(f"window = {window!r}: must be None or 'hann'")
    p = np.abs(np.fft.fft2(hh)) ** 2 * a * a / (ny * nx)
    qy = 2 * np.pi * np.fft.fftfreq(ny, d=a)[:, None]
    qx = 2 * np.pi * np.fft.fftfreq(nx, d=a)[None, :]
    q = np.hypot(qx, qy).ravel()
    p = p.ravel()
    keep = q > 0
    q, p = q[keep], p[keep]
    nbins = nbins or max(4, int(2 * math.log2(max(2, min(ny, nx)))))
    edges = np.geomspace(q.min(), q.max() * (1 + 1e-12), nbins + 1)
    idx = np.digitize(q, edges) - 1
    qc, cc, nc = [], [], []
    for b in range(nbins):
        sel = idx == b
        if sel.any():
            qc.append(np.exp(np.mean(np.log(q[sel]))))
            cc.append(np.mean(p[sel]))
            nc.append(int(sel.sum()))
    return np.array(qc), np.array(cc), np.array(nc)


def hurst_fit_range(shape: tuple[int, int], a: float = 1.0) -> tuple[float, float]:
    """Default wavenumbers of the Hurst fit: from 4 times the lowest wavenumber to half the
    Nyquist wavenumber (where discretisation bends the spectrum)."""
    return 4 * 2 * np.pi / (max(shape) * a), 0.5 * np.pi / a


def hurst_estimate(h: np.ndarray, a: float = 1.0, *, qmin: float | None = None,
                   qmax: float | None = None, window: str | None = None) -> float:
    r"""Hurst exponent from the slope of the radial PSD, :math:`C \propto q^{-2(1+H)}`.

    Fits ``log C`` against ``log q`` over ``qmin <= q <= qmax`` (default: from 4 times the
    lowest wavenumber to half the Nyquist wavenumber, where discretisation bends the spectrum),
    weighting each bin by the square root of its number of modes (the standard error of a
    bin's log-mean power falls like one over that). The bare estimate over a fixed range; a
    range chosen from the spectrum and an uncertainty with the fit's systematic error:
    :func:`roughslip.surfaces.hurst.fit_hurst`.
    """
    q, c, count = radial_psd(h, a, window=window)
    ny, nx = h.shape
    lo, hi = hurst_fit_range((ny, nx), a)
    qlo = qmin if qmin is not None else lo
    qhi = qmax if qmax is not None else hi
    sel = (q >= qlo) & (q <= qhi) & (c > 0)
    if sel.sum() < 3:
        raise InputError("too few wavenumbers in the fitting range to estimate H")
    slope = np.polyfit(np.log(q[sel]), np.log(c[sel]), 1, w=np.sqrt(count[sel]))[0]
    return float(-slope / 2 - 1)
