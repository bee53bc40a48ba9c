r"""The coupled normal–tangential model with exact event tracking (docs/theory/coupled.rst#coupled).

For a contact set :math:`C` (:math:`u_z = \bar u_z` imposed, :math:`f_z` unknown) and a stick
set :math:`S \subseteq C` (:math:`u_x = D_x` imposed, :math:`f_x` unknown; other sites carry
:math:`f_x = 0`, the break law)

.. math::

    \begin{bmatrix} G_{zz}(C,C) & G_{zx}(C,S) \\ G_{xz}(S,C) & G_{xx}(S,S) \end{bmatrix}
    \begin{bmatrix} f_z(C) \\ f_x(S) \end{bmatrix}
    = \begin{bmatrix} \bar u_z(C) \\ 0 \end{bmatrix}
    + D_x \begin{bmatrix} 0 \\ 1(S) \end{bmatrix},

an SPD principal block of the full operator (docs/theory/halfspace.rst#matrix-properties). Between
events every force, displacement and gap is exactly affine in :math:`D_x`: :math:`f = f^0 + D_x
f^1`, :math:`g = g^0 + D_x g^1`. The next event is the smallest root beyond the current :math:`D_x`
of: a bond reaching :math:`f_x = \pm\lambda f_z` (stick to slip, either direction), a contact force
reaching zero (contact lost), a gap closing (contact gained; the new contact is not bonded). After
an event the state is re-solved at the same :math:`D_x` and any violations are resolved one at a
time (contact lost, then penetration, then the most overloaded bond; ties to the lowest flat index)
before the pull continues: an avalanche.

The squeeze at :math:`D_x = 0` keeps every contact bonded (:math:`u_x = 0`), as the report proposes;
under coupling this already needs tangential forces, and bonds that violate :math:`|f_x| \le \lambda
f_z` there are released, most violated first, before pulling (the report misses this, erratum T25
(docs/theory/errata.rst#erratum-t25)). The friction force is the largest :math:`F_x` on the path,
reported with :math:`F_z` at the same :math:`D_x` (erratum T26
(docs/theory/errata.rst#erratum-t26)). At :math:`\nu = 1/2`, :math:`G_{zx} = 0` and the model
reduces exactly to the decoupled one.

The squeeze goes to a depth or to a normal force, and the pull holds either the depth (the
report's pull) or the normal force, with the depth following (``_State``,
docs/theory/coupled.rst#coupled-load-control).

Under the Coulomb law a failed bond slips, carrying :math:`f_x = \sigma\lambda f_z` in the
direction :math:`\sigma` of its force as :math:`f_z` changes (the system is then not
symmetric: ``_State._solve_many``), and a slipping bond whose slip the pull would turn around
sticks again where it is (``_State.reversal``; docs/theory/coupled.rst#coupled-coulomb).

Solvers (registered in :data:`SOLVERS`): ``"dense"`` assembles the reduced block from the
closed-form kernels and keeps its inverse up to date, O(m) per removed unknown, while it fits
in memory (docs/theory/coupled.rst#coupled-solvers); ``"cg"`` runs conjugate gradients
(:func:`roughslip.linalg.cg.cg`) on the restricted FFT block operator
(:meth:`roughslip.contact.problem.Problem.restricted_block`). Both follow the same event logic,
and every solve is certified against the FFT operator.
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy import linalg
from scipy.sparse.linalg import LinearOperator, gmres

from roughslip.contact.methods import Registry
from roughslip.contact.problem import Problem, finite
from roughslip.contact.pull import check_friction
from roughslip.errors import InputError, MemoryLimitError, NumericalError
from roughslip.linalg.cg import cg
from roughslip.linalg.inverse import BYTES_PER_ORDER2, Tracked, UpdatableInverse
from roughslip.linalg.memory import available_bytes
from roughslip.linalg.threads import blas_threads

TIE = 1e-9
#: a slipping bond sticks again when its slip rate (per unit pull) opposes its force by more
RATE_TIE = 1e-9


@dataclass(frozen=True)
class Event:
    """One recorded state of the pull."""

    dx: float
    fx: float  # total tangential force F_x
    fz: float  # total normal force F_z at the same D_x
    kind: str  # "start", "slip+", "slip-", "lost", "gained", "stick" (a slipping bond sticks)
    site: int  # flat index (-1 for "start")
    dz: float = math.nan  # the depth D_z at the same D_x (it moves when the force is held)


@dataclass(frozen=True)
class CoupledResult:
    """Outcome of :func:`squeeze_pull_coupled` (fields indexed ``[iy, ix]``)."""

    friction_force: float
    normal_force_at_peak: float
    peak_dx: float
    events: list[Event]
    normal_force: float  # F_z after the squeeze and the initial release, at D_x = 0
    contact_area: float  # fraction, at D_x = 0
    released: int  # contact sites without a bond when the pull starts (D_x = 0)
    fz0: np.ndarray  # normal forces at D_x = 0 (after release)
    fx0: np.ndarray  # tangential forces at D_x = 0 (after release)
    contact0: np.ndarray
    stick0: np.ndarray
    fz_peak: np.ndarray
    fx_peak: np.ndarray
    stick_peak: np.ndarray
    contact_peak: np.ndarray
    converged: bool
    seconds: float  # the whole solve: squeeze, release at D_x = 0 and pull
    solves: int
    method: str
    message: str = ""
    #: of :attr:`seconds`, those until the pull starts (the squeeze and the release of the
    #: bonds it overloads at :math:`D_x = 0`)
    squeeze_seconds: float = math.nan
    #: worst relative residual of the block solves against the FFT operator (both solvers); a
    #: measure of convergence, not of the error: where equally overloaded bonds are released
    #: (a symmetric contact), the matrix-free solver's friction force was 20 % off at residual
    #: 1e-6 (docs/methods.rst#estimates-against-truth)
    residual: float = math.nan
    #: D_z after the squeeze (given, or found under load control)
    depth: float = math.nan
    #: what the pull holds: ``"depth"`` (D_z fixed, the report's pull) or ``"force"``
    pull_control: str = "depth"
    #: with ``record_states=True``: (D_x, f_z, f_x, gap, contact, stick) at every event
    states: list | None = None
    #: seconds in dense linear algebra (the dense solver's factorisation, products and
    #: updates; 0 for the matrix-free solver)
    blas_seconds: float = 0.0
    #: why ``auto`` went on matrix-free (the dense inverse did not fit), else ""
    fallback: str = ""
    #: what a failed bond carries: ``"break"`` (nothing) or ``"coulomb"`` (lam f_z)
    slip_law: str = "break"
    #: GMRES iterations of the solves with Coulomb slip forces (0 under the break law)
    slip_iterations: int = 0

    @property
    def dx(self) -> np.ndarray:
        return np.array([e.dx for e in self.events])

    @property
    def fx(self) -> np.ndarray:
        return np.array([e.fx for e in self.events])

    @property
    def fz(self) -> np.ndarray:
        return np.array([e.fz for e in self.events])

    @property
    def dz(self) -> np.ndarray:
        return np.array([e.dz for e in self.events])


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


@SOLVERS.register("dense", "the reduced block's inverse, updated at every event")
class _Dense:
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
    which the event loop needs anyway for the gaps, give the residual on the unknowns; above
    ``tol`` (relative) it is refined by :math:`x \leftarrow x + M^{-1}_{\rm current} r`, up to
    ``refinements`` times (:meth:`UpdatableInverse.refine`), and the worst certified residual
    is reported. With ``reference=True`` every state is factorised from scratch and
    displacements are dense sums (no FFT at all): the test reference.
    """

    refinements = 3
    bulk_min = 2000

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
        self.bulk: _CG | None = None  # the matrix-free solver of the bulk passes, when used
        #: the updated inverse of the block (unknowns ``2 i``: f_z, ``2 i + 1``: f_x)
        self.inverse = UpdatableInverse(self.entries, 2 * self.ny * self.nx, room=self._room,
                                        threads=threads)
        self.dense = True  # False while the bulk passes or the fallback solve matrix-free

    @property
    def blas_seconds(self) -> float:
        """Seconds in dense linear algebra (factorisation, products, updates)."""
        return self.inverse.blas_seconds

    # -- assembly ------------------------------------------------------------------------------
    def _block(self, ci: np.ndarray, cj: np.ndarray, comp: str) -> np.ndarray:
        T, w, off = self.tables[comp]
        iy, ix = np.divmod(ci, self.nx)
        jy, jx = np.divmod(cj, self.nx)
        lin_i, lin_j = iy * w + ix, jy * w + jx
        return T[lin_i[:, None] - lin_j[None, :] + off]

    def entries(self, ids_i: np.ndarray, ids_j: np.ndarray, order: str = "C") -> np.ndarray:
        """Block entries between two lists of unknowns (u_a at i due to f_b at j)."""
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
                if (a, b) == (1, 0):  # G_xz(i - j) = G_zx(j - i)
                    blk = self._block(sj, si, "zx").T
                else:
                    blk = self._block(si, sj, "zx" if a != b else ("zz" if a == 0 else "xx"))
                out[np.ix_(ri, cj)] = blk
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
            self.bulk = _CG(self.problem, tol=self.tol)
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
        ok = ok and all(inv.remove(int(u)) for u in gone)
        ok = ok and (not new.size or inv.add(new) is not False)
        if not ok:
            self._factor(np.concatenate([2 * np.flatnonzero(C), 2 * np.flatnonzero(S) + 1]))
        elif (~inv.live).sum() > 0.25 * inv.m:
            inv.compact(0)

    def residual(self) -> float:
        return self.worst

    def reset(self) -> bool:
        """Drop the updated inverse: the next :meth:`prepare` factorises afresh. True: there
        was one to drop."""
        had = self.inverse.ready
        self.inverse.reset()
        return had

    def add_solves(self, n: int) -> None:
        self.solves += n

    # -- solutions -----------------------------------------------------------------------------
    def _layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The live rows, the site of each, and whether it holds f_x (else f_z)."""
        inv = self.inverse
        rows = np.flatnonzero(inv.live)
        ids = inv.ids[rows]
        return rows, ids >> 1, (ids & 1).astype(bool)

    def _to_rows(self, rz: np.ndarray, rx: np.ndarray, layout) -> np.ndarray:
        """The right-hand side on the rows (zero on dead rows)."""
        rows, sites, isx = layout
        b = np.zeros(self.inverse.m)
        b[rows] = np.where(isx, rx.ravel()[sites], rz.ravel()[sites])
        return b

    def _to_fields(self, x: np.ndarray, layout, shape: tuple[int, ...]
                   ) -> tuple[np.ndarray, np.ndarray]:
        """The solution on the rows as force fields (f_z, f_x)."""
        rows, sites, isx = layout
        fz, fx = np.zeros(shape), np.zeros(shape)
        fz.ravel()[sites[~isx]] = x[rows[~isx]]
        fx.ravel()[sites[isx]] = x[rows[isx]]
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
        rows, sites, isx = layout
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
        out = []
        for (rz, rx, key), b, x in zip(rhs, bs, xs, strict=True):
            scale = max(float(np.linalg.norm(b)), np.finfo(float).tiny)
            last: list[np.ndarray] = []

            def residual(x, b=b, rz=rz, last=last, scale=scale):
                fz, fx = self._to_fields(x, layout, rz.shape)
                uz, ux = self._displacements(fz, fx)
                last[:] = [fz, fx, uz]
                r = np.zeros(inv.m)
                r[rows] = b[rows] - np.where(isx, ux.ravel()[sites], uz.ravel()[sites])
                return r, float(np.linalg.norm(r)) / scale

            x, res, _ = inv.refine(x, residual, math.inf if self.reference else self.tol,
                                   self.refinements)
            self.worst = max(self.worst, res)
            inv.tracked[key] = Tracked(b, x, _rhs_values(rz.copy(), rx.copy()))
            out.append(tuple(last))
        return out

    def displacements(self, fz: np.ndarray, fx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._displacements(fz, fx)

    def apply_inverse(self, rz: np.ndarray, rx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f_z, f_x) = the current inverse times the right-hand side, uncertified (the inner
        products of the Coulomb solves, whose result is certified as a whole)."""
        layout = self._layout()
        x = self.inverse.apply(self._to_rows(rz, rx, layout))
        return self._to_fields(x, layout, rz.shape)


