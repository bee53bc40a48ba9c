r"""A compressed inverse of a symmetric matrix on a changing index set: a HODLR factorisation
with pending rank-one updates.

The matrix :math:`A` is known through its assembler ``entries(i, j, order)`` (as for
:class:`~roughslip.linalg.inverse.UpdatableInverse`) and each unknown has a point in the plane.
The unknowns are ordered by a *cluster tree*: each cluster is halved at the median of its
wider coordinate until a leaf holds at most ``leaf`` unknowns. In that order the matrix is
*hierarchically off-diagonal low-rank* (HODLR; Ambikasaran & Darve, *J. Sci. Comput.* 57,
2013): on every cluster :math:`\tau` with halves :math:`\tau_1, \tau_2`,

.. math:: A_\tau = \begin{pmatrix} A_{\tau_1} & U V^T \\ V U^T & A_{\tau_2} \end{pmatrix}
          = D_\tau + Z K Z^T, \qquad Z = \begin{pmatrix} U & 0 \\ 0 & V\end{pmatrix}, \quad
          K = \begin{pmatrix} 0 & I \\ I & 0 \end{pmatrix},

with dense blocks on the leaves. The off-diagonal blocks are compressed once, from entries, by
adaptive cross approximation with partial pivoting (Bebendorf, *Numer. Math.* 86, 2000)
followed by a truncated SVD: :math:`\|A_{\tau_1\tau_2} - UV^T\|_F \le` ``tol``
:math:`\|A_{\tau_1\tau_2}\|_F` as far as the cross approximation's estimate of the remainder
tells (it is an estimate: the callers certify what they compute against the exact operator).

The factorisation is Woodbury's identity applied from the leaves up,

.. math:: A_\tau^{-1} = D_\tau^{-1} - Y_\tau\, S_\tau^{-1} Y_\tau^T, \qquad
          Y_\tau = D_\tau^{-1} Z, \qquad S_\tau = K + Z^T Y_\tau,

so a solve costs :math:`O(n k \log n)` and a column of the inverse :math:`O(n k)` (one cluster
per level holds the unit vector's support), :math:`k` the ranks. The diagonal of the inverse
follows the same recursion: :math:`\mathrm{diag}(A_\tau^{-1}) = \mathrm{diag}(D_\tau^{-1}) -
\mathrm{rowsum}((Y_\tau S_\tau^{-1}) \circ Y_\tau)`.

Removing unknown :math:`r` subtracts :math:`c\,c^T/c_r` (Sherman & Morrison), kept pending as
in the dense inverse; shifting its diagonal entry by :math:`\delta` subtracts
:math:`\delta\,c\,c^T/(1 + \delta c_r)`. Folding them (:meth:`HierarchicalInverse.flush`) does
not touch the compression: the compressed matrix restricted to the remaining unknowns is the
same blocks with rows deleted and the shifts added to the leaves' diagonals, so the fold does
that and factorises again, which is exactly the pending updates' result up to rounding. The
only approximation is the compression itself, fixed when the set is factorised. Adding
unknowns compresses the new set afresh (:meth:`HierarchicalInverse.add`).

The matrix may be indefinite (symmetric, nonsingular; ``definite=False``): the leaves and the
Woodbury matrices are then inverted through their eigenvalues, which also give the inertia of
the compressed matrix. By Haynsworth's inertia theorem applied to the bordered matrix
:math:`\begin{pmatrix} D_\tau & Z \\ Z^T & -K \end{pmatrix}` (:math:`K^{-1} = K`; the Schur
complement of :math:`D_\tau` is :math:`-S_\tau`, that of :math:`-K` is :math:`A_\tau`, and
:math:`-K` has :math:`k` eigenvalues of each sign),

.. math:: \nu_-(A_\tau) = \nu_-(A_{\tau_1}) + \nu_-(A_{\tau_2}) + \nu_+(S_\tau) - k,

so the count of negative eigenvalues (:attr:`HierarchicalInverse.negatives`) comes out of the
factorisation; each update then changes it by the sign of its pivot, as in the dense inverse.
The factorisation needs every cluster's matrix to be nonsingular, not only the whole one: a
singular one raises :class:`~roughslip.errors.NumericalError`, a nearly singular one amplifies
the rounding, which the callers' certification against the exact operator sees.

Its memory is estimated before it is built (:func:`hierarchical_bytes`, from a rank model
measured on rough contacts): the leaves, and per cluster level the bases :math:`U, V` and
:math:`Y`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from roughslip.errors import NumericalError
from roughslip.linalg.inverse import (
    Entries,
    Tracked,
    UpdatableInverse,
    _keep_order,
    _nonsingular,
    shift_pivot,
    take_out,
)
from roughslip.linalg.threads import blas_threads

#: relative truncation of the off-diagonal blocks (cross approximation and SVD)
TOL = 1e-8
#: the most pending terms held before a fold, whatever the cost balance asks
FOLD_MAX = 1024
#: what reading one word of a pending term costs, in flops of the factorisation (its GEMMs run
#: near the machine's flop rate, a column's pending terms at its memory bandwidth); it moves
#: the fold point only, never a result
WORD_FLOPS = 20.0
#: the cross approximation runs to this fraction of ``tol`` before the SVD truncates to ``tol``
#: (its stopping rule estimates the remainder from the last cross only)
ACA_MARGIN = 0.1
#: the most unknowns of a leaf
LEAF = 64
#: the largest rank of an off-diagonal block
MAX_RANK = 1024


def cluster_tree(points: np.ndarray, leaf: int) -> tuple[np.ndarray, list[tuple[int, int]],
                                                           np.ndarray, np.ndarray]:
    """The cluster tree of ``points`` (``m x 2``): the order of the points (``perm``: the
    point at each tree position), and the clusters in breadth-first order as ``(start, stop)``
    ranges of tree positions with their children (``left[c]``, ``-1`` for a leaf; the right
    child is ``left[c] + 1``). A cluster of more than ``leaf`` points is halved at the median of
    its wider coordinate (ties kept in their order: the tree is deterministic)."""
    m = points.shape[0]
    perm = np.arange(m)
    ranges: list[tuple[int, int]] = [(0, m)]
    left: list[int] = [-1]
    level: list[int] = [0]
    c = 0
    while c < len(ranges):
        a, b = ranges[c]
        if b - a > leaf:
            p = points[perm[a:b]]
            axis = int(np.argmax(p.max(axis=0) - p.min(axis=0)))
            order = np.argsort(p[:, axis], kind="stable")
            perm[a:b] = perm[a:b][order]
            h = a + (b - a) // 2
            left[c] = len(ranges)
            ranges += [(a, h), (h, b)]
            left += [-1, -1]
            level += [level[c] + 1] * 2
        c += 1
    return perm, ranges, np.array(left, dtype=np.int64), np.array(level, dtype=np.int64)


def aca(row: Callable[[int], np.ndarray], col: Callable[[int], np.ndarray], shape: tuple[int, int],
        tol: float, max_rank: int) -> tuple[np.ndarray, np.ndarray]:
    r"""Adaptive cross approximation with partial pivoting of a block known by its rows and
    columns (Bebendorf 2000): :math:`A \approx U V^T`, stopped when the last cross
    :math:`\|u_k\|\|v_k\|` falls below ``tol`` times the estimate of :math:`\|UV^T\|_F`, or at
    ``max_rank``. The next row is the largest entry of the last column among the rows not yet
    used; a zero row moves to the next unused one."""
    m, n = shape
    U = np.zeros((m, min(max_rank, m, n)))
    V = np.zeros((n, U.shape[1]))
    used = np.zeros(m, dtype=bool)
    i, k, norm2 = 0, 0, 0.0
    while k < U.shape[1]:
        used[i] = True
        r = row(i) - U[i, :k] @ V[:, :k].T
        j = int(np.argmax(np.abs(r)))
        if r[j] == 0.0:
            free = np.flatnonzero(~used)
            if free.size == 0:
                break
            i = int(free[0])
            continue
        v = r / r[j]
        u = col(j) - U[:, :k] @ V[j, :k]
        nu, nv = float(np.linalg.norm(u)), float(np.linalg.norm(v))
        norm2 += (nu * nv) ** 2 + 2.0 * float((U[:, :k].T @ u) @ (V[:, :k].T @ v))
        U[:, k], V[:, k] = u, v
        k += 1
        if nu * nv <= tol * math.sqrt(max(norm2, 0.0)):
            break
        au = np.abs(u)
        au[used] = -1.0
        i = int(np.argmax(au))
        if au[i] < 0:
            break
    return U[:, :k], V[:, :k]


def recompress(U: np.ndarray, V: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    r""":math:`UV^T` at its numerical rank: QR of both factors and an SVD of the small core,
    truncated where the singular values' tail falls below ``tol`` of their norm (Frobenius)."""
    if U.shape[1] == 0:
        return U, V
    Qu, Ru = np.linalg.qr(U)
    Qv, Rv = np.linalg.qr(V)
    W, s, Zt = np.linalg.svd(Ru @ Rv.T)
    tail = np.sqrt(np.cumsum((s * s)[::-1]))[::-1]  # tail[k]: norm of s[k:]
    keep = int(np.count_nonzero(tail > tol * tail[0])) if tail[0] > 0 else 0
    return Qu @ (W[:, :keep] * s[:keep]), Qv @ Zt[:keep].T


