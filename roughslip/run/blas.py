"""Which BLAS computed a run: the library, its version and the kernel it chose for this CPU.

The dense solvers' numbers depend on the BLAS below numpy and SciPy: OpenBLAS picks its kernels
at start-up from the CPU it finds (its "architecture": Haswell, SkylakeX, Zen, ...), and two
kernels can round differently. A run file records what the writing process loaded
(:func:`blas_libraries`, the root attribute ``blas``), and ``roughslip inspect`` shows it in one
line (:func:`blas_line`). The pool's workers load the same libraries on the same machine; the
workers of a Dask cluster run on machines of their own.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def blas_libraries() -> list[dict[str, str]]:
    """The BLAS libraries loaded in this process, after numpy and ``scipy.linalg``.

    Returns
    -------
    list of dict
        One per library, as threadpoolctl finds it: ``library`` (``openblas``, ``mkl``,
        ``blis``, ...), ``version``, ``architecture`` (the kernel OpenBLAS chose; empty for
        the others), ``threading`` (its threading layer), ``package`` (the Python package that
        ships it, empty for a system library) and ``file``; sorted by package and file, so
        that the list does not depend on the order the process loaded them in.
    """
    import numpy  # noqa: F401  (each loads its own BLAS)
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_info

    libs = [{"library": str(info.get("internal_api") or "?"),
             "version": str(info.get("version") or "?"),
             "architecture": str(info.get("architecture") or ""),
             "threading": str(info.get("threading_layer") or ""),
             "package": _package(str(info.get("filepath") or "")),
             "file": str(info.get("filepath") or "")}
            for info in threadpool_info() if info.get("user_api") == "blas"]
    return sorted(libs, key=lambda lib: (lib["package"], lib["file"]))


def _package(file: str) -> str:
    """The package that ships a library, from its path (``numpy.libs/...`` -> numpy)."""
    for part in reversed(Path(file).parts[:-1]):
        if part.endswith(".libs"):
            return part[: -len(".libs")]
        if part in ("numpy", "scipy"):
            return part
    return ""


def blas_line(stored: Any) -> str:
    """One short line for the ``blas`` attribute of a run file, e.g. ``openblas 0.3.30
    SkylakeX (scipy); openblas 0.3.31 SkylakeX (numpy)``.

    Parameters
    ----------
    stored : str or None
        The attribute as read (JSON text), None for files written before it existed.

    Returns
    -------
    str
    """
    if stored is None:
        return "not recorded (a file of an earlier version)"
    try:
        libs = json.loads(stored)
    except (TypeError, ValueError):
        return "not readable"
    if not libs:
        return "none found"
    parts = []
    for lib in libs:
        words = [lib.get("library", "?"), lib.get("version", "?"), lib.get("architecture", "")]
        text = " ".join(w for w in words if w)
        parts.append(f"{text} ({lib['package']})" if lib.get("package") else text)
    return "; ".join(parts)
