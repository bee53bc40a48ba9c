"""A pull method whose stick solver recomputes the dense inverse from scratch at every change
(the recipe "an exact pull method" of docs/extending.md): one class implementing
:class:`~roughslip.linalg.stick.StickSolver` and one entry of
:data:`~roughslip.friction.pull.METHODS`. It offers every capability, so it runs every law;
the shared suite compares it with the updated inverse."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from roughslip.friction.pull import CAPABILITIES, METHODS, PullMethod
from roughslip.linalg.inverse import Entries, Tracked, refine


class RecomputedInverse:
    """:math:`A_{SS}^{-1}` recomputed by LAPACK at every change of the set, the diagonal or a
    right-hand side; tracked solutions recomputed from their right-hand sides. Nothing is
    pending (``k = 0``), so the event logic never folds."""

    #: what it is, in messages
    kind = "recomputed"

    def __init__(self, entries: Entries, size: int, *, room: Callable[[int], bool],
                 threads: int = 1, block: int = 512, definite: bool = True,
                 lower: bool = False, dtype: type = np.float64,
                 points: np.ndarray | None = None) -> None:
        self.entries, self.room, self.definite, self.block = entries, room, definite, block
        self.row = np.full(int(size), -1, dtype=np.int64)
        self.ids = np.empty(0, dtype=np.int64)
        self.live = np.empty(0, dtype=bool)
        self.m, self.k = 0, 0
        self.pivot = float("nan")
        self.tracked: dict[str, Tracked] = {}
        self.blas_seconds = 0.0
        self.inv = np.zeros((0, 0))
        self._shift: tuple[int, float] | None = None  # a shift the assembler gives only later

    @staticmethod
    def memory_bytes(m: int, *, block: int = 512, itemsize: int = 8, per_point: int = 1) -> int:
        """One dense inverse and the matrix it is computed from."""
        return 2 * 8 * m * m

    def _matrix(self, rows: np.ndarray) -> np.ndarray:
        A = np.array(self.entries(self.ids[rows], self.ids[rows], "F"), dtype=float)
        if self._shift is not None:
            r, delta = self._shift
            hit = np.flatnonzero(rows == r)
            A[hit, hit] += delta
        return A

    def _recompute(self) -> None:
        rows = np.flatnonzero(self.live)
        inv = np.zeros((self.m, self.m))
        if rows.size:
            A = self._matrix(rows)
            if self.definite:
                np.linalg.cholesky(A)  # raises when not positive definite
            inv[np.ix_(rows, rows)] = np.linalg.inv(A)
        self.inv = inv
        for t in self.tracked.values():
            t.x = inv @ t.b

    def factor(self, ids: np.ndarray, positive: bool | None = None) -> bool:
        ids = np.asarray(ids, dtype=np.int64)
        if not self.room(ids.size):
            return False
        self.row[self.ids] = -1
        self.ids, self.m = ids.copy(), ids.size
        self.live = np.ones(self.m, dtype=bool)
        self.row[ids] = np.arange(self.m)
        self.tracked = {}
        definite, self.definite = self.definite, self.definite if positive is None else positive
        try:
            self._recompute()
        finally:
            self.definite = definite
        return True

    def apply(self, B: np.ndarray) -> np.ndarray:
        return self.inv @ B

    def column(self, r: int) -> np.ndarray:
        return self.inv[:, r].copy()

    def diagonal(self) -> np.ndarray:
        return np.diagonal(self.inv).copy()

    def remove(self, unknown: int, column: np.ndarray | None = None,
               held: dict[str, float] | None = None) -> bool:
        r = int(self.row[unknown])
        cr = float(self.inv[r, r])
        if not (cr > 0 if self.definite else abs(cr) > 0):
            return False
        self.pivot = cr
        self.live[r] = False
        rows = np.flatnonzero(self.live)
        for name, h in (held or {}).items():  # b_S' -= A_S'r h
            b = self.tracked[name].b
            b[rows] -= self.entries(self.ids[rows], self.ids[[r]], "F")[:, 0] * h
        for t in self.tracked.values():
            t.b[r] = 0.0
        self.row[unknown] = -1
        self._recompute()
        return True

    def shift(self, unknown: int, delta: float, column: np.ndarray | None = None
              ) -> np.ndarray | None:
        r = int(self.row[unknown])
        self.pivot = 1.0 + delta * float(self.inv[r, r])
        self._shift = (r, delta)
        try:
            self._recompute()
        finally:
            self._shift = None
        return self.column(r)

    def add(self, new: np.ndarray) -> bool | None:
        new = np.asarray(new, dtype=np.int64)
        if not self.room(self.m + new.size):
            return None
        rows = np.flatnonzero(self.live)
        B = self.entries(self.ids[rows], new, "C")
        Sc = self.entries(new, new, "C") - B.T @ self.inv[np.ix_(rows, rows)] @ B
        if new.size == 1:
            self.pivot = float(Sc[0, 0])
        m = self.m
        self.ids = np.concatenate([self.ids, new])
        self.live = np.concatenate([self.live, np.ones(new.size, dtype=bool)])
        self.row[new] = np.arange(m, m + new.size)
        self.m = m + new.size
        for t in self.tracked.values():
            t.b = np.concatenate([t.b, t.values(new)])
        self._recompute()
        return True

    def change_rhs(self, name: str, unknown: int, delta: float,
                   column: np.ndarray | None = None) -> None:
        t = self.tracked[name]
        t.b[int(self.row[unknown])] += delta
        t.x = self.inv @ t.b

    def refine(self, x: np.ndarray, residual, tol: float, refinements: int):
        def correct(x: np.ndarray, r: np.ndarray) -> np.ndarray:
            step = self.apply(r)
            step[~self.live] = 0.0
            return x + step

        return refine(x, residual, correct, tol, refinements)

    def flush(self) -> None:
        """Nothing is pending."""

    def compact(self, extra: int = 0) -> bool:
        keep = np.flatnonzero(self.live)
        self.row[:] = -1
        self.ids, self.m = self.ids[keep], keep.size
        self.live = np.ones(self.m, dtype=bool)
        self.row[self.ids] = np.arange(self.m)
        self.inv = self.inv[np.ix_(keep, keep)]
        for t in self.tracked.values():
            t.b, t.x = t.b[keep], t.x[keep]
        return True


METHODS.register("recomputed", "test only: the dense inverse recomputed at every change")(
    PullMethod("recomputed", exact=True, dense=True, solver=RecomputedInverse,
               offers=frozenset(CAPABILITIES), auto=False))
