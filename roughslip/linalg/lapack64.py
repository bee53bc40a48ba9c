"""Dense kernels of the pull's inverse method, safe for matrices with more than 2^31 entries.

scipy's bundled LAPACK uses 32-bit integers: its index arithmetic overflows for ``n x n``
matrices with ``n > 46340`` (a segfault was observed at ``n = 52417``). numpy's bundled
OpenBLAS is built with 64-bit integers and exports LAPACKE and CBLAS entry points with a
``64_`` suffix; this module calls them through ctypes, in place, on Fortran-ordered arrays.
When that library is not present (other numpy builds), the scipy routines are used and larger
matrices are refused with a clear error instead.

Only what the inverse method needs: Cholesky factorisation and inversion of an SPD matrix
(lower triangle), a symmetric rank-k update and a symmetric matrix-vector product, each in
double (float64) and single (float32) precision: the routine follows the matrix's dtype.
"""

from __future__ import annotations

import ctypes
import glob
import os
from types import SimpleNamespace

import numpy as np
from scipy.linalg import blas, lapack

from roughslip.errors import NumericalError, SizeLimitError

#: largest n for which an n x n matrix has fewer than 2^31 entries (32-bit LAPACK is safe)
LP64_MAX_N = 46340
#: orders above which the inverse avoids OpenBLAS's dpotrf driver, which segfaults for large
#: orders (observed here at 52 259, and with two threads at 25 698 after other BLAS work in the
#: process; OpenBLAS issues #352 and #2562). The block sweep is GEMM-based and as fast (25 698:
#: 172 s by the sweep, 2 threads).
SWEEP_MIN_N = 16384
#: the block of :func:`sweep_inverse`: its two work panels hold ``n x SWEEP_BLOCK`` entries each
SWEEP_BLOCK = 1024

_COL_MAJOR, _LOWER, _NO_TRANS, _TRANS = 102, 122, 111, 112
_LIB = None
_TRIED = False


def _load():
    global _LIB, _TRIED
    if _TRIED:
        return _LIB
    _TRIED = True
    here = os.path.dirname(np.__file__)
    for pattern in ("../numpy.libs/libscipy_openblas64_*", ".libs/libscipy_openblas64_*"):
        for path in glob.glob(os.path.join(here, pattern)):
            try:
                lib = ctypes.CDLL(path)
                fns = {p: {name: getattr(lib, f"scipy_{pre}{p}{name}64_")
                           for pre, name in (("LAPACKE_", "potrf"), ("LAPACKE_", "potri"),
                                             ("cblas_", "symv"), ("cblas_", "gemm"))}
                       for p in "ds"}
            except (OSError, AttributeError):
                continue
            i64, i32, ptr = ctypes.c_int64, ctypes.c_int, ctypes.c_void_p
            for p, num in (("d", ctypes.c_double), ("s", ctypes.c_float)):
                f = fns[p]
                for name in ("potrf", "potri"):
                    f[name].restype = i64
                    f[name].argtypes = [i32, ctypes.c_char, i64, ptr, i64]
                f["symv"].restype = None
                f["symv"].argtypes = [i32, i32, i64, num, ptr, i64, ptr, i64, num, ptr, i64]
                f["gemm"].restype = None
                f["gemm"].argtypes = [i32, i32, i32, i64, i64, i64, num, ptr, i64, ptr, i64,
                                      num, ptr, i64]
            _LIB = {np.dtype(np.float64): SimpleNamespace(**fns["d"]),
                    np.dtype(np.float32): SimpleNamespace(**fns["s"])}
            return _LIB
    return None


def available() -> bool:
    """Whether the 64-bit-integer routines were found."""
    return _load() is not None


def max_n() -> int | None:
    """Largest supported matrix order (None: no limit beyond memory)."""
    return None if available() else LP64_MAX_N


#: the precisions these routines take
DTYPES = (np.dtype(np.float64), np.dtype(np.float32))


def _check(a: np.ndarray) -> None:
    if a.dtype not in DTYPES or not a.flags.f_contiguous or a.ndim != 2:
        raise ValueError("need a Fortran-contiguous float64 or float32 matrix")


def _lib(dtype: np.dtype) -> SimpleNamespace | None:
    """The 64-bit-integer routines of one precision (None without the library)."""
    lib = _load()
    return None if lib is None else lib[np.dtype(dtype)]


def check_size(n: int) -> None:
    """Refuse an order the available LAPACK cannot index."""
    limit = max_n()
    if limit is not None and n > limit:
        raise SizeLimitError(
            f"{n} bonds: the dense inverse needs a LAPACK with 64-bit integers beyond {limit} "
            "(this numpy build has none); use pull method 'cg' (exact, matrix-free)")


