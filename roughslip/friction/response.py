r"""The response of the bonds to their slips, :math:`K = G_{xx}^{-1}` on all bonds, as a burst
of slip-weakening reads it (:mod:`~roughslip.friction.relax`, :mod:`~roughslip.friction.least`).

With every bond holding its displacement, a slip :math:`y` of the bonds changes their forces by
:math:`-K y`. A burst reads :math:`K` through its row sums (the forces of a unit drive), its
blocks between the moving bonds and the others, single columns, diagonal entries and products
:math:`K v`. Two forms give them, with one interface (:class:`Response`):

* :class:`DenseResponse`: the matrix, from Cholesky and LAPACK's inverse (:math:`n^2` words);
  exact to rounding.
* :class:`CompressedResponse`: the compressed inverse of :math:`G_{xx}`
  (:class:`~roughslip.linalg.hierarchical.HierarchicalInverse`), whose columns and products are
  certified against the FFT operator by iterative refinement
  (:func:`~roughslip.linalg.inverse.refine`) until the residual :math:`\|e - G_{xx} x\|` is at
  most ``tol`` of :math:`\|e\|`, and kept (columns up to a memory budget, the least recently
  used dropped first: a dropped column is recomputed to the same bits). It takes
  :math:`O(n k \log n)` words instead of :math:`n^2`.

:func:`burst_response` takes the dense form whenever it fits in memory and the pull's own
inverse is dense, so such a pull gives the numbers it always gave; a pull on a compressed
inverse takes the compressed form.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Protocol

import numpy as np

from roughslip.errors import MemoryLimitError, NumericalError
from roughslip.friction.bonds import Bonds
from roughslip.linalg import lapack64
from roughslip.linalg.hierarchical import HierarchicalInverse, hierarchical_bytes
from roughslip.linalg.inverse import inverse_bytes
from roughslip.linalg.memory import available_bytes

#: the memory the compressed response keeps its refined columns in (bytes)
CACHE_BYTES = 256 * 2**20
#: corrections of a column or product before its residual must be within the tolerance
REFINEMENTS = 4


class Response(Protocol):
    """:math:`K = G_{xx}^{-1}` on all bonds, as a burst reads it (module docstring). What it
    returns is read, never changed in place (a column may be a view or a kept array)."""

    #: :math:`K 1`, the forces of a unit drive with every bond stuck
    row_sums: np.ndarray
    #: the largest relative residual of what it gave against the FFT operator (0: exact to
    #: rounding)
    worst: float

    def block(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """:math:`K_{ij}` for the bonds ``i`` (rows) and ``j`` (columns)."""
        ...

    def column(self, q: int) -> np.ndarray:
        """Column ``q`` of :math:`K` (all bonds)."""
        ...

    def diagonal(self, i: np.ndarray) -> np.ndarray:
        """:math:`K_{ii}` for the bonds ``i``."""
        ...

    def times(self, v: np.ndarray) -> np.ndarray:
        """:math:`K v`."""
        ...

    def room(self, m: int, extra: int = 0) -> bool:
        """Whether a burst may invert its matrix on ``m`` moving bonds and hold ``extra`` bytes
        besides (raises :class:`~roughslip.errors.MemoryLimitError` when not)."""
        ...

    def describe(self) -> str:
        """What the pull's message adds about it ("" for the dense matrix)."""
        ...


