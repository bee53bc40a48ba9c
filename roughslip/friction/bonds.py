r"""The bonds of a squeezed contact and what every decoupled pull method shares.

After the squeeze every contact site (:math:`f_z > 0`) is a bond; pulled by :math:`D_x`, the
stick set :math:`S` holds :math:`u_x = D_x` through :math:`G_{xx}[S,S]` (docs/theory/pull.rst).
:class:`Bonds` holds the sites, :math:`\lambda f_z`, and the tangential operator;
:func:`bond_inverse` the inverse of :math:`G_{xx}` on them, updated as bonds leave
(:class:`~roughslip.linalg.inverse.UpdatableInverse` in its lower-triangle layout);
:func:`certify` checks a tracked solution against the FFT operator with the package's one
iterative refinement; :class:`BreakCurve` accumulates a break sequence and its peak.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from roughslip.contact.squeeze import NormalResult
from roughslip.elastic.operators import ElasticOperator
from roughslip.elastic.tables import gather_pairs
from roughslip.errors import MemoryLimitError, NumericalError
from roughslip.friction.events import Curve, EventKind, argext, plane_direction
from roughslip.friction.result import (
    DecoupledDetails,
    PullResult,
    PullState,
    renamed,
    start_curve,
)
from roughslip.linalg.cg import cg
from roughslip.linalg.hierarchical import HierarchicalInverse
from roughslip.linalg.inverse import Tracked, UpdatableInverse
from roughslip.linalg.memory import available_bytes
from roughslip.linalg.restricted import Restricted
from roughslip.linalg.stick import SolverFactory, StickSolver


def __getattr__(name: str) -> type:
    """``SlipResult``, the result type of earlier versions (deprecated)."""
    if name == "SlipResult":
        return renamed(__name__, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def decoupled_result(b: Bonds, *, friction_force: float, curve: Curve, peak_event: int,
                     peak_fx: np.ndarray, peak_stick: np.ndarray, t0: float, method: str,
                     slip_law: str, converged: bool, residual: float = 0.0, solves: int = 0,
                     message: str = "", early_stopped: bool = False, precision: str = "",
                     peak_fy: np.ndarray | None = None) -> PullResult:
    """The :class:`~roughslip.friction.result.PullResult` of a decoupled pull of the bonds
    ``b``: the normal forces and the contact are the squeeze's (the pull does not move them),
    the start has every bond holding and no tangential force. ``peak_fy``: the y forces of
    the peak, in the model with both components (None in the x-only model)."""
    normal = b.normal
    stick0 = b.mask(np.arange(b.n))
    fy0 = None if peak_fy is None else np.zeros(b.shape)
    return PullResult(
        friction_force=friction_force, normal_force_at_peak=normal.normal_force,
        normal_force=normal.normal_force, curve=curve, peak_event=peak_event,
        peak=PullState(normal.fz, peak_fx, normal.contact, peak_stick, peak_fy),
        start=PullState(normal.fz, np.zeros(b.shape), normal.contact, stick0, fy0),
        converged=converged, seconds=time.perf_counter() - t0, method=method,
        slip_law=slip_law, residual=residual, solves=solves, message=message,
        details=DecoupledDetails(lam=b.lam, n_bonds=b.n,
                                 early_stopped=early_stopped, precision=precision,
                                 components="".join(b.components),
                                 direction=b.direction))


@dataclass(frozen=True)
class PullOptions:
    """The settings every pull method reads (validated by :func:`pull`).

    ``slip_law``, the law's name, follows ``law`` (earlier versions took the name; the law
    object is what the methods read)."""

    slip_law: str = ""
    tol: float = 1e-10
    early_stop: bool = True
    batch_size: int = 16
    block: int = 128
    max_iter: int = 10_000
    #: BLAS threads of the dense methods
    threads: int = 1
    #: the slip law, bound to its parameters (:meth:`roughslip.friction.laws.SlipLaw.bind`)
    law: object = None
    #: the pull method (:class:`roughslip.friction.pull.PullMethod`); its
    #: :attr:`~roughslip.friction.pull.PullMethod.solver` builds the stick solver
    method: object = None
    #: the precision of the stored inverse (``"double"`` or ``"single"``)
    precision: str = "double"
    #: the facets of the polygon inscribed in the Coulomb cone (the traction vector at
    #: :math:`\nu > 0`, :mod:`roughslip.friction.cone`)
    facets: int = 64

    def __post_init__(self) -> None:
        if self.law is not None:
            object.__setattr__(self, "slip_law", self.law.name)

    @property
    def method_name(self) -> str:
        """The pull method's name (``"inverse"`` when no method is given)."""
        return "inverse" if self.method is None else self.method.name

    def solver(self) -> SolverFactory:
        """The stick solver's factory (:class:`~roughslip.linalg.inverse.UpdatableInverse`
        when no method is given: the dense inverse)."""
        return UpdatableInverse if self.method is None else self.method.solver


