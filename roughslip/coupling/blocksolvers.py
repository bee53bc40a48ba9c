r"""Linear solvers for the reduced block of the coupled model, behind one protocol.

For a contact set :math:`C` and a stick set :math:`S \subseteq C` the event loop solves

.. math::

    \begin{bmatrix} G_{zz}(C,C) & G_{zx}(C,S) \\ G_{xz}(S,C) & G_{xx}(S,S) \end{bmatrix}
    \begin{bmatrix} f_z(C) \\ f_x(S) \end{bmatrix} = \begin{bmatrix} r_z(C) \\ r_x(S)
    \end{bmatrix},

an SPD principal block of the full operator (docs/theory/halfspace.rst#matrix-properties).
:class:`BlockSolver` lists everything the event loop calls. ``"dense"``
(:class:`DenseBlockSolver`) assembles the block from the closed-form kernels and keeps its
inverse up to date (:class:`~roughslip.linalg.inverse.UpdatableInverse`), while it fits in
memory (docs/theory/coupled.rst#coupled-solvers); ``"cg"`` (:class:`MatrixFreeBlockSolver`)
runs conjugate gradients on the restricted FFT block operator
(:meth:`roughslip.contact.problem.Problem.restricted_block`). Every solve is certified against
the FFT operator.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np
from scipy import linalg
from scipy.sparse.linalg import LinearOperator, gmres

from roughslip.contact.problem import Problem
from roughslip.elastic.tables import gather_pairs
from roughslip.errors import MemoryLimitError, NumericalError
from roughslip.linalg.cg import cg
from roughslip.linalg.inverse import (
    BYTES_PER_ORDER2,
    Tracked,
    UpdatableInverse,
    refine,
    submatrix,
)
from roughslip.linalg.memory import available_bytes
from roughslip.registry import AUTO, Registry

# ------------------------------------------------------------------------------------------------
# Linear solvers for the reduced block
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Components:
    """How the block's unknowns are numbered: one per site and force component, site-major,
    ``unknown = len(names) * site + names.index(component)``. The coupled model's components
    are ``("z", "x")``; a tangential force vector adds ``"y"``."""

    names: tuple[str, ...] = ("z", "x")

    @property
    def n(self) -> int:
        """Components per site."""
        return len(self.names)

    def unknowns(self, sites: np.ndarray, component: str) -> np.ndarray:
        """The unknowns of ``component`` at the flat indices ``sites``."""
        return self.n * np.asarray(sites, dtype=np.int64) + self.names.index(component)

    def site(self, ids: np.ndarray) -> np.ndarray:
        """The site of each unknown."""
        return ids // self.n

    def component(self, ids: np.ndarray) -> np.ndarray:
        """The component index of each unknown (an index of :attr:`names`)."""
        return ids % self.n

    def kernel(self, a: int, b: int, tables: dict) -> tuple[str, bool]:
        """The pair table of the displacement component ``a`` due to the force component
        ``b``, and whether it is read with its offsets negated: a table holds
        :math:`G_{ab}` or the symmetric :math:`G_{ba}(j - i) = G_{ab}(i - j)`."""
        name = self.names[a] + self.names[b]
        return (name, False) if name in tables else (name[::-1], True)


#: the unknowns of the coupled model: f_z and f_x per site
COMPONENTS = Components()


class BlockSolver(Protocol):
    """A linear solver for the reduced block on the contact set C and the stick set S: the
    contract the coupled model's states and histories use, and all of it
    (``tests/test_coupled.py`` reads their code to check). A class that derives from it
    inherits the matrix-free slip solves (:meth:`solve_slip`)."""

    #: solves so far (:meth:`add_solves` counts those the caller does on the solver's behalf)
    solves: int
    #: seconds in dense linear algebra
    blas_seconds: float
    #: GMRES iterations of the solves with slip forces (:meth:`solve_slip`)
    slip_iterations: int
    #: the registered name of the solver that solved the last state (:data:`SOLVERS`)
    method: str
    #: why the solver went on with another method (a dense inverse that did not fit), else ""
    fallback: str
    #: the relative residual every solve is certified to, and the worst one so far
    tol: float
    worst: float

    def prepare(self, C: np.ndarray, S: np.ndarray, bulk: bool = False) -> None:
        """Set the unknowns: f_z on C, f_x on S. ``bulk``: the sets are about to change by
        many sites at once (no point in keeping an inverse for them)."""

    def solve(self, rz: np.ndarray, rx: np.ndarray, key: str
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Grid fields (f_z, f_x, u_z) for right-hand sides on the grid (used on C and S);
        ``key`` names the right-hand side, for warm starts and tracked solutions."""

    def solve_many(self, rhs: list[tuple[np.ndarray, np.ndarray, str]]
                   ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """:meth:`solve` for several ``(rz, rx, key)`` at once."""

    def displacements(self, fz: np.ndarray, fx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u_z, u_x) on the grid for the force fields (f_z, f_x)."""

    def solve_slip(self, rhs: list[tuple[np.ndarray, np.ndarray, str]], C: np.ndarray,
                   S: np.ndarray, P: np.ndarray, w: np.ndarray
                   ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        r"""(f_z, f_x, u_z, u_x) on the grid for each ``(rz, rx, key)`` with slip forces: on
        the slip sites ``P`` (contact sites off the stick set) a bond carries
        :math:`f_x = w f_z`, so the system is not symmetric. Every solution is certified
        against the FFT operator on the whole system (:func:`certified_slip_solves`).

        The default, matrix-free: GMRES on the whole system, one FFT product per iteration,
        warm-started from the last solution of the same right-hand side
        (:func:`free_slip_solve`)."""
        return certified_slip_solves(self, rhs, C, S, P, w,
                                     lambda *a: free_slip_solve(self, C, S, *a))

    def unit_responses(self, sites: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The forces (f_z, f_x), flat grids as rows, of the block's solution for a unit
        right-hand side on the f_x unknown of each of ``sites`` (stick sites): the response
        to a unit tangential displacement of one bond. The default solves them
        (:meth:`solve_many`, certified)."""
        shape = self.problem.shape
        zero = np.zeros(shape)
        rhs = []
        for j in sites:
            e = np.zeros(shape)
            e.ravel()[j] = 1.0
            rhs.append((zero, e, f"unit {int(j)}"))
        out = self.solve_many(rhs)
        return (np.array([o[0].ravel() for o in out]), np.array([o[1].ravel() for o in out]))

    def residual(self) -> float:
        """The worst relative residual of the solves so far."""

    def reset(self) -> bool:
        """Drop what the solver kept between states (an updated inverse), so that the next
        :meth:`prepare` starts afresh; False when there was nothing to drop."""

    def add_solves(self, n: int) -> None:
        """Count ``n`` solves done with this solver's operators by the caller."""


#: the coupled block solvers, by name (``method`` of :func:`couple`)
SOLVERS: Registry[type] = Registry("coupled solver")


def certified_slip_solves(solver: BlockSolver, rhs: list[tuple[np.ndarray, np.ndarray, str]],
                          C: np.ndarray, S: np.ndarray, P: np.ndarray, w: np.ndarray,
                          solve: Callable[..., tuple[np.ndarray, np.ndarray]]
                          ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    r"""The solves with slip forces of :meth:`BlockSolver.solve_slip`, each certified: the
    residual of the whole system against the FFT operator (``solver.displacements``), and
    above the solver's ``tol`` a correction by ``solve`` on the residual, at most twice
    (:func:`~roughslip.linalg.inverse.refine`). ``solve(rz, rx, key, P, w)`` gives the forces
    for one right-hand side (``key`` ``"refine"``: a correction). The worst residual goes
    into the solver's."""
    out = []
    for rz, rx, key in rhs:
        scale = max(float(np.linalg.norm(np.concatenate([rz[C], rx[S]]))),
                    np.finfo(float).tiny)
        last: list[np.ndarray] = []

        def residual(f, rz=rz, rx=rx, scale=scale, last=last):
            uz, ux = solver.displacements(*f)
            last[:] = [uz, ux]
            ez, ex = np.where(C, rz - uz, 0.0), np.where(S, rx - ux, 0.0)
            res = float(np.linalg.norm(np.concatenate([ez[C], ex[S]]))) / scale
            return (ez, ex), res

        def correct(f, e):
            dz, dx = solve(*e, "refine", P, w)
            return f[0] + dz, f[1] + dx

        (fz, fx), res, _ = refine(solve(rz, rx, key, P, w), residual, correct, solver.tol, 2)
        solver.worst = max(solver.worst, res)
        out.append((fz, fx, last[0], last[1]))
    return out


def free_slip_solve(solver: BlockSolver, C: np.ndarray, S: np.ndarray, rz: np.ndarray,
                    rx: np.ndarray, key: str, P: np.ndarray, w: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Matrix-free: GMRES on the whole non-symmetric system, one FFT product per iteration,
    warm-started from the last solution of the same right-hand side (kept by the solver in
    ``slip_warm``)."""
    nc, n = int(C.sum()), int(C.sum() + S.sum())
    shape = rz.shape

    def fields(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        fz, fx = np.zeros(shape), np.zeros(shape)
        fz[C] = y[:nc]
        fx[S] = y[nc:]
        fx[P] = w * fz[P]
        return fz, fx

    def matvec(y: np.ndarray) -> np.ndarray:
        solver.slip_iterations += 1
        uz, ux = solver.displacements(*fields(np.ravel(y)))
        return np.concatenate([uz[C], ux[S]])

    b = np.concatenate([rz[C], rx[S]])
    prev = solver.slip_warm.get(key)
    x0 = None if prev is None else np.concatenate([prev[0][C], prev[1][S]])
    bnorm = max(float(np.linalg.norm(b)), np.finfo(float).tiny)
    y, _ = gmres(LinearOperator((n, n), matvec=matvec, dtype=float), b, x0=x0, rtol=0.0,
                 atol=0.1 * solver.tol * bnorm, restart=min(n, 200), maxiter=50)
    solver.add_solves(1)
    fz, fx = fields(y)
    solver.slip_warm[key] = (fz, fx)
    return fz, fx

#: the name of the dense solver's tracked block of slip responses
_SLIP = "slip response"


@SOLVERS.register("dense", "the reduced block's inverse, updated at every event")
class DenseBlockSolver(BlockSolver):
    r"""Reduced block assembled from the operator's kernel tables, solved through its inverse.

    The unknowns are :math:`f_z` and :math:`f_x` per site, numbered by :data:`COMPONENTS`.
    The explicit inverse of the block on the current unknowns is an
    :class:`~roughslip.linalg.inverse.UpdatableInverse`: updated when the contact or stick set
    changes (downdates, bordered additions, blocked BLAS-3 folding, compaction), never
    recomputed for it, and kept solutions of unchanged right-hand sides are updated with it.

    * When more than a third of the unknowns change at once, the block is factorised afresh.
    * The squeeze's first passes, which drop every tensile contact at once from the geometric
      overlap (``prepare(..., bulk=True)``), are solved by warm-started conjugate gradients
      on the FFT operator when they have more than ``bulk_min`` unknowns: an inverse of the
      overlap block would cost far more than the rest of the squeeze and pull together, and
      would be thrown away at the next pass.

    Every solution is certified against the FFT operator: the displacements of the forces,
    which the event loop needs anyway for the gaps, give the residual on the unknowns. When an
    unknown leaves, every kept solution moves along the same column of the inverse, so with two
    or more of them one block product of that column updates all their displacements; they are
    computed afresh after ``refresh_every`` such updates, after an addition, and for every
    solution that is refined. Above ``tol`` (relative) a solution is refined by
    :math:`x \leftarrow x + M^{-1}_{\rm current} r`, up to ``refinements`` times
    (:meth:`UpdatableInverse.refine`), and the worst certified residual is reported. With
    ``reference=True`` every state is factorised from scratch and displacements are dense
    sums (no FFT at all): the test reference.
    """

    refinements = 3
    bulk_min = 2000
    #: pending rank-one terms before a fold (BLAS-3) into the stored inverse: every column of
    #: the current inverse is a pass over them, and the folds cost the same flops in any block,
    #: so a smaller block reads less per event (measured at N = 128 against 512: the
    #: ``frictionless``, ``bonded`` and ``indent`` pulls at 17.5 % contact 10 %, 11 % and 3 %
    #: faster, none slower; docs/benchmarks.md)
    block = 128
    #: removals after which the displacements of a kept solution are computed afresh (the
    #: updates add the round-off of one block product each)
    refresh_every = 16
    #: calls of :meth:`solve_inner` for a right-hand side between certified solves of it (its
    #: tracked solution takes the round-off of one update per removal meanwhile)
    inner_every = 16

    def __init__(self, problem: Problem, *, reference: bool = False, tol: float = 1e-12,
                 may_fall_back: bool = False, threads: int = 1, **_: object) -> None:
        # The factorisation and the folding of pending terms (BLAS-3) get ``threads``; the
        # event loop runs with one BLAS thread: its products are matrix-vector, and idle BLAS
        # threads spinning beside the FFTs cost more than they gain (measured: N = 128, 5 %
        # contact, 2.0 s with one thread, 4.9 s with two).
        #: when an inverse does not fit in memory: go on matrix-free (True, recorded in
        #: :attr:`fallback`) or refuse (False, :class:`MemoryLimitError`)
        self.may_fall_back = may_fall_back
        #: why the solver went on matrix-free for good, else ""
        self.fallback = ""
        self.slip_iterations = 0
        #: the last forces (f_z, f_x) with slip forces by right-hand side: GMRES's start
        self.slip_warm: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        op = problem.operator("zz", "zx", "xx").with_threads(1)
        self.problem = problem
        self.ny, self.nx = op.shape
        self.op = op
        self.tables = {c: op.tables.pair(c) for c in ("zz", "zx", "xx")}
        self.reference = reference
        self.tol = tol
        self.solves = 0
        self.worst = 0.0
        #: the matrix-free solver of the bulk passes, when used
        self.bulk: MatrixFreeBlockSolver | None = None
        #: the updated inverse of the block (unknowns numbered by :data:`COMPONENTS`)
        self.inverse = UpdatableInverse(self.entries, COMPONENTS.n * self.ny * self.nx,
                                        room=self._room,
                                        threads=threads, block=self.block)
        self.dense = True  # False while the bulk passes or the fallback solve matrix-free
        #: the displacements of the kept solutions, by right-hand side (:class:`_Fields`)
        self._fields: dict[str, _Fields] = {}
        #: the version of the rows and the last :meth:`_layout` derived from them
        self._layout_of: tuple[int, _Layout] | None = None
        #: the site of each column of the tracked slip block, and whether it is live
        #: (:meth:`slip_response`)
        self._slip_sites = np.empty(0, dtype=np.int64)
        self._slip_live = np.empty(0, dtype=bool)
        #: calls of :meth:`solve_inner` by key since its last certified solve
        self._inner_age: dict[str, int] = {}
        #: whether the slip block fits in memory (False once it did not)
        self._slip_room = True
        #: the buffer of the slip block's columns (:meth:`_slip_columns`)
        self._slip_buf: np.ndarray | None = None
        #: the last answer of :meth:`slip_response`, for the same state's other solves
        self._slip_memo: tuple | None = None

    @property
    def blas_seconds(self) -> float:
        """Seconds in dense linear algebra (factorisation, products, updates)."""
        return self.inverse.blas_seconds

    @property
    def method(self) -> str:
        """``"cg"`` once the solver went on matrix-free for good (:attr:`fallback`), else
        ``"dense"``."""
        return "cg" if self.fallback else "dense"

    # -- assembly ------------------------------------------------------------------------------
    def _lin(self, sites: np.ndarray, comp: str) -> np.ndarray:
        """The index of each site in the pair table of ``comp``."""
        w = self.tables[comp][1]
        iy, ix = np.divmod(sites, self.nx)
        return iy * w + ix

    def entries(self, ids_i: np.ndarray, ids_j: np.ndarray, order: str = "C") -> np.ndarray:
        """Block entries between two lists of unknowns (u_a at i due to f_b at j), gathered
        from the kernels' pair tables (:func:`~roughslip.elastic.tables.gather_pairs`)."""
        ids_i, ids_j = np.asarray(ids_i, dtype=np.int64), np.asarray(ids_j, dtype=np.int64)
        out = np.empty((ids_i.size, ids_j.size), order=order)
        ci, cj_all = COMPONENTS.component(ids_i), COMPONENTS.component(ids_j)
        for a in range(COMPONENTS.n):
            ri = np.flatnonzero(ci == a)
            si = COMPONENTS.site(ids_i[ri])
            for b in range(COMPONENTS.n):
                cj = np.flatnonzero(cj_all == b)
                if not ri.size or not cj.size:
                    continue
                sj = COMPONENTS.site(ids_j[cj])
                comp, flipped = COMPONENTS.kernel(a, b, self.tables)
                T, _, off = self.tables[comp]
                li, lj = self._lin(si, comp), self._lin(sj, comp)
                if flipped:  # G_ab(i - j) = G_ba(j - i)
                    li, lj = -li, -lj
                gather_pairs(T, li, lj, off, out, ri, cj)
        return out

    # -- the inverse ---------------------------------------------------------------------------
    def _room(self, m: int) -> bool:
        """Whether an inverse for ``m`` unknowns fits in memory (:func:`dense_memory_bytes`).
        If not: refuse, or with :attr:`may_fall_back` drop the inverse and record why in
        :attr:`fallback`."""
        need, have = _inverse_bytes(m), available_bytes()
        if need <= have:
            return True
        msg = (f"needs ~{need / 2**30:.2f} GiB for {m} unknowns (contact and stick sites) but "
               f"{have / 2**30:.2f} GiB are available")
        if not self.may_fall_back:
            raise MemoryLimitError(
                f"coupled model, method 'dense': {msg}; use method 'cg' (matrix-free) or "
                "'auto', a smaller depth or grid, or raise execution.memory_limit_gb")
        self.fallback = f"auto chose cg: the dense solver {msg}"
        self.inverse.reset()
        return False

    def _factor(self, ids: np.ndarray) -> None:
        try:
            self.inverse.factor(ids)
        except NumericalError:
            raise NumericalError("coupled model: the coupled block on the contact and stick "
                                 "sets is not positive definite") from None

    def prepare(self, C: np.ndarray, S: np.ndarray, bulk: bool = False) -> None:
        bulk = bulk and not self.reference and int(C.sum() + S.sum()) > self.bulk_min
        if not (self.fallback or bulk):
            self._update(C, S)
            if not self.fallback:
                return
        # matrix-free: the bulk passes, or for good once an inverse did not fit
        if self.bulk is None:
            self.bulk = MatrixFreeBlockSolver(self.problem, tol=self.tol)
        self.bulk.prepare(C, S)
        self.inverse.reset()
        self.dense = False

    def _update(self, C: np.ndarray, S: np.ndarray) -> None:
        """Bring the inverse to the unknowns of C and S: updated when few change, afresh
        otherwise (or when an update loses positive definiteness)."""
        self.dense = True
        inv = self.inverse
        want = np.zeros(inv.row.size, dtype=bool)
        want[COMPONENTS.unknowns(np.flatnonzero(C), "z")] = True
        want[COMPONENTS.unknowns(np.flatnonzero(S), "x")] = True
        have = inv.row >= 0
        gone = np.flatnonzero(have & ~want)
        new = np.flatnonzero(want & ~have)
        ok = not (self.reference or not inv.ready
                  or gone.size + new.size > max(4, int(inv.live.sum()) // 3))
        # stops at the first failed removal; an addition fails only on a non-positive Schur
        # complement (None: the memory did not allow it, and the note says so)
        ok = ok and all(self._remove(int(u)) for u in gone)
        ok = ok and (not new.size or inv.add(new) is not False)
        if not ok:
            self._factor(_unknowns(C, S))
        elif (~inv.live).sum() > 0.25 * inv.m:
            kept = [(key, f) for key, t in inv.tracked.items()
                    if (f := self._fields.get(key)) is not None and f.x is t.x]
            inv.compact(0)
            for key, f in kept:  # the same forces on fewer rows
                f.x = inv.tracked[key].x

    def _remove(self, unknown: int) -> bool:
        r"""Remove ``unknown`` from the inverse (False: its pivot was not positive) and move
        the displacements of the kept solutions with it: each changes by
        :math:`-(x_r/c_r)\,G c` for the column :math:`c` of the inverse, one block product
        for all of them (class docstring)."""
        inv = self.inverse
        r = int(inv.row[unknown])
        c = inv.column(r)
        moving = [(f, float(t.x[r]) / float(c[r])) for key, t in inv.tracked.items()
                  if (f := self._fields.get(key)) is not None and f.x is t.x]
        forces = None
        if len(moving) > 1:  # the column's forces, on the rows before the removal (r included)
            forces = self._to_fields(c, self._layout(), (self.ny, self.nx))
        if not inv.remove(unknown, column=c):
            return False
        if len(moving) == 1:  # one product either way: the fresh one, at the next solve
            moving[0][0].x = None
        elif moving:
            gz, gx = self._displacements(*forces)
            for f, a in moving:
                if f.age >= self.refresh_every:
                    f.x = None  # computed afresh at the next solve
                    continue
                f.uz, f.ux, f.age = f.uz - a * gz, f.ux - a * gx, f.age + 1
        return True

    def residual(self) -> float:
        return self.worst

    def reset(self) -> bool:
        """Drop the updated inverse: the next :meth:`prepare` factorises afresh. True: there
        was one to drop."""
        had = self.inverse.ready
        self.inverse.reset()
        self._fields = {}
        self._inner_age = {}
        return had

    def add_solves(self, n: int) -> None:
        self.solves += n

    # -- solutions -----------------------------------------------------------------------------
    def _layout(self) -> _Layout:
        """The live rows, the site of each, whether it holds f_x (else f_z), and the sites and
        rows of each kind; kept until the rows change (:attr:`UpdatableInverse.version`)."""
        inv = self.inverse
        if self._layout_of is None or self._layout_of[0] != inv.version:
            rows = np.flatnonzero(inv.live)
            ids = inv.ids[rows]
            sites, isx = COMPONENTS.site(ids), COMPONENTS.component(ids) == _X
            self._layout_of = (inv.version, _Layout(rows, sites, isx, sites[~isx], rows[~isx],
                                                    sites[isx], rows[isx]))
        return self._layout_of[1]

    def _to_rows(self, rz: np.ndarray, rx: np.ndarray, layout: _Layout) -> np.ndarray:
        """The right-hand side on the rows (zero on dead rows)."""
        b = np.zeros(self.inverse.m)
        b[layout.rows] = np.where(layout.isx, rx.ravel()[layout.sites], rz.ravel()[layout.sites])
        return b

    def _to_fields(self, x: np.ndarray, layout: _Layout, shape: tuple[int, ...]
                   ) -> tuple[np.ndarray, np.ndarray]:
        """The solution on the rows as force fields (f_z, f_x)."""
        fz, fx = np.zeros(shape), np.zeros(shape)
        fz.ravel()[layout.z_sites] = x[layout.z_rows]
        fx.ravel()[layout.x_sites] = x[layout.x_rows]
        return fz, fx

    def _displacements(self, fz: np.ndarray, fx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u_z, u_x) on the grid: FFT, or dense sums for the reference."""
        if not self.reference:
            return self.op.apply_block(fz, fx)
        n = self.ny * self.nx
        src = _unknowns(fz.ravel() != 0, fx.ravel() != 0)
        val = _values(src, fz, fx)
        every = np.arange(n)
        uz = self.entries(COMPONENTS.unknowns(every, "z"), src) @ val
        ux = self.entries(COMPONENTS.unknowns(every, "x"), src) @ val
        return uz.reshape(fz.shape), ux.reshape(fz.shape)

    def solve(self, rz: np.ndarray, rx: np.ndarray, key: str = ""
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.solve_many([(rz, rx, key)])[0]

    def solve_many(self, rhs: list[tuple[np.ndarray, np.ndarray, str]]
                   ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(f_z, f_x, u_z) on the grid for each ``(rz, rx, key)``: the tracked solution when
        the right-hand side on the unknowns is unchanged, else one product with the inverse
        for all the new ones (read from memory once); each certified (class docstring)."""
        self.solves += len(rhs)
        if not self.dense:
            out = self.bulk.solve_many(rhs)
            self.worst = max(self.worst, self.bulk.worst)
            return out
        inv = self.inverse
        layout = self._layout()
        rows, sites, isx = layout.rows, layout.sites, layout.isx
        bs, xs = self._solutions(rhs, layout)
        out = []
        for (rz, rx, key), b, x in zip(rhs, bs, xs, strict=True):
            scale = max(float(np.linalg.norm(b)), np.finfo(float).tiny)
            last: list = []
            kept = self._fields.get(key)
            if kept is None or kept.x is None or kept.x is not x:
                kept = None  # no displacements for this solution (new, or computed afresh)

            def residual(x, b=b, rz=rz, last=last, scale=scale, kept=kept):
                fz, fx = self._to_fields(x, layout, rz.shape)
                if kept is not None and x is kept.x:  # the kept solution, not yet refined
                    uz, ux, age = kept.uz, kept.ux, kept.age
                else:
                    (uz, ux), age = self._displacements(fz, fx), 0
                last[:] = [fz, fx, uz, ux, age]
                r = np.zeros(inv.m)
                r[rows] = b[rows] - np.where(isx, ux.ravel()[sites], uz.ravel()[sites])
                return r, float(np.linalg.norm(r)) / scale

            x, res, _ = inv.refine(x, residual, math.inf if self.reference else self.tol,
                                   self.refinements)
            self.worst = max(self.worst, res)
            inv.tracked[key] = Tracked(b, x, _rhs_values(rz.copy(), rx.copy()))
            fz, fx, uz, ux, age = last
            if not self.reference:
                self._fields[key] = _Fields(x, uz, ux, age)
            out.append((fz, fx, uz))
        return out

    def displacements(self, fz: np.ndarray, fx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._displacements(fz, fx)

    def solve_inner(self, rz: np.ndarray, rx: np.ndarray, key: str
                    ) -> tuple[np.ndarray, np.ndarray]:
        """(f_z, f_x) for the right-hand side ``(rz, rx)``, kept as a tracked solution under
        ``key`` like :meth:`solve_many`'s, but certified only every :attr:`inner_every`
        calls: the inner solution of a solve that certifies its own result as a whole (the
        Coulomb law's, :class:`~roughslip.coupling.state.ContactState`). Between
        certifications it costs no FFT product: its displacements are not kept or moved."""
        age = self._inner_age.get(key, self.inner_every)
        if age >= self.inner_every:
            self._inner_age[key] = 1
            fz, fx, _ = self.solve(rz, rx, key)
            return fz, fx
        self._inner_age[key] = age + 1
        self._fields.pop(key, None)
        self.solves += 1
        layout = self._layout()
        (b,), (x,) = self._solutions([(rz, rx, key)], layout)
        hit = self.inverse.tracked.get(key)
        if hit is None or hit.x is not x:  # a new solution: tracked from now on
            self.inverse.tracked[key] = Tracked(b, x, _rhs_values(rz.copy(), rx.copy()))
        return self._to_fields(x, layout, rz.shape)

    def _solutions(self, rhs: list[tuple[np.ndarray, np.ndarray, str]], layout: _Layout
                   ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """The right-hand sides on the rows, and for each the tracked solution when its
        right-hand side is unchanged, else the product with the inverse (one product for all
        the new ones: the inverse is read from memory once)."""
        inv = self.inverse
        bs, xs, todo = [], [], []
        for k, (rz, rx, key) in enumerate(rhs):
            b = self._to_rows(rz, rx, layout)
            hit = inv.tracked.get(key)
            if hit is not None and np.array_equal(hit.b, b):
                xs.append(hit.x)
            else:
                xs.append(None)
                todo.append(k)
            bs.append(b)
        if todo:
            X = inv.apply(np.column_stack([bs[k] for k in todo]))
            for j, k in enumerate(todo):
                xs[k] = np.ascontiguousarray(X[:, j])
        return bs, xs

    def unit_responses(self, sites: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`BlockSolver.unit_responses`: the columns of the inverse, uncertified (the
        caller certifies the forces it combines from them against the FFT operator)."""
        if not self.dense:
            return BlockSolver.unit_responses(self, sites)
        inv = self.inverse
        layout = self._layout()
        n = self.ny * self.nx
        fz, fx = np.zeros((len(sites), n)), np.zeros((len(sites), n))
        rows = inv.row[COMPONENTS.unknowns(np.asarray(sites, dtype=np.int64), "x")]
        if np.any(rows < 0):
            raise NumericalError("unit response of a site with no f_x unknown (internal error)")
        for k, r in enumerate(rows):
            c = inv.column(int(r))
            fz[k, layout.z_sites] = c[layout.z_rows]
            fx[k, layout.x_sites] = c[layout.x_rows]
        return fz, fx

    def apply_inverse(self, rz: np.ndarray, rx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f_z, f_x) = the current inverse times the right-hand side, uncertified (the inner
        products of the Coulomb solves, whose result is certified as a whole)."""
        layout = self._layout()
        x = self.inverse.apply(self._to_rows(rz, rx, layout))
        return self._to_fields(x, layout, rz.shape)

    def slip_response(self, sites: np.ndarray
                      ) -> tuple[np.ndarray, Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
                                 ] | None:
        r"""The response of the block to tangential forces on the slip sites ``sites`` (flat
        indices of contact sites with no :math:`f_x` unknown), for the Coulomb law's solves.

        With :math:`H_j` the displacements on the unknowns of a unit :math:`f_x` at site
        :math:`j` and :math:`K^{-1}` the current inverse, the block
        :math:`Z = K^{-1} [H_j]_{j \in P}` is kept as a tracked solution with one column per
        site (:class:`~roughslip.linalg.inverse.Tracked`): a removal moves it by one rank-one
        update, a bordering and a compaction carry it along, so a site's column costs one
        product with the inverse when it starts to slip and :math:`O(m)` per event after
        that. Columns of sites that leave ``sites`` are marked dead and dropped when they are
        a quarter of the block; a new factorisation drops the block, which is then built
        again by one product with the inverse.

        Returns the :math:`|P| \times |P|` matrix :math:`E_P^T Z` (the :math:`f_z` rows of the
        sites, columns in the order of ``sites``) and ``fields(v)``: the force fields
        :math:`(f_z, f_x)` of :math:`Z v`; None when the block does not fit in memory (with
        two copies of it, for a bordering or a compaction). Uncertified: the Coulomb solves
        certify their result as a whole
        (:class:`~roughslip.coupling.state.ContactState`).
        """
        if not self._slip_room:
            return None
        inv = self.inverse
        sites = np.asarray(sites, dtype=np.int64)
        t = inv.tracked.get(_SLIP)
        memo = self._slip_memo
        if (memo is not None and t is not None and memo[0] == (inv.version, inv.shifts)
                and np.array_equal(memo[1], sites)):
            return memo[2]  # the same state: its other right-hand sides
        if t is None:
            self._slip_sites = np.empty(0, dtype=np.int64)
            self._slip_live = np.empty(0, dtype=bool)
            t = Tracked(None, np.zeros((inv.m, 0), order="F"), self._slip_values())
        have, live = self._slip_sites, self._slip_live  # the site of each column
        live &= np.isin(have, sites)
        new = np.setdiff1d(sites, have[live])
        Z = t.x
        if 4 * int((~live).sum()) > live.size:  # drop the dead columns
            keep = np.flatnonzero(live)
            Z, have, live = self._slip_columns(Z, keep.size, keep), have[keep], live[keep]
        q = have.size
        if new.size and Z is not None:
            Z = self._slip_columns(Z, q + new.size)
        if Z is None:  # no room: the caller goes without the block from now on
            inv.tracked.pop(_SLIP, None)
            self._slip_buf = self._slip_memo = None
            self._slip_room = False
            return None
        layout = self._layout()
        if new.size:
            B = np.zeros((inv.m, new.size), order="F")
            B[layout.rows] = self.entries(inv.ids[layout.rows], COMPONENTS.unknowns(new, "x"))
            Z[:, q:] = inv.apply(B)
            Z[~inv.live, q:] = 0.0
            have = np.concatenate([have, new])
            live = np.concatenate([live, np.ones(new.size, dtype=bool)])
        t.x = Z
        inv.tracked[_SLIP] = t
        self._slip_sites, self._slip_live = have, live
        held = np.flatnonzero(live)
        order = np.argsort(have[held], kind="stable")
        cols = held[order[np.searchsorted(have[held][order], sites)]]
        shape = (self.ny, self.nx)

        def fields(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            w = np.zeros(Z.shape[1])
            w[cols] = v
            return self._to_fields(Z @ w, layout, shape)

        E = submatrix(Z, inv.row[COMPONENTS.unknowns(sites, "z")], cols)
        self._slip_memo = ((inv.version, inv.shifts), sites.copy(), (E, fields))
        return E, fields

    def solve_slip(self, rhs: list[tuple[np.ndarray, np.ndarray, str]], C: np.ndarray,
                   S: np.ndarray, P: np.ndarray, w: np.ndarray
                   ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        r"""The solves with slip forces (:meth:`BlockSolver.solve_slip`). Through the inverse:
        the solution is :math:`y = y_0 - K^{-1}H w t` with :math:`y_0 = K^{-1} r` and
        :math:`t = f_z(P)` the solution of the :math:`|P|`-sized system
        :math:`(I + E_P^T K^{-1} H w)\,t = E_P^T y_0` (:math:`H` the displacements on the
        unknowns of tangential forces on :math:`P`), solved by GMRES warm-started from the
        last state's slip forces. The iteration matrix is of the order of :math:`\lambda`
        times the coupling :math:`G_{zx}/G_{zz}`, so a few iterations suffice, and
        :math:`K^{-1}H` is the tracked block :meth:`slip_response`, so an iteration is a
        product with the :math:`|P| 	imes |P|` matrix :math:`E_P^T K^{-1} H w`. While
        matrix-free (the bulk passes, a fallback): the default. The reference solves the
        non-symmetric system directly."""
        if self.reference:
            return self._slip_direct(rhs, C, S, P, w)
        if not self.dense:
            return BlockSolver.solve_slip(self, rhs, C, S, P, w)
        return certified_slip_solves(self, rhs, C, S, P, w, self._slip_solve)

    def _slip_solve(self, rz: np.ndarray, rx: np.ndarray, key: str, P: np.ndarray,
                    w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The forces with the slip law on P for one right-hand side, through the inverse
        (:meth:`solve_slip`)."""
        fz0, fx0 = self.solve_inner(rz, rx, key)
        block = self.slip_response(np.flatnonzero(P))
        if block is not None:
            E, fields = block
            T = E * w  # E_P^T K^{-1} H w

            def correction(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                return fields(w * t)

            def product(t: np.ndarray) -> np.ndarray:
                return T @ t
        else:  # no room for the block: an FFT product and a product with the inverse
            zero = np.zeros(rz.shape)

            def correction(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                fxs = np.zeros(rz.shape)
                fxs[P] = w * t
                return self.apply_inverse(*self.displacements(zero, fxs))

            def product(t: np.ndarray) -> np.ndarray:
                return correction(t)[0][P]

        n = int(P.sum())
        b = fz0[P]

        def matvec(t: np.ndarray) -> np.ndarray:
            self.slip_iterations += 1
            return t + product(np.ravel(t))

        A = LinearOperator((n, n), matvec=matvec, dtype=float)
        prev = self.slip_warm.get(key)
        x0 = prev[0][P] if prev is not None else b
        bnorm = max(float(np.linalg.norm(b)), np.finfo(float).tiny)
        # a GMRES that stops short shows in the certified residual of the whole solution
        t, _ = gmres(A, b, x0=x0, rtol=0.0, atol=0.1 * self.tol * bnorm,
                     restart=min(n, 50), maxiter=max(20, n))
        fz1, fx1 = correction(t)
        fz, fx = fz0 - fz1, fx0 - fx1
        fx[P] = w * fz[P]
        self.slip_warm[key] = (fz, fx)
        return fz, fx

    def _slip_direct(self, rhs: list[tuple[np.ndarray, np.ndarray, str]], C: np.ndarray,
                     S: np.ndarray, P: np.ndarray, w: np.ndarray
                     ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """The reference: the non-symmetric system with the slip forces, assembled by dense
        sums and solved directly (LU)."""
        self.add_solves(len(rhs))
        ids = _unknowns(C, S)
        A = self.entries(ids, ids)
        pz = np.flatnonzero(P)
        # f_z(P) among the unknowns
        cols = np.searchsorted(ids[: int(C.sum())], COMPONENTS.unknowns(pz, "z"))
        A[:, cols] += self.entries(ids, COMPONENTS.unknowns(pz, "x")) * w
        sites, isx = COMPONENTS.site(ids), COMPONENTS.component(ids) == _X
        B = np.column_stack([_values(ids, rz, rx) for rz, rx, _ in rhs])
        Y = linalg.solve(A, B, check_finite=False)
        out = []
        for k, (rz, _, _) in enumerate(rhs):
            fz, fx = np.zeros(rz.shape), np.zeros(rz.shape)
            fz.ravel()[sites[~isx]] = Y[~isx, k]
            fx.ravel()[sites[isx]] = Y[isx, k]
            fx[P] = w * fz[P]
            uz, ux = self.displacements(fz, fx)
            out.append((fz, fx, uz, ux))
        return out

    def _slip_columns(self, Z: np.ndarray, q: int, keep: np.ndarray | None = None
                      ) -> np.ndarray | None:
        """The slip block with ``q`` columns, the first ones those of ``Z`` (``keep``: only
        those columns, in order): a view of a Fortran-ordered buffer with spare columns, so
        that a new column is written in place; a new buffer when ``Z`` is not its start
        (after a bordering or a compaction) or when it is full. None when a new buffer would
        not fit in memory with two copies of it."""
        buf = self._slip_buf
        if keep is not None:
            Z = Z[:, keep]  # a copy: safe to write back into the buffer
        elif buf is not None and Z.base is buf and q <= buf.shape[1]:
            return buf[:, :q]  # the columns are in place
        if buf is None or buf.shape[0] != Z.shape[0] or q > buf.shape[1]:
            cap = max(q + q // 2, 64)
            # the buffer, and the copies a bordering or a compaction makes of the block
            if 3 * 8 * Z.shape[0] * cap > available_bytes():
                return None
            buf = np.empty((Z.shape[0], cap), order="F")
            self._slip_buf = buf
        buf[:, : Z.shape[1]] = Z
        return buf[:, :q]

    def _slip_values(self) -> Callable[[np.ndarray], np.ndarray]:
        """The slip block's right-hand sides on unknowns added later (:meth:`slip_response`;
        dead columns are bordered too, as their sites give them)."""
        return lambda ids: self.entries(ids, COMPONENTS.unknowns(self._slip_sites, "x"))


class _Layout(NamedTuple):
    """The dense solver's live rows: the site of each and whether it holds f_x (else f_z),
    and the sites and rows of each kind."""

    rows: np.ndarray
    sites: np.ndarray
    isx: np.ndarray
    z_sites: np.ndarray
    z_rows: np.ndarray
    x_sites: np.ndarray
    x_rows: np.ndarray


@dataclass
class _Fields:
    """The displacements (u_z, u_x) of the forces of a kept solution ``x`` of the dense
    solver's inverse (``x`` None: to be computed afresh), and the removals they were moved
    through since they were computed."""

    x: np.ndarray | None
    uz: np.ndarray
    ux: np.ndarray
    age: int


#: the index of the tangential component among :data:`COMPONENTS`
_X = COMPONENTS.names.index("x")


def _unknowns(C: np.ndarray, S: np.ndarray) -> np.ndarray:
    """The unknowns of the sets: f_z on C, then f_x on S (boolean grids or flat masks)."""
    return np.concatenate([COMPONENTS.unknowns(np.flatnonzero(C), "z"),
                           COMPONENTS.unknowns(np.flatnonzero(S), "x")])


def _values(ids: np.ndarray, rz: np.ndarray, rx: np.ndarray) -> np.ndarray:
    """The entries of the fields ``rz`` (on f_z unknowns) and ``rx`` (on f_x unknowns) at
    the unknowns ``ids``."""
    sites = COMPONENTS.site(ids)
    return np.where(COMPONENTS.component(ids) == _X, rx.ravel()[sites], rz.ravel()[sites])


def _rhs_values(rz: np.ndarray, rx: np.ndarray):
    """The right-hand side of unknowns (:func:`_values` of ``rz`` and ``rx``), for the
    bordering of a tracked solution."""
    def values(ids: np.ndarray) -> np.ndarray:
        return _values(ids, rz, rx)
    return values


@SOLVERS.register("cg", "matrix-free: warm-started CG on the restricted FFT block operator")
class MatrixFreeBlockSolver(BlockSolver):
    """Conjugate gradients (:func:`roughslip.linalg.cg.cg`) on the restricted block operator,
    warm-started from the previous solution of the same right-hand side."""

    def __init__(self, problem: Problem, *, tol: float = 1e-12, max_iter: int = 20_000,
                 **_: object) -> None:
        self.problem, self.tol, self.max_iter = problem, tol, max_iter
        self.op = problem.operator("zz", "zx", "xx")
        self.solves = 0
        self.worst = 0.0
        self.blas_seconds, self.fallback = 0.0, ""  # no dense linear algebra, no fallback
        self.method = "cg"
        self.prev: dict[str, np.ndarray] = {}
        self.slip_iterations = 0
        #: the last forces (f_z, f_x) with slip forces by right-hand side: GMRES's start
        self.slip_warm: dict[str, tuple[np.ndarray, np.ndarray]] = {}

    def prepare(self, C: np.ndarray, S: np.ndarray, bulk: bool = False) -> None:
        self.A = self.problem.restricted_block(C, S)

    def residual(self) -> float:
        return self.worst

    def reset(self) -> bool:
        return False  # nothing kept that a fresh start would compute differently

    def add_solves(self, n: int) -> None:
        self.solves += n

    def solve(self, rz: np.ndarray, rx: np.ndarray, key: str = ""
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.solves += 1
        r = cg(self.A, np.stack([rz, rx]), x0=self.prev.get(key), tol=self.tol,
               max_iter=self.max_iter)
        self.worst = max(self.worst, r.residual)
        self.prev[key] = r.x
        return r.x[0], r.x[1], self.op.apply_block(r.x[0], r.x[1])[0]

    def solve_many(self, rhs: list[tuple[np.ndarray, np.ndarray, str]]
                   ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        return [self.solve(rz, rx, key) for rz, rx, key in rhs]

    def displacements(self, fz: np.ndarray, fx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.op.apply_block(fz, fx)


#: dense solver's peak memory per squared unknown count (bytes): that of the updatable inverse
DENSE_BYTES_PER_UNKNOWN2 = BYTES_PER_ORDER2


def dense_memory_bytes(sites: int) -> int:
    """Peak memory of ``method="dense"`` for ``sites`` contact sites, all bonded (bytes):
    ``m = 2 sites`` unknowns."""
    return _inverse_bytes(COMPONENTS.n * int(sites))


def _inverse_bytes(m: int) -> int:
    """Peak memory of the dense solver's inverse on ``m`` unknowns (bytes)."""
    return DENSE_BYTES_PER_UNKNOWN2 * m * m


def choose_solver(method: str) -> str:
    """The solver class name for ``method`` (``auto`` starts dense; the dense solver checks its
    memory before each factorisation and, under ``auto``, falls back to ``cg``)."""
    if method == AUTO:
        return SOLVERS.names()[0]  # the dense solver, registered first
    SOLVERS.get(method)
    return method


def make_solver(problem: Problem, method: str, reference: bool, tol: float,
                 max_iter: int) -> tuple[BlockSolver, str]:
    """The block solver for ``method`` (``auto`` starts dense and may fall back to CG) and
    the name of its class."""
    name = choose_solver(method)
    solver = SOLVERS.get(name)(problem, reference=reference, tol=tol, max_iter=max_iter,
                               threads=problem.threads, may_fall_back=method == AUTO)
    return solver, name
