r"""What a topography file may make roughslip read, and what a scan must hold.

A file is read only after what it declares has been checked against what it holds and against
fixed limits, so that neither a damaged nor a hostile file can take the machine's memory:

Arrays (``.npy``, the arrays of ``.npz``, HDF5 datasets)
    The shape and the data type in the header are checked first (:func:`check_array`): a real
    2-D array of at most :data:`MAX_SCAN_POINTS` points whose data has exactly the size the
    file holds, and whose heights fit in the memory available.
Archive members (X3P, ``.npz``)
    Before a member is read, its declared size is checked against a cap (the exact size that
    ``main.xml`` implies for point data; :data:`MAX_XML_BYTES` for ``main.xml``) and its
    compression ratio against :data:`MAX_COMPRESSION_RATIO`; it is then read with a bounded
    read of at most the cap plus one byte, so that a size that lies cannot matter
    (:func:`read_member`). Other instrument files that are zip archives, which
    SurfaceTopography reads, have every member's declared size and ratio checked before they
    are handed over (:func:`check_archive`).

A scan that was read must be at least :data:`MIN_SCAN_SIDE` pixels along each axis, hold at
least one valid point, and not be flat: its rms height above :data:`FLAT_RELIEF` times its
largest absolute height (:func:`check_scan`). The same rules apply to what the preparation of
a run leaves (crop, down-sampling, tiles, detrending; :mod:`roughslip.surfaces.topography`).
"""

from __future__ import annotations

import math
import zipfile
import zlib
from typing import IO

import numpy as np

from roughslip.errors import InputError, MemoryLimitError, echo
from roughslip.linalg.memory import available_bytes

#: The smallest scan side, in pixels, along each axis. Every statistic ``roughslip
#: topography`` prints and every preparation step is defined from 4 on: the rms slope needs 2
#: points per axis (differences), the rms curvature 3 (a central second difference), the
#: ``curvature`` detrend 3 distinct coordinates per axis (a quadric), and the Hann window of
#: the power spectrum is zero on the edge rows and columns, so it keeps two rows and columns
#: of a 4-pixel side (one of a 3-pixel side, nothing of a 2-pixel side, where the windowed
#: spectrum is 0 / 0). A Hurst exponent needs far more (about 32 per side for three
#: wavenumber bins in its fit); without them it is reported as not estimated, not refused.
MIN_SCAN_SIDE = 4

#: the rule of :data:`MIN_SCAN_SIDE`, as messages state it
SIDE_RULE = f"a scan must be at least {MIN_SCAN_SIDE} x {MIN_SCAN_SIDE} pixels"

#: A scan whose rms height is at most this fraction of its largest absolute height is flat:
#: a constant, or a constant plus rounding. Float64 heights resolve 2.2e-16 of their
#: magnitude, so at 1e-12 the variation spans only about 4,500 rounding steps of the offset
#: it sits on, fewer than four significant digits once the mean is removed; measured
#: roughness is many orders of magnitude above that. Depths in rms units (``depth_unit =
#: "rms"``) would all be 0 on such a surface, and in length units every point touches at once.
FLAT_RELIEF = 1e-12

#: The most points a height map may have: 2^30, e.g. 32768 x 32768 pixels, 8 GiB as float64.
#: Above the largest single scans of instruments and far above the grids a run solves (its
#: FFT operators need several times the heights); it bounds what a header can make roughslip
#: allocate, whatever the memory available.
MAX_SCAN_POINTS = 2**30

#: The largest ``main.xml`` of an X3P file that is read, in bytes (16 MiB). With binary point
#: data it is a few kilobytes; listing the points as XML (``DataList``) takes about 27 bytes a
#: point, so 16 MiB holds about 600,000 points (a 775 x 775 scan): larger scans store binary
#: data. Parsing it takes about ten times its size in memory.
MAX_XML_BYTES = 16 * 2**20

#: The largest compression ratio (declared size over compressed size) of an archive member.
#: Deflate, the method of X3P writers and of ``numpy.savez_compressed``, cannot exceed 1032:1
#: (its longest match, 258 bytes, costs at least two bits), so no real member is refused;
#: the methods that can (bzip2, LZMA) inflate a kilobyte to gigabytes in a zip bomb.
MAX_COMPRESSION_RATIO = 1100