#: the tangential models, by the name of ``pull.components``: the force components each bond
#: carries. ``"x"``, the report's model: :math:`f_x` alone, pulled along x, :math:`u_y` free;
#: ``"xy"``: the traction vector :math:`(f_x, f_y)`, which the half-space couples through
#: :math:`G_{xy}` (docs/theory/pull.rst#traction-vector)
TANGENTIAL_MODELS: dict[str, tuple[str, ...]] = {"x": ("x",), "xy": ("x", "y")}


def _kernel(a: str, b: str) -> str:
    """The kernel between components ``a`` (displacement) and ``b`` (force):
    :math:`G_{yx} = G_{xy}` on the pixel grid (both odd in x and in y)."""
    return "xy" if {a, b} == {"x", "y"} else a + b


class Bonds:
    r"""The bonded sites of a squeezed contact and the tangential operator on the grid.

    Each bond carries the force ``components`` (:data:`TANGENTIAL_MODELS`; ``k`` of them), and
    the *unknowns* of the pull are its bonds' components, unknown ``u`` being component
    ``u % k`` of the bond at position ``u // k``; with the x component alone an unknown is a
    bond position. The stick set holds :math:`\mathbf u_t = D\,\hat{\mathbf e}` with the
    drive's unit vector :math:`\hat{\mathbf e}` at the angle ``direction`` (degrees from x
    toward y; :attr:`drive`: its ``components``, :math:`(1)` in the report's model).
    """

    def __init__(self, normal: NormalResult, lam: float, threads: int | None = None,
                 components: tuple[str, ...] = ("x",), direction: float = 0.0) -> None:
        self.normal = normal
        self.problem = normal.problem
        self.grid = normal.grid
        self.shape = normal.grid.shape
        self.lam = lam
        self.sites = np.flatnonzero(normal.contact.ravel() & (normal.fz.ravel() > 0))
        self.n = int(self.sites.size)
        self.fz = normal.fz.ravel()[self.sites].astype(float)
        self.cap = lam * self.fz  # lambda f_z per bond
        self.components = tuple(components)
        self.k = len(self.components)
        #: the unknowns: k per bond
        self.size = self.n * self.k
        self.direction = float(direction)
        plane = plane_direction(self.direction)
        self.drive = np.array([plane[("x", "y").index(c)] for c in self.components])
        kernels = sorted({_kernel(a, b) for a in self.components for b in self.components},
                         key=("xx", "xy", "yy").index)
        op = self.problem.operator(*kernels)
        self.op: ElasticOperator = op if threads is None else op.with_threads(threads)
        self._tmp: np.ndarray | None = None

    @staticmethod
    def count(normal: NormalResult) -> int:
        """The number of bonds a squeeze leaves: its contact sites with :math:`f_z > 0`."""
        return int(np.count_nonzero(normal.contact.ravel() & (normal.fz.ravel() > 0)))

    def apply(self, v: np.ndarray, out: np.ndarray) -> np.ndarray:
        r"""The tangential displacements of the forces ``v`` on the grid: :math:`G_{xx} f_x`
        for the x component alone; with two, stacked fields ``[f_x, f_y]`` of shape
        ``(2, ny, nx)`` and :math:`u_a = \sum_b G_{ab} f_b`."""
        if self.k == 1:
            return self.op.apply("xx", v, out=out)
        if self.components == ("x", "y"):  # two forward and two backward FFTs
            self.op.apply_tangential(v[0], v[1], out[0], out[1])
            return out
        if self._tmp is None:
            self._tmp = np.empty(self.shape)
        tmp = self._tmp
        for a, ca in enumerate(self.components):
            self.op.apply(_kernel(ca, self.components[0]), v[0], out=out[a])
            for b in range(1, self.k):
                out[a] += self.op.apply(_kernel(ca, self.components[b]), v[b], out=tmp)
        return out

    def restricted(self, unknowns: np.ndarray | None = None) -> Restricted:
        """:math:`G_{tt}[S, S]` on the ``unknowns`` (all by default): :math:`G_{xx}` on bond
        positions with the x component alone. With several components its compressed vectors
        list the unknowns component by component (the C order of its ``(k, ny, nx)`` mask),
        not in the order of ``unknowns``: :meth:`product` and :meth:`solve_stick` take that
        order."""
        mask = self.unknown_mask(np.arange(self.size) if unknowns is None else unknowns)
        return Restricted(self.apply, mask)

    def unknown_mask(self, unknowns: np.ndarray) -> np.ndarray:
        """The ``unknowns`` as a mask of the fields :meth:`apply` acts on (the grid with the x
        component alone, ``(k, ny, nx)`` otherwise)."""
        if self.k == 1:
            return self.mask(unknowns)
        m = np.zeros((self.k, *self.shape), dtype=bool)
        bond, comp = np.divmod(np.asarray(unknowns, dtype=np.int64), self.k)
        m.reshape(self.k, -1)[comp, self.sites[bond]] = True
        return m

    def product(self, unknowns: np.ndarray, v: np.ndarray) -> np.ndarray:
        r""":math:`G_{tt}[S,S]\,v` for ``v`` on the ``unknowns`` (in their order), by the FFT
        operator (:math:`G_{xx}[S,S]` by :meth:`restricted` with the x component alone)."""
        if self.k == 1:
            return self.restricted(unknowns).matvec(v)
        u = self.apply(self.unknown_field(v, unknowns), np.empty((self.k, *self.shape)))
        bond, comp = np.divmod(np.asarray(unknowns, dtype=np.int64), self.k)
        return u.reshape(self.k, -1)[comp, self.sites[bond]]

    def solve_stick(self, unknowns: np.ndarray, x0: np.ndarray, tol: float, max_iter: int
                    ) -> np.ndarray:
        r""":math:`\varphi` on the stick ``unknowns`` (in their order) by CG on the FFT operator
        from ``x0``: :math:`G_{tt}[S,S]\varphi = \hat{\mathbf e}` (:meth:`drive_rows`)."""
        A = self.restricted(unknowns)
        if self.k == 1:
            res = cg(A, A.weights, x0=self.field(x0, unknowns), tol=tol, max_iter=max_iter)
            return A.gather(res.x)
        rhs = A.weights * self.drive[:, None, None]
        res = cg(A, rhs, x0=self.unknown_field(x0, unknowns), tol=tol, max_iter=max_iter)
        bond, comp = np.divmod(np.asarray(unknowns, dtype=np.int64), self.k)
        return res.x.reshape(self.k, -1)[comp, self.sites[bond]]

    def bond_values(self, x: np.ndarray) -> np.ndarray:
        r"""Per bond, from values on its ``k`` consecutive unknowns: the Euclidean norm
        :math:`|\mathbf x_i|` (the absolute value with the x component alone)."""
        return bond_norms(x, self.k)

    def along(self, x: np.ndarray) -> float:
        r""":math:`\hat{\mathbf e}\cdot\sum_i \mathbf x_i`, the sum of the values on the
        unknowns projected on the drive (the plain sum with the x component alone)."""
        if self.k == 1:
            return float(x.sum())
        return float(x.reshape(-1, self.k).sum(axis=0) @ self.drive)

    def unknown_field(self, values: np.ndarray, unknowns: np.ndarray) -> np.ndarray:
        """The field :meth:`apply` acts on with ``values`` at the ``unknowns``, zero
        elsewhere."""
        if self.k == 1:
            return self.field(values, unknowns)
        out = np.zeros((self.k, *self.shape))
        bond, comp = np.divmod(np.asarray(unknowns, dtype=np.int64), self.k)
        out.reshape(self.k, -1)[comp, self.sites[bond]] = values
        return out

    def drive_rows(self, unknowns: np.ndarray) -> np.ndarray | float:
        r"""The drive's component of each unknown: the right-hand side of
        :math:`G_{tt}[S,S]\varphi = \hat{\mathbf e}` (1.0 with the x component alone)."""
        if self.k == 1:
            return 1.0
        return self.drive[np.asarray(unknowns, dtype=np.int64) % self.k]

    def field(self, values: np.ndarray, positions: np.ndarray | None = None) -> np.ndarray:
        out = np.zeros(self.shape)
        sites = self.sites if positions is None else self.sites[positions]
        out.ravel()[sites] = values
        return out

    def points(self) -> np.ndarray:
        """The point ``(iy, ix)`` of each unknown (a bond's components share its site), for
        a compressed solver's cluster tree."""
        iy, ix = np.divmod(np.repeat(self.sites, self.k), self.shape[1])
        return np.column_stack([iy, ix]).astype(float)

    def mask(self, positions: np.ndarray) -> np.ndarray:
        m = np.zeros(self.shape, dtype=bool)
        m.ravel()[self.sites[positions]] = True
        return m

    def entries(self, i: np.ndarray, j: np.ndarray, order: str = "F", dtype: type = float
                ) -> np.ndarray:
        """:math:`G_{xx}` between the bonds at positions ``i`` and ``j`` (the assembler of
        :func:`bond_inverse`); a square block by columns (:meth:`dense_into`), in ``dtype``
        (the double-precision entries rounded once)."""
        if self.k > 1:
            return self._entries_components(np.asarray(i), np.asarray(j), order, dtype)
        if np.array_equal(i, j):
            return self.dense(i, order=order, dtype=dtype)
        T, _, off = self.op.tables.pair("xx")
        out = np.empty((len(i), len(j)), order=order, dtype=dtype)
        return gather_pairs(T.astype(out.dtype, copy=False), self._lin(i), self._lin(j), off,
                            out)

    def _entries_components(self, i: np.ndarray, j: np.ndarray, order: str, dtype: type
                            ) -> np.ndarray:
        r""":meth:`entries` between unknowns with several components: the block of
        :math:`G_{ab}` between the unknowns of components ``a`` and ``b``, for each pair."""
        out = np.empty((len(i), len(j)), order=order, dtype=dtype)
        bi, ci = np.divmod(i.astype(np.int64), self.k)
        bj, cj = np.divmod(j.astype(np.int64), self.k)
        lin = self._lin()
        for a, ca in enumerate(self.components):
            rows = np.flatnonzero(ci == a)
            for b, cb in enumerate(self.components):
                cols = np.flatnonzero(cj == b)
                T, _, off = self.op.tables.pair(_kernel(ca, cb))
                gather_pairs(T.astype(out.dtype, copy=False), lin[bi[rows]], lin[bj[cols]],
                             off, out, rows, cols)
        return out

    def _lin(self, positions: np.ndarray | None = None) -> np.ndarray:
        """The index of each bond's site in the pair table of :math:`G_{xx}`."""
        _, w, _ = self.op.tables.pair("xx")
        sites = self.sites if positions is None else self.sites[positions]
        iy, ix = np.divmod(sites, self.shape[1])
        return (iy * w + ix).astype(np.intp)

    def dense(self, positions: np.ndarray | None = None, order: str = "F",
              dtype: type = float) -> np.ndarray:
        """:math:`G_{xx}[S,S]` assembled from the closed-form kernel (in ``dtype``: no
        double-precision copy of the matrix is made); with several components, :math:`G_{tt}`
        on the unknowns ``positions``."""
        if self.k > 1:
            u = np.arange(self.size) if positions is None else np.asarray(positions)
            return self._entries_components(u, u, order, dtype)
        n = self.n if positions is None else len(positions)
        A = np.empty((n, n), order=order, dtype=dtype)
        return self.dense_into(A, positions)

    def dense_into(self, A: np.ndarray, positions: np.ndarray | None = None) -> np.ndarray:
        """Fill ``A`` with :math:`G_{xx}[S,S]` from the operator's pair table
        (:func:`~roughslip.elastic.tables.gather_pairs`). A float32 ``A`` gathers from the table
        rounded once to float32 (the same entries as rounding each gathered one)."""
        T, _, off = self.op.tables.pair("xx")
        lin = self._lin(positions)
        return gather_pairs(T.astype(A.dtype, copy=False), lin, lin, off, A)


