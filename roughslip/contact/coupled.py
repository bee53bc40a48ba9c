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

Solvers (registered in :data:`SOLVERS`): ``"dense"`` assembles the reduced block from the
closed-form kernels and keeps its inverse up to date (for up to a few thousand contact sites);
``"cg"`` runs conjugate gradients (:func:`roughslip.linalg.cg.cg`) on the restricted FFT block
operator (:meth:`roughslip.contact.problem.Problem.restricted_block`). Both follow the same
event logic.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy import linalg
from scipy.linalg import blas

from roughslip.contact.methods import Registry
from roughslip.contact.problem import Problem, finite
from roughslip.errors import InputError, MemoryLimitError, NumericalError
from roughslip.linalg import lapack64
from roughslip.linalg.cg import cg
from roughslip.linalg.memory import available_bytes
from roughslip.linalg.threads import blas_threads

TIE = 1e-9


@dataclass(frozen=True)
class Event:
    """One recorded state of the pull."""

    dx: float
    fx: float  # total tangential force F_x
    fz: float  # total normal force F_z at the same D_x
    kind: str  # "start", "slip+", "slip-", "lost", "gained", "release" (at D_x = 0)
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
    seconds: float
    solves: int
    method: str
    message: str = ""
    #: worst relative residual of the block solves (``cg``); NaN when not measured (``dense``)
    residual: float = math.nan
    #: D_z after the squeeze (given, or found under load control)
    depth: float = math.nan
    #: what the pull holds: ``"depth"`` (D_z fixed, the report's pull) or ``"force"``
    pull_control: str = "depth"
    #: with ``record_states=True``: (D_x, f_z, f_x, gap, contact, stick) at every event
    states: list | None = None

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
    """A linear solver for the reduced block on the contact set C and the stick set S."""

    solves: int

    def prepare(self, C: np.ndarray, S: np.ndarray) -> None:
        """Set the unknowns: f_z on C, f_x on S."""

    def solve(self, rz: np.ndarray, rx: np.ndarray, key: str) -> tuple[np.ndarray, np.ndarray]:
        """Grid fields (f_z, f_x) for right-hand sides on the grid; ``key`` names the
        right-hand side, for warm starts."""

    def solve_many(self, rhs: list[tuple[np.ndarray, np.ndarray, str]]
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
        """:meth:`solve` for several ``(rz, rx, key)`` at once."""

    def displacement_z(self, fz: np.ndarray, fx: np.ndarray) -> np.ndarray:
        """u_z on the whole grid."""

    def displacement_x(self, fz: np.ndarray, fx: np.ndarray, site: int) -> float:
        """u_x at one site (flat index)."""

    def residual(self) -> float:
        """The worst relative residual of the solves so far (NaN when not measured)."""


#: the coupled block solvers, by name (``method`` of :func:`couple`)
SOLVERS: Registry[type] = Registry("coupled solver")


@SOLVERS.register("dense", "the reduced block's inverse, updated at every event")
class _Dense:
    r"""Reduced block assembled from the operator's kernel tables, solved directly.

    The explicit inverse :math:`M` of the block on the current unknowns is updated when the
    contact or stick set changes. Removing an unknown :math:`k` is the rank-one downdate
    :math:`M - c\,c^T/c_k` with :math:`c` the current column :math:`k` (Sherman-Morrison);
    the scaled columns :math:`c/\sqrt{c_k}` are kept in :math:`U` and applied lazily, as
    :math:`(M - UU^T)\,b`, so a removal costs :math:`O(m\,|U|)`, and every ``block`` removals
    one rank-``block`` product updates :math:`M` (BLAS-3). Adding an unknown is a bordered
    inverse, :math:`O(m^2)`. Every ``refresh`` updates, or when many unknowns change at once,
    the block is factorised afresh. With ``reference=True`` every state is factorised from
    scratch and displacements are dense sums (no FFT at all): the test reference.
    """

    refresh = 200
    block = 64

    def __init__(self, problem: Problem, *, reference: bool = False, threads: int = 1,
                 **_: object) -> None:
        # dense solves get the BLAS threads; the FFTs beside them one thread
        op = problem.operator("zz", "zx", "xx").with_threads(1)
        self.ny, self.nx = op.shape
        self.op = op
        self.tables = {c: op.tables.pair(c) for c in ("zz", "zx", "xx")}
        self.reference = reference
        self.solves = 0
        self.M: np.ndarray | None = None
        self.U: np.ndarray | None = None  # pending downdates: the inverse is M - U U^T
        self.k = 0
        self._set_keys([])
        self.updates = 0

    def _set_keys(self, keys: list[tuple[str, int]]) -> None:
        """The unknowns in matrix order (all live), and what :meth:`solve` derives from them."""
        self.keys = list(keys)
        self.pos = {k: i for i, k in enumerate(self.keys)}
        self.live = np.ones(len(self.keys), dtype=bool)  # rows of M still in the system
        self.idx = np.array([i for _, i in self.keys], dtype=np.int64)  # grid sites
        self.isz = np.array([t == "z" for t, _ in self.keys], dtype=bool)

    def _block(self, ci: np.ndarray, cj: np.ndarray, comp: str) -> np.ndarray:
        T, w, off = self.tables[comp]
        iy, ix = np.divmod(ci, self.nx)
        jy, jx = np.divmod(cj, self.nx)
        lin_i, lin_j = iy * w + ix, jy * w + jx
        return T[lin_i[:, None] - lin_j[None, :] + off]

    def _entries(self, keys_i: list[tuple[str, int]], keys_j: list[tuple[str, int]]
                 ) -> np.ndarray:
        """Block entries between two lists of unknowns (u_a at i due to f_b at j)."""
        out = np.empty((len(keys_i), len(keys_j)))
        for a in ("z", "x"):
            ri = [k for k, (t, _) in enumerate(keys_i) if t == a]
            si = np.array([keys_i[k][1] for k in ri], dtype=np.int64)
            for b in ("z", "x"):
                cj = [k for k, (t, _) in enumerate(keys_j) if t == b]
                if not ri or not cj:
                    continue
                sj = np.array([keys_j[k][1] for k in cj], dtype=np.int64)
                if a + b == "xz":  # G_xz(i - j) = G_zx(j - i)
                    blk = self._block(sj, si, "zx").T
                else:
                    blk = self._block(si, sj, a + b)
                out[np.ix_(ri, cj)] = blk
        return out

    def _factor(self, keys: list[tuple[str, int]]) -> None:
        """The inverse of the block on ``keys`` afresh: Cholesky and LAPACK's inverse from it
        (potrf + potri, in place: a third of the work of solving for the identity)."""
        A = np.asfortranarray(self._entries(keys, keys))
        try:
            lapack64.cholesky_inverse(A)
        except NumericalError:
            raise NumericalError("coupled model: the coupled block on the contact and stick "
                                 "sets is not positive definite") from None
        n, b = A.shape[0], 512
        for j in range(0, n, b):  # mirror the lower triangle, a panel at a time
            A[j:j + b, j + b:] = A[j + b:, j:j + b].T
            blk = A[j:j + b, j:j + b]
            blk[np.triu_indices(blk.shape[0], 1)] = blk.T[np.triu_indices(blk.shape[0], 1)]
        self.M = A
        self.U = np.empty((n, self.block), order="F")
        self.k = 0
        self._set_keys(keys)
        self.updates = 0

    def _flush(self) -> None:
        """Apply the pending downdates: M -= U U^T (one GEMM)."""
        if self.k:
            U = self.U[:, : self.k]
            out = blas.dgemm(-1.0, U, U, beta=1.0, c=self.M, trans_b=1, overwrite_c=1)
            if not np.shares_memory(out, self.M):
                self.M = np.asfortranarray(out)
            dead = ~self.live
            self.M[dead, :] = 0.0
            self.M[:, dead] = 0.0
            self.k = 0

    def _remove(self, r: int) -> bool:
        """Downdate for removing unknown ``r`` (lazily); False when it is not positive."""
        c = self.M[:, r].copy()
        if self.k:
            c -= self.U[:, : self.k] @ self.U[r, : self.k]
        cr = float(c[r])
        if not cr > 0:
            return False
        self.U[:, self.k] = c * (1.0 / math.sqrt(cr))
        self.k += 1
        self.live[r] = False
        if self.k == self.block:
            self._flush()
        return True

    def prepare(self, C: np.ndarray, S: np.ndarray) -> None:
        want = [("z", int(i)) for i in np.flatnonzero(C)] + \
            [("x", int(i)) for i in np.flatnonzero(S)]
        wset = set(want)
        # before the first factorisation there are no keys: everything is new
        gone = [k for k, ok in zip(self.keys, self.live, strict=True) if ok and k not in wset]
        new = [k for k in want if k not in self.pos or not self.live[self.pos[k]]]
        m = int(self.live.sum())
        if (self.reference or self.M is None or len(gone) + len(new) > max(4, m // 3)
                or self.updates + len(gone) + len(new) > self.refresh):
            self._factor(want)
            return
        for key in gone:  # lazy rank-one downdates (Sherman-Morrison), one unknown each
            if not self._remove(self.pos[key]):
                self._factor(want)
                return
            self.updates += 1
        if new:  # bordered inverse on the live unknowns, then compact
            self._flush()
            keep = np.flatnonzero(self.live)
            keys = [self.keys[i] for i in keep]
            Mk = self.M[np.ix_(keep, keep)]
            B = self._entries(keys, new)
            D = self._entries(new, new)
            MB = Mk @ B
            Sc = D - B.T @ MB
            try:  # the Schur complement of an SPD block is SPD: Cholesky checks and inverts
                Si = linalg.cho_solve(linalg.cho_factor(Sc, lower=True, check_finite=False),
                                      np.eye(len(new)), check_finite=False)
            except linalg.LinAlgError:
                self._factor(want)
                return
            k1, k2 = len(keys), len(new)
            M2 = np.empty((k1 + k2, k1 + k2), order="F")
            M2[:k1, :k1] = Mk + MB @ Si @ MB.T
            M2[:k1, k1:] = -MB @ Si
            M2[k1:, :k1] = M2[:k1, k1:].T
            M2[k1:, k1:] = Si
            self.M = M2
            self.U = np.empty((k1 + k2, self.block), order="F")
            self._set_keys(keys + list(new))
            self.updates += k2
        elif (~self.live).sum() > 0.25 * self.live.size:
            self._flush()
            keep = np.flatnonzero(self.live)
            self.M = np.asfortranarray(self.M[np.ix_(keep, keep)])
            self.U = np.empty((keep.size, self.block), order="F")
            self._set_keys([self.keys[i] for i in keep])

    def residual(self) -> float:
        return math.nan  # direct solves: not measured

    def reset(self) -> None:
        """Drop the updated inverse: the next :meth:`prepare` factorises afresh."""
        self.M = None

    def solve(self, rz: np.ndarray, rx: np.ndarray, key: str = "") -> tuple[np.ndarray,
                                                                             np.ndarray]:
        """Grid fields (fz, fx) for right-hand sides given on the grid (used on C and S)."""
        return self.solve_many([(rz, rx, key)])[0]

    def solve_many(self, rhs: list[tuple[np.ndarray, np.ndarray, str]]
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
        """:meth:`solve` for several right-hand sides with one matrix product (the inverse is
        read from memory once)."""
        self.solves += len(rhs)
        idx, isz = self.idx, self.isz
        B = np.column_stack([np.where(isz, rz.ravel()[idx], rx.ravel()[idx]) * self.live
                             for rz, rx, _ in rhs])
        sol = self.M @ B
        if self.k:
            U = self.U[:, : self.k]
            sol -= U @ (U.T @ B)
        live_z, live_x = isz & self.live, ~isz & self.live
        out = []
        for k, (rz, _, _) in enumerate(rhs):
            fz, fx = np.zeros(rz.shape), np.zeros(rz.shape)
            fz.ravel()[idx[live_z]] = sol[live_z, k]
            fx.ravel()[idx[live_x]] = sol[live_x, k]
            out.append((fz, fx))
        return out

    def displacement_z(self, fz: np.ndarray, fx: np.ndarray) -> np.ndarray:
        if self.reference:
            n = self.ny * self.nx
            allc = np.arange(n)
            cz, cx = np.flatnonzero(fz.ravel()), np.flatnonzero(fx.ravel())
            u = self._block(allc, cz, "zz") @ fz.ravel()[cz]
            u += self._block(allc, cx, "zx") @ fx.ravel()[cx]
            return u.reshape(fz.shape)
        return self.op.apply_block(fz, fx)[0]

    def displacement_x(self, fz: np.ndarray, fx: np.ndarray, site: int) -> float:
        if self.reference:  # u_x(i) = sum_j G_xz(i - j) f_z(j) + G_xx(i - j) f_x(j)
            i = np.array([site])
            cz, cx = np.flatnonzero(fz.ravel()), np.flatnonzero(fx.ravel())
            return float(-(self._block(i, cz, "zx") @ fz.ravel()[cz])[0]
                         + (self._block(i, cx, "xx") @ fx.ravel()[cx])[0])
        return float(self.op.apply_block(fz, fx)[1].ravel()[site])


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
        self.prev: dict[str, np.ndarray] = {}

    def prepare(self, C: np.ndarray, S: np.ndarray) -> None:
        self.A = self.problem.restricted_block(C, S)

    def residual(self) -> float:
        return self.worst

    def solve(self, rz: np.ndarray, rx: np.ndarray, key: str = "") -> tuple[np.ndarray,
                                                                             np.ndarray]:
        self.solves += 1
        r = cg(self.A, np.stack([rz, rx]), x0=self.prev.get(key), tol=self.tol,
               max_iter=self.max_iter)
        self.worst = max(self.worst, r.residual)
        self.prev[key] = r.x
        return r.x[0], r.x[1]

    def solve_many(self, rhs: list[tuple[np.ndarray, np.ndarray, str]]
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
        return [self.solve(rz, rx, key) for rz, rx, key in rhs]

    def displacement_z(self, fz: np.ndarray, fx: np.ndarray) -> np.ndarray:
        return self.op.apply_block(fz, fx)[0]

    def displacement_x(self, fz: np.ndarray, fx: np.ndarray, site: int) -> float:
        return float(self.op.apply_block(fz, fx)[1].ravel()[site])


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
                 gained: str = "unbonded"):
        self.solver, self.base, self.lam = solver, base, lam
        self.gained = gained
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

    def hold_depth(self, depth: float) -> None:
        """Switch to displacement control at ``depth`` (then call :meth:`solve`)."""
        self.depth, self.force = depth, None

    def hold_force(self, force: float) -> None:
        """Switch to load control at ``force`` (then call :meth:`solve`)."""
        self.depth, self.force = None, force

    def solve(self) -> None:
        """Solve the current sets. A non-finite solution from an updated inverse (round-off
        grown through many updates) is recomputed from a fresh factorisation; one that stays
        non-finite is an error, never a silent NaN."""
        self._solve()
        if self._finite():
            return
        reset = getattr(self.solver, "reset", None)
        if reset is not None:
            reset()
            self._solve()
            if self._finite():
                return
        raise NumericalError("non-finite forces in the solve of the contact and stick sets")

    def _finite(self) -> bool:
        return all(np.all(np.isfinite(a)) for a in (*self.f0, *self.f1, self.g0, self.g1))

    def _solve(self) -> None:
        s = self.solver
        s.prepare(self.C, self.S)
        stick = bool(self.S.any())
        if self.force is None:
            ubar = self.base + self.depth
            rhs = [(ubar, self.offset, "0")] + ([(self.zero, self.ones, "1")] if stick else [])
            sols = s.solve_many(rhs)
            self.f0 = sols[0]
            self.f1 = sols[1] if stick else (self.zero, self.zero)
            self.d0, self.d1 = self.depth, 0.0
            self.g0 = s.displacement_z(*self.f0) - ubar
            self.g1 = s.displacement_z(*self.f1)
            return
        rhs = [(self.base, self.offset, "b"), (self.ones, self.zero, "d")]
        sols = s.solve_many(rhs + ([(self.zero, self.ones, "1")] if stick else []))
        fb, fd = sols[0], sols[1]
        f1 = sols[2] if stick else (self.zero, self.zero)
        sd = float(fd[0].sum())
        if not sd > 0:
            raise NumericalError("load control: the contact set carries no force under a "
                                 "uniform approach (no contact left)")
        self.d0 = (self.force - float(fb[0].sum())) / sd
        self.d1 = -float(f1[0].sum()) / sd
        self.f0 = (fb[0] + self.d0 * fd[0], fb[1] + self.d0 * fd[1])
        self.f1 = (f1[0] + self.d1 * fd[0], f1[1] + self.d1 * fd[1])
        self.g0 = s.displacement_z(*self.f0) - self.base - self.d0
        self.g1 = s.displacement_z(*self.f1) - self.d1
        self.scale_g = max(self.scale_g, float(np.max(self.base)) + self.d0)

    def depth_at(self, D: float) -> float:
        """:math:`D_z` at pull displacement ``D``."""
        return self.d0 + self.d1 * D

    def at(self, D: float):
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
        elif kind == "gained":
            C[j] = True
            if self.pulling and self.gained == "bonded":
                # a new bond holds the elastic point where it is: no jump in any force
                fz, fx, _ = self.at(D)
                self.offset.ravel()[j] = self.solver.displacement_x(fz, fx, j) - D
                S[j] = True
        else:
            S[j] = False

    def interval(self) -> tuple[float, float, str, int]:
        r"""The displacements at which this state is admissible, ``[lo, hi]``, and the event
        (kind, flat index) that ends it at ``hi``.

        Every constraint is affine, :math:`a + bD \ge 0`: :math:`f_z \ge 0` on C,
        :math:`g \ge 0` off C, :math:`\lambda f_z \mp f_x \ge 0` on S
        (docs/theory/coupled.rst#coupled).
        Ties at ``hi`` go to the lowest flat index, then to the kinds in that order.
        """
        (fz0, fx0), (fz1, fx1) = self.f0, self.f1
        lam = self.lam
        fs = max(float(np.abs(fz0).max()), float(np.abs(fz1).max()) * self.Dscale,
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
            flat = m & (np.abs(b) * self.Dscale <= tiny)
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
    close = np.abs(vals - ext) <= TIE * max(abs(ext), np.finfo(float).tiny)
    return int(np.flatnonzero(close & mask.ravel())[0])


#: dense solver's peak memory per squared unknown count: measured 4.0-4.9 x 8 m^2 bytes
#: (tracemalloc, m = 1 380 and 3 248 unknowns), with a margin
DENSE_BYTES_PER_UNKNOWN2 = 48


def dense_memory_bytes(sites: int) -> int:
    """Peak memory of ``method="dense"`` for ``sites`` geometric-overlap sites (bytes): the
    reduced block starts with every site in contact and bonded, ``m = 2 sites`` unknowns."""
    m = 2 * int(sites)
    return DENSE_BYTES_PER_UNKNOWN2 * m * m


def _choose_solver(method: str, sites: int) -> tuple[str, str]:
    """The solver for ``sites`` geometric-overlap sites, and a note when ``auto`` fell back;
    :class:`MemoryLimitError` when ``dense`` is asked for and does not fit."""
    if method != "auto":
        SOLVERS.get(method)
    need, have = dense_memory_bytes(sites), available_bytes()
    if method == "auto":
        if sites <= 4000 and need <= have:
            return "dense", ""
        note = ("" if sites > 4000 else
                f"auto chose cg: the dense solver would need ~{need / 2**30:.2f} GiB, "
                f"{have / 2**30:.2f} GiB available; ")
        return "cg", note
    if method == "dense" and need > have:
        raise MemoryLimitError(
            f"coupled model, method 'dense': needs ~{need / 2**30:.2f} GiB for "
            f"{sites} overlap sites but {have / 2**30:.2f} GiB are available; use "
            "method 'cg' (matrix-free) or 'auto', a smaller depth or grid, or raise "
            "execution.memory_limit_gb")
    return method, ""


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
    an overloaded bond is released.
    """
    while True:
        st.solve()
        fz, _, _ = st.at(0.0)
        fscale = max(float(np.abs(fz).max()), np.finfo(float).tiny)
        neg = st.C & (fz < -TIE * fscale)
        if not neg.any():
            break
        st.C &= ~neg
        st.S &= ~neg
    seen: set[bytes] = set()
    while (v := st.violation(0.0)) is not None:
        st.apply(*v)
        key = st.C.tobytes() + st.S.tobytes()
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


def _pull_events(st: _State, limit: int, record_states: bool) -> _Path:
    """Follow the events from D_x = 0 until no bond is left (module docstring)."""
    path = _Path([], [] if record_states else None, _Snapshot.of(st, 0.0))

    def record(D: float, kind: str, site: int) -> None:
        F_x, F_z = st.totals(D)
        path.events.append(Event(D, F_x, F_z, kind, site, st.depth_at(D)))
        if path.states is not None:
            fz, fx, g = st.at(D)
            path.states.append((D, fz.copy(), fx.copy(), g.copy(), st.C.copy(), st.S.copy()))

    record(0.0, "start", -1)
    st.pulling = True
    D = 0.0
    first = True
    while st.S.any():
        if len(path.events) + path.transient > limit:
            path.message = f"stopped after {limit} events"
            break
        lo, hi, kind, j = st.interval()
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
        jumps) and breaks by the same law. Contacts gained while the squeeze corrects its
        sets, at :math:`D_x = 0`, always enter unbonded.
    method : str
        ``"auto"`` or a name from :data:`SOLVERS`: ``auto`` is ``dense`` up to 4000
        geometric-overlap sites when its memory (:func:`dense_memory_bytes`) fits the budget,
        ``cg`` otherwise. ``dense`` refuses with :class:`MemoryLimitError` when it does not
        fit.
    tol : float
        Relative residual of the CG solves (``method="cg"``).
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
    geo = _check_couple(problem, depth, force, lam, pull_control, gained)
    depth = None if depth is None else finite(depth, "depth")
    force = None if force is None else finite(force, "force")
    method, note = _choose_solver(method, int(geo.sum()))
    if not geo.any():
        z = np.zeros(problem.shape)
        return CoupledResult(
            friction_force=0.0, normal_force_at_peak=0.0, peak_dx=0.0, events=[],
            normal_force=0.0, contact_area=0.0, released=0, fz0=z, fx0=z, contact0=geo,
            stick0=geo, fz_peak=z, fx_peak=z, stick_peak=geo, contact_peak=geo,
            converged=True, seconds=time.perf_counter() - t0, solves=0, method=method,
            message="no overlap: no contact", depth=0.0 if depth is None else depth,
            pull_control=pull_control)
    solver = SOLVERS.get(method)(problem, reference=reference, tol=tol, max_iter=max_iter,
                                 threads=problem.threads)
    limit = max_events if max_events is not None else 20 * int(geo.sum()) + 100
    with blas_threads(problem.threads if method == "dense" else 1):
        st = _State(solver, problem.base, float(lam), geo, depth=depth, force=force,
                    gained=gained)
        try:
            released = _squeeze_bonded(st)
            start = _Snapshot.of(st, 0.0)
            squeezed_depth = st.depth_at(0.0)
            # the pull holds what it is asked to: switch the control if the squeeze used the
            # other one (the state at D_x = 0 is the same)
            if pull_control == "depth" and force is not None:
                st.hold_depth(squeezed_depth)
                st.solve()
            elif pull_control == "force" and depth is not None:
                st.hold_force(start.fz_total)
                st.solve()
            path = _pull_events(st, limit, record_states)
        except NumericalError as exc:
            raise NumericalError(f"coupled model: {exc}") from None
    residual = solver.residual()
    message = path.message
    if not message and residual > 10 * tol:
        message = f"worst CG residual {residual:.2e}"
    peak = path.peak
    for name, arr in (("fz", start.fz), ("fx", start.fx), ("fz at peak", peak.fz)):
        if not np.all(np.isfinite(arr)):
            raise NumericalError(f"coupled model: non-finite {name}")
    return CoupledResult(
        friction_force=float(peak.fx_total), normal_force_at_peak=float(peak.fz_total),
        peak_dx=float(peak.dx), events=path.events, normal_force=float(start.fz.sum()),
        contact_area=float(start.contact.sum()) / start.contact.size, released=released,
        fz0=start.fz, fx0=start.fx, contact0=start.contact, stick0=start.stick,
        fz_peak=peak.fz, fx_peak=peak.fx, stick_peak=peak.stick, contact_peak=peak.contact,
        converged=not message, seconds=time.perf_counter() - t0, solves=solver.solves,
        method=method, residual=residual,
        message=note + (message or f"{len(path.events)} events, {path.transient} transient "
                        "state(s)"),
        states=path.states, depth=float(squeezed_depth), pull_control=pull_control,
    )


def _check_couple(problem: Problem, depth: float | None, force: float | None, lam: float,
                  pull_control: str, gained: str) -> np.ndarray:
    """Validate the arguments of :func:`couple`; returns the starting contact set."""
    if not (isinstance(lam, int | float) and math.isfinite(lam) and lam > 0):
        raise InputError(f"lam = {lam!r}: must be a finite number > 0")
    if (depth is None) == (force is None):
        raise InputError("give exactly one of depth and force")
    if pull_control not in PULL_CONTROLS:
        raise InputError(f"pull_control = {pull_control!r}: must be 'depth' or 'force'")
    if gained not in GAINED_RULES:
        raise InputError(f"gained = {gained!r}: must be 'unbonded' or 'bonded'")
    if depth is not None:
        return problem.overlap(finite(depth, "depth")) > 0
    force = finite(force, "force")
    if force < 0:
        raise InputError(f"force = {force:g}: must be >= 0")
    return _initial_contact(problem, force) if force > 0 else np.zeros(problem.shape, bool)


def squeeze_pull_coupled(
    heights: np.ndarray | Problem,
    *,
    depth: float | None = None,
    force: float | None = None,
    lam: float = 0.2,
    pull_control: str = "depth",
    gained: str = "unbonded",
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
                  gained=gained, method=method, tol=tol, max_iter=max_iter,
                  max_events=max_events, reference=reference, record_states=record_states)