def cholesky_inverse(a: np.ndarray) -> np.ndarray:
    """Overwrite the lower triangle of SPD ``a`` with that of its inverse (in place)."""
    _check(a)
    n = a.shape[0]
    lib = _lib(a.dtype)
    if lib is None:
        check_size(n)
        potrf, potri = lapack.get_lapack_funcs(("potrf", "potri"), (a,))
        c, info = potrf(a, lower=1, overwrite_a=1, clean=0)
        if info == 0:
            c, info = potri(c, lower=1, overwrite_c=1)
        if not np.shares_memory(c, a):
            raise NumericalError("LAPACK did not work in place")
    elif _sweeps(n, a.dtype):
        return sweep_inverse(a)
    else:
        info = lib.potrf(_COL_MAJOR, b"L", n, a.ctypes.data, n)
        if info == 0:
            info = lib.potri(_COL_MAJOR, b"L", n, a.ctypes.data, n)
    if info != 0:
        raise NumericalError(f"the matrix is not positive definite (LAPACK info {info})")
    return a


def mirror_lower(a: np.ndarray, block: int = 512) -> np.ndarray:
    """Copy the lower triangle of square ``a`` onto its upper one (in place), a panel of
    ``block`` columns at a time, so that no index array of the whole matrix is made."""
    n = a.shape[0]
    for j in range(0, n, block):
        a[j:j + block, j + block:] = a[j + block:, j:j + block].T
        blk = a[j:j + block, j:j + block]
        upper = np.triu_indices(blk.shape[0], 1)
        blk[upper] = blk.T[upper]
    return a


def _sweeps(n: int, dtype: np.dtype) -> bool:
    """Whether :func:`cholesky_inverse` of order ``n`` takes the block sweep."""
    return n > SWEEP_MIN_N and _lib(dtype) is not None


def cholesky_inverse_work_bytes(n: int, itemsize: int = 8) -> int:
    """Memory :func:`cholesky_inverse` allocates besides the matrix (bytes): when it takes
    the block sweep, the two ``n x SWEEP_BLOCK`` panels of :func:`sweep_inverse` and a few
    copies of its pivot block (counted as four in double precision), else none (LAPACK
    works in place)."""
    if _sweeps(n, np.float32 if itemsize == 4 else np.float64):
        block = min(SWEEP_BLOCK, n)
        return 2 * itemsize * n * SWEEP_BLOCK + 32 * block * block
    return 0


def sweep_inverse(a: np.ndarray, block: int = SWEEP_BLOCK) -> np.ndarray:
    r"""Overwrite the lower triangle of SPD ``a`` with that of its inverse, by block sweeps.

    The sweep operator on a pivot block :math:`p` with the rest :math:`r`,

    .. math::

        A_{pp} \leftarrow -A_{pp}^{-1},\quad A_{rp} \leftarrow A_{rp}A_{pp}^{-1},\quad
        A_{rr} \leftarrow A_{rr} - A_{rp}A_{pp}^{-1}A_{pr},

    applied to every block gives :math:`-A^{-1}` (symmetric block Gauss–Jordan). Each pivot
    block is then a Schur complement of the SPD matrix, hence SPD and inverted by Cholesky on
    a small copy; the updates are GEMMs on block-column panels. Work :math:`n^3`, like
    Cholesky plus inversion; extra memory two ``n x block`` panels.
    """
    _check(a)
    n = a.shape[0]
    bounds = [*range(0, n, block), n]
    nb = len(bounds) - 1
    X = np.empty((n, block), dtype=a.dtype, order="F")
    Z = np.empty((n, block), dtype=a.dtype, order="F")
    for k in range(nb):
        k0, k1 = bounds[k], bounds[k + 1]
        w = k1 - k0
        akk = np.tril(a[k0:k1, k0:k1])
        akk = akk + np.tril(akk, -1).T
        try:
            d = np.linalg.inv(np.linalg.cholesky(akk))
        except np.linalg.LinAlgError:
            raise NumericalError("the matrix is not positive definite (block sweep)") from None
        d = d.T @ d  # A_kk^{-1}
        # X = A[:, k] (full symmetric column block, from the lower triangle), Z = X D
        X[:k0, :w] = a[k0:k1, :k0].T
        X[k0:k1, :w] = 0.0
        X[k1:, :w] = a[k1:, k0:k1]
        np.matmul(X[:, :w], d, out=Z[:, :w])
        # A_ij -= Z_i X_j^T for all blocks i >= j outside block k: per column block j, the
        # rows from j down (two panels around block k)
        for j in range(nb):
            if j == k:
                continue
            j0, j1 = bounds[j], bounds[j + 1]
            for r0, r1 in ((j0, k0), (max(j0, k1), n)):
                _gemm_nt(a, r0, r1, j0, j1, Z, X, w, -1.0)
        a[k1:, k0:k1] = Z[k1:, :w]
        a[k0:k1, :k0] = Z[:k0, :w].T
        a[k0:k1, k0:k1] = -d
    # the sweeps leave -A^{-1}
    for j in range(nb):
        j0, j1 = bounds[j], bounds[j + 1]
        np.negative(a[j0:, j0:j1], out=a[j0:, j0:j1])
    return a