#: what reading a damaged archive member raises (zlib.error: corrupt deflate data;
#: RuntimeError: encrypted; NotImplementedError: an unknown compression method)
_ARCHIVE_ERRORS: tuple[type[BaseException], ...] = (
    zipfile.BadZipFile, zlib.error, OSError, EOFError, RuntimeError, NotImplementedError,
    ValueError)
try:
    from lzma import LZMAError
except ImportError:  # a Python without lzma cannot read LZMA members at all
    pass
else:
    _ARCHIVE_ERRORS += (LZMAError,)


class Refused(InputError):
    """A file refused by a limit of this module: what it declares is too large, or not what it
    holds. Readers do not hand such a file to another reader (which would trust it)."""


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


def check_array(shape: tuple[int, ...], dtype: np.dtype, data_bytes: int | None, where: str
                ) -> int:
    """Check a height map's header before its data is read.

    Parameters
    ----------
    shape : tuple of int
        The shape the header declares.
    dtype : numpy.dtype
        The data type it declares.
    data_bytes : int or None
        The bytes of data the file (or the archive member) holds after the header; None when
        the data is not stored as one block (an HDF5 dataset).
    where : str
        The file, for the messages.

    Returns
    -------
    int
        The number of points.

    Raises
    ------
    InputError
        For a data type that is not a real number, an array that is not 2-D or has no point,
        more than :data:`MAX_SCAN_POINTS` points, or data of another size than the header
        implies.
    MemoryLimitError
        When the data and its float64 copy do not fit in the memory available
        (:func:`roughslip.linalg.memory.available_bytes`).
    """
    if dtype.hasobject or dtype.fields is not None or dtype.kind not in "iuf":
        raise InputError(f"{where}: heights must be real numbers (the file declares dtype "
                         f"{echo(str(dtype))})")
    if len(shape) != 2:
        raise InputError(f"{where}: heights must be a 2-D array (the file declares "
                         f"{len(shape)}-D, shape {echo(tuple(shape))})")
    count = math.prod(int(n) for n in shape)  # Python integers: no overflow
    if count == 0:
        raise InputError(f"{where}: is empty (shape {tuple(shape)})")
    if count > MAX_SCAN_POINTS:
        raise Refused(f"{where}: declares a {shape[0]} x {shape[1]} array ({count:.3g} "
                         f"points): a height map may have at most {MAX_SCAN_POINTS} "
                         f"(2^{int(math.log2(MAX_SCAN_POINTS))})")
    need = count * dtype.itemsize
    if data_bytes is not None and need != data_bytes:
        raise Refused(f"{where}: declares a {shape[0]} x {shape[1]} {dtype.name} array "
                         f"({need} bytes of data) but holds {data_bytes}: the file is "
                         "damaged or not what it claims")
    have = available_bytes()
    if need + 8 * count > have:
        raise MemoryLimitError(f"{where}: a {shape[0]} x {shape[1]} height map needs "
                               f"~{_gib(need + 8 * count)} to read but {_gib(have)} are "
                               "available")
    return count


def read_member(z: zipfile.ZipFile, name: str, where: str, *, limit: int,
                expected: int | None = None, why: str = "") -> bytes:
    """Read one archive member, bounded.

    Parameters
    ----------
    z : zipfile.ZipFile
        The open archive.
    name : str
        The member.
    where : str
        The file, for the messages.
    limit : int
        The most bytes the member may hold.
    expected : int, optional
        The exact size the member must have (point data whose size ``main.xml`` implies).
    why : str
        What makes ``expected`` the size, for the message (``"20 x 10 x 1 float64 values
        ... need"``).

    Returns
    -------
    bytes

    Raises
    ------
    KeyError
        When the archive has no such member (the caller words that error).
    InputError
        When the declared size is not ``expected`` or exceeds ``limit``, the compression
        ratio exceeds :data:`MAX_COMPRESSION_RATIO`, the data read is longer or shorter than
        declared, or the archive is damaged.
    """
    info = z.getinfo(name)
    what = f"{where}: {echo(name)}"
    if expected is not None and info.file_size != expected:
        raise Refused(f"{what} declares {info.file_size} bytes; "
                      f"{why or 'the file header says'} {expected}")
    if info.file_size > limit:
        raise Refused(f"{what} declares {info.file_size} bytes, more than the {limit} "
                      "allowed")
    _check_ratio(info, what)
    try:
        with z.open(info) as fh:
            data = fh.read(limit + 1)
    except _ARCHIVE_ERRORS as exc:
        raise Refused(f"{what}: damaged archive ({type(exc).__name__}: {echo(str(exc))})"
                      ) from None
    if len(data) != info.file_size:
        raise Refused(f"{what}: {len(data)} bytes read where {info.file_size} are "
                      "declared: the archive is damaged")
    return data


