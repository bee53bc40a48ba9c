"""A block solver of the coupled model that solves every state directly (the recipe "a block
solver" of docs/extending.md): one class deriving from the
:class:`~roughslip.coupling.blocksolvers.BlockSolver` protocol and one entry of
:data:`~roughslip.coupling.blocksolvers.SOLVERS`. The whole grid's block is assembled once
from FFT products of unit forces and each state's principal block is solved by LAPACK; the
solves with slip forces are the protocol's matrix-free default. The shared suite runs it
against the dense reference."""

from __future__ import annotations

import numpy as np

from roughslip.coupling.blocksolvers import SOLVERS, BlockSolver
from roughslip.testing import dense_block


class DirectBlockSolver(BlockSolver):
    """Each state solved afresh from the dense block, each solution certified by one FFT
    product (its residual against the FFT operator)."""

    def __init__(self, problem, *, tol: float = 1e-12, **_: object) -> None:
        self.op = problem.operator("zz", "zx", "xx")
        self.A = dense_block(problem)  # unknowns: f_z at site i is row i, f_x is row n + i
        self.n = problem.base.size
        self.tol, self.worst, self.solves = tol, 0.0, 0
        self.blas_seconds, self.slip_iterations = 0.0, 0
        self.method, self.fallback = "direct", ""
        self.slip_warm: dict = {}

    def prepare(self, C: np.ndarray, S: np.ndarray, bulk: bool = False) -> None:
        self.rows = np.concatenate([np.flatnonzero(C), self.n + np.flatnonzero(S)])

    def solve(self, rz: np.ndarray, rx: np.ndarray, key: str = ""):
        return self.solve_many([(rz, rx, key)])[0]

    def solve_many(self, rhs):
        out = []
        K = self.A[np.ix_(self.rows, self.rows)]
        for rz, rx, _ in rhs:
            self.solves += 1
            b = np.concatenate([rz.ravel(), rx.ravel()])[self.rows]
            f = np.zeros(2 * self.n)
            f[self.rows] = np.linalg.solve(K, b)
            fz, fx = f[: self.n].reshape(rz.shape), f[self.n:].reshape(rz.shape)
            uz, ux = self.op.apply_block(fz, fx)
            u = np.concatenate([uz.ravel(), ux.ravel()])[self.rows]
            scale = max(float(np.linalg.norm(b)), np.finfo(float).tiny)
            self.worst = max(self.worst, float(np.linalg.norm(b - u)) / scale)
            out.append((fz, fx, uz))
        return out

    def displacements(self, fz: np.ndarray, fx: np.ndarray):
        return self.op.apply_block(fz, fx)

    def residual(self) -> float:
        return self.worst

    def reset(self) -> bool:
        return False  # nothing is kept between states

    def add_solves(self, n: int) -> None:
        self.solves += n


SOLVERS.register("direct", "test only: every state solved afresh from the dense block")(
    DirectBlockSolver)
