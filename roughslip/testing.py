"""Helpers for testing runs: bitwise comparison of run files, processes, topography writers,
and the dense block operator of a problem.

:func:`differences` compares two run files dataset by dataset, the wall-clock timings
excepted.

:func:`write_x3p` and :func:`write_sdf` write topography files from the formats' specifications
(ISO 25178-72 and -71), so that readers can be tested against an independent writer.

The process helpers read Linux's ``/proc``: :func:`session_processes` lists every process of a
session (a run started with ``start_new_session=True`` keeps its workers and helpers in the
session of its main process, even after they are re-parented), which is how orphans are found;
:func:`wait_stopped` waits for a process to stop (a run that stopped itself at a checkpoint).
"""

from __future__ import annotations

import hashlib
import os
import time
import zipfile
from pathlib import Path

import numpy as np

#: datasets that measure the machine rather than the model: excluded from comparisons
TIMINGS = ("seconds", "pull_seconds")


def dense_block(problem) -> np.ndarray:
    """The full (z, x) block operator of a :class:`~roughslip.contact.problem.Problem` as a
    dense matrix, column by column from FFT products of unit forces (not from the kernel
    tables the solvers assemble from), symmetrised. Unknowns: f_z at site i is row i, f_x at
    site i is row n + i."""
    op = problem.operator("zz", "zx", "xx")
    n, shape = problem.base.size, problem.shape
    A = np.empty((2 * n, 2 * n))
    for j in range(2 * n):
        f = np.zeros(2 * n)
        f[j] = 1.0
        uz, ux = op.apply_block(f[:n].reshape(shape), f[n:].reshape(shape))
        A[:, j] = np.concatenate([uz.ravel(), ux.ravel()])
    return 0.5 * (A + A.T)


def session_processes(sid: int) -> list[int]:
    """Pids of the live (not zombie) processes whose session id is ``sid`` (Linux)."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", encoding="ascii", errors="replace") as fh:
                stat = fh.read()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()  # after "pid (comm) "
        state, session = fields[0], int(fields[3])
        if session == sid and state not in ("Z", "X"):
            found.append(int(entry))
    return found


def wait_gone(sid: int, timeout: float) -> list[int]:
    """Wait up to ``timeout`` seconds for every process of session ``sid`` to end; return
    those still alive."""
    deadline = time.monotonic() + timeout
    while True:
        alive = session_processes(sid)
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.05)


def wait_stopped(pid: int, timeout: float) -> bool:
    """Wait up to ``timeout`` seconds for process ``pid`` to be stopped (SIGSTOP); False if it
    ended first or did not stop in time."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
                stat = fh.read()
        except OSError:
            return False
        state = stat[stat.rindex(")") + 2]
        if state in "tT":
            return True
        if state in "ZX":
            return False
        time.sleep(0.01)
    return False


def datasets(path: str | Path) -> dict[str, np.ndarray]:
    """Every dataset of an HDF5 file, by path."""
    import h5py

    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset)
                     else None)
    return out


def differences(a: str | Path, b: str | Path) -> list[str]:
    """Datasets that are not bitwise equal between two run files (NaN equals NaN), the
    wall-clock timings excepted; a dataset present in one file only counts too."""
    da, db = datasets(a), datasets(b)
    diff = sorted(set(da) ^ set(db))
    for k in sorted(set(da) & set(db)):
        if k in TIMINGS:
            continue
        x, y = da[k], db[k]
        same = x.dtype == y.dtype and x.shape == y.shape and (
            np.array_equal(x, y, equal_nan=True) if x.dtype.kind == "f"
            else np.array_equal(x, y))
        if not same:
            diff.append(k)
    return diff


# ----------------------------------------------------------------------------------------------
# Topography files written from their specifications (independent of any reader)
# ----------------------------------------------------------------------------------------------


def write_x3p(path: str | Path, h: np.ndarray, dx: float, dy: float) -> None:
    """ISO 25178-72 (X3P), written from the specification: a zip with main.xml (axes in
    metres), bindata/data.bin (little-endian doubles, x fastest) and md5checksum.hex."""
    data = np.ascontiguousarray(h, dtype="<f8").tobytes()
    ny, nx = h.shape

    def axis(name: str, kind: str, inc: float | None) -> str:
        inc_xml = "" if inc is None else f"<Increment>{inc!r}</Increment>"
        return (f"<{name}><AxisType>{kind}</AxisType><DataType>D</DataType>{inc_xml}"
                f"<Offset>0</Offset></{name}>")

    xml = ('<?xml version="1.0" encoding="UTF-8"?>\n'
           '<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2"><Record1>'
           '<Revision>ISO5436 - 2000</Revision><FeatureType>SUR</FeatureType><Axes>'
           + axis("CX", "I", dx) + axis("CY", "I", dy) + axis("CZ", "A", None)
           + '</Axes></Record1><Record3><MatrixDimension>'
           f'<SizeX>{nx}</SizeX><SizeY>{ny}</SizeY><SizeZ>1</SizeZ></MatrixDimension>'
           '<DataLink><PointDataLink>bindata/data.bin</PointDataLink>'
           f'<MD5ChecksumPointData>{hashlib.md5(data).hexdigest()}</MD5ChecksumPointData>'
           '</DataLink></Record3><Record4><ChecksumFile>md5checksum.hex</ChecksumFile>'
           '</Record4></p:ISO5436_2>').encode()
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("main.xml", xml)
        z.writestr("bindata/data.bin", data)
        z.writestr("md5checksum.hex", f"{hashlib.md5(xml).hexdigest()} *main.xml\n")


def write_sdf(path: str | Path, h: np.ndarray, dx: float, dy: float) -> None:
    """ISO 25178-71 SDF, ASCII, written from the specification (scales in metres)."""
    ny, nx = h.shape
    head = (f"aISO-1.0\nManufacID   = test\nCreateDate  = 010120261200\n"
            f"ModDate     = 010120261200\nNumPoints   = {nx}\nNumProfiles = {ny}\n"
            f"Xscale      = {dx!r}\nYscale      = {dy!r}\nZscale      = 1.0\n"
            "Zresolution = -1\nCompression = 0\nDataType    = 7\nCheckType   = 0\n*\n")
    body = "\n".join(" ".join(repr(float(v)) for v in row) for row in h)
    Path(path).write_text(head + body + "\n*\n")