def _check_ratio(info: zipfile.ZipInfo, what: str) -> None:
    ratio = info.file_size / max(info.compress_size, 1)
    if ratio > MAX_COMPRESSION_RATIO:
        raise Refused(f"{what} declares {info.file_size} bytes compressed to "
                      f"{info.compress_size} (ratio {ratio:.0f}:1): an archive member may be "
                      f"compressed at most {MAX_COMPRESSION_RATIO}:1")


def check_archive(path: str, where: str) -> None:
    """Check every member of a zip archive before another library reads it: its declared size
    at most :data:`MAX_SCAN_POINTS` float64 values plus :data:`MAX_XML_BYTES`, its compression
    ratio at most :data:`MAX_COMPRESSION_RATIO`. A file that is not a zip archive passes.

    Parameters
    ----------
    path : str
        The file.
    where : str
        The file, for the messages.

    Raises
    ------
    InputError
        Naming the file and the member.
    """
    try:
        if not zipfile.is_zipfile(path):
            return
        with zipfile.ZipFile(path) as z:
            infos = z.infolist()
    except (zipfile.BadZipFile, OSError, ValueError):
        return  # not readable as an archive: the reader says what it is
    limit = 8 * MAX_SCAN_POINTS + MAX_XML_BYTES
    for info in infos:
        what = f"{where}: {echo(info.filename)}"
        if info.file_size > limit:
            raise Refused(f"{what} declares {info.file_size} bytes, more than the {limit} "
                          "allowed")
        _check_ratio(info, what)


def read_exactly(fh: IO[bytes], size: int, where: str) -> bytes:
    """Read ``size`` bytes, no more (a bounded read of ``size + 1``: a stream that holds more
    or fewer than the header said is an error).

    Parameters
    ----------
    fh : binary file object
    size : int
    where : str
        The file, for the messages.

    Returns
    -------
    bytes
    """
    data = fh.read(size + 1)
    if len(data) != size:
        raise Refused(f"{where}: holds {'more' if len(data) > size else len(data)} bytes of "
                      f"data where its header declares {size}")
    return data


def check_scan(h: np.ndarray, where: str, *, scale: float | None = None) -> None:
    """Refuse a height map that is too small, wholly missing or flat.

    Parameters
    ----------
    h : ndarray
        Heights ``[iy, ix]``, NaN at missing points.
    where : str
        What the messages name first: the file, or the configuration key (and the file) of
        the preparation step that made ``h``.
    scale : float, optional
        The largest absolute height of the file the flatness is measured against (default:
        that of ``h``); a tile is measured against its file's, so that a trend removed down
        to rounding leaves a flat tile.

    Raises
    ------
    InputError
        One line: ``scan.npy: 1 x 64 pixels (ny x nx): a scan must be at least 4 x 4
        pixels``, ``... every point is missing``, or ``... the heights are constant (rms
        height 0, largest |height| 5): a topography needs an rms height above 1e-12 x its
        largest |height|``.
    """
    ny, nx = h.shape
    if min(ny, nx) < MIN_SCAN_SIDE:
        raise InputError(f"{where}: {ny} x {nx} pixels (ny x nx): {SIDE_RULE}")
    finite = h[np.isfinite(h)]
    if finite.size == 0:
        raise InputError(f"{where}: every point is missing (NaN or masked)")
    rms = float(np.sqrt(np.mean((finite - finite.mean()) ** 2)))
    top = float(np.max(np.abs(finite))) if scale is None else float(scale)
    if not rms > FLAT_RELIEF * top:
        of = "" if scale is None else " of the file"
        raise InputError(f"{where}: the heights are constant (rms height {rms:.3g}, largest "
                         f"|height|{of} {top:.3g}): a topography needs an rms height above "
                         f"{FLAT_RELIEF:g} x its largest |height|")
