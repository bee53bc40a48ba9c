r"""ISO 25178-72 (X3P) areal topographies, read from the standard's structure.

Both revisions are read: ISO 5436-2:2000 (``<Revision>ISO5436 - 2000</Revision>``) and
ISO 25178-72:2017 with its amendment (``ISO25178-72:2017...``); they share the parts read here.
An X3P file is a zip archive:

``main.xml``
    ``Record1``: the revision, the feature type (``SUR`` for an areal surface) and the axes
    ``CX``, ``CY``, ``CZ``. A surface on a regular grid has incremental x and y axes (``AxisType``
    ``I``) whose ``Increment`` is the pixel size in metres, and an absolute z axis (``A``) whose
    ``DataType`` is ``I`` (int16), ``L`` (int32), ``F`` (float32) or ``D`` (float64). A height is
    :math:`z = \mathrm{Offset} + \mathrm{Increment}\cdot\mathrm{stored}` (the increment is 1
    when absent). ``Record3``: ``MatrixDimension`` (``SizeX``, ``SizeY``, ``SizeZ`` layers) and
    either a ``DataLink`` to the binary point data (little-endian, x fastest, then y, then the
    layer) with optional MD5 checksums and a ``ValidPointsLink`` (one bit per point, least
    significant first, 1 for a valid point), or a ``DataList`` of ``Datum`` elements in the same
    order (an empty one is a missing point).
``md5checksum.hex``
    The MD5 checksum of ``main.xml`` (``Record4``).

Heights come out in metres as ``[iy, ix]`` (the file's x is the last axis), with NaN at the
missing points (invalid bits, empty ``Datum``, NaN in floating-point data). A checksum that does
not match is an error: the file is corrupt.

No member is read whole on trust (:func:`roughslip.surfaces.limits.read_member`): ``main.xml``
and the checksum file may hold at most :data:`~roughslip.surfaces.limits.MAX_XML_BYTES`, the
point data exactly ``SizeX x SizeY x SizeZ`` values of the z axis's type (checked against
:data:`~roughslip.surfaces.limits.MAX_SCAN_POINTS` and the memory available first), the valid
points one bit a point (:data:`VALID_PADDING` bytes more at most); each compressed at most
:data:`~roughslip.surfaces.limits.MAX_COMPRESSION_RATIO` to 1 and read with a bounded read.
"""

from __future__ import annotations

import hashlib
import math
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from roughslip.errors import InputError, echo
from roughslip.surfaces.limits import MAX_XML_BYTES, check_array, read_member

#: stored types of the z axis
DTYPES = {"I": np.dtype("<i2"), "L": np.dtype("<i4"), "F": np.dtype("<f4"),
          "D": np.dtype("<f8")}


#: Bytes a valid-points member may hold beyond its ``ceil(points / 8)``: a writer may pad the
#: bits to a 64-bit word; a longer member is not a bit mask of this matrix.
VALID_PADDING = 8


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _find(node: ElementTree.Element, *path: str) -> ElementTree.Element | None:
    """The first descendant along ``path`` by local names (namespaces ignored)."""
    for name in path:
        node = next((c for c in node if _local(c.tag) == name), None)
        if node is None:
            return None
    return node


def _text(node: ElementTree.Element, *path: str, where: str) -> str:
    found = _find(node, *path)
    if found is None or found.text is None or not found.text.strip():
        raise InputError(f"{where}: main.xml has no {'/'.join(path)}")
    return found.text.strip()


def _number(node: ElementTree.Element, *path: str, where: str, default: float | None = None
            ) -> float:
    found = _find(node, *path)
    if found is None or found.text is None or not found.text.strip():
        if default is None:
            raise InputError(f"{where}: main.xml has no {'/'.join(path)}")
        return default
    try:
        value = float(found.text)
    except ValueError:
        raise InputError(f"{where}: {'/'.join(path)} = {echo(found.text.strip())} is not a "
                         "number") from None
    if not math.isfinite(value):
        raise InputError(f"{where}: {'/'.join(path)} = {value} is not finite")
    return value


def _member(z: zipfile.ZipFile, link: str, where: str, *, limit: int,
            expected: int | None = None, why: str = "") -> bytes:
    """The member ``link`` names, at most ``limit`` bytes (exactly ``expected`` when given, as
    ``why`` says): :func:`roughslip.surfaces.limits.read_member`."""
    name = link.strip().replace("\\", "/").lstrip("/")
    if ".." in name.split("/"):
        raise InputError(f"{where}: link {echo(link)} leaves the archive")
    try:
        return read_member(z, name, where, limit=limit, expected=expected, why=why)
    except KeyError:
        raise InputError(f"{where}: the archive has no {echo(name)} (linked from "
                         "main.xml)") from None


def _check_md5(data: bytes, expected: str | None, what: str, where: str) -> None:
    if expected and hashlib.md5(data).hexdigest().lower() != expected.strip().lower():
        raise InputError(f"{where}: the MD5 checksum of {what} does not match: the file is "
                         "corrupt")


