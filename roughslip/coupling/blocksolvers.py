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

from roughslip.contact.problem import Problem
from roughslip.elastic.tables import gather_pairs
from roughslip.errors import MemoryLimitError, NumericalError
from roughslip.linalg.cg import cg
from roughslip.linalg.inverse import BYTES_PER_ORDER2, Tracked, UpdatableInverse, submatrix
from roughslip.linalg.memory import available_bytes
from roughslip.registry import Registry

# ------------------------------------------------------------------------------------------------
# Linear solvers for the reduced block
# ------------------------------------------------------------------------------------------------


class BlockSolver(Protocol):
    """A linear solver for the reduced block on the contact set C and the stick set S: the
    contract the event loop uses, and all of it."""

    #: solves so far (:meth:`add_solves` counts those the caller does on the solver's behalf)
    solves: int
    #: seconds in dense linear algebra
    blas_seconds: float
    #: why the solver went on matrix-free (the dense inverse did not fit), else ""
    note: str
    #: the dense test reference: every state factorised afresh, displacements by dense sums
    reference: bool
    #: whether the current state is solved through an explicit inverse (then
    #: :meth:`apply_inverse` is available), else matrix-free
    dense: bool

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

    def apply_inverse(self, rz: np.ndarray, rx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f_z, f_x): the current inverse times a right-hand side, uncertified (only while
        :attr:`dense`)."""

    def residual(self) -> float:
        """The worst relative residual of the solves so far."""

    def reset(self) -> bool:
        """Drop what the solver kept between states (an updated inverse), so that the next
        :meth:`prepare` starts afresh; False when there was nothing to drop."""

    def add_solves(self, n: int) -> None:
        """Count ``n`` solves done with this solver's operators by the caller."""


#: the coupled block solvers, by name (``method`` of :func:`couple`)
SOLVERS: Registry[type] = Registry("coupled solver")

#: the name of the dense solver's tracked block of slip responses
_SLIP = "slip response"