#: the rank model of the memory estimate: a typical rank of the block between the halves of a
#: cluster of ``s`` unknowns, ``RANK_MODEL[0] + RANK_MODEL[1] sqrt(s)``. Single blocks exceed
#: it (the root: 227 for 13 074 open-boundary bonds, 806 for 52 259, 483 for 6 249 periodic
#: ones, whose halves touch twice), the total stays below it on the rough contacts measured
#: (2 410 MiB held against 3 149 estimated at 52 259 bonds)
RANK_MODEL = (16.0, 3.0)


def model_rank(s: float, max_rank: int = MAX_RANK, per_point: int = 1) -> int:
    """The rank the memory estimate assumes for the halves of a cluster of ``s`` unknowns;
    with ``per_point`` unknowns at each point (the components of a vector), that of a
    cluster of ``s / per_point`` points, once per component."""
    k = per_point
    return int(min(max_rank, s / 2, k * (RANK_MODEL[0] + RANK_MODEL[1] * math.sqrt(s / k))))


def hierarchical_bytes(m: int, *, leaf: int = LEAF, max_rank: int = MAX_RANK,
                       block: int = 512, itemsize: int = 8, per_point: int = 1,
                       capacity: int | None = None) -> int:
    """The memory a :class:`HierarchicalInverse` of order ``m`` is estimated to take (bytes):
    the dense leaves and their inverses; on each level of the cluster tree the bases ``U, V``
    and their solves ``Y`` (every unknown has one row of each, of the level's rank,
    :func:`model_rank`) and the Woodbury matrices; the pending terms; and the factorisation's
    work arrays (one level's bases again). The ranks are a model, not a bound; the held memory
    is :meth:`HierarchicalInverse.nbytes`. ``itemsize``: 8 in double precision, 4 in
    single. ``per_point``: the unknowns at each point (:func:`model_rank`; 2 for the traction
    vector, whose blocks carry both components: at 3 275 bonds 261 MiB estimated, 208
    held). ``capacity``: the pending terms held (:class:`HierarchicalInverse`)."""
    if m == 0:
        return 0
    words = 2 * m * leaf + m * (max(block, FOLD_MAX) if capacity is None else capacity)
    s, count, top = float(m), 1, 0
    while s > leaf:
        r = model_rank(s, max_rank, per_point)
        top = max(top, r)
        words += 2 * m * r + count * (2 * r) ** 2
        s, count = s / 2, count * 2
    # the compression's work arrays (two bases of the largest rank) stay in double precision
    return itemsize * int(words) + 8 * int(2 * m * top)