def bond_norms(x: np.ndarray, k: int) -> np.ndarray:
    """The Euclidean norm of each run of ``k`` consecutive entries (a bond's components; the
    absolute value for ``k = 1``)."""
    if k == 1:
        return np.abs(x)
    return np.sqrt(np.square(x).reshape(-1, k).sum(axis=1))


def select(phi: np.ndarray, cap: np.ndarray, k: int = 1) -> tuple[int, float]:
    r"""Position of the next bond to break and the maximum ratio :math:`|\varphi|/(\lambda
    f_z)` (ties: :func:`~roughslip.friction.events.argext`). With ``k`` components per bond,
    ``phi`` and ``cap`` hold a bond's components on ``k`` consecutive entries, the ratio is
    :math:`|\boldsymbol\varphi_i|/(\lambda f_{z,i})` with the Euclidean norm, and the
    position is that of the bond's first entry."""
    if k > 1:
        j, m = select(bond_norms(phi, k), cap[::k])
        return j * k, m
    ratio = np.abs(phi) / cap
    m = float(ratio.max())
    if not math.isfinite(m):
        raise NumericalError("pull: non-finite tangential force ratio")
    return argext(ratio, None, "max"), m


class BreakCurve:
    """Accumulates the pull curve and the peak state."""

    def __init__(self, bonds: Bonds, early_stop: bool):
        self.b = bonds
        self.early_stop = early_stop
        self.dx: list[float] = []
        self.fx: list[float] = []
        self.site: list[int] = []
        self.best = -math.inf
        self.peak = 0
        self.peak_state: tuple[np.ndarray, np.ndarray, float] | None = None
        self.stopped = False

    def record(self, phi_sum: float, m: float, site_pos: int,
               stick: Callable[[], tuple[np.ndarray, np.ndarray]]) -> None:
        r"""Append one break: :math:`D_{x,\rm lim} = 1/m`, :math:`F_{x,\rm lim} =
        D_{x,\rm lim}\sum\varphi`.

        ``stick()`` returns the stick set (bond positions) and its :math:`\varphi`; it is
        called only when the step is a new peak."""
        dx = 1.0 / m
        flim = phi_sum * dx
        self.dx.append(dx)
        self.fx.append(flim)
        self.site.append(int(self.b.sites[site_pos]))
        if flim > self.best:
            self.best = flim
            self.peak = len(self.fx) - 1
            pos, phi = stick()
            self.peak_state = (pos, phi * dx, dx)

    def should_stop(self, cap_sum_after: float) -> bool:
        """Exact early stop: every later F_x,lim <= lambda * sum of f_z over the stick set."""
        if self.early_stop and cap_sum_after <= self.best:
            self.stopped = True
        return self.stopped

    def result(self, t0: float, method: str, *, converged: bool, slip_law: str = "break",
               residual: float = 0.0, solves: int = 0, message: str = "",
               precision: str = "") -> PullResult:
        """The pull's result: the break sequence from its start, and the peak state."""
        b = self.b
        fy = None if b.k == 1 else np.zeros(b.shape)
        if self.peak_state is None:
            stick, fx = np.zeros(b.shape, bool), np.zeros(b.shape)
        elif b.k == 1:
            pos, f, _ = self.peak_state
            stick, fx = b.mask(pos), b.field(f, pos)
        else:  # the unknowns of each bond, its components in order
            pos, f, _ = self.peak_state
            bonds = pos[:: b.k] // b.k
            stick, fx, fy = b.mask(bonds), b.field(f[:: b.k], bonds), b.field(f[1 :: b.k], bonds)
        n = len(self.fx)
        curve = Curve.empty() if b.n == 0 else start_curve(
            np.array(self.dx), np.array(self.fx), (EventKind.BREAK,) * n,
            np.array(self.site, dtype=np.int64), b.normal.normal_force, b.normal.depth)
        return decoupled_result(
            b, friction_force=max(self.best, 0.0), curve=curve,
            peak_event=self.peak + 1 if n else 0, peak_fx=fx, peak_stick=stick, t0=t0,
            method=method, slip_law=slip_law, converged=converged, residual=residual,
            solves=solves, message=message, early_stopped=self.stopped, precision=precision,
            peak_fy=fy)


