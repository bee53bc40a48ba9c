r"""An explicit inverse of a symmetric matrix on a changing index set, updated, not recomputed.

The matrix :math:`A` is known through an assembler: ``entries(i, j, order)`` returns the block
:math:`A_{ij}` for two arrays of indices (the *unknowns*, numbered ``0 .. size - 1``). The
object holds :math:`A_{SS}^{-1}` for the current set :math:`S` of unknowns as

.. math:: A_{SS}^{-1} = M + V\,\mathrm{diag}(s)\,V^T,

a stored matrix :math:`M` and up to ``block`` pending rank-one terms of sign
:math:`s = \pm 1`, which one BLAS-3 product folds into :math:`M` when they are full.

* **Removing** unknown :math:`r` subtracts :math:`c\,c^T/c_r`, :math:`c` the current column
  :math:`r` (Sherman & Morrison 1950). A tracked solution :math:`x` of an unchanged
  right-hand side becomes :math:`x - c\,x_r/c_r` in :math:`O(m)`.
* **Adding** unknowns with couplings :math:`B = A_{S,new}` and diagonal block
  :math:`D = A_{new,new}` borders the inverse through the Schur complement
  :math:`S_c = D - B^T M B`: the old block gains :math:`(MB)\,S_c^{-1}(MB)^T`, the new rows are
  written into spare capacity, and tracked solutions are bordered in :math:`O(mk)`.
* **Shifting** a diagonal entry, :math:`A_{rr} \leftarrow A_{rr} + \delta`, subtracts
  :math:`\delta\,c\,c^T/(1 + \delta c_r)` (Sherman & Morrison again); a tracked solution
  becomes :math:`x - c\,\delta x_r/(1 + \delta c_r)`.
* **Compacting** drops the rows of removed unknowns, in place when they fit.
* **Factorising** afresh: Cholesky and LAPACK's inverse from it (``definite``), else a
  symmetric-indefinite inverse.

Two storage layouts. The default keeps the whole symmetric matrix with spare rows, so the set
can grow as well as shrink. ``lower=True`` keeps only the lower triangle of an exactly sized
matrix, for a set that only shrinks (a pull that breaks bonds): products by the symmetric
kernel (DSYMV), folding by a symmetric rank-k update (DSYRK), and compaction in place inside
the one buffer, so the peak memory stays one matrix of the starting order. That layout may also
store the matrix in single precision (``dtype=numpy.float32``: half the memory, twice the
flops of the factorisation and the folding); columns, products and pending terms are still
returned and kept in double precision, so only the stored matrix carries the single-precision
rounding, and callers certify what they compute from it (:func:`refine`).

With ``definite=True`` (the default) the matrix is taken to be positive definite, and an update
whose pivot or Schur complement is not reports failure, so the caller can factorise afresh.
With ``definite=False`` the matrix may be indefinite (symmetric, nonsingular): a negative
pivot adds a term of the other sign, and the Schur complement is inverted through its
eigenvalues. Only a numerically singular update fails: a pivot, or an eigenvalue of the Schur
complement, at or below ``order x eps`` times the largest entry of its column (of its
spectrum), the rank threshold of LAPACK and ``numpy.linalg.matrix_rank``.

The memory is checked before every allocation through ``room(m)``, a callable that says whether
an inverse of order ``m`` may be allocated (:func:`inverse_bytes` gives its peak). Solutions
are certified against an exact operator by :func:`refine`, the package's one iterative
refinement (:meth:`UpdatableInverse.refine` corrects with the current inverse).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from scipy import linalg

from roughslip.errors import NumericalError
from roughslip.linalg import jit, lapack64
from roughslip.linalg.threads import blas_threads

#: peak memory per squared order (bytes): the inverse with up to 27 % spare rows
#: (8 x 1.27^2 m^2), and a second one while it is compacted or grown
BYTES_PER_ORDER2 = 28

#: what a ``lower`` inverse's solve needs besides the matrix and its work arrays (bytes, and a
#: share of the matrix): the certifications' FFT arrays and the O(m) vectors. Measured with the
#: single-precision pull: 20 MB at 13 074 bonds (N = 256) and 46 MB at 77 036 (N = 512)
LOWER_RESERVE = (64 * 2**20, 1 / 128)

#: the assembler: ``entries(i, j, order)``, the block of the matrix between two index arrays
Entries = Callable[[np.ndarray, np.ndarray, str], np.ndarray]


def inverse_bytes(m: int, *, lower: bool = False, block: int = 512, itemsize: int = 8) -> int:
    """Peak memory of an :class:`UpdatableInverse` of order ``m`` (bytes): with spare rows
    and a second matrix while it grows (:data:`BYTES_PER_ORDER2`), or for ``lower`` storage
    one matrix of ``itemsize``-byte entries (8: double, 4: single precision), plus the larger
    of the factorisation's work arrays (freed before the pull starts;
    :func:`~roughslip.linalg.lapack64.cholesky_inverse_work_bytes`) and the ``block`` pending
    columns with O(m) work arrays (double precision), plus :data:`LOWER_RESERVE` for the rest
    of the solve."""
    if lower:
        work = max(lapack64.cholesky_inverse_work_bytes(m, itemsize), 8 * m * (3 * block + 64))
        matrix = itemsize * m * m
        return int(matrix + work + LOWER_RESERVE[0] + matrix * LOWER_RESERVE[1])
    return BYTES_PER_ORDER2 * m * m


def refine(x: object, residual: Callable[[object], tuple[object, float]],
           correct: Callable[[object, object], object], tol: float, limit: int
           ) -> tuple[object, float, int]:
    r"""Iterative refinement: the certification of every solve in the package.

    ``residual(x)`` returns the residual of ``x`` against the exact operator and its relative
    norm; while that is above ``tol``, :math:`x \leftarrow` ``correct(x, r)`` (an approximate
    solve of the residual equation added to ``x``), at most ``limit`` times (Wilkinson's
    iterative refinement; Higham, *Accuracy and Stability of Numerical Algorithms*, 2002,
    ch. 12). Returns ``(x, norm of its residual, corrections done)``.
    """
    done = 0
    while True:
        r, res = residual(x)
        if res <= tol or done >= limit:
            return x, res, done
        x = correct(x, r)
        done += 1


def _compact_lower(flat: np.ndarray, m: int, keep: np.ndarray) -> np.ndarray:
    """Gather rows and columns ``keep`` of the Fortran ``m x m`` matrix held in ``flat`` into
    a Fortran ``k x k`` matrix at the start of the same buffer (lower triangle).

    New column ``c`` starts at ``c k <= keep[c] m``, the start of its source column, and
    ends before the next source column, so a forward sweep never overwrites unread data
    (element by element too: every later read lies beyond every earlier write). Compiled
    when :data:`roughslip.linalg.jit.ENABLED`, else a column at a time; both copy the same
    entries.
    """
    k = keep.size
    if jit.ENABLED:
        _compaction_kernels().lower(flat, m, keep.astype(np.int64))
    else:
        for c in range(k):
            col = flat[int(keep[c]) * m + keep[c:]]  # lower part of the source column (a copy)
            flat[c * k + c: c * k + k] = col
    return flat[: k * k].reshape((k, k), order="F")


def _compact_full(src: np.ndarray, dst: np.ndarray, keep: np.ndarray) -> None:
    """``dst[:k, :k] = src[keep][:, keep]`` for Fortran-ordered ``src`` and ``dst``, which may
    be the same buffer: column ``j`` of the result overwrites source column ``j <= keep[j]``
    after reading it (compiled, or a column at a time)."""
    if jit.ENABLED:
        _compaction_kernels().full(src, dst, keep.astype(np.int64))
        return
    k = keep.size
    for j, col in enumerate(keep):
        dst[:k, j] = src[keep, col]


@functools.cache
def _compaction_kernels() -> SimpleNamespace:
    """The compiled compactions (defined and compiled, or loaded from numba's cache, at first
    use): forward sweeps, element by element, in the order of the numpy versions' columns;
    and the gather of a submatrix (:func:`submatrix`)."""
    njit = jit.njit()

    @njit
    def lower(flat, m, keep):
        k = keep.size
        for c in range(k):
            base = keep[c] * m
            for i in range(c, k):
                flat[c * k + i] = flat[base + keep[i]]

    @njit
    def full(src, dst, keep):
        k = keep.size
        for j in range(k):
            col = keep[j]
            for i in range(k):
                dst[i, j] = src[keep[i], col]

    @njit
    def gather(src, rows, cols, out):
        for j in range(cols.size):
            col = cols[j]
            for i in range(rows.size):
                out[i, j] = src[rows[i], col]

    return SimpleNamespace(lower=lower, full=full, gather=gather)


def submatrix(A: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``A[rows][:, cols]`` (Fortran-ordered), reading only those entries (compiled when
    :data:`roughslip.linalg.jit.ENABLED`, else numpy's gather of the columns, then the
    rows; both copy the same entries)."""
    rows, cols = np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64)
    if jit.ENABLED:
        out = np.empty((rows.size, cols.size), order="F")
        _compaction_kernels().gather(A, rows, cols, out)
        return out
    return np.asfortranarray(A[:, cols][rows])