#: rows of a single-precision basis widened to double precision at a time
ROWS = 4096


def _times(a: np.ndarray, x: np.ndarray, transpose: bool) -> np.ndarray:
    """``a.T @ x`` (``transpose``) or ``a @ x`` in double precision; a single-precision ``a``
    is widened :data:`ROWS` rows at a time, so the product takes the memory of a block of
    rows, not of a copy of ``a``."""
    if a.dtype == np.float64:
        return a.T @ x if transpose else a @ x
    if transpose:
        out = np.zeros((a.shape[1], *x.shape[1:]))
        for i in range(0, a.shape[0], ROWS):
            out += a[i:i + ROWS].astype(np.float64).T @ x[i:i + ROWS]
        return out
    out = np.empty((a.shape[0], *x.shape[1:]))
    for i in range(0, a.shape[0], ROWS):
        out[i:i + ROWS] = a[i:i + ROWS].astype(np.float64) @ x
    return out


def _symmetric_inverse(A: np.ndarray, what: str, dtype: np.dtype, positive: bool = False
                       ) -> tuple[np.ndarray, int]:
    """The inverse of the symmetric ``A`` through its eigenvalues, rounded to ``dtype``, and
    the count of its negative eigenvalues (``positive``: of its positive ones). Raises
    :class:`NumericalError` naming ``what`` when it is numerically singular (an eigenvalue at or
    below ``order x eps`` times the largest, as the dense inverse judges it)."""
    w, Q = np.linalg.eigh(0.5 * (A + A.T))
    if not _nonsingular(w, w):
        raise NumericalError(f"{what} on {A.shape[0]} unknowns is singular")
    count = int(np.count_nonzero(w > 0 if positive else w < 0))
    return ((Q / w) @ Q.T).astype(dtype), count


@dataclass
class _Cluster:
    """One cluster of the tree: its range of tree positions, its children, its parent and
    what the factorisation keeps (module docstring)."""

    start: int
    stop: int
    left: int  # first child (-1: leaf); the second is left + 1
    parent: int
    U: np.ndarray | None = None  # A[first half, second half] = U V^T
    V: np.ndarray | None = None
    YL: np.ndarray | None = None  # A_first^{-1} U
    YR: np.ndarray | None = None  # A_second^{-1} V
    T: np.ndarray | None = None  # S^{-1}
    dense: np.ndarray | None = None  # a leaf's block
    inverse: np.ndarray | None = None  # a leaf's inverse


