r"""The stick-solver protocol: what a pull's event logic asks of its linear algebra.

A decoupled pull holds, on the set :math:`S` of bonds that stick, the inverse of a symmetric
matrix :math:`A` (:math:`G_{xx}` on the bonds, shifted on the diagonal of weakening bonds
under slip-weakening) and the solutions of a few right-hand sides, and changes :math:`S` one
unknown at a time as bonds fail, weaken or stick again. Every pull method that works on such
a set implements :class:`StickSolver`: the dense updated inverse
(:class:`~roughslip.linalg.inverse.UpdatableInverse`, in double or single precision), the
compressed one (:class:`~roughslip.linalg.hierarchical.HierarchicalInverse`), and any other
representation of :math:`A_{SS}^{-1}`. The event
logic is written once against the protocol (:mod:`roughslip.friction.sliding`,
:mod:`roughslip.friction.weakening`, :mod:`roughslip.friction.breaking`), and a method is one
class plus one entry of :data:`roughslip.friction.pull.METHODS`.

The unknowns are numbered ``0 .. size - 1`` (bond positions); a solver keeps them in *rows*,
``ids[row]`` the unknown of a row, ``live[row]`` whether it is still in the set and
``row[unknown]`` the row of an unknown (-1: not in the set). Removed rows keep their place
until :meth:`StickSolver.compact`, and entries of a solution on them are meaningless.

A tracked solution (:class:`~roughslip.linalg.inverse.Tracked`) is kept current through
every change: :math:`x = A_{SS}^{-1} b` on the rows. Two changes move a right-hand side
with the set: :meth:`StickSolver.remove` with ``held`` keeps the removed unknown's value in a
solution at a given number (it moves to the right-hand side: :math:`b_{S'} \leftarrow b_{S'} -
A_{S'r}\,h`), and :meth:`StickSolver.change_rhs` changes one entry of a right-hand side.

Updates may be pending (:attr:`StickSolver.k` of at most :attr:`StickSolver.block`) and are
folded by :meth:`StickSolver.flush`; callers certify their solutions against the FFT
operator after a fold (:meth:`StickSolver.refine`), which is where an inexact representation
is corrected. The pivot of the last update (:attr:`StickSolver.pivot`) gives its change of
inertia (slip-weakening counts negative eigenvalues with it).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np

from roughslip.linalg.inverse import Entries, Tracked


@runtime_checkable
class StickSolver(Protocol):
    """The inverse of a symmetric matrix on a changing set of unknowns, with tracked
    solutions (module docstring). Every attribute and method here is used by the pull's
    event logic; nothing else is."""

    #: the unknown of each row, whether each row is live, and the row of each unknown
    ids: np.ndarray
    live: np.ndarray
    row: np.ndarray
    #: rows in use (removed ones included)
    m: int
    #: counts every change of the rows (their unknowns or which are live)
    version: int
    #: pending updates, and how many are kept before they are folded
    k: int
    block: int
    #: the pivot of the last update (its sign: the change of inertia)
    pivot: float
    #: tracked solutions by name
    tracked: dict[str, Tracked]
    #: seconds in dense linear algebra
    blas_seconds: float
    #: what it is, in messages ("dense", "hierarchical", ...)
    kind: str

    def factor(self, ids: np.ndarray, positive: bool | None = None) -> bool:
        """Hold the inverse on the unknowns ``ids`` afresh (tracked solutions dropped); False
        when its memory is refused."""
        ...

    def apply(self, B: np.ndarray) -> np.ndarray:
        """The current inverse times ``B`` (on the rows; removed rows zero)."""
        ...

    def column(self, r: int) -> np.ndarray:
        """Column ``r`` (a row) of the current inverse."""
        ...

    def diagonal(self) -> np.ndarray:
        """The diagonal of the current inverse on the rows."""
        ...

    def remove(self, unknown: int, column: np.ndarray | None = None,
               held: dict[str, float] | None = None) -> bool:
        """Take ``unknown`` out of the set; ``held[name]``: its value in that tracked solution
        is held at this number (moved to the right-hand side). False when the update is
        singular (or loses definiteness for a definite matrix)."""
        ...

    def shift(self, unknown: int, delta: float, column: np.ndarray | None = None
              ) -> np.ndarray | None:
        """Add ``delta`` to the diagonal entry of ``unknown``; the new column, or None when
        singular."""
        ...

    def add(self, new: np.ndarray) -> bool | None:
        """Border the set with ``new`` (tracked right-hand sides from their ``values``);
        False when singular, None when its memory is refused."""
        ...

    def change_rhs(self, name: str, unknown: int, delta: float,
                   column: np.ndarray | None = None) -> None:
        """Add ``delta`` to the entry of ``unknown`` in the right-hand side of the tracked
        solution ``name`` (``column``: its current column, when the caller has it)."""
        ...

    def refine(self, x: np.ndarray, residual: Callable[[np.ndarray], tuple[np.ndarray, float]],
               tol: float, refinements: int) -> tuple[np.ndarray, float, int]:
        """Certify ``x`` against an exact residual, correcting with the current inverse."""
        ...

    def flush(self) -> None:
        """Fold the pending updates."""
        ...

    def compact(self, extra: int = 0) -> bool:
        """Drop the removed rows (tracked solutions follow)."""
        ...


#: how a pull method builds its stick solver: ``solver(entries, size, room=..., threads=...,
#: block=..., definite=..., lower=..., dtype=..., points=...)`` (the signature of
#: :class:`~roughslip.linalg.inverse.UpdatableInverse`). ``lower``: the set only shrinks and
#: the matrix is definite (a layout may use it); ``dtype``: the precision of what is stored;
#: ``points``: the point of each unknown (a compressed solver clusters by it). The factory
#: also says what it is (``kind``, in messages) and what it takes before it is built
#: (``memory_bytes(m, block=..., itemsize=...)``, and ``per_point=k`` when ``k`` unknowns
#: share each point: the components of the traction vector).
SolverFactory = Callable[..., StickSolver]

__all__ = ["Entries", "SolverFactory", "StickSolver", "Tracked"]