def syrk_update(c: np.ndarray, u: np.ndarray, alpha: float = -1.0) -> None:
    """``c += alpha u u^T`` on the lower triangle of ``c``, in place.

    With the 64-bit library the update is done by GEMMs on column panels
    (:func:`syrk_panels`): OpenBLAS's threaded DSYRK segfaults for large orders once a DGEMM
    has run in the process (observed with OpenBLAS 0.3.31 at n = 33 982 and at n ~ 29 000;
    single-threaded it does not).
    """
    _check(c)
    u = np.asfortranarray(u, dtype=c.dtype)
    if _load() is None:
        syrk = blas.get_blas_funcs("syrk", (c,))
        out = syrk(alpha, u, beta=1.0, c=c, lower=1, overwrite_c=1)
        if not np.shares_memory(out, c):
            c[...] = out
        return
    syrk_panels(c, u, alpha)


def syrk_panels(c: np.ndarray, u: np.ndarray, alpha: float = -1.0, block: int = 1024) -> None:
    """:func:`syrk_update` by DGEMMs: ``C[j0:, j0:j1] += alpha U[j0:] U[j0:j1]^T`` for each
    column panel ``j0:j1`` of width ``block`` (the lower triangle and a little above it
    inside each diagonal block, which is never read)."""
    _check(c)
    u = np.asfortranarray(u, dtype=c.dtype)
    n, k = u.shape
    for j0 in range(0, n, block):
        _gemm_nt(c, j0, n, j0, min(j0 + block, n), u, u, k, alpha)


def gemm_update(c: np.ndarray, m: int, p: np.ndarray, q: np.ndarray, k: int,
                alpha: float = 1.0) -> None:
    """``C[:m, :m] += alpha P[:m, :k] Q[:m, :k]^T`` in place: one GEMM into ``c`` with the
    64-bit library (no temporary of the product), else numpy by column panels.

    ``c``, ``p`` and ``q`` are Fortran-ordered with as many rows as ``c``. The sum is rounded
    as the library's GEMM accumulates it, which can differ in the last bits from adding the
    separately computed product.
    """
    if _lib(c.dtype) is not None:
        _gemm_nt(c, 0, m, 0, m, p, q, k, alpha)
        return
    P, Q, M = alpha * p[:m, :k], q[:m, :k], c[:m, :m]
    for j in range(0, m, 2048):  # column panels: no copy of M, small temporaries
        M[:, j:j + 2048] += P @ Q[j:j + 2048].T


def _gemm_nt(c: np.ndarray, r0: int, r1: int, j0: int, j1: int, p: np.ndarray, q: np.ndarray,
             k: int, alpha: float) -> None:
    """``C[r0:r1, j0:j1] += alpha P[r0:r1, :k] Q[j0:j1, :k]^T`` in place, by the 64-bit DGEMM.

    ``c``, ``p`` and ``q`` are Fortran-ordered with as many rows as ``c`` (the leading
    dimension of all three); the blocks are addressed inside them without copies.
    """
    if r1 <= r0 or j1 <= j0 or k == 0:
        return
    lib = _lib(c.dtype)
    if lib is None:
        raise NumericalError("the panel update needs the 64-bit-integer BLAS")
    n = c.shape[0]
    if p.shape[0] != n or q.shape[0] != n or not (p.flags.f_contiguous and q.flags.f_contiguous):
        raise ValueError("panels must be Fortran-ordered with the rows of c")
    if not p.dtype == q.dtype == c.dtype:
        raise ValueError("panels must have the dtype of c")
    w = c.itemsize
    lib.gemm(_COL_MAJOR, _NO_TRANS, _TRANS, r1 - r0, j1 - j0, k, alpha, p.ctypes.data + w * r0,
             n, q.ctypes.data + w * j0, n, 1.0, c.ctypes.data + w * (j0 * n + r0), n)


def symv(a: np.ndarray, x: np.ndarray, n: int | None = None) -> np.ndarray:
    """``a[:n, :n] @ x`` for symmetric ``a[:n, :n]`` of which only the lower triangle is valid
    (``n`` defaults to the order of ``a``; the leading block is read in place). It reads half
    the memory of a general product. A float32 ``a`` takes ``x`` rounded to float32 and
    accumulates in float32; the result is returned in float64 either way."""
    _check(a)
    x = np.ascontiguousarray(x, dtype=a.dtype)
    lda = a.shape[0]
    n = lda if n is None else int(n)
    if x.shape != (n,):
        raise ValueError(f"x has shape {x.shape}, expected ({n},)")
    lib = _lib(a.dtype)
    if lib is None:
        symv = blas.get_blas_funcs("symv", (a,))
        return symv(1.0, a[:n, :n], x, lower=1).astype(np.float64)
    y = np.zeros(n, dtype=a.dtype)
    lib.symv(_COL_MAJOR, _LOWER, n, 1.0, a.ctypes.data, lda, x.ctypes.data, 1, 0.0,
             y.ctypes.data, 1)
    return y.astype(np.float64, copy=False)