def _rank_one(x: np.ndarray, c: np.ndarray, a: np.ndarray | float) -> None:
    """``x -= c a^T`` in place: a tracked vector (``a`` a scalar), or a tracked block of
    columns (``a`` one value per column; BLAS's rank-one update where the block is
    Fortran-ordered, which the block's owner keeps)."""
    if x.ndim == 1:
        x -= c * a
    elif x.flags.f_contiguous and x.dtype == np.float64:
        linalg.blas.dger(-1.0, c, np.ascontiguousarray(a), a=x, overwrite_a=True)
    else:
        x -= np.multiply.outer(c, a)


def take_out(inv: object, r: int, c: np.ndarray, held: dict[str, float] | None) -> None:
    r"""Take row ``r`` out of the set of ``inv`` (an inverse with ``tracked``, ``live``,
    ``row``, ``ids`` and ``version``): each tracked solution becomes
    :math:`x - c\,(x_r - h)/c_r` with ``held[name] = h`` (else :math:`h = 0`), for ``c`` the
    current column of the row; the row's entries are zeroed and it is marked removed."""
    for name, h in (held or {}).items():
        inv.tracked[name].x[r] -= h
    cr = float(c[r])
    for t in inv.tracked.values():
        _rank_one(t.x, c, t.x[r] / cr)
        t.x[r] = 0.0
        if t.b is not None:
            t.b[r] = 0.0
    inv.live[r] = False
    inv.version += 1
    inv.row[inv.ids[r]] = -1