def shrinking_only(ids: np.ndarray) -> np.ndarray:
    """The right-hand side of added unknowns for a tracked solution of a pull's inverse: there
    are none, the stick set only shrinks (a bond that sticks again refactorises)."""
    raise AssertionError("the stick set of a pull only shrinks")  # pragma: no cover


#: the pull's precisions by the dtype of the stored inverse
PRECISION_NAMES = {np.dtype(np.float64): "double", np.dtype(np.float32): "single"}


def bond_inverse(b: Bonds, block: int, threads: int, dtype: type = np.float64,
                 solver: SolverFactory = UpdatableInverse) -> StickSolver:
    r"""The inverse of :math:`G_{xx}` on all bonds, held by the stick solver ``solver``
    (:class:`~roughslip.linalg.stick.StickSolver`; unknown ``i``: bond position ``i``; with
    both tangential components, :math:`G_{tt}` on the unknowns of :class:`Bonds`), for a
    set that only shrinks: for the dense inverse, the lower-triangle layout of
    :class:`~roughslip.linalg.inverse.UpdatableInverse`, one :math:`n \times n` matrix of
    ``dtype`` (float64, or float32 for the single-precision pull), compacted in place as bonds
    leave.

    Raises :class:`MemoryLimitError` before allocating when it does not fit
    (:func:`~roughslip.linalg.inverse.inverse_bytes`), and :class:`NumericalError` when
    :math:`G_{xx}` on the bonds is not positive definite.
    """
    n = b.size
    dtype = np.dtype(dtype)
    k = {"per_point": b.k} if b.k > 1 else {}  # the components of a bond share its point
    need = solver.memory_bytes(n, block=block, itemsize=dtype.itemsize, **k)
    what = "G_xx" if b.k == 1 else f"G_tt ({b.k} components)"

    def room(m: int) -> bool:
        if need > available_bytes():
            half = solver.memory_bytes(n, block=block, itemsize=4, **k)
            other = ("pull precision 'single' (half the memory), "
                     if dtype.itemsize == 8 and half < need and half <= available_bytes()
                     else "")
            if (solver is not HierarchicalInverse
                    and HierarchicalInverse.memory_bytes(n, block=block, itemsize=4, **k)
                    <= available_bytes()):
                other += "pull method 'hierarchical' (compressed, exact), "
            last = ("pull method 'cg' (exact, matrix-free) or 'batch' (approximate)"
                    if b.k == 1 else "pull.components = 'x' (a quarter of the unknowns' "
                    "memory)")
            raise MemoryLimitError(
                f"the inverse of {what} on {b.n} bonds ({solver.kind}, "
                f"{PRECISION_NAMES[dtype]} precision) needs ~{need / 2**30:.2f} GiB but "
                f"{available_bytes() / 2**30:.2f} GiB are available; use {other}{last}")
        return True

    inv = solver(b.entries, n, room=room, threads=threads, block=block, lower=True,
                 dtype=dtype, points=b.points())
    try:
        inv.factor(np.arange(n))
    except NumericalError as exc:
        raise NumericalError(f"{what} on the stick set: {exc}") from None
    return inv