class DenseResponse:
    """:math:`K` held as a matrix (module docstring)."""

    def __init__(self, K: np.ndarray) -> None:
        self.K = K
        self.row_sums = K.sum(axis=1)
        self.worst = 0.0

    def block(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        return self.K[np.ix_(i, j)]

    def column(self, q: int) -> np.ndarray:
        return self.K[:, q]

    def diagonal(self, i: np.ndarray) -> np.ndarray:
        return np.diagonal(self.K)[i]

    def times(self, v: np.ndarray) -> np.ndarray:
        return self.K @ v

    def room(self, m: int, extra: int = 0) -> bool:
        """Always: :func:`burst_response` counted a burst's inverse on all bonds."""
        return True

    def describe(self) -> str:
        return ""


class CompressedResponse:
    """:math:`K` from the compressed inverse of :math:`G_{xx}`, every column and product
    refined against the FFT operator to ``tol`` (module docstring).

    Parameters
    ----------
    b
        The bonds (their operator and sites).
    tol
        The largest relative residual of a column or product; one that stays above it after
        :data:`REFINEMENTS` corrections raises :class:`~roughslip.errors.NumericalError`.
    threads
        BLAS threads of the factorisation.
    """

    def __init__(self, b: Bonds, tol: float, threads: int = 1) -> None:
        self.b, self.tol = b, float(tol)
        n = b.n
        # nothing is ever updated: no buffer of pending terms
        self.inv = HierarchicalInverse(b.entries, n, room=lambda m: True, threads=threads,
                                       points=b.points(), block=1, capacity=1)
        try:
            self.inv.factor(np.arange(n))
        except NumericalError as exc:
            raise NumericalError(f"G_xx on all bonds: {exc}") from None
        self.columns: OrderedDict[int, np.ndarray] = OrderedDict()
        self.capacity = max(16, CACHE_BYTES // (8 * max(n, 1)))  # columns kept
        #: the largest relative residual reached
        self.worst = 0.0
        #: the refinements' corrections made
        self.refinements = 0
        self.computed = 0  # columns computed (a dropped one again when read again)
        self.diag = np.full(n, np.nan)  # K_qq, once read
        self.row_sums = self._solve(np.ones(n), self.inv.apply(np.ones(n)))

    @staticmethod
    def memory_bytes(n: int) -> int:
        """What it holds for ``n`` bonds (bytes): the compressed inverse, the columns and the
        diagonal."""
        return hierarchical_bytes(n, capacity=1) + CACHE_BYTES + 8 * n

    def _solve(self, e: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``x`` refined until :math:`\\|e - G_{xx} x\\| \\le` ``tol`` :math:`\\|e\\|`."""
        b = self.b
        scale = max(float(np.linalg.norm(e)), np.finfo(float).tiny)

        def residual(x: np.ndarray) -> tuple[np.ndarray, float]:
            u = b.apply(b.field(x), np.empty(b.shape)).ravel()[b.sites]
            r = e - u
            return r, float(np.linalg.norm(r)) / scale

        x, res, done = self.inv.refine(x, residual, self.tol, REFINEMENTS)
        self.worst, self.refinements = max(self.worst, res), self.refinements + done
        if not res <= self.tol:
            raise NumericalError(f"slip-weakening: a solve with G_xx on {b.n} bonds kept a "
                                 f"relative residual of {res:.1e} above the tolerance "
                                 f"{self.tol:.1e} after {done} refinements")
        return x

    def column(self, q: int) -> np.ndarray:
        q = int(q)
        col = self.columns.get(q)
        if col is not None:
            self.columns.move_to_end(q)
            return col
        e = np.zeros(self.b.n)
        e[q] = 1.0
        col = self._solve(e, self.inv.column(q))
        self.computed += 1
        col.flags.writeable = False
        self.columns[q] = col
        if len(self.columns) > self.capacity:
            self.columns.popitem(last=False)
        return col

    def block(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        out = np.empty((np.size(i), np.size(j)))
        for c, q in enumerate(np.asarray(j).ravel()):
            out[:, c] = self.column(int(q))[i]
        return out

    def diagonal(self, i: np.ndarray) -> np.ndarray:
        """Kept apart from the columns, whose budget a burst's stability tests, one entry
        from each of thousands of columns, would otherwise cycle through over and over (an
        entry is the same bits whenever its column is computed)."""
        i = np.asarray(i, dtype=np.int64).ravel()
        for q in i[np.isnan(self.diag[i])].tolist():
            self.diag[q] = self.column(q)[q]
        return self.diag[i]

    def times(self, v: np.ndarray) -> np.ndarray:
        if not np.any(v):
            return np.zeros(self.b.n)
        return self._solve(v, self.inv.apply(v))

    def room(self, m: int, extra: int = 0) -> bool:
        """Whether the inverse of a burst's matrix on ``m`` moving bonds and ``extra`` bytes fit
        in memory; raises :class:`~roughslip.errors.MemoryLimitError` when not."""
        need = inverse_bytes(m) + extra
        if need > available_bytes():
            raise MemoryLimitError(
                f"slip-weakening: a burst moves {m} bonds, whose matrix's inverse needs "
                f"~{need / 2**30:.2f} GiB but {available_bytes() / 2**30:.2f} GiB are "
                "available")
        return True

    def describe(self) -> str:
        return (f"; the bursts read G_xx^-1 compressed, {self.computed} columns refined "
                f"against the FFT operator ({self.refinements} corrections) to a relative "
                f"residual of {self.worst:.1e} at most")


#: the response of a pull without bursts, in its result
NO_BURSTS = DenseResponse(np.zeros((0, 0)))


def burst_response(b: Bonds, tol: float, threads: int = 1, compressed: bool = False
                   ) -> Response:
    r""":math:`K` for the bursts of a pull: dense when it and the inverse of a burst's matrix on
    all bonds fit in memory (twice :func:`~roughslip.linalg.inverse.inverse_bytes`) and the
    pull holds no compressed matrix (``compressed``: its stick solver is compressed), else
    compressed (:class:`CompressedResponse`), whose bursts then check the memory of their own
    moving set; :class:`~roughslip.errors.MemoryLimitError` when neither fits."""
    n = b.n
    if not compressed and 2 * inverse_bytes(n) <= available_bytes():
        K = np.asfortranarray(b.dense())
        lapack64.mirror_lower(lapack64.cholesky_inverse(K))  # G_xx is positive definite
        return DenseResponse(K)
    need = CompressedResponse.memory_bytes(n)
    if need > available_bytes():
        raise MemoryLimitError(
            f"slip-weakening: a burst needs G_xx^-1 on all {n} bonds, "
            f"~{2 * inverse_bytes(n) / 2**30:.2f} GiB dense or ~{need / 2**30:.2f} GiB "
            f"compressed, but {available_bytes() / 2**30:.2f} GiB are available")
    return CompressedResponse(b, tol, threads)


__all__ = ["CompressedResponse", "DenseResponse", "Response", "burst_response"]