class HierarchicalInverse:
    """The inverse of a symmetric matrix on a changing set of unknowns, as a HODLR
    factorisation with pending rank-one updates (module docstring); a
    :class:`~roughslip.linalg.stick.StickSolver`.

    Parameters
    ----------
    entries
        The assembler ``entries(i, j, order)`` of the matrix.
    size
        The number of unknowns (indices ``0 .. size - 1``).
    room
        ``room(m)``: whether an inverse of order ``m`` may be held (:func:`hierarchical_bytes`
        is what it takes).
    points
        The point of each unknown (``size x 2``), from which the cluster tree is built.
    threads
        BLAS threads of the factorisation.
    block
        Pending rank-one terms kept before they are folded in (at least, :meth:`_balance`).
    capacity
        The most pending terms held (default: the larger of ``block`` and
        ``FOLD_MAX``); an inverse that is never updated takes 1.
    tol, leaf, max_rank
        The compression (module docstring).
    definite
        Whether the matrix is positive definite (leaves by Cholesky; a removal whose pivot is
        not positive fails), or symmetric and possibly indefinite (module docstring; a
        numerically singular update fails).
    lower
        The dense inverse's layout hint; not used.
    dtype
        What the bases, the leaves, their solves and the pending terms are stored and
        multiplied in: float64, or float32 (half the memory and half the bytes a column
        reads). The compression, the leaves' Cholesky factors and the Woodbury matrices'
        inverses are computed in double precision and then rounded; the compressed matrix is
        the rounded one (:meth:`compressed_product`).
    """

    #: what it is, in messages
    kind = "hierarchical"

    def __init__(self, entries: Entries, size: int, *, room: Callable[[int], bool],
                 points: np.ndarray, threads: int = 1, block: int = 512,
                 definite: bool = True, lower: bool = True, dtype: type = np.float64,
                 tol: float = TOL, leaf: int = LEAF, max_rank: int = MAX_RANK,
                 capacity: int | None = None) -> None:
        if np.dtype(dtype) not in (np.float64, np.float32):
            raise ValueError("the hierarchical inverse holds a matrix in double or single "
                             "precision")
        self.dtype = np.dtype(dtype)
        self.entries, self.room, self.threads = entries, room, threads
        #: pending terms the buffer holds, and the fold point callers read (set after each
        #: factorisation by the cost balance, :meth:`_balance`)
        self.capacity = max(int(block), FOLD_MAX) if capacity is None else int(capacity)
        self.floor = self.block = int(block)
        self.flops = 0.0  # counted since the last factorisation began
        self.points = np.asarray(points, dtype=float)
        self.tol, self.leaf, self.max_rank = tol, leaf, max_rank
        self.definite = bool(definite)
        #: negative eigenvalues of the compressed matrix on the set at the last factorisation
        #: (module docstring), changed since by each update's pivot
        self.negatives = 0
        self.blas_seconds = 0.0
        self.compress_seconds = 0.0
        self.factorisations = 0
        self.row = np.full(int(size), -1, dtype=np.int64)
        self.ids = np.empty(0, dtype=np.int64)
        self.live = np.empty(0, dtype=bool)
        self.m = 0
        self.V = np.empty((0, block), order="F", dtype=self.dtype)
        self.s = np.empty(0)  # the sign of each pending term: x += V diag(s) V^T b
        self.pending_shift = np.empty(0)  # diagonal shifts since the last fold, per row
        self.k = 0
        self.pivot = math.nan
        self.tracked: dict[str, Tracked] = {}
        self.version = 0
        self.shifts = 0
        self.clusters: list[_Cluster] = []
        self.perm = np.empty(0, dtype=np.int64)  # the row at each tree position
        self.where = np.empty(0, dtype=np.int64)  # the tree position of each row (-1: none)
        self.leaf_of = np.empty(0, dtype=np.int64)  # the leaf cluster of each tree position

    @staticmethod
    def memory_bytes(m: int, *, block: int = 512, itemsize: int = 8, per_point: int = 1) -> int:
        """The most memory an inverse of order ``m`` takes (:func:`hierarchical_bytes` with
        the default compression; ``per_point`` unknowns at each point)."""
        return hierarchical_bytes(m, block=block, itemsize=itemsize, per_point=per_point)

    # -- state ---------------------------------------------------------------------------------
    @property
    def ready(self) -> bool:
        """Whether an inverse is held."""
        return bool(self.clusters)

    def unknowns(self) -> np.ndarray:
        """The unknowns in the set, in row order."""
        return self.ids[self.live]

    def ranks(self) -> np.ndarray:
        """The rank of each cluster's off-diagonal block (leaves: 0)."""
        return np.array([0 if c.U is None else c.U.shape[1] for c in self.clusters])

    def nbytes(self) -> int:
        """The memory held now (bytes)."""
        total = self.V.nbytes
        for c in self.clusters:
            for a in (c.U, c.V, c.YL, c.YR, c.T, c.dense, c.inverse):
                total += 0 if a is None else a.nbytes
        return total

    # -- building ------------------------------------------------------------------------------
    def factor(self, ids: np.ndarray, positive: bool | None = None) -> bool:
        """Compress and factorise the matrix on the unknowns ``ids`` afresh (tracked solutions
        dropped); False when ``room`` refuses it. Raises :class:`NumericalError` when the
        compressed matrix is not positive definite on a leaf (``definite``), not positive
        definite at all (``positive`` on an indefinite object: an indefinite one may start
        from a definite set), or singular on a cluster."""
        if positive is False and self.definite:
            raise ValueError("a definite hierarchical inverse holds a positive definite matrix")
        ids = np.asarray(ids, dtype=np.int64)
        if not self.room(ids.size):
            return False
        self.row[self.ids] = -1
        self.ids, self.m = ids, ids.size
        self.row[ids] = np.arange(ids.size)
        self.live = np.ones(ids.size, dtype=bool)
        self.V = np.zeros((ids.size, self.capacity), order="F", dtype=self.dtype)
        self.s = np.zeros(self.capacity)
        self.pending_shift = np.zeros(ids.size)
        self.k = 0
        self.tracked = {}
        self.version += 1
        t0 = time.perf_counter()
        perm, ranges, left, _ = cluster_tree(self.points[ids], self.leaf)
        parent = np.full(len(ranges), -1, dtype=np.int64)
        for c in np.flatnonzero(left >= 0):
            parent[left[c]] = parent[left[c] + 1] = c
        self.perm = perm
        self.clusters = [_Cluster(a, b, int(left[c]), int(parent[c]))
                         for c, (a, b) in enumerate(ranges)]
        unk = ids[perm]  # the unknown at each tree position
        for c in self.clusters:
            if c.left < 0:
                c.dense = np.ascontiguousarray(self.entries(unk[c.start:c.stop],
                                                            unk[c.start:c.stop], "C"),
                                               dtype=self.dtype)
                continue
            one, two = self.clusters[c.left], self.clusters[c.left + 1]
            I, J = unk[one.start:one.stop], unk[two.start:two.stop]
            U, V = aca(lambda i, I=I, J=J: self.entries(I[i:i + 1], J, "C")[0],
                       lambda j, I=I, J=J: self.entries(I, J[j:j + 1], "F")[:, 0],
                       (I.size, J.size), self.tol * ACA_MARGIN, self.max_rank)
            U, V = recompress(U, V, self.tol)
            c.U, c.V = U.astype(self.dtype), V.astype(self.dtype)
        self.compress_seconds += time.perf_counter() - t0
        self._factorise()
        if positive and self.negatives:
            raise NumericalError(f"the compressed matrix on {ids.size} unknowns is not positive "
                                 f"definite ({self.negatives} negative eigenvalues)")
        return True

    def _index(self) -> None:
        """The tree position of each row and the leaf of each position."""
        self.where = np.full(self.m, -1, dtype=np.int64)
        self.where[self.perm] = np.arange(self.perm.size)
        self.leaf_of = np.empty(self.perm.size, dtype=np.int64)
        for n, c in enumerate(self.clusters):
            if c.left < 0:
                self.leaf_of[c.start:c.stop] = n

    def _balance(self) -> None:
        r"""The fold point: a fold costs the factorisation's counted flops :math:`F`, and the
        :math:`j`-th pending term adds :math:`m` words to every later column, so :math:`k`
        removals between folds cost :math:`F/k + W m k/2` per removal, least at
        :math:`k = \sqrt{2F/(Wm)}` (:data:`WORD_FLOPS` is :math:`W`), within
        ``[block, capacity]``. Counted, not timed: the same folds on every run."""
        live = max(int(self.live.sum()), 1)
        best = math.sqrt(2.0 * self.flops / (WORD_FLOPS * live))
        self.block = int(min(self.capacity, max(self.floor, round(best))))

    def _factorise(self) -> None:
        """Woodbury's identity from the leaves up (module docstring); the inertia with it when
        the matrix may be indefinite."""
        t0 = time.perf_counter()
        self.flops = 0.0
        neg = np.zeros(len(self.clusters), dtype=np.int64)
        with blas_threads(self.threads):
            for n in range(len(self.clusters) - 1, -1, -1):  # children come after parents
                c = self.clusters[n]
                if c.left < 0:
                    if c.stop == c.start:
                        c.inverse = np.zeros((0, 0), dtype=self.dtype)
                        continue
                    if not self.definite:
                        c.inverse, neg[n] = _symmetric_inverse(c.dense.astype(np.float64),
                                                               "a leaf's matrix", self.dtype)
                        self.flops += 4 * (c.stop - c.start) ** 3
                        continue
                    try:
                        L = np.linalg.cholesky(c.dense.astype(np.float64))
                    except np.linalg.LinAlgError:
                        raise NumericalError(f"the matrix on {c.stop - c.start} unknowns of a "
                                             "leaf is not positive definite") from None
                    Li = np.linalg.inv(L)
                    c.inverse = (Li.T @ Li).astype(self.dtype)
                    self.flops += (c.stop - c.start) ** 3
                    continue
                k = c.U.shape[1]
                c.YL = c.YR = c.T = None  # a fold's old solves go before the new are made
                if k == 0 and not self.definite:  # uncoupled halves: nothing to invert
                    neg[n] = neg[c.left] + neg[c.left + 1]
                    continue
                c.YL = self._solve(c.left, c.U.copy())
                c.YR = self._solve(c.left + 1, c.V.copy())
                S = np.block([[(c.U.T @ c.YL).astype(np.float64), np.eye(k)],
                              [np.eye(k), (c.V.T @ c.YR).astype(np.float64)]])
                if not self.definite:
                    c.T, pos = _symmetric_inverse(S, "a compressed block's Woodbury matrix",
                                                  self.dtype, positive=True)
                    neg[n] = neg[c.left] + neg[c.left + 1] + pos - k
                    self.flops += 10 * (2 * k) ** 3
                    continue
                try:
                    c.T = np.linalg.inv(S).astype(self.dtype)
                    self.flops += 2 * (2 * k) ** 3
                except np.linalg.LinAlgError:
                    raise NumericalError("a compressed block's Woodbury matrix is "
                                         "singular") from None
        self._index()
        self.negatives = int(neg[0]) if self.clusters else 0
        self.factorisations += 1
        self._balance()
        self.blas_seconds += time.perf_counter() - t0

    # -- products ------------------------------------------------------------------------------
    def _solve(self, n: int, B: np.ndarray) -> np.ndarray:
        """:math:`A_\\tau^{-1} B` for cluster ``n`` (``B`` in tree order on its range),
        overwriting ``B`` and returning it: the solve holds one product of half of ``B`` at a
        time besides it, where a solve into new arrays would hold several copies of ``B`` at
        the root (a fold's peak memory)."""
        c = self.clusters[n]
        cols = 1 if B.ndim == 1 else B.shape[1]
        if c.left < 0:
            self.flops += 2.0 * B.shape[0] ** 2 * cols
            B[...] = c.inverse @ B
            return B
        h = self.clusters[c.left].stop - c.start
        yL = self._solve(c.left, B[:h])
        yR = self._solve(c.left + 1, B[h:])
        k = c.U.shape[1]
        if k == 0:
            return B
        self.flops += (8.0 * k * B.shape[0] + 8.0 * k * k) * cols
        t = c.T @ np.concatenate([c.U.T @ yL, c.V.T @ yR])
        yL -= c.YL @ t[:k]
        yR -= c.YR @ t[k:]
        return B

    def apply(self, B: np.ndarray) -> np.ndarray:
        """The current inverse times ``B`` (on the rows; rows removed since the last fold must
        be zero, and are zero in the result up to rounding)."""
        t0 = time.perf_counter()
        x = np.zeros(B.shape)
        Bs = B.astype(self.dtype, copy=False)
        x[self.perm] = self._solve(0, Bs[self.perm])
        if self.k:
            V = self.V[:, : self.k]
            if self.definite:  # removals from a definite matrix: every sign is -1
                x -= V @ (V.T @ Bs)
            else:
                s = self.s[: self.k] if B.ndim == 1 else self.s[: self.k, None]
                x += V @ (s * (V.T @ Bs))
        self.blas_seconds += time.perf_counter() - t0
        return x

    def _product(self, n: int, x: np.ndarray) -> np.ndarray:
        """The compressed matrix of cluster ``n`` times ``x`` (tree order on its range)."""
        c = self.clusters[n]
        if c.left < 0:
            return _times(c.dense, x, False)
        h = self.clusters[c.left].stop - c.start
        y = np.concatenate([self._product(c.left, x[:h]), self._product(c.left + 1, x[h:])])
        if c.U.shape[1]:
            y[:h] += _times(c.U, _times(c.V, x[h:], True), False)
            y[h:] += _times(c.V, _times(c.U, x[:h], True), False)
        return y

    def compressed_product(self, x: np.ndarray) -> np.ndarray:
        """The compressed matrix times ``x`` on the rows factorised at the last fold (other
        entries of ``x`` must be zero; they are zero in the result): what the inverse held
        inverts, so that its error against the exact matrix can be measured (in double
        precision, whatever the storage)."""
        y = np.zeros(x.shape)
        y[self.perm] = self._product(0, x[self.perm])
        return y

    def _unit_solve(self, p: int) -> np.ndarray:
        r""":math:`A^{-1} e_p` in tree order for tree position ``p``: one cluster per level
        holds the support until the root (module docstring). On the way up, :math:`x =
        A_{\tau_1}^{-1} e_p` on the half that holds :math:`p`, so :math:`U^T x = (A_{\tau_1}^{-1}
        U)^T e_p` is a row of :math:`Y` (:math:`A` symmetric): two products with the solves
        :math:`Y` per level, and none with the bases."""
        n = int(self.leaf_of[p])
        c = self.clusters[n]
        x = c.inverse[:, p - c.start].copy()
        while c.parent >= 0:
            up = self.clusters[c.parent]
            k = up.U.shape[1]
            first = up.left == n
            out = np.zeros(up.stop - up.start, dtype=self.dtype)
            if k == 0:
                out[c.start - up.start:c.stop - up.start] = x
            elif first:
                t = up.T[:, :k] @ up.YL[p - c.start]
                h = x.size
                out[:h] = x - up.YL @ t[:k]
                out[h:] = -(up.YR @ t[k:])
            else:
                t = up.T[:, k:] @ up.YR[p - c.start]
                h = out.size - x.size
                out[:h] = -(up.YL @ t[:k])
                out[h:] = x - up.YR @ t[k:]
            x, n, c = out, c.parent, up
        return x

    def column(self, r: int) -> np.ndarray:
        """Column ``r`` (a row) of the current inverse."""
        t0 = time.perf_counter()
        col = np.zeros(self.m)
        p = int(self.where[r])
        if p >= 0:
            col[self.perm] = self._unit_solve(p)
        if self.k:
            V = self.V[:, : self.k]
            if self.definite:
                col -= V @ V[r]
            else:
                col += V @ (self.s[: self.k] * V[r])
        self.blas_seconds += time.perf_counter() - t0
        return col

    def _diag(self, n: int) -> np.ndarray:
        c = self.clusters[n]
        if c.left < 0:
            return np.diagonal(c.inverse).astype(np.float64)
        d = np.concatenate([self._diag(c.left), self._diag(c.left + 1)])
        k = c.U.shape[1]
        if k:
            h = self.clusters[c.left].stop - c.start
            d[:h] -= np.einsum("ij,ij->i", c.YL @ c.T[:k, :k], c.YL, dtype=np.float64)
            d[h:] -= np.einsum("ij,ij->i", c.YR @ c.T[k:, k:], c.YR, dtype=np.float64)
        return d

    def diagonal(self) -> np.ndarray:
        """The diagonal of the current inverse on the rows (removed rows hold stale
        values)."""
        d = np.zeros(self.m)
        d[self.perm] = self._diag(0)
        if self.k:
            V = self.V[:, : self.k]
            if self.definite:
                d -= np.einsum("ij,ij->i", V, V, dtype=np.float64)
            else:
                d += np.einsum("ij,ij,j->i", V, V, self.s[: self.k], dtype=np.float64)
        return d

    #: certify against an exact operator, correcting with the current inverse (the dense
    #: inverse's method: it reads only :meth:`apply` and ``live``)
    refine = UpdatableInverse.refine

    # -- updates -------------------------------------------------------------------------------
    def remove(self, unknown: int, column: np.ndarray | None = None,
               held: dict[str, float] | None = None) -> bool:
        """Remove ``unknown`` from the set (as
        :meth:`~roughslip.linalg.inverse.UpdatableInverse.remove`); False when its pivot is
        not positive (``definite``) or is numerically zero. A negative pivot takes one
        negative eigenvalue with it."""
        r = int(self.row[unknown])
        c = self.column(r) if column is None else column
        cr = float(c[r])
        if not (cr > 0 if self.definite else _nonsingular(np.array([cr]), c)):
            return False
        self.pivot = cr
        self.negatives -= cr < 0
        take_out(self, r, c, held)
        if self.k == self.capacity:  # the fold deletes the row: nothing left to keep pending
            self.flush()
            return True
        self._push(c * (1.0 / math.sqrt(abs(cr))), -1.0 if cr > 0 else 1.0)
        return True

    def _push(self, v: np.ndarray, sign: float) -> None:
        """One pending term ``sign v v^T`` (the buffer has room)."""
        self.V[:, self.k] = v
        self.s[self.k] = sign
        self.k += 1

    def flush(self) -> None:
        """Fold the pending updates: delete the removed rows from the compressed blocks, add
        the shifts to the leaves' diagonals and factorise again (module docstring)."""
        if not self.k:
            return
        keep = self.live[self.perm]
        if not keep.all():
            pos = np.concatenate([[0], np.cumsum(keep)])
            for c in self.clusters:
                a, b = c.start, c.stop
                if c.left < 0:
                    on = keep[a:b]
                    c.dense = np.ascontiguousarray(c.dense[np.ix_(on, on)])
                else:
                    h = self.clusters[c.left].stop
                    c.U, c.V = c.U[keep[a:h]], c.V[keep[h:b]]
                c.start, c.stop = int(pos[a]), int(pos[b])
            self.perm = self.perm[keep]
        self._shift_leaves()
        self.V[:, : self.k] = 0.0
        self.k = 0
        self._factorise()

    def _shift_leaves(self) -> None:
        """Add the diagonal shifts made since the last fold to the leaves' blocks (tree
        positions of the current ``perm``)."""
        shift = self.pending_shift[self.perm]
        if not shift.any():
            return
        for c in self.clusters:
            if c.left < 0 and c.stop > c.start:
                d = shift[c.start:c.stop]
                c.dense[np.diag_indices(d.size)] += d.astype(self.dtype)
        self.pending_shift[:] = 0.0

    def compact(self, extra: int = 0) -> bool:
        """Drop the removed rows (tracked solutions follow); no spare rows are kept
        (:meth:`add` compresses the new set afresh)."""
        if extra:
            raise ValueError("the hierarchical inverse keeps no spare rows: add() grows it")
        self.flush()
        keep = np.flatnonzero(self.live)
        new = np.full(self.m, -1, dtype=np.int64)
        new[keep] = np.arange(keep.size)
        self.perm = new[self.perm]
        self.tracked = {key: Tracked(None if t.b is None else t.b[keep],
                                     _keep_order(t.x, t.x[keep]), t.values)
                        for key, t in self.tracked.items()}
        self.ids = self.ids[keep]
        self.m = keep.size
        self.row[self.ids] = np.arange(self.m)
        self.live = np.ones(self.m, dtype=bool)
        self.V = np.zeros((self.m, self.capacity), order="F", dtype=self.dtype)
        self.pending_shift = np.zeros(self.m)
        self.version += 1
        self._index()
        return True

    def shift(self, unknown: int, delta: float, column: np.ndarray | None = None
              ) -> np.ndarray | None:
        r"""Add ``delta`` to the diagonal entry of ``unknown`` (as
        :meth:`~roughslip.linalg.inverse.UpdatableInverse.shift`: the new column, or None when
        :math:`1 + \delta c_r` is numerically zero; its sign in ``pivot`` gives the change
        of inertia). The assembler must give the shifted entry from now on (for
        :meth:`factor` and :meth:`add`); a fold adds the shift to the compressed leaf."""
        if self.definite:
            raise ValueError("a definite hierarchical inverse holds no shifted diagonal")
        r = int(self.row[unknown])
        c = self.column(r) if column is None else column
        g = shift_pivot(self, r, c, delta)
        if g is None:
            return None
        if self.pivot < 0:
            self.negatives += 1 if delta < 0 else -1
        self.pending_shift[r] += delta
        if self.k == self.capacity:  # the fold takes the shift into the leaf
            self.flush()
        else:
            self._push(c * math.sqrt(abs(g)), -1.0 if g > 0 else 1.0)
        return c / self.pivot

    def add(self, new: np.ndarray) -> bool | None:
        r"""Add the unknowns ``new`` to the set: the pivots come from the Schur complement
        :math:`S_c = A_{new,new} - B^T A_{SS}^{-1} B` (:math:`B = A_{S,new}`) on the current
        inverse, the tracked solutions are bordered with it as in
        :meth:`~roughslip.linalg.inverse.UpdatableInverse.add`, and the new set is compressed
        and factorised afresh (its blocks change with the set). False when :math:`S_c` is not
        positive definite (``definite``) or is singular; None when ``room`` refuses the new
        set (nothing changed). The new unknowns take the last rows."""
        new = np.asarray(new, dtype=np.int64)
        if not self.room(self.live.sum() + new.size):
            return None
        live = np.flatnonzero(self.live)
        B = np.zeros((self.m, new.size))
        B[live] = self.entries(self.ids[live], new, "C")
        MB = self.apply(B)
        MB[~self.live] = 0.0
        Sc = self.entries(new, new, "C") - B.T @ MB
        w, Q = np.linalg.eigh(0.5 * (Sc + Sc.T))
        if not (_nonsingular(w, w) and (w.min() > 0 or not self.definite)):
            return False
        Si = (Q / w) @ Q.T
        grown = {}
        for name, t in self.tracked.items():  # bordered: [x - MB z; z]
            bn = t.values(new)
            z = Si @ (bn - B.T @ t.x)
            x = np.concatenate([(t.x - MB @ z)[live], z])
            b = None if t.b is None else np.concatenate([t.b[live], bn])
            grown[name] = Tracked(b, _keep_order(t.x, x), t.values)
        if not self.factor(np.concatenate([self.ids[live], new])):
            return None
        self.pivot = float(Sc[0, 0]) if new.size == 1 else math.nan
        self.tracked = grown
        return True

    #: add to a right-hand side entry of a tracked solution (the dense inverse's method: it
    #: reads only ``row``, :meth:`column` and ``tracked``)
    change_rhs = UpdatableInverse.change_rhs