def track(inv: StickSolver, name: str, rhs: np.ndarray) -> np.ndarray:
    """Keep the solution for ``rhs`` (on the rows) current through the removals."""
    x = inv.apply(rhs)
    inv.tracked[name] = Tracked(rhs.copy(), x, shrinking_only)
    return x


class BondRows:
    r""":math:`\lambda f_z` on the rows of a bond inverse (:func:`bond_inverse`), infinite once
    the bond has left the stick set, and the count of rows left: compacted with the
    inverse. With several components a bond's :math:`\lambda f_z` is on each of its rows."""

    def __init__(self, b: Bonds) -> None:
        self.cap = b.cap.copy() if b.k == 1 else np.repeat(b.cap, b.k)
        self.alive = b.size

    def remove(self, inv: StickSolver, row: int, column: np.ndarray | None = None,
               held: dict[str, float] | None = None) -> None:
        """Remove the bond of ``row`` from the inverse (its tracked solutions follow, with the
        values ``held``, :meth:`~roughslip.linalg.stick.StickSolver.remove`); ``column``: the
        current column of the inverse at ``row``, when the caller has it."""
        if not inv.remove(int(inv.ids[row]), column, held):
            raise NumericalError("lost positive definiteness in the inverse update")
        self.cap[row] = math.inf
        self.alive -= 1

    def fold(self, inv: StickSolver, dead: float = 0.25) -> bool:
        """Once ``block`` removals are pending, fold them in and compact when a share
        ``dead`` of the rows are dead; True when it did (the moment to certify)."""
        if inv.k < inv.block:
            return False
        inv.flush()
        if self.alive < (1 - dead) * inv.m:
            self.cap = self.cap[inv.live]
            inv.compact()
        return True