def shift_pivot(inv: object, r: int, c: np.ndarray, delta: float) -> float | None:
    r"""Shift the diagonal entry of row ``r`` of ``inv`` (an inverse with ``tracked``, ``m``,
    ``pivot`` and ``shifts``) by ``delta``, ``c`` the row's current column: the pivot
    :math:`1 + \delta c_r` (None, nothing changed, when it is numerically zero: at or below
    ``m x eps`` times :math:`\max(1, |\delta c_r|)`), kept in ``pivot``, and each tracked
    solution becomes :math:`x - c\,\delta x_r/(1 + \delta c_r)`. Returns the weight
    :math:`g = \delta/(1 + \delta c_r)` of the pending term :math:`-g\,c\,c^T`."""
    dc = delta * float(c[r])
    den = 1.0 + dc
    if not (math.isfinite(den) and abs(den) > inv.m * np.finfo(float).eps * max(1.0, abs(dc))):
        return None
    inv.pivot = den
    inv.shifts += 1
    g = delta / den
    for t in inv.tracked.values():
        _rank_one(t.x, c, g * t.x[r])
    return g


def _keep_order(old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """``new`` in the memory order of ``old`` (a tracked block stays Fortran-ordered)."""
    return np.asfortranarray(new) if old.ndim == 2 and old.flags.f_contiguous else new


def _nonsingular(pivots: np.ndarray, scale: np.ndarray) -> bool:
    """Whether every pivot is finite and above ``len(scale) x eps x max|scale|``."""
    if not (np.all(np.isfinite(pivots)) and np.all(np.isfinite(scale))):
        return False
    floor = scale.size * np.finfo(float).eps * float(np.max(np.abs(scale)))
    return bool(np.min(np.abs(pivots)) > floor)


@dataclass
class Tracked:
    """A solution kept current through the updates: ``x = A_SS^{-1} b`` on the rows.

    ``b`` and ``x`` are vectors, or matrices with one column per right-hand side (rows
    first); ``b`` may be None where nobody compares right-hand sides. ``values(ids)`` gives
    the right-hand side for unknowns that are added later.
    """

    b: np.ndarray | None
    x: np.ndarray
    values: Callable[[np.ndarray], np.ndarray]


class UpdatableInverse:
    """The inverse of a symmetric matrix on a changing set of unknowns (module docstring).

    Parameters
    ----------
    entries
        The assembler ``entries(i, j, order)`` of the matrix.
    size
        The number of unknowns the matrix has (indices ``0 .. size - 1``).
    room
        ``room(m)``: whether an inverse of order ``m`` may be allocated. When it says no, the
        operation that needed it does nothing and reports so.
    threads
        BLAS threads of the factorisation, the folding of pending terms and products with
        large inverses (everything else runs on one).
    block
        Pending rank-one terms kept before they are folded in.
    definite
        Whether the matrix is positive definite (module docstring).
    lower
        Keep the lower triangle only, for a set that only shrinks (module docstring):
        :meth:`add` is refused, and every product runs on ``threads``. Positive definite
        matrices only (every pending term then has the sign -1).
    points
        The point of each unknown: not used (the dense inverse needs no geometry; a
        compressed one clusters by it).
    """

    #: what it is, in messages
    kind = "dense"

    threaded_min = 8192  # order from which products with the inverse use the threads
    symv_min = 1024  # order from which products with few columns use the symmetric kernel

    def __init__(self, entries: Entries, size: int, *, room: Callable[[int], bool],
                 threads: int = 1, block: int = 512, definite: bool = True,
                 lower: bool = False, dtype: type = np.float64,
                 points: np.ndarray | None = None) -> None:
        if lower and not definite:
            raise ValueError("the lower-triangle layout holds a positive definite matrix")
        self.dtype = np.dtype(dtype)
        if self.dtype not in lapack64.DTYPES or (self.dtype != np.float64 and not lower):
            raise ValueError(f"dtype {self.dtype}: float64, or float32 in the lower layout")
        self.entries = entries
        self.lower = lower
        if lower:  # the matrix is large by choice: every product gets the threads
            self.threaded_min = 0
        self.room = room
        self.threads = threads
        self.block = block
        self.definite = definite
        self.factorisations = 0
        #: seconds in dense linear algebra (factorisation, products, updates)
        self.blas_seconds = 0.0
        self.row = np.full(int(size), -1, dtype=np.int64)  # unknown -> row, -1: not in the set
        self.buf: np.ndarray | None = None  # F-order, capacity x capacity; M = buf[:m, :m]
        self.m = 0  # rows in use, removed ones included
        self.V = np.empty((0, block), order="F")  # pending terms
        self.s = np.empty(block)  # their signs
        self.k = 0  # pending terms in use
        #: the pivot of the last :meth:`remove` (:math:`c_r`), :meth:`shift`
        #: (:math:`1 + \delta c_r`) or :meth:`add` of one unknown (its Schur complement): its
        #: sign says how the inertia changed
        self.pivot = math.nan
        self.ids = np.empty(0, dtype=np.int64)  # unknown of each row
        self.live = np.empty(0, dtype=bool)  # rows still in the set
        #: tracked solutions by name (:class:`Tracked`, on the rows)
        self.tracked: dict[str, Tracked] = {}
        #: counts every change of the rows (their unknowns or which are live), so that a
        #: layout derived from them can be kept until the next change
        self.version = 0
        #: counts the changes of the inverse that keep its rows (:meth:`shift`): with
        #: :attr:`version`, what a product derived from the inverse must be kept against
        self.shifts = 0

    @staticmethod
    def memory_bytes(m: int, *, block: int = 512, itemsize: int = 8, per_point: int = 1) -> int:
        """The peak memory of an inverse of order ``m`` on a set that only shrinks (the
        lower-triangle layout, :func:`inverse_bytes`; how many unknowns share a point,
        ``per_point``, does not change it)."""
        return inverse_bytes(m, lower=True, block=block, itemsize=itemsize)

    # -- state ---------------------------------------------------------------------------------
    @property
    def ready(self) -> bool:
        """Whether an inverse is held (after :meth:`factor`, until :meth:`reset`)."""
        return self.buf is not None

    def unknowns(self) -> np.ndarray:
        """The unknowns in the set, in row order."""
        return self.ids[self.live]

    def reset(self) -> None:
        """Drop the inverse and the tracked solutions."""
        self.row[:] = -1
        self.buf, self.m, self.k = None, 0, 0
        self.ids = np.empty(0, dtype=np.int64)
        self.live = np.empty(0, dtype=bool)
        self.tracked = {}
        self.version += 1

    def _adopt(self, buf: np.ndarray, m: int, ids: np.ndarray) -> None:
        """Take ``buf[:m, :m]`` as the inverse on the unknowns ``ids`` (nothing pending)."""
        self.row[self.ids] = -1
        self.buf, self.m = buf, m
        if self.lower:  # the flat view of the one buffer, for compaction in place
            self._flat = buf.reshape(-1, order="F")
        self.ids = np.asarray(ids, dtype=np.int64)
        self.row[self.ids] = np.arange(m)
        self.live = np.ones(m, dtype=bool)
        self.version += 1
        if not (self.lower and self.V.shape[0] >= m):  # lower: the pending columns shrink too
            self.V = np.zeros((buf.shape[0], self.block), order="F")
        self.k = 0

    # -- factorising ---------------------------------------------------------------------------
    def factor(self, ids: np.ndarray, positive: bool | None = None) -> bool:
        """The inverse on the unknowns ``ids`` afresh; False when ``room`` refused it.

        Positive definite (``positive``, by default ``definite``: an indefinite object may
        start from a definite set): Cholesky and LAPACK's inverse from it (potrf + potri, in
        place: a third of the work of solving for the identity). Indefinite: an LU inverse.
        Raises :class:`NumericalError` when the matrix is not positive definite
        (``positive``) or is singular.
        """
        positive = self.definite if positive is None else positive
        ids = np.asarray(ids, dtype=np.int64)
        if not self.room(ids.size):
            return False
        lapack64.check_size(ids.size)
        A = (self.entries(ids, ids, "F") if self.dtype == np.float64
             else self.entries(ids, ids, "F", self.dtype))
        t0 = time.perf_counter()
        try:
            with blas_threads(self.threads):
                if positive:
                    lapack64.cholesky_inverse(A)
                else:
                    A = np.asfortranarray(np.linalg.inv(A))
        except (NumericalError, np.linalg.LinAlgError) as exc:
            what = "not positive definite" if positive else "singular"
            raise NumericalError(f"the matrix on {ids.size} unknowns is {what}") from exc
        finally:
            self.blas_seconds += time.perf_counter() - t0
        if positive and not self.lower:
            lapack64.mirror_lower(A)
        self._adopt(A, ids.size, ids)
        self.tracked = {}
        self.factorisations += 1
        return True

    # -- products ------------------------------------------------------------------------------
    def apply(self, B: np.ndarray) -> np.ndarray:
        """The current inverse times ``B`` (one or more columns on the rows; rows of removed
        unknowns must be zero)."""
        if B.ndim == 1 and not self.lower:
            return self.apply(B[:, None])[:, 0]
        if B.ndim == 2 and self.lower:
            return np.column_stack([self.apply(B[:, j]) for j in range(B.shape[1])])
        t0, m = time.perf_counter(), self.m
        # a product with a large inverse is bound by memory bandwidth: more threads read
        # faster, and a few columns go by the symmetric product, which reads half of it
        with blas_threads(self.threads if m >= self.threaded_min else 1):
            if self.lower:
                sol = lapack64.symv(self.buf, B, m)
            elif B.shape[1] <= 4 and m >= self.symv_min:
                sol = np.column_stack([lapack64.symv(self.buf, B[:, j], m)
                                       for j in range(B.shape[1])])
            else:
                sol = self.buf[:m, :m] @ B
            if self.k:
                V = self.V[:m, : self.k]
                sgn = self.s[: self.k] if B.ndim == 1 else self.s[: self.k, None]
                sol += V @ (sgn * (V.T @ B))
        self.blas_seconds += time.perf_counter() - t0
        return sol

    def column(self, r: int) -> np.ndarray:
        """Column ``r`` of the current inverse."""
        t0 = time.perf_counter()
        if self.lower:
            c = np.empty(self.m)
            c[:r] = self.buf[r, :r]
            c[r:] = self.buf[r: self.m, r]
        else:
            c = self.buf[: self.m, r].copy()
        if self.k:
            V, sgn = self.V[: self.m, : self.k], self.s[: self.k]
            if self.lower:  # removals from a definite matrix: every sign is -1
                c -= V @ V[r]
            else:
                c += V @ (sgn * V[r])
        self.blas_seconds += time.perf_counter() - t0
        return c

    def diagonal(self) -> np.ndarray:
        """The diagonal of the current inverse on the rows (removed rows hold stale
        values)."""
        d = np.diagonal(self.buf[: self.m, : self.m]).copy()
        if self.k:
            V = self.V[: self.m, : self.k]
            d += (V * V) @ self.s[: self.k]
        return d

    def refine(self, x: np.ndarray, residual: Callable[[np.ndarray], tuple[np.ndarray, float]],
               tol: float, refinements: int) -> tuple[np.ndarray, float, int]:
        r"""Certify ``x`` against an exact operator (:func:`refine`): ``residual(x)`` returns
        the residual on the rows and its relative norm; while that is above ``tol``,
        :math:`x \leftarrow x + A_{SS}^{-1} r` on the live rows (removed rows stay as they
        are), at most ``refinements`` times. Returns ``(x, norm, refinements done)``."""
        def correct(x: np.ndarray, r: np.ndarray) -> np.ndarray:
            step = self.apply(r)
            step[~self.live] = 0.0
            return x + step

        return refine(x, residual, correct, tol, refinements)

    # -- pending terms -------------------------------------------------------------------------
    def _push(self, W: np.ndarray, sign: float | np.ndarray) -> None:
        """Pending terms ``W diag(sign) W^T`` (W with m rows; one sign or one per column)."""
        if self.k + W.shape[1] > self.V.shape[1]:
            self.flush()
        if W.shape[1] > self.V.shape[1]:  # too many to keep pending: fold in now
            M = self.buf[: self.m, : self.m]
            M += (sign * (W @ W.T)) if np.ndim(sign) == 0 else (W * sign) @ W.T
            return
        k2 = self.k + W.shape[1]
        self.V[: self.m, self.k:k2] = W
        self.s[self.k:k2] = sign
        self.k = k2

    def flush(self) -> None:
        """Fold the pending terms into M (GEMMs on column panels); clear dead columns."""
        if self.k:
            t0 = time.perf_counter()
            m, V = self.m, self.V[: self.m, : self.k]
            M = self.buf[:m, :m]
            if self.lower:  # one symmetric rank-k update (every sign is -1); dead entries
                with blas_threads(self.threads):  # are never read
                    lapack64.syrk_update(M, V, -1.0)
            else:
                Vs = np.empty(self.V.shape, order="F")  # the rows of V: the GEMM's layout
                np.multiply(V, self.s[: self.k], out=Vs[:m, : self.k])
                with blas_threads(self.threads):
                    lapack64.gemm_update(self.buf, m, Vs, self.V, self.k)
                # dead columns are cleared (contiguous); dead rows only feed dead entries of
                # solutions, which are never read
                M[:, ~self.live] = 0.0
            self.V[:m, : self.k] = 0.0
            self.k = 0
            self.blas_seconds += time.perf_counter() - t0

    # -- updates -------------------------------------------------------------------------------
    def remove(self, unknown: int, column: np.ndarray | None = None,
               held: dict[str, float] | None = None) -> bool:
        r"""Remove ``unknown`` from the set; False when its pivot is not positive (definite)
        or numerically zero (indefinite, module docstring). ``column``: its current column,
        when the caller has it.

        ``held[name] = h``: in the tracked solution ``name`` the unknown keeps the value
        :math:`h`, which moves to the right-hand side: the solution becomes
        :math:`A_{S'S'}^{-1}(b_{S'} - A_{S'r} h) = [x - c\,(x_r - h)/c_r]_{S'}`. The stored
        right-hand side ``b`` is not updated for it."""
        r = int(self.row[unknown])
        c = self.column(r) if column is None else column
        cr = float(c[r])
        if not (cr > 0 if self.definite else _nonsingular(np.array([cr]), c)):
            return False
        self.pivot = cr
        take_out(self, r, c, held)
        self._push((c * (1.0 / math.sqrt(abs(cr))))[:, None], -1.0 if cr > 0 else 1.0)
        return True

    def shift(self, unknown: int, delta: float, column: np.ndarray | None = None
              ) -> np.ndarray | None:
        r"""Add ``delta`` to the diagonal entry of ``unknown`` (module docstring); returns the
        new column of the inverse on the rows, or None (nothing changed) when the update is
        numerically singular: :math:`|1 + \delta c_r|` at or below ``m x eps`` times
        :math:`\max(1, |\delta c_r|)`. Tracked solutions keep their right-hand sides.

        The number of negative eigenvalues grows by one when ``delta < 0`` and the pivot
        :math:`1 + \delta c_r` (kept in :attr:`pivot`) is negative, and falls by one when
        ``delta > 0`` and it is negative; otherwise it stays.

        The assembler must give the shifted entry from now on (for :meth:`add` and
        :meth:`factor`). ``column``: the current column of ``unknown``, when the caller has
        it.
        """
        if self.lower:
            raise ValueError("a lower-triangle inverse holds a set that only shrinks")
        r = int(self.row[unknown])
        c = self.column(r) if column is None else column
        g = shift_pivot(self, r, c, delta)
        if g is None:
            return None
        self._push((c * math.sqrt(abs(g)))[:, None], -1.0 if g > 0 else 1.0)
        return c / self.pivot

    def change_rhs(self, name: str, unknown: int, delta: float,
                   column: np.ndarray | None = None) -> None:
        """Add ``delta`` to the entry of ``unknown`` in the right-hand side of the tracked
        solution ``name``: the solution moves by ``delta`` times the unknown's column
        (``column``: that column, when the caller has it)."""
        r = int(self.row[unknown])
        c = self.column(r) if column is None else column
        t = self.tracked[name]
        t.x += delta * c
        if t.b is not None:
            t.b[r] += delta

    def compact(self, extra: int = 0) -> bool:
        """Drop removed rows; in place when ``extra`` more rows fit, else into a larger buffer
        (False when ``room`` refused it).

        Column by column in increasing order (each a gather within one contiguous column):
        in place, column ``j`` of the result overwrites source column ``j <= keep[j]``, which
        was read before."""
        keep = np.flatnonzero(self.live)
        k = keep.size
        if self.lower and extra:
            raise ValueError("a lower-triangle inverse holds a set that only shrinks")
        if k + extra > self.buf.shape[0] and not self.room(k + extra):
            return False
        self.flush()
        tracked = {key: Tracked(None if t.b is None else t.b[keep],
                                _keep_order(t.x, t.x[keep]), t.values)
                   for key, t in self.tracked.items()}
        if self.lower:
            self._adopt(_compact_lower(self._flat, self.m, keep), k, self.ids[keep])
            self.tracked = tracked
            return True
        buf = self.buf
        if k + extra > buf.shape[0]:
            cap = k + max(extra, k // 8 + 16)
            buf = np.zeros((cap, cap), order="F")
        _compact_full(self.buf, buf, keep)
        self._adopt(buf, k, self.ids[keep])
        self.tracked = tracked
        return True

    def add(self, new: np.ndarray) -> bool | None:
        """Border the inverse with the unknowns ``new``.

        Returns True when done, False when the Schur complement is not positive definite
        (``definite``) or is singular, and None when ``room`` refused the larger buffer
        (nothing changed).
        """
        if self.lower:
            raise ValueError("a lower-triangle inverse holds a set that only shrinks")
        if self.m + new.size > self.buf.shape[0]:  # no spare rows left: compact and grow
            if not self.compact(new.size):
                return None
        m, k2 = self.m, new.size
        B = np.zeros((m, k2))
        rows = np.flatnonzero(self.live)
        B[rows] = self.entries(self.ids[rows], new, "C")
        MB = self.apply(B)
        MB[~self.live] = 0.0
        Sc = self.entries(new, new, "C") - B.T @ MB
        if self.definite:
            try:  # the Schur complement of an SPD block is SPD: Cholesky checks
                L = linalg.cholesky(Sc, lower=True, check_finite=False)
            except linalg.LinAlgError:
                return False
            Linv = linalg.solve_triangular(L, np.eye(k2), lower=True, check_finite=False)
            Si = Linv.T @ Linv
            W, sign = MB @ Linv.T, 1.0
        else:
            w, Q = linalg.eigh(Sc, check_finite=False)
            if not _nonsingular(w, w):
                return False
            Si = (Q / w) @ Q.T
            W, sign = MB @ (Q / np.sqrt(np.abs(w))), np.sign(w)
        if k2 == 1:
            self.pivot = float(Sc[0, 0])
        MBSi = MB @ Si
        buf = self.buf
        buf[m:m + k2, :m] = -MBSi.T
        buf[:m, m:m + k2] = -MBSi
        buf[m:m + k2, m:m + k2] = Si
        self._push(W, sign)
        for t in self.tracked.values():  # border the tracked solutions
            bn = t.values(new)
            z = Si @ (bn - B.T @ t.x)
            if t.b is not None:
                t.b = np.concatenate([t.b, bn])
            x = np.empty((m + k2, *t.x.shape[1:]),
                         order="F" if t.x.ndim == 2 and t.x.flags.f_contiguous else "C")
            np.subtract(t.x, MB @ z, out=x[:m])
            x[m:] = z
            t.x = x
        self.m = m + k2
        self.ids = np.concatenate([self.ids, new])
        self.row[new] = np.arange(m, m + k2)
        self.live = np.concatenate([self.live, np.ones(k2, dtype=bool)])
        self.version += 1
        return True