@SOLVERS.register("dense", "the reduced block's inverse, updated at every event")
class DenseBlockSolver:
    r"""Reduced block assembled from the operator's kernel tables, solved through its inverse.

    The unknowns are numbered ``2 i`` (:math:`f_z` at site ``i``) and ``2 i + 1``
    (:math:`f_x`). The explicit inverse of the block on the current unknowns is an
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
                 fallback: bool = False, threads: int = 1, **_: object) -> None:
        # The factorisation and the folding of pending terms (BLAS-3) get ``threads``; the
        # event loop runs with one BLAS thread: its products are matrix-vector, and idle BLAS
        # threads spinning beside the FFTs cost more than they gain (measured: N = 128, 5 %
        # contact, 2.0 s with one thread, 4.9 s with two).
        #: when an inverse does not fit in memory: go on matrix-free (True, with a :attr:`note`)
        #: or refuse (False, :class:`MemoryLimitError`)
        self.fallback = fallback
        self.note = ""
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
        #: the updated inverse of the block (unknowns ``2 i``: f_z, ``2 i + 1``: f_x)
        self.inverse = UpdatableInverse(self.entries, 2 * self.ny * self.nx, room=self._room,
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
        for a in (0, 1):  # 0: z, 1: x
            ri = np.flatnonzero((ids_i & 1) == a)
            si = ids_i[ri] >> 1
            for b in (0, 1):
                cj = np.flatnonzero((ids_j & 1) == b)
                if not ri.size or not cj.size:
                    continue
                sj = ids_j[cj] >> 1
                comp = "zx" if a != b else ("zz" if a == 0 else "xx")
                T, _, off = self.tables[comp]
                li, lj = self._lin(si, comp), self._lin(sj, comp)
                if (a, b) == (1, 0):  # G_xz(i - j) = G_zx(j - i)
                    li, lj = -li, -lj
                gather_pairs(T, li, lj, off, out, ri, cj)
        return out

    # -- the inverse ---------------------------------------------------------------------------
    def _room(self, m: int) -> bool:
        """Whether an inverse for ``m`` unknowns fits in memory (:func:`dense_memory_bytes`).
        If not: refuse, or with :attr:`fallback` drop the inverse and leave a :attr:`note`."""
        need, have = _inverse_bytes(m), available_bytes()
        if need <= have:
            return True
        msg = (f"needs ~{need / 2**30:.2f} GiB for {m} unknowns (contact and stick sites) but "
               f"{have / 2**30:.2f} GiB are available")
        if not self.fallback:
            raise MemoryLimitError(
                f"coupled model, method 'dense': {msg}; use method 'cg' (matrix-free) or "
                "'auto', a smaller depth or grid, or raise execution.memory_limit_gb")
        self.note = f"auto chose cg: the dense solver {msg}"
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
        if not (self.note or bulk):
            self._update(C, S)
            if not self.note:
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
        want[2 * np.flatnonzero(C)] = True
        want[2 * np.flatnonzero(S) + 1] = True
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
            self._factor(np.concatenate([2 * np.flatnonzero(C), 2 * np.flatnonzero(S) + 1]))
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
            sites, isx = ids >> 1, (ids & 1).astype(bool)
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
        src = np.concatenate([2 * np.flatnonzero(fz.ravel()), 2 * np.flatnonzero(fx.ravel()) + 1])
        val = np.where(src % 2 == 1, fx.ravel()[src >> 1], fz.ravel()[src >> 1])
        uz = self.entries(2 * np.arange(n), src) @ val
        ux = self.entries(2 * np.arange(n) + 1, src) @ val
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
            B[layout.rows] = self.entries(inv.ids[layout.rows], 2 * new + 1)
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

        E = submatrix(Z, inv.row[2 * sites], cols)
        self._slip_memo = ((inv.version, inv.shifts), sites.copy(), (E, fields))
        return E, fields

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
        return lambda ids: self.entries(ids, 2 * self._slip_sites + 1)


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


def _rhs_values(rz: np.ndarray, rx: np.ndarray):
    """The right-hand side of unknowns (``2 i``: rz at site i, ``2 i + 1``: rx), for the
    bordering of a tracked solution."""
    def values(ids: np.ndarray) -> np.ndarray:
        return np.where((ids & 1).astype(bool), rx.ravel()[ids >> 1], rz.ravel()[ids >> 1])
    return values


@SOLVERS.register("cg", "matrix-free: warm-started CG on the restricted FFT block operator")
class MatrixFreeBlockSolver:
    """Conjugate gradients (:func:`roughslip.linalg.cg.cg`) on the restricted block operator,
    warm-started from the previous solution of the same right-hand side."""

    def __init__(self, problem: Problem, *, tol: float = 1e-12, max_iter: int = 20_000,
                 **_: object) -> None:
        self.problem, self.tol, self.max_iter = problem, tol, max_iter
        self.op = problem.operator("zz", "zx", "xx")
        self.solves = 0
        self.worst = 0.0
        self.blas_seconds, self.note = 0.0, ""  # no dense linear algebra, no fallback
        self.reference, self.dense = False, False
        self.prev: dict[str, np.ndarray] = {}

    def prepare(self, C: np.ndarray, S: np.ndarray, bulk: bool = False) -> None:
        self.A = self.problem.restricted_block(C, S)

    def residual(self) -> float:
        return self.worst

    def reset(self) -> bool:
        return False  # nothing kept that a fresh start would compute differently

    def add_solves(self, n: int) -> None:
        self.solves += n

    def apply_inverse(self, rz: np.ndarray, rx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError("the matrix-free solver keeps no inverse (dense is False)")

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
    return _inverse_bytes(2 * int(sites))


def _inverse_bytes(m: int) -> int:
    """Peak memory of the dense solver's inverse on ``m`` unknowns (bytes)."""
    return DENSE_BYTES_PER_UNKNOWN2 * m * m


def choose_solver(method: str) -> str:
    """The solver class name for ``method`` (``auto`` starts dense; the dense solver checks its
    memory before each factorisation and, under ``auto``, falls back to ``cg``)."""
    if method == "auto":
        return "dense"
    SOLVERS.get(method)
    return method


def make_solver(problem: Problem, method: str, reference: bool, tol: float,
                 max_iter: int) -> tuple[BlockSolver, str]:
    """The block solver for ``method`` (``auto`` starts dense and may fall back to CG) and
    the name of its class."""
    name = choose_solver(method)
    solver = SOLVERS.get(name)(problem, reference=reference, tol=tol, max_iter=max_iter,
                               threads=problem.threads, fallback=method == "auto")
    return solver, name