def stick_residual(b: Bonds, pos: np.ndarray, v: np.ndarray, rhs: np.ndarray | float
                   ) -> tuple[np.ndarray, float]:
    r"""Residual :math:`r = \mathrm{rhs} - G_{xx}[S,S]\,v` on the stick set ``pos`` (bond
    positions; the unknowns of :class:`Bonds` with both components, :math:`G_{tt}`), by the
    FFT operator, and its norm relative to that of ``rhs``."""
    u = b.product(pos, v)
    rhs = np.broadcast_to(np.asarray(rhs, dtype=float), u.shape)
    r = rhs - u
    return r, float(np.linalg.norm(r)) / max(float(np.linalg.norm(rhs)), 1e-300)


def tracked_rhs(b: Bonds, pos: np.ndarray, load: np.ndarray | None,
                shift: np.ndarray | None = None) -> np.ndarray | float:
    r"""The right-hand side on the stick set ``pos`` of :math:`\varphi` (``load`` None: the
    drive's component) or of :math:`\psi`, :math:`(G_{xx} f_L)_S` for the grid field ``load``,
    less ``shift`` (per bond position: the offsets of bonds that stuck again)."""
    rhs = (b.drive_rows(pos) if load is None
           else b.apply(load, np.empty(b.shape)).ravel()[b.sites[pos]])
    if shift is not None and np.any(shift[pos]):
        rhs = rhs - shift[pos]
    return rhs


def certify(b: Bonds, inv: StickSolver, name: str, load: np.ndarray | None, tol: float,
            shift: np.ndarray | None = None) -> tuple[float, int]:
    r"""Check the tracked solution ``name`` against the FFT operator, refining it if needed
    (:meth:`~roughslip.linalg.inverse.UpdatableInverse.refine`, at most 3 times).

    It must satisfy :math:`(G_{xx} v)_i = 1` on the live bonds (:math:`\varphi`, ``load``
    None) or :math:`(G_{xx} v)_i = (G_{xx} f_L)_i` for the grid field ``load``
    :math:`= f_L` of fixed slip forces (:math:`\psi`), minus ``shift`` (per bond position:
    the offsets of bonds that stuck again). Returns the relative residual and the number of
    refinements.
    """
    t, live = inv.tracked[name], inv.live
    pos = inv.ids[live]
    rhs = tracked_rhs(b, pos, load, shift)

    def residual(x: np.ndarray) -> tuple[np.ndarray, float]:
        r, res = stick_residual(b, pos, x[live], rhs)
        full = np.zeros(inv.m)
        full[live] = r
        return full, res

    t.x, res, nref = inv.refine(t.x, residual, tol, 3)
    return res, nref