def read_x3p(path: str | Path, layer: int = 0) -> tuple[np.ndarray, tuple[float, float], str]:
    """Read an areal X3P file (module docstring).

    Parameters
    ----------
    path : str or Path
        The ``.x3p`` file.
    layer : int
        The layer of a file with several (``SizeZ > 1``).

    Returns
    -------
    heights : ndarray
        ``[iy, ix]`` in metres, NaN at missing points.
    pixel_size : (float, float)
        ``(dy, dx)`` in metres.
    revision : str
        The ``Revision`` text.

    Raises
    ------
    InputError
        For a file that is not a readable areal X3P (naming the file and what is wrong).
    """
    where = str(path)
    try:
        z = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError(f"{where}: cannot read as X3P: not a zip archive ({exc})") from None
    with z:
        try:
            xml = read_member(z, "main.xml", where, limit=MAX_XML_BYTES)
        except KeyError:
            raise InputError(f"{where}: the archive has no main.xml") from None
        try:
            root = ElementTree.fromstring(xml)
        except ElementTree.ParseError as exc:
            raise InputError(f"{where}: main.xml is not valid XML ({exc})") from None
        if "md5checksum.hex" in z.namelist():
            line = read_member(z, "md5checksum.hex", where, limit=MAX_XML_BYTES
                               ).decode("ascii", "replace").split()
            _check_md5(xml, line[0] if line else None, "main.xml", where)
        revision = _text(root, "Record1", "Revision", where=where)
        feature = _text(root, "Record1", "FeatureType", where=where)
        if feature != "SUR":
            raise InputError(f"{where}: feature type {echo(feature)}; an areal surface (SUR) is "
                             "needed (PRF is a profile, PCL a point cloud)")
        axes = _find(root, "Record1", "Axes")
        if axes is None:
            raise InputError(f"{where}: main.xml has no Record1/Axes")
        for name in ("CX", "CY"):
            kind = _text(axes, name, "AxisType", where=where)
            if kind != "I":
                raise InputError(f"{where}: axis {name} is {echo(kind)}, not incremental (I): "
                                 "not a regular grid")
        dx = _number(axes, "CX", "Increment", where=where)
        dy = _number(axes, "CY", "Increment", where=where)
        if not (dx > 0 and dy > 0):
            raise InputError(f"{where}: pixel size {dx:g} x {dy:g} m: must be > 0")
        ztype = _text(axes, "CZ", "DataType", where=where)
        if ztype not in DTYPES:
            raise InputError(f"{where}: z data type {echo(ztype)}: must be one of "
                             f"{', '.join(DTYPES)}")
        zinc = _number(axes, "CZ", "Increment", where=where, default=1.0)
        zoff = _number(axes, "CZ", "Offset", where=where, default=0.0)
        nx = int(_number(root, "Record3", "MatrixDimension", "SizeX", where=where))
        ny = int(_number(root, "Record3", "MatrixDimension", "SizeY", where=where))
        nz = int(_number(root, "Record3", "MatrixDimension", "SizeZ", where=where, default=1))
        if min(nx, ny, nz) < 1:
            raise InputError(f"{where}: matrix {nx} x {ny} x {nz}: every size must be >= 1")
        if not 0 <= layer < nz:
            raise InputError(f"{where}: layer {layer}: the file has {nz}")
        count = nx * ny * nz
        link = _find(root, "Record3", "DataLink")
        listing = _find(root, "Record3", "DataList")
        if (link is None) == (listing is None):
            raise InputError(f"{where}: Record3 needs exactly one of DataLink and DataList")
        if link is not None:
            dtype = DTYPES[ztype]
            # the matrix's size first, then a member of exactly that size: nothing larger is read
            check_array((nz * ny, nx), dtype, None,
                        where if nz == 1 else f"{where} ({nz} layers of {ny} x {nx})")
            need = count * dtype.itemsize
            data_link = _text(link, "PointDataLink", where=where)
            raw = _member(z, data_link, where, limit=need, expected=need,
                          why=f"{nx} x {ny} x {nz} {dtype.name} values (SizeX x SizeY x "
                              "SizeZ of main.xml) need")
            md5 = _find(link, "MD5ChecksumPointData")
            _check_md5(raw, None if md5 is None else md5.text, "the point data", where)
            values = np.frombuffer(raw, dtype=dtype).astype(float)
            valid = np.ones(count, dtype=bool)
            vlink = _find(link, "ValidPointsLink")
            if vlink is not None and vlink.text and vlink.text.strip():
                bits = _member(z, vlink.text, where,
                               limit=math.ceil(count / 8) + VALID_PADDING)
                vmd5 = _find(link, "MD5ChecksumValidPoints")
                _check_md5(bits, None if vmd5 is None else vmd5.text, "the valid points",
                           where)
                if len(bits) * 8 < count:
                    raise InputError(f"{where}: the valid-points data has {len(bits) * 8} "
                                     f"bits for {count} points")
                valid = np.unpackbits(np.frombuffer(bits, np.uint8), count=count,
                                      bitorder="little").astype(bool)
        else:
            datums = [d for d in listing if _local(d.tag) == "Datum"]
            if len(datums) != count:
                raise InputError(f"{where}: DataList holds {len(datums)} points; {nx} x {ny} x "
                                 f"{nz} need {count}")
            values = np.full(count, np.nan)
            for i, d in enumerate(datums):
                text = (d.text or "").strip()
                if text:
                    try:
                        values[i] = float(text.split(";")[-1])
                    except ValueError:
                        raise InputError(f"{where}: Datum {i} = {echo(text)} is not a "
                                         "number") from None
            valid = np.isfinite(values)
    heights = zoff + zinc * values
    heights[~valid] = np.nan
    heights = heights.reshape(nz, ny, nx)[layer]
    if np.isinf(heights).any():
        raise InputError(f"{where}: {int(np.isinf(heights).sum())} infinite height(s)")
    return heights, (dy, dx), revision