def _rhs_values(rz: np.ndarray, rx: np.ndarray):
    """The right-hand side of unknowns (``2 i``: rz at site i, ``2 i + 1``: rx), for the
    bordering of a tracked solution."""
    def values(ids: np.ndarray) -> np.ndarray:
        return np.where((ids & 1).astype(bool), rx.ravel()[ids >> 1], rz.ravel()[ids >> 1])
    return values


@SOLVERS.register("cg", "matrix-free: warm-started CG on the restricted FFT block operator")
class _CG:
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


# ------------------------------------------------------------------------------------------------
# The event loop
# ------------------------------------------------------------------------------------------------


class _State:
    r"""The contact and stick sets, and the solution on them as affine functions of D_x.

    Displacement control (``force`` None) holds :math:`D_z`: the normal right-hand side is
    :math:`\bar u = b + D_z` with :math:`b = h - \max h`. Load control holds
    :math:`F_z = \sum_C f_z = F`, and :math:`D_z` becomes an unknown: with the solutions
    :math:`f^b, f^d, f^1` for the right-hand sides :math:`(b, 0)`, :math:`(1_C, 0)` and
    :math:`(0, 1_S)`, the force constraint gives :math:`D_z = d_0 + d_1 D_x` with
    :math:`d_0 = (F - \sum f^b_z)/\sum f^d_z`, :math:`d_1 = -\sum f^1_z/\sum f^d_z`, and
    every force stays affine in :math:`D_x`: :math:`f = (f^b + d_0 f^d) + D_x (f^1 + d_1 f^d)`.
    The events are found exactly as under displacement control.
    """

    def __init__(self, solver, base: np.ndarray, lam: float, C: np.ndarray, *,
                 depth: float | None = None, force: float | None = None,
                 gained: str = "unbonded", slip_law: str = "break", tol: float = 1e-12,
                 drive: str = "x"):
        self.solver, self.base, self.lam = solver, base, lam
        self.gained = gained
        self.slip_law, self.tol = slip_law, tol
        #: slip direction of the sites in C but not in S: +-1, a slipping bond carrying
        #: f_x = sigma lam f_z (Coulomb law); 0, no tangential force (a broken bond, or a
        #: contact that never was a bond)
        self.sigma = np.zeros(base.shape)
        self.worst = 0.0  # worst relative residual of the solves with slip forces
        self.u1x: np.ndarray | None = None  # rate of u_x in D_x, with slipping bonds
        self.gmres_iterations = 0
        #: the last forces (f_z, f_x) with slip by right-hand side: GMRES's starting points
        self._warm: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.pulling = False  # contacts gained while pulling follow the rule ``gained``
        #: bond offsets: a bond formed at D_x = D_g holds u_x = D_x + o, o = u_x(D_g) - D_g
        self.offset = np.zeros(base.shape)
        self.depth, self.force = depth, force
        self.C = C.copy()
        self.S = C.copy()
        self.ones = np.ones(base.shape)
        self.zero = np.zeros(base.shape)
        self.scale_g = float(np.max(base + (depth if depth is not None else 0.0)))
        self.Dscale = 1.0  # displacement scale for tolerances (set from the first event)
        self.d0, self.d1 = (depth if depth is not None else math.nan), 0.0
        #: solve for the rate in D_x too (the pull); the squeeze at D_x = 0 needs none
        self.slope = True
        #: what the loop's parameter D moves: "x", the pull D_x (at a depth or force held);
        #: "z", the depth D_z itself at D_x = 0, up to ``depth`` (frictional indentation,
        #: :func:`indent`; ``depth`` then only sets the gap scale)
        self.drive = drive

    @property
    def slipping(self) -> np.ndarray:
        """The slipping bonds: contact sites off the stick set with a slip direction."""
        return self.C & ~self.S & (self.sigma != 0)

    def hold_depth(self, depth: float) -> None:
        """Switch to displacement control at ``depth`` (then call :meth:`solve`)."""
        self.depth, self.force = depth, None

    def hold_force(self, force: float) -> None:
        """Switch to load control at ``force`` (then call :meth:`solve`)."""
        self.depth, self.force = None, force

    def solve(self, bulk: bool = False) -> None:
        """Solve the current sets (``bulk``: see :meth:`BlockSolver.prepare`). A non-finite
        solution from an updated inverse (round-off grown through many updates) is recomputed
        from a fresh factorisation; one that stays non-finite is an error, never a silent
        NaN."""
        self._solve(bulk)
        if self._finite():
            return
        if self.solver.reset():
            self._solve(bulk)
            if self._finite():
                return
        raise NumericalError("non-finite forces in the solve of the contact and stick sets")

    def _finite(self) -> bool:
        return all(np.all(np.isfinite(a)) for a in (*self.f0, *self.f1, self.g0, self.g1))

    def _solve(self, bulk: bool = False) -> None:
        """Solve for the state at D_x = 0 and, with :attr:`slope`, for its rate in D_x (the
        squeeze's corrections at D_x = 0 need no rate: one solve per state); with slipping
        bonds, also the rate of :math:`u_x` (one more FFT product), for :meth:`reversal`."""
        self._solve_forces(bulk)
        self.u1x = None
        if self.slope and self.slipping.any():
            self.u1x = self.solver.displacements(*self.f1)[1]

    def _solve_forces(self, bulk: bool) -> None:
        s = self.solver
        s.prepare(self.C, self.S, bulk=bulk)
        if self.drive == "z":  # u_z = b + D on C: f = f(b) + D f(1_C), g = u_z - b - D
            sols = self._solve_many([(self.base, self.offset, "0"),
                                     (self.ones, self.zero, "1")])
            self.f0, self.g0 = sols[0][:2], sols[0][2] - self.base
            self.f1, self.g1 = sols[1][:2], sols[1][2] - 1.0
            self.d0, self.d1 = 0.0, 1.0
            return
        slope = self.slope and bool(self.S.any())
        tail = [(self.zero, self.ones, "1")] if slope else []
        if self.force is None:
            ubar = self.base + self.depth
            sols = self._solve_many([(ubar, self.offset, "0"), *tail])
            self.f0, self.g0 = sols[0][:2], sols[0][2] - ubar
            self.f1, self.g1 = (sols[1][:2], sols[1][2]) if slope else (
                (self.zero, self.zero), self.zero)
            self.d0, self.d1 = self.depth, 0.0
            return
        sols = self._solve_many([(self.base, self.offset, "b"), (self.ones, self.zero, "d"),
                                 *tail])
        (fbz, fbx, ub), (fdz, fdx, ud) = sols[0], sols[1]
        f1z, f1x, u1 = sols[2] if slope else (self.zero, self.zero, self.zero)
        sd = float(fdz.sum())
        if not sd > 0:
            raise NumericalError("load control: the contact set carries no force under a "
                                 "uniform approach (no contact left)")
        self.d0 = (self.force - float(fbz.sum())) / sd
        self.d1 = -float(f1z.sum()) / sd
        self.f0 = (fbz + self.d0 * fdz, fbx + self.d0 * fdx)
        self.f1 = (f1z + self.d1 * fdz, f1x + self.d1 * fdx)
        self.g0 = ub + self.d0 * ud - self.base - self.d0
        self.g1 = u1 + self.d1 * ud - self.d1
        self.scale_g = max(self.scale_g, float(np.max(self.base)) + self.d0)

    def _solve_many(self, rhs: list[tuple[np.ndarray, np.ndarray, str]]
                    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        r"""(f_z, f_x, u_z) on the grid for each right-hand side ``(r_z, r_x, key)``, with the
        slip forces of the Coulomb law: on the slip sites :math:`P` (in C, not in S,
        :math:`\sigma \ne 0`), :math:`f_x = \sigma\lambda f_z`.

        With :math:`K` the block on (C, S) that the solver inverts and :math:`H` the
        displacements on (C, S) of tangential forces on P, the system is
        :math:`K y + H\,\mathrm{diag}(\sigma\lambda)\,y_z(P) = r`: not symmetric. Its
        solution is :math:`y = y_0 - K^{-1}H w t` with :math:`y_0 = K^{-1} r` and
        :math:`t = f_z(P)` the solution of the :math:`|P|`-sized system
        :math:`(I + E_P^T K^{-1} H w)\,t = E_P^T y_0` (:math:`w = \sigma\lambda`), solved by
        GMRES warm-started from the last state's slip forces: each iteration one FFT product
        and one solve with :math:`K`, and the iteration matrix is of the order of
        :math:`\lambda` times the coupling :math:`G_{zx}/G_{zz}`, so a few iterations suffice.
        Every solution is certified against the FFT operator on the full system and refined
        when its residual is above tol. The dense reference solves the non-symmetric system
        directly instead.
        """
        P = self.slipping
        if not P.any():
            return self.solver.solve_many(rhs)
        w = self.lam * self.sigma[P]
        if self.solver.reference:
            return self._solve_direct(rhs, P, w)
        solve = self._slip_solve if self.solver.dense else self._slip_solve_free
        out = []
        for rz, rx, key in rhs:
            fz, fx = solve(rz, rx, key, P, w)
            scale = max(float(np.linalg.norm(np.concatenate([rz[self.C], rx[self.S]]))),
                        np.finfo(float).tiny)
            for attempt in range(3):
                uz, ux = self.solver.displacements(fz, fx)
                ez, ex = np.where(self.C, rz - uz, 0.0), np.where(self.S, rx - ux, 0.0)
                res = float(np.linalg.norm(np.concatenate([ez[self.C], ex[self.S]]))) / scale
                if res <= self.tol or attempt == 2:
                    break
                dz, dx = solve(ez, ex, "refine", P, w)
                fz, fx = fz + dz, fx + dx
            self.worst = max(self.worst, res)
            out.append((fz, fx, uz))
        return out

    def _slip_solve(self, rz: np.ndarray, rx: np.ndarray, key: str, P: np.ndarray,
                    w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The forces with the slip law on P for one right-hand side (:meth:`_solve_many`)."""
        s = self.solver
        fz0, fx0, _ = s.solve(rz, rx, key)

        def correction(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            fxs = np.zeros(self.base.shape)
            fxs[P] = w * t
            return s.apply_inverse(*s.displacements(self.zero, fxs))

        n = int(P.sum())
        b = fz0[P]

        def matvec(t: np.ndarray) -> np.ndarray:
            self.gmres_iterations += 1
            return t + correction(np.ravel(t))[0][P]

        A = LinearOperator((n, n), matvec=matvec, dtype=float)
        prev = self._warm.get(key)
        x0 = prev[0][P] if prev is not None else b
        bnorm = max(float(np.linalg.norm(b)), np.finfo(float).tiny)
        # a GMRES that stops short shows in the certified residual of the whole solution
        t, _ = gmres(A, b, x0=x0, rtol=0.0, atol=0.1 * self.tol * bnorm,
                     restart=min(n, 50), maxiter=max(20, n))
        fz1, fx1 = correction(t)
        fz, fx = fz0 - fz1, fx0 - fx1
        fx[P] = w * fz[P]
        self._warm[key] = (fz, fx)
        return fz, fx

    def _slip_solve_free(self, rz: np.ndarray, rx: np.ndarray, key: str, P: np.ndarray,
                         w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Matrix-free: GMRES on the whole non-symmetric system, one FFT product per
        iteration, warm-started from the last solution of the same right-hand side."""
        C, S = self.C, self.S
        nc, n = int(C.sum()), int(C.sum() + S.sum())

        def fields(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            fz, fx = np.zeros(self.base.shape), np.zeros(self.base.shape)
            fz[C] = y[:nc]
            fx[S] = y[nc:]
            fx[P] = w * fz[P]
            return fz, fx

        def matvec(y: np.ndarray) -> np.ndarray:
            self.gmres_iterations += 1
            uz, ux = self.solver.displacements(*fields(np.ravel(y)))
            return np.concatenate([uz[C], ux[S]])

        b = np.concatenate([rz[C], rx[S]])
        prev = self._warm.get(key)
        x0 = None if prev is None else np.concatenate([prev[0][C], prev[1][S]])
        bnorm = max(float(np.linalg.norm(b)), np.finfo(float).tiny)
        y, _ = gmres(LinearOperator((n, n), matvec=matvec, dtype=float), b, x0=x0, rtol=0.0,
                     atol=0.1 * self.tol * bnorm, restart=min(n, 200), maxiter=50)
        self.solver.add_solves(1)
        fz, fx = fields(y)
        self._warm[key] = (fz, fx)
        return fz, fx

    def _solve_direct(self, rhs: list[tuple[np.ndarray, np.ndarray, str]], P: np.ndarray,
                      w: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """The reference: the non-symmetric system with the slip forces, assembled by dense
        sums and solved directly (LU)."""
        s = self.solver
        s.add_solves(len(rhs))
        ids = np.concatenate([2 * np.flatnonzero(self.C), 2 * np.flatnonzero(self.S) + 1])
        A = s.entries(ids, ids)
        pz = np.flatnonzero(P)
        cols = np.searchsorted(ids[: int(self.C.sum())], 2 * pz)  # f_z(P) among the unknowns
        A[:, cols] += s.entries(ids, 2 * pz + 1) * w
        sites, isx = ids >> 1, (ids & 1).astype(bool)
        B = np.column_stack([np.where(isx, rx.ravel()[sites], rz.ravel()[sites])
                             for rz, rx, _ in rhs])
        Y = linalg.solve(A, B, check_finite=False)
        out = []
        for k, (rz, _, _) in enumerate(rhs):
            fz, fx = np.zeros(rz.shape), np.zeros(rz.shape)
            fz.ravel()[sites[~isx]] = Y[~isx, k]
            fx.ravel()[sites[isx]] = Y[isx, k]
            fx[P] = w * fz[P]
            out.append((fz, fx, s.displacements(fz, fx)[0]))
        return out

    def depth_at(self, D: float) -> float:
        """:math:`D_z` at pull displacement ``D``."""
        return self.d0 + self.d1 * D

    def dx_at(self, D: float) -> float:
        """:math:`D_x` at the loop's parameter ``D`` (0 when the depth is driven)."""
        return D if self.drive == "x" else 0.0

    def at(self, D: float):
        if not math.isfinite(D):
            raise NumericalError(f"the pull reached a non-finite displacement D_x = {D!r}")
        if not self.slope and D != 0:
            raise NumericalError(f"the state at D_x = {D!r} needs its rate (internal error)")
        fz = self.f0[0] + D * self.f1[0]
        fx = self.f0[1] + D * self.f1[1]
        g = self.g0 + D * self.g1
        return fz, fx, g

    def violation(self, D: float):
        """The first violation to resolve at D: (kind, flat index) or None."""
        fz, fx, g = self.at(D)
        fscale = max(float(np.max(np.abs(fz))), np.finfo(float).tiny)
        bad = self.C & (fz < -TIE * fscale)
        if bad.any():
            return "lost", _argext(fz, bad, "min")
        bad = ~self.C & (g < -TIE * max(self.scale_g, np.finfo(float).tiny))
        if bad.any():
            return "gained", _argext(g, bad, "min")
        over = np.zeros(fz.shape)
        np.divide(np.abs(fx), self.lam * fz, out=over, where=self.S & (fz > 0))
        over[self.S & (fz <= 0)] = np.inf
        bad = self.S & (over > 1 + TIE)
        if bad.any():
            j = _argext(over, bad, "max")
            return ("slip+" if fx.ravel()[j] > 0 else "slip-"), j
        return None

    def apply(self, kind: str, j: int, D: float = 0.0) -> None:
        """Update the sets for an event at site ``j`` at pull displacement ``D``."""
        C, S = self.C.ravel(), self.S.ravel()
        if kind == "lost":
            C[j] = False
            S[j] = False
            self.sigma.ravel()[j] = 0.0
        elif kind == "stick":  # a slipping bond sticks again where it is
            self._bond_here(j, D)
            self.sigma.ravel()[j] = 0.0
        elif kind == "gained":
            C[j] = True
            if self.pulling and self.gained == "bonded":
                self._bond_here(j, D)
        else:  # a bond fails: it breaks, or slips in the direction of its force (Coulomb)
            S[j] = False
            if self.slip_law == "coulomb":
                self.sigma.ravel()[j] = 1.0 if kind == "slip+" else -1.0

    def _bond_here(self, j: int, D: float) -> None:
        """Bond site ``j`` at the elastic point where it is at ``D``: its offset makes the
        bond hold :math:`u_x = D_x + o` from here, so no force jumps."""
        fz, fx, _ = self.at(D)
        ux = self.solver.displacements(fz, fx)[1]
        self.offset.ravel()[j] = ux.ravel()[j] - self.dx_at(D)
        self.S.ravel()[j] = True

    def reversal(self) -> int | None:
        r"""A slipping bond whose slip would run against its force, or None: the one that
        does so most (the lowest flat index among ties).

        A bond slipping with :math:`f_x = \sigma\lambda f_z` lags behind the rigid surface,
        :math:`\sigma\,(\partial u_x/\partial D - v) \le 0` with :math:`v` the rigid
        surface's tangential rate (1 in a pull, 0 when the depth is driven). The rate is
        constant over a
        state and changes only when the sets change, so a reversal is found at the start of a
        state, never inside one; such a bond sticks again where it is (its force is
        continuous: it starts at its bound and moves inwards).
        """
        if self.u1x is None:
            return None
        P = self.slipping
        rigid = 1.0 if self.drive == "x" else 0.0  # the rigid surface's tangential rate
        back = np.where(P, self.sigma * (self.u1x - rigid), -np.inf).ravel()
        top = float(back.max())
        if not top > RATE_TIE:
            return None
        return int(np.flatnonzero(back >= top - TIE * max(1.0, top))[0])

    def interval(self, D: float) -> tuple[float, float, str, int]:
        r"""The displacements at which this state is admissible, ``[lo, hi]``, and the event
        (kind, flat index) that ends it at ``hi``, for a state reached at pull displacement
        ``D``. A constraint is flat when its change over the displacement scale
        :math:`\max(D_{\rm scale}, |D|)` is below the tolerance; a violated flat constraint
        makes the state admissible nowhere (``lo = inf``, ``hi = -inf``).

        Every constraint is affine, :math:`a + bD \ge 0`: :math:`f_z \ge 0` on C,
        :math:`g \ge 0` off C, :math:`\lambda f_z \mp f_x \ge 0` on S
        (docs/theory/coupled.rst#coupled).
        Ties at ``hi`` go to the lowest flat index, then to the kinds in that order.
        """
        (fz0, fx0), (fz1, fx1) = self.f0, self.f1
        lam = self.lam
        # the scale over which a rate matters: the first event's displacement, or how far the
        # pull has come (a rate negligible over the first event may not be over the pull)
        Dref = max(self.Dscale, abs(D))
        fs = max(float(np.abs(fz0).max()), float(np.abs(fz1).max()) * Dref,
                 np.finfo(float).tiny)
        gs = max(self.scale_g, np.finfo(float).tiny)
        cons = (
            ("lost", self.C, fz0, fz1, fs),
            ("gained", ~self.C, self.g0, self.g1, gs),
            ("slip+", self.S, lam * fz0 - fx0, lam * fz1 - fx1, fs),
            ("slip-", self.S, lam * fz0 + fx0, lam * fz1 + fx1, fs),
        )
        lo, hi, kind, site = -math.inf, math.inf, "", -1
        for name, mask, a, b, scale in cons:
            m = mask.ravel()
            a, b = a.ravel(), b.ravel()
            tiny = TIE * scale
            flat = m & (np.abs(b) * Dref <= tiny)
            if np.any(flat & (a < -tiny)):
                return math.inf, -math.inf, name, int(np.flatnonzero(flat & (a < -tiny))[0])
            with np.errstate(divide="ignore", invalid="ignore"):
                root = -a / b
            up = m & ~flat & (b < 0)
            if up.any():
                r = np.where(up, root, np.inf)
                v = float(r.min())
                tol = TIE * max(abs(v), self.Dscale)
                j = int(np.flatnonzero(up & (r <= v + tol))[0])
                if v < hi - tol or (abs(v - hi) <= tol and j < site):
                    hi, kind, site = v, name, j
            down = m & ~flat & (b > 0)
            if down.any():
                lo = max(lo, float(np.where(down, root, -np.inf).max()))
        return lo, hi, kind, site

    def totals(self, D: float) -> tuple[float, float]:
        fz, fx, _ = self.at(D)
        return float(fx.sum()), float(fz.sum())


def _argext(a: np.ndarray, mask: np.ndarray, how: str) -> int:
    vals = np.where(mask, a, np.inf if how == "min" else -np.inf).ravel()
    ext = vals.min() if how == "min" else vals.max()
    if not math.isfinite(ext):  # an infinite extreme (a bond with no normal force left)
        return int(np.flatnonzero((vals == ext) & mask.ravel())[0])
    close = np.abs(vals - ext) <= TIE * max(abs(ext), np.finfo(float).tiny)
    return int(np.flatnonzero(close & mask.ravel())[0])


#: the largest tolerance a run gives the coupled model (``pull.tol``, at most this)
COUPLED_TOL = 1e-10

#: dense solver's peak memory per squared unknown count (bytes): that of the updatable inverse
DENSE_BYTES_PER_UNKNOWN2 = BYTES_PER_ORDER2


def dense_memory_bytes(sites: int) -> int:
    """Peak memory of ``method="dense"`` for ``sites`` contact sites, all bonded (bytes):
    ``m = 2 sites`` unknowns."""
    return _inverse_bytes(2 * int(sites))


def _inverse_bytes(m: int) -> int:
    """Peak memory of the dense solver's inverse on ``m`` unknowns (bytes)."""
    return DENSE_BYTES_PER_UNKNOWN2 * m * m


def _choose_solver(method: str) -> str:
    """The solver class name for ``method`` (``auto`` starts dense; the dense solver checks its
    memory before each factorisation and, under ``auto``, falls back to ``cg``)."""
    if method == "auto":
        return "dense"
    SOLVERS.get(method)
    return method


@dataclass
class _Snapshot:
    """The state at one displacement: totals and fields."""

    fx_total: float
    fz_total: float
    dx: float
    fz: np.ndarray
    fx: np.ndarray
    stick: np.ndarray
    contact: np.ndarray

    @classmethod
    def of(cls, st: _State, D: float) -> _Snapshot:
        fz, fx, _ = st.at(D)
        F_x, F_z = st.totals(D)
        return cls(F_x, F_z, D, fz.copy(), fx.copy(), st.S.copy(), st.C.copy())


def _squeeze_bonded(st: _State) -> int:
    """The squeeze at D_x = 0 with every contact bonded; returns the bonds released.

    First the report's removal of all negative forces at once (the set only shrinks, so this
    ends), then every remaining violation one at a time, most violated first: a lost contact
    leaves, a penetrating site enters contact unbonded (bonded it may need a tensile force),
    an overloaded bond is released. The states at D_x = 0 need no rate in D_x
    (:attr:`_State.slope` is off until the pull).
    """
    st.slope = False
    while True:
        st.solve(bulk=True)
        fz, _, _ = st.at(0.0)
        fscale = max(float(np.abs(fz).max()), np.finfo(float).tiny)
        neg = st.C & (fz < -TIE * fscale)
        if not neg.any():
            break
        st.C &= ~neg
        st.S &= ~neg
        st.sigma[neg] = 0.0
    st.solve()  # the updated inverse from here on (the bulk passes may have used CG)
    seen: set[bytes] = set()
    while (v := st.violation(0.0)) is not None:
        st.apply(*v)
        key = hashlib.blake2b(st.C.tobytes() + st.S.tobytes(), digest_size=16).digest()
        if key in seen:
            raise NumericalError("coupled squeeze: the contact and stick sets cycle at "
                                 "D_x = 0 (no admissible state reached)")
        seen.add(key)
        st.solve()
    return int((st.C & ~st.S).sum())


@dataclass
class _Path:
    """The pull path: events, the peak, and how the loop ended."""

    events: list[Event]
    states: list | None
    peak: _Snapshot
    transient: int = 0
    message: str = ""
    #: (contact sites, stick sites) at every recorded event
    counts: list[tuple[int, int]] = field(default_factory=list)


def _pull_events(st: _State, limit: int, record_states: bool, end: float = math.inf) -> _Path:
    """Follow the events from D = 0 (module docstring): for a pull until no bond is left, for
    a driven depth (:func:`indent`) until ``end``."""
    path = _Path([], [] if record_states else None, _Snapshot.of(st, 0.0))

    def record(D: float, kind: str, site: int) -> None:
        F_x, F_z = st.totals(D)
        path.events.append(Event(st.dx_at(D), F_x, F_z, kind, site, st.depth_at(D)))
        path.counts.append((int(st.C.sum()), int(st.S.sum())))
        if path.states is not None:
            fz, fx, g = st.at(D)
            path.states.append((D, fz.copy(), fx.copy(), g.copy(), st.C.copy(), st.S.copy()))

    record(0.0, "start", -1)
    st.pulling = True
    D = 0.0
    first = True
    # until no bond holds; under the Coulomb law also until no slipping bond turns back
    # (a bond slipping against the pull sticks again, even when every other one slips)
    while (D < end if math.isfinite(end) else st.S.any() or st.reversal() is not None):
        if len(path.events) + path.transient > limit:
            path.message = f"stopped after {limit} events"
            break
        lo, hi, kind, j = st.interval(D)
        if first and math.isfinite(hi) and hi > 0:
            st.Dscale = hi  # the first event sets the displacement scale
            first = False
        tol_d = TIE * max(st.Dscale, abs(D))
        if (lo > D + tol_d or lo > hi + tol_d) and st.violation(D) is None:
            # Admissible at D within the value tolerances of every constraint, which the
            # test in D missed: a constraint that changes slowly with D (a gap closing at a
            # small rate, say) puts its root far from D for a violation far below the
            # solver's residual. Take the state as admissible from D on.
            lo = min(lo, D, hi)
        feasible = lo <= hi + tol_d
        if feasible and lo <= D + tol_d and hi >= D - tol_d:
            # admissible at D, but a slipping bond would turn back: it sticks again, unless
            # an event is due at D itself (a bound reached at once), which goes first (it
            # changes the rates: a new contact that sticks and at once slips would otherwise
            # turn the whole slip zone back and forth)
            j_back = st.reversal() if hi > D + tol_d else None
            if j_back is not None:
                record(D, "stick", j_back)
                st.apply("stick", j_back, D)
                st.solve()
                continue
            if hi > end:  # the driven depth reaches its end before the next event
                D = end
                record(D, "end", -1)
                break
            if not math.isfinite(hi):
                path.message = "no further event: the remaining bonds never break"
                break
            D = max(D, hi)  # the next event of a stable state
            at = D
        elif feasible and hi < D:
            at = hi  # an avalanche state, recorded at its own limit (below D)
        else:
            v = st.violation(D)  # transient: admissible at no D up to the current one
            if v is None:
                raise NumericalError("inconsistent state (no violation but no admissible "
                                     "displacement)")
            st.apply(*v, D)
            st.solve()
            path.transient += 1
            continue
        record(at, kind, j)
        F_x, _ = st.totals(at)
        if F_x > path.peak.fx_total:
            path.peak = _Snapshot.of(st, at)
        st.apply(kind, j, at)
        st.solve()
    return path


#: what a coupled pull can hold constant
PULL_CONTROLS = ("depth", "force")
#: how contacts gained during the pull enter (the first is the default)
GAINED_RULES = ("unbonded", "bonded")


def _event_limit(max_events: int | None, overlap: np.ndarray) -> int:
    """``max_events``, by default 20 events per site of the geometric overlap, plus 100."""
    return max_events if max_events is not None else 20 * int(overlap.sum()) + 100


def _make_solver(problem: Problem, method: str, reference: bool, tol: float,
                 max_iter: int) -> tuple[BlockSolver, str]:
    """The block solver for ``method`` (``auto`` starts dense and may fall back to CG) and
    the name of its class."""
    name = _choose_solver(method)
    solver = SOLVERS.get(name)(problem, reference=reference, tol=tol, max_iter=max_iter,
                               threads=problem.threads, fallback=method == "auto")
    return solver, name


@dataclass(frozen=True)
class _Outcome:
    """How a coupled solve ended: the worst residual, whether it converged, the message, and
    the solver that finished it."""

    residual: float
    converged: bool
    message: str
    method: str

    @classmethod
    def of(cls, solver, st: _State, path: _Path, method: str, tol: float) -> _Outcome:
        residual = max(solver.residual(), st.worst)
        problem = path.message or (f"worst block-solve residual {residual:.2e}"
                                   if residual > 10 * tol else "")
        summary = problem or f"{len(path.events)} events, {path.transient} transient state(s)"
        return cls(residual, not problem, "; ".join(filter(None, [solver.note, summary])),
                   "cg" if solver.note else method)


def _check_finite(where: str, **fields: np.ndarray) -> None:
    """A non-finite result field is an error, never a silent NaN."""
    for name, arr in fields.items():
        if not np.all(np.isfinite(arr)):
            raise NumericalError(f"{where}: non-finite {name}")


def _initial_contact(problem: Problem, force: float) -> np.ndarray:
    """A starting contact set for a squeeze to ``force``: the geometric overlap at the depth
    the frictionless squeeze needs for that force, widened by 10 %. The set is then corrected
    by the same removals and additions as under displacement control."""
    from roughslip.contact.squeeze import NormalSolver

    r = NormalSolver(problem, tol=1e-8).solve(force=force)
    return problem.overlap(1.1 * r.depth + 1e-12 * max(problem.grid.a, 1.0)) > 0


def couple(
    problem: Problem,
    *,
    depth: float | None = None,
    force: float | None = None,
    lam: float = 0.2,
    pull_control: str = "depth",
    gained: str = "unbonded",
    slip_law: str = "break",
    method: str = "auto",
    tol: float = 1e-12,
    max_iter: int = 20_000,
    max_events: int | None = None,
    reference: bool = False,
    record_states: bool = False,
) -> CoupledResult:
    r"""Squeeze a problem with bonded contacts and pull it with the coupled model until every
    bond has broken (module docstring; [Report2003] §6.1 with errata T25 and T26).

    Parameters
    ----------
    problem : Problem
        Heights, grid and material; its operator gets the ``zz``, ``zx`` and ``xx`` spectra.
    depth : float, optional
        Squeeze to the penetration :math:`D_z` from first touch (displacement control).
    force : float, optional
        Squeeze to the total normal force :math:`F_z` (load control). Exactly one of ``depth``
        and ``force``.
    lam : float
        Local friction coefficient.
    pull_control : {"depth", "force"}
        What the pull holds constant: ``"depth"``, the depth reached by the squeeze (the
        report's pull; :math:`F_z` changes as the contact changes), or ``"force"``, the normal
        force after the squeeze, as a dead weight does; then :math:`D_z` follows (recorded per
        event as ``Event.dz``).
    gained : {"unbonded", "bonded"}
        How a site that comes into contact during the pull enters: ``"unbonded"`` (the
        default: in the report's model the bonds are the contacts of the squeeze, and the pull
        only breaks them), carrying a normal force and no tangential one; or ``"bonded"``, with
        a new bond that holds the elastic point where it is when the gap closes (so no force
        jumps) and fails by the same law. Contacts gained while the squeeze corrects its
        sets, at :math:`D_x = 0`, always enter unbonded.
    slip_law : {"break", "coulomb"}
        What a bond carries once :math:`|f_x|` reaches :math:`\lambda f_z`: nothing
        (``"break"``, the report's law), or :math:`f_x = \pm\lambda f_z` in the direction
        of its force, following :math:`f_z` as it changes (``"coulomb"``; a slipping bond
        whose slip the pull would turn around sticks again where it is, event ``"stick"``).
    method : str
        ``"auto"`` or a name from :data:`SOLVERS`. The dense solver checks the memory of
        its inverse (:func:`dense_memory_bytes`) before each factorisation: ``dense``
        refuses with :class:`MemoryLimitError` when it does not fit, ``auto`` goes on with
        ``cg`` and says so in the message.
    tol : float
        Relative residual of every block solve (CG's tolerance; the dense solver's
        certification against the FFT operator).
    max_events : int, optional
        Stop after this many events (default ``20 x overlap sites + 100``).
    reference : bool
        With ``dense``: also compute displacements by dense sums (no FFT at all).
    record_states : bool
        Keep the full state at every event (for checks on small grids).

    Returns
    -------
    CoupledResult
    """
    t0 = time.perf_counter()
    geo = _check_couple(problem, depth, force, lam, pull_control, gained, slip_law)
    depth = None if depth is None else finite(depth, "depth")
    force = None if force is None else finite(force, "force")
    if not geo.any():
        z = np.zeros(problem.shape)
        return CoupledResult(
            friction_force=0.0, normal_force_at_peak=0.0, peak_dx=0.0, events=[],
            normal_force=0.0, contact_area=0.0, released=0, fz0=z, fx0=z, contact0=geo,
            stick0=geo, fz_peak=z, fx_peak=z, stick_peak=geo, contact_peak=geo,
            converged=True, seconds=time.perf_counter() - t0, solves=0,
            squeeze_seconds=time.perf_counter() - t0,
            method=_choose_solver(method), residual=0.0,  # nothing to solve
            message="no overlap: no contact", depth=0.0 if depth is None else depth,
            pull_control=pull_control, slip_law=slip_law)
    solver, method = _make_solver(problem, method, reference, tol, max_iter)
    limit = _event_limit(max_events, geo)
    with blas_threads(1):  # the dense solver raises it for its BLAS-3 work
        st = _State(solver, problem.base, float(lam), geo, depth=depth, force=force,
                    gained=gained, slip_law=slip_law, tol=tol)
        try:
            released = _squeeze_bonded(st)
            start = _Snapshot.of(st, 0.0)
            squeezed_depth = st.depth_at(0.0)
            t_squeeze = time.perf_counter() - t0
            # the pull holds what it is asked to: switch the control if the squeeze used the
            # other one (the state at D_x = 0 is the same); the pull needs the rates in D_x
            if pull_control == "depth" and force is not None:
                st.hold_depth(squeezed_depth)
            elif pull_control == "force" and depth is not None:
                st.hold_force(start.fz_total)
            st.slope = True
            st.solve()
            path = _pull_events(st, limit, record_states)
        except NumericalError as exc:
            raise NumericalError(f"coupled model: {exc}") from None
    peak = path.peak
    _check_finite("coupled model", fz=start.fz, fx=start.fx, **{"fz at peak": peak.fz})
    out = _Outcome.of(solver, st, path, method, tol)
    return CoupledResult(
        friction_force=float(peak.fx_total), normal_force_at_peak=float(peak.fz_total),
        peak_dx=float(peak.dx), events=path.events, normal_force=float(start.fz.sum()),
        contact_area=float(start.contact.sum()) / start.contact.size, released=released,
        fz0=start.fz, fx0=start.fx, contact0=start.contact, stick0=start.stick,
        fz_peak=peak.fz, fx_peak=peak.fx, stick_peak=peak.stick, contact_peak=peak.contact,
        converged=out.converged, seconds=time.perf_counter() - t0, solves=solver.solves,
        squeeze_seconds=t_squeeze, blas_seconds=solver.blas_seconds, fallback=solver.note,
        method=out.method,
        residual=out.residual, slip_law=slip_law, slip_iterations=st.gmres_iterations,
        message=out.message, states=path.states, depth=float(squeezed_depth),
        pull_control=pull_control,
    )


def _check_couple(problem: Problem, depth: float | None, force: float | None, lam: float,
                  pull_control: str, gained: str, slip_law: str) -> np.ndarray:
    """Validate the arguments of :func:`couple`; returns the starting contact set."""
    check_friction(lam, slip_law)
    if (depth is None) == (force is None):
        raise InputError("give exactly one of depth and force")
    if pull_control not in PULL_CONTROLS:
        raise InputError(f"pull_control = {pull_control!r}: must be 'depth' or 'force'")
    if gained not in GAINED_RULES:
        raise InputError(f"gained = {gained!r}: must be 'unbonded' or 'bonded'")
    if depth is not None:
        return problem.overlap(problem.check_depth(depth)) > 0
    force = finite(force, "force")
    if force < 0:
        raise InputError(f"force = {force:g}: must be >= 0")
    return _initial_contact(problem, force) if force > 0 else np.zeros(problem.shape, bool)


@dataclass(frozen=True)
class IndentResult:
    """Outcome of :func:`indent` (fields indexed ``[iy, ix]``, at the final depth)."""

    depth: float
    normal_force: float
    tangential_force: float  # F_x: zero for a surface symmetric in x
    events: list[Event]  # Event.dz is the depth of each event (Event.dx = 0)
    contact_counts: np.ndarray  # contact sites at every event
    stick_counts: np.ndarray  # stick sites at every event
    fz: np.ndarray
    fx: np.ndarray
    contact: np.ndarray
    stick: np.ndarray
    slip: np.ndarray  # slip direction (+1, -1) of slipping sites, 0 elsewhere
    converged: bool
    seconds: float
    solves: int
    method: str
    residual: float
    slip_law: str = "coulomb"
    message: str = ""
    #: with ``record_states=True``: (D_z, f_z, f_x, gap, contact, stick) at every event
    states: list | None = None

    @property
    def dz(self) -> np.ndarray:
        return np.array([e.dz for e in self.events])


def indent(
    problem: Problem,
    *,
    depth: float,
    lam: float = 0.2,
    slip_law: str = "coulomb",
    method: str = "auto",
    tol: float = 1e-12,
    max_iter: int = 20_000,
    max_events: int | None = None,
    reference: bool = False,
    record_states: bool = False,
) -> IndentResult:
    r"""Frictional indentation: the rigid surface approaches from first touch to ``depth``,
    with no tangential motion (:math:`D_x = 0`), under the coupled model
    (docs/theory/coupled.rst#coupled-indentation).

    Every site sticks where it touches (a bond holding the elastic point where it met the
    rigid surface), and the bonds fail by the slip law as the normal forces and the coupling
    load them: under ``"coulomb"`` they slip with :math:`f_x = \pm\lambda f_z` and stick
    again when their slip would reverse; under ``"break"`` they carry nothing after. The
    events are found exactly as in the pull, with the depth as the parameter: every force is
    affine in :math:`D_z` between events. This is the setting of Spence's frictional Hertz
    problem; on a profile that does not depend on y, on a grid periodic in y, it is the plane
    (cylinder) problem.

    Parameters
    ----------
    problem : Problem
    depth : float
        Final penetration :math:`D_z` from first touch.
    lam : float
        Local friction coefficient.
    slip_law : {"coulomb", "break"}
    method, tol, max_iter, reference, record_states
        As in :func:`couple`.
    max_events : int, optional
        Stop after this many events (default ``20 x overlap sites + 100``).

    Returns
    -------
    IndentResult
    """
    t0 = time.perf_counter()
    check_friction(lam, slip_law)
    depth = problem.check_depth(depth)
    if depth < 0:
        raise InputError(f"depth = {depth:g}: must be >= 0")
    solver, method = _make_solver(problem, method, reference, tol, max_iter)
    top = problem.base >= 0.0  # the highest pixels touch at D_z = 0
    limit = _event_limit(max_events, problem.overlap(depth) > 0)
    with blas_threads(1):
        st = _State(solver, problem.base, float(lam), top, depth=depth, gained="bonded",
                    slip_law=slip_law, tol=tol, drive="z")
        try:
            st.solve()
            path = _pull_events(st, limit, record_states, end=depth)
        except NumericalError as exc:
            raise NumericalError(f"coupled indentation: {exc}") from None
    D = path.events[-1].dz
    fz, fx, _ = st.at(D)
    _check_finite("coupled indentation", fz=fz, fx=fx)
    out = _Outcome.of(solver, st, path, method, tol)
    counts = np.array(path.counts, dtype=np.int64).reshape(-1, 2)
    return IndentResult(
        depth=float(D), normal_force=float(fz.sum()), tangential_force=float(fx.sum()),
        events=path.events, contact_counts=counts[:, 0], stick_counts=counts[:, 1],
        fz=fz, fx=fx, contact=st.C.copy(), stick=st.S.copy(),
        slip=np.where(st.C & ~st.S, st.sigma, 0.0).astype(np.int8), converged=out.converged,
        seconds=time.perf_counter() - t0, solves=solver.solves, method=out.method,
        residual=out.residual, slip_law=slip_law, message=out.message, states=path.states)


def squeeze_pull_coupled(
    heights: np.ndarray | Problem,
    *,
    depth: float | None = None,
    force: float | None = None,
    lam: float = 0.2,
    pull_control: str = "depth",
    gained: str = "unbonded",
    slip_law: str = "break",
    a: float = 1.0,
    E: float = 1.0,
    nu: float = 0.3,
    boundary: str = "open",
    periodic_kernel: str = "pixel",
    method: str = "auto",
    tol: float = 1e-12,
    max_iter: int = 20_000,
    max_events: int | None = None,
    fft: str = "auto",
    threads: int = 1,
    reference: bool = False,
    record_states: bool = False,
) -> CoupledResult:
    """:func:`couple` on a problem built from plain numbers (or given, ignoring ``a`` ...
    ``threads``)."""
    problem = heights if isinstance(heights, Problem) else Problem.from_arrays(
        heights, a=a, E=E, nu=nu, boundary=boundary, periodic_kernel=periodic_kernel, fft=fft,
        threads=threads)
    return couple(problem, depth=depth, force=force, lam=lam, pull_control=pull_control,
                  gained=gained, slip_law=slip_law, method=method, tol=tol, max_iter=max_iter,
                  max_events=max_events, reference=reference, record_states=record_states)
