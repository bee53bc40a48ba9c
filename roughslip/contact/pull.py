r"""Horizontal pull and slip of a squeezed contact, decoupled model (docs/theory/pull.rst#break-law;
[Report2003] §4.6-4.7).

After the squeeze every contact site (``f_z > 0``) is a bond. The rigid surface is pulled by
:math:`D_x`: bonded (stick) sites have :math:`u_x = D_x`, other sites carry no tangential force,
so on the stick set :math:`S`

.. math:: G_{xx}[S,S]\,\varphi = 1_S, \qquad f_x = D_x\,\varphi, \qquad F_x = D_x \sum_S \varphi.

Break law
    The report's model, corrected by erratum T17 (docs/theory/errata.rst#erratum-t17) and
    erratum T18 (docs/theory/errata.rst#erratum-t18).
    The bond with the largest :math:`|f_x|/(\lambda f_z)` breaks next; it breaks at
    :math:`D_{x,\rm lim} = 1/\max_i |\varphi_i|/(\lambda f_{z,i})` and pull force
    :math:`F_{x,\rm lim} = D_{x,\rm lim} \sum_S\varphi`; its force drops to zero and the stick set
    shrinks by one site ("repeat from 3"). The static friction force is
    :math:`F_{\rm friction} = \max F_{x,\rm lim}`. Ties (within a relative 1e-9) go to the lowest
    flat index. Because every later :math:`F_{x,\rm lim} \le \lambda \sum_S f_z`, the sequence may
    stop, exactly, once that bound falls below the best value found (``early_stop``).

Coulomb law
    A slipping site carries :math:`f_x = \pm\lambda f_z` instead of 0. Between events all forces
    are affine in :math:`D_x`; the next stick site to reach its bound slips (see
    :func:`pull`). For a Hertz contact this is Cattaneo–Mindlin
    (docs/methods.rst#cattaneo-mindlin).

Methods (all exact except ``"batch"``)
    ``"literal"``: the report's algorithm done literally, one CG solve from zero per break, all
    bonds. The reference; slow.
    ``"inverse"``: the inverse of :math:`G_{xx}[S,S]`, updated by delayed blocks of rank-one
    removals applied as one symmetric rank-k product (BLAS-3); :math:`\varphi` is updated in
    :math:`O(n)` per break and certified against the FFT operator after every block. Needs
    one :math:`n \times n` matrix of doubles, compacted in place as bonds break (checked
    before starting, see :func:`inverse_memory_bytes`).
    ``"cg"``: matrix-free; per break a warm-started CG solve of the correction, with the early
    stop. Memory :math:`O(N^2)`.
    ``"batch"``: approximate; breaks the ``batch_size`` sites with the largest ratios per solve.
    Biased low, with no error estimate: its error is a staircase in the batch size
    (docs/methods.rst#estimates-against-truth).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from roughslip.contact.estimates import REFINE_TOL as SQUEEZE_REFINE_TOL
from roughslip.contact.estimates import squeeze_correction
from roughslip.contact.methods import Registry
from roughslip.contact.squeeze import NormalResult
from roughslip.elastic.operators import ElasticOperator
from roughslip.errors import InputError, MemoryLimitError, NumericalError
from roughslip.linalg import lapack64
from roughslip.linalg.cg import CGResult, cg
from roughslip.linalg.memory import available_bytes
from roughslip.linalg.restricted import Restricted
from roughslip.linalg.threads import blas_threads

#: slip laws: what a site carries once it leaves the stick set
SLIP_LAWS = ("break", "coulomb")
TIE_TOL = 1e-9


@dataclass(frozen=True)
class SlipResult:
    r"""Outcome of a pull.

    Attributes
    ----------
    friction_force : float
        :math:`F_{\rm friction} = \max F_{x,\rm lim}` (break law) or :math:`\lambda F_n`
        (Coulomb law: full sliding).
    peak_index : int
        Index of the maximum in the pull curve.
    dx_lim, fx_lim : ndarray
        The pull curve: the displacement and pull force at which each bond breaks (break law),
        or at which each site starts to slip (Coulomb law), in order.
    broken_site : ndarray of int
        Flat indices (``iy * nx + ix``) of the sites, in the same order.
    stick_at_peak : ndarray of bool
        The stick set just before the peak break.
    fx_at_peak : ndarray
        Tangential pixel forces at the peak (:math:`D_x = D_{x,\rm lim}` of the peak state).
    converged : bool
        All solves met their tolerance (and, for ``"inverse"``, every certification passed).
    method : str
        The method actually used (``"auto"`` resolved).
    error_estimate : float
        Estimated relative error of ``friction_force``, NaN when not estimated. With
        ``pull(..., estimate_error=True)``: ``solve_error_estimate + normal_error_estimate``,
        the errors of the pull's own solves and of the squeeze's normal forces it starts
        from. Within a factor 3.2 of the true error on every verify scene. The approximate
        ``"batch"`` method has none (NaN): its error is a staircase in the batch size that no
        cheap comparison estimates.
    solve_error_estimate : float
        The pull's own part: :func:`refinement_estimate` (one step of iterative refinement
        on the peak state) for the break law, at the rounding level for ``"inverse"``; 0 for
        the Coulomb law, whose friction force :math:`\sum_i s_i\lambda f_{z,i}` does not
        depend on the tangential solves.
    normal_error_estimate : float
        The squeeze's part, :func:`normal_share` (how the estimated error of the normal
        forces moves the friction force).
    error_bound : float
        With ``estimate_error=True``: :math:`\hat\kappa\,\rho`, the condition estimate
        times the worst relative residual ``residual`` (see :func:`bond_spectrum`), an
        *estimate of a bound* on the relative error of the tangential forces. On the verify
        scenes it is never below the error of the friction force and up to
        :math:`7\cdot10^6` times above it; NaN otherwise.
    condition : float
        With ``estimate_error=True``: :math:`\hat\kappa`, the Lanczos estimate of the
        condition number of :math:`G_{xx}` on the initial bonds (the exact value bounds that
        of every later stick set); NaN otherwise.
    """

    friction_force: float
    peak_index: int
    dx_lim: np.ndarray
    fx_lim: np.ndarray
    broken_site: np.ndarray
    stick_at_peak: np.ndarray
    fx_at_peak: np.ndarray
    converged: bool
    seconds: float
    method: str
    slip_law: str = "break"
    lam: float = 0.2
    error_estimate: float = math.nan
    n_bonds: int = 0
    steps: int = 0
    early_stopped: bool = False
    solves: int = 0
    residual: float = 0.0
    message: str = ""
    normal_force: float = 0.0
    condition: float = math.nan
    error_bound: float = math.nan
    solve_error_estimate: float = math.nan
    normal_error_estimate: float = math.nan

    @property
    def peak_dx(self) -> float:
        """Pull displacement at the peak."""
        return float(self.dx_lim[self.peak_index]) if self.dx_lim.size else 0.0


@dataclass(frozen=True)
class PullOptions:
    """The settings every pull method reads (validated by :func:`pull`)."""

    slip_law: str = "break"
    tol: float = 1e-10
    early_stop: bool = True
    batch_size: int = 16
    block: int = 128
    max_iter: int = 10_000


@dataclass(frozen=True)
class PullMethod:
    """A pull method: ``run(bonds, options, t0) -> SlipResult``.

    Attributes
    ----------
    exact : bool
        Gives the exact pull curve (up to the solver tolerance).
    dense : bool
        Works on an n x n matrix: BLAS gets the threads, and the FFTs one thread.
    laws : tuple of str
        The slip laws it implements.
    """

    run: Callable[..., SlipResult] | None
    exact: bool
    dense: bool
    laws: tuple[str, ...] = ("break",)


#: the pull methods, by name (the configuration's ``pull.method``)
METHODS: Registry[PullMethod] = Registry("pull method")


# ----------------------------------------------------------------------------------------------
# Problem setup shared by the methods
# ----------------------------------------------------------------------------------------------


class _Bonds:
    """The bonded sites of a squeezed contact and the tangential operator on the grid."""

    def __init__(self, normal: NormalResult, lam: float, threads: int | None = None):
        self.normal = normal
        self.problem = normal.problem
        self.grid = normal.grid
        self.shape = normal.grid.shape
        self.lam = lam
        self.sites = np.flatnonzero(normal.contact.ravel() & (normal.fz.ravel() > 0))
        self.n = int(self.sites.size)
        self.fz = normal.fz.ravel()[self.sites].astype(float)
        self.cap = lam * self.fz  # lambda f_z per bond
        op = self.problem.operator("xx")
        self.op: ElasticOperator = op if threads is None else op.with_threads(threads)

    def apply(self, v: np.ndarray, out: np.ndarray) -> np.ndarray:
        return self.op.apply("xx", v, out=out)

    def restricted(self, positions: np.ndarray | None = None) -> Restricted:
        """:math:`G_{xx}[S, S]` on the bonds at ``positions`` (all bonds by default)."""
        mask = self.mask(np.arange(self.n) if positions is None else positions)
        return Restricted(self.apply, mask)

    def field(self, values: np.ndarray, positions: np.ndarray | None = None) -> np.ndarray:
        out = np.zeros(self.shape)
        sites = self.sites if positions is None else self.sites[positions]
        out.ravel()[sites] = values
        return out

    def mask(self, positions: np.ndarray) -> np.ndarray:
        m = np.zeros(self.shape, dtype=bool)
        m.ravel()[self.sites[positions]] = True
        return m

    def dense(self, positions: np.ndarray | None = None, order: str = "F") -> np.ndarray:
        """:math:`G_{xx}[S,S]` assembled from the closed-form kernel."""
        n = self.n if positions is None else len(positions)
        A = np.empty((n, n), order=order)
        return self.dense_into(A, positions)

    def dense_into(self, A: np.ndarray, positions: np.ndarray | None = None) -> np.ndarray:
        """Fill the Fortran-ordered ``A`` with :math:`G_{xx}[S,S]`, one column at a time.

        The operator's pair table gives one linear index per pair of sites (open or periodic);
        gathering a column at a time keeps the index vector and the table in cache (six
        times faster than panels of columns).
        """
        nx = self.shape[1]
        T, w, off = self.op.tables.pair("xx")
        sites = self.sites if positions is None else self.sites[positions]
        iy, ix = np.divmod(sites, nx)
        lin = (iy * w + ix).astype(np.intp)
        for c in range(sites.size):
            A[:, c] = T[lin + (off - lin[c])]
        return A


def _select(phi: np.ndarray, cap: np.ndarray) -> tuple[int, float]:
    """Position of the next bond to break and the maximum ratio (ties: lowest index)."""
    ratio = np.abs(phi) / cap
    m = float(ratio.max())
    if not math.isfinite(m):
        raise NumericalError("pull: non-finite tangential force ratio")
    j = int(np.flatnonzero(ratio >= m * (1.0 - TIE_TOL))[0])
    return j, m


class _Curve:
    """Accumulates the pull curve and the peak state."""

    def __init__(self, bonds: _Bonds, early_stop: bool):
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
        """Append one break: :math:`D_{x,lim} = 1/m`, :math:`F_{x,lim} = D_{x,lim}\\sum\varphi`.

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

    def result(self, t0: float, method: str, **kw) -> SlipResult:
        b = self.b
        if self.peak_state is None:
            stick, fx = np.zeros(b.shape, bool), np.zeros(b.shape)
        else:
            pos, f, _ = self.peak_state
            stick, fx = b.mask(pos), b.field(f, pos)
        return SlipResult(
            friction_force=max(self.best, 0.0), peak_index=self.peak,
            dx_lim=np.array(self.dx), fx_lim=np.array(self.fx),
            broken_site=np.array(self.site, dtype=np.int64), stick_at_peak=stick,
            fx_at_peak=fx, seconds=time.perf_counter() - t0, method=method, lam=b.lam,
            n_bonds=b.n, steps=len(self.fx), early_stopped=self.stopped,
            normal_force=b.normal.normal_force, **kw,
        )


# ----------------------------------------------------------------------------------------------
# Break law: the methods
# ----------------------------------------------------------------------------------------------


def _solve_phi(b: _Bonds, alive_pos: np.ndarray, tol: float, x0: np.ndarray | None,
               max_iter: int) -> tuple[np.ndarray, CGResult]:
    r""":math:`\varphi` on the stick set: :math:`G_{xx}[S,S]\varphi = 1_S` by CG."""
    A = b.restricted(alive_pos)
    x0f = None if x0 is None else b.field(x0, alive_pos)
    r = cg(A, A.weights, x0=x0f, tol=tol, max_iter=max_iter)
    return A.gather(r.x), r


def _break_literal(b: _Bonds, opt: PullOptions, t0: float) -> SlipResult:
    """The report's algorithm: one CG solve from zero per break, every bond."""
    return _break_solves(b, opt, t0, warm=False)


def _break_cg(b: _Bonds, opt: PullOptions, t0: float) -> SlipResult:
    """Matrix-free exact: one warm-started CG solve per break, with the early stop."""
    return _break_solves(b, opt, t0, warm=True)


def _break_solves(b: _Bonds, opt: PullOptions, t0: float, *, warm: bool) -> SlipResult:
    """One CG solve per break (cold from zero, or warm from the previous solution)."""
    tol, max_iter = opt.tol, opt.max_iter
    method = "cg" if warm else "literal"
    curve = _Curve(b, opt.early_stop and warm)
    alive = np.arange(b.n)
    phi = None
    ok, solves, iters, worst = True, 0, 0, 0.0
    cap_sum = float(b.cap.sum())
    while alive.size:
        phi, r = _solve_phi(b, alive, tol, phi if warm else None, max_iter)
        solves += 1
        iters += r.iterations
        worst = max(worst, r.residual)
        ok &= r.converged
        j, m = _select(phi, b.cap[alive])
        curve.record(float(phi.sum()), m, alive[j], lambda a=alive, p=phi: (a.copy(), p))
        cap_sum -= float(b.cap[alive[j]])
        if curve.should_stop(cap_sum):
            break
        alive = np.delete(alive, j)
        phi = np.delete(phi, j)
    return curve.result(t0, method, converged=bool(ok), solves=solves, residual=worst,
                        message=f"{solves} CG solves, {iters} iterations")


def inverse_memory_bytes(n: int, block: int = 128) -> int:
    """Peak memory of the ``"inverse"`` method for ``n`` bonds (bytes): one n x n matrix,
    compacted in place, plus O(n block) work arrays."""
    return int(8 * n * n + 8 * n * (3 * block + 64))


def _compact(buf: np.ndarray, n_old: int, keep: np.ndarray) -> np.ndarray:
    """Gather rows/columns ``keep`` of the Fortran ``n_old x n_old`` matrix held in ``buf``
    into a Fortran ``k x k`` matrix at the start of the same buffer (lower triangle).

    New column ``c`` starts at ``c k <= keep[c] n_old``, the start of its source column, and
    ends before the next source column, so a forward sweep never overwrites unread data.
    """
    k = keep.size
    for c in range(k):
        src = int(keep[c])
        col = buf[src * n_old + keep[c:]]  # lower part of the source column (a copy)
        buf[c * k + c : c * k + k] = col
    return buf[: k * k].reshape((k, k), order="F")


class _InverseSweep:
    r"""The inverse of :math:`G_{xx}` on a shrinking set of bonds, with blocked updates.

    Removing site :math:`j` changes the inverse :math:`C = G_{SS}^{-1}` by the rank-one term
    :math:`-c\,c^T/c_j` (Sherman–Morrison), :math:`c` the column of :math:`j`; a solution
    :math:`v = C r` for a fixed right-hand side becomes :math:`v - c\,v_j/c_j`. The scaled
    columns :math:`c/\sqrt{c_j}` of the last ``block`` removals are kept in :math:`U`, so the
    column of the current inverse is the stored one minus :math:`U U_j^T` (:math:`O(nk)`).
    :meth:`flush` applies :math:`B \leftarrow B - UU^T` as one symmetric rank-k product
    (lower triangle, in place) and compacts dead rows away in place: the memory stays at one
    ``n x n`` matrix. Vectors registered in :attr:`v` are compacted along.
    """

    def __init__(self, b: _Bonds, block: int):
        n = b.n
        need = inverse_memory_bytes(n, block)
        if need > available_bytes():
            raise MemoryLimitError(
                f"the inverse of G_xx on {n} bonds needs ~{need / 2**30:.1f} GiB but "
                f"{available_bytes() / 2**30:.1f} GiB are available; use pull method 'cg' "
                "(exact, matrix-free) or 'batch' (approximate)")
        lapack64.check_size(n)
        self.b = b
        self.block = block
        self.buf = np.empty(n * n)
        B = self.buf.reshape((n, n), order="F")
        b.dense_into(B)
        try:
            lapack64.cholesky_inverse(B)  # in place, 64-bit indexing where available
        except NumericalError as exc:
            raise NumericalError(f"G_xx on the stick set: {exc}") from None
        self.B = B
        self.U = np.empty((n, block), order="F")
        self.k = 0
        self.n_alive = n
        #: per-row vectors, compacted with the matrix; "pos" is the bond position of each row
        #: and "cap" is lambda f_z, set to inf when a bond leaves the set
        self.v: dict[str, np.ndarray] = {"pos": np.arange(n), "cap": b.cap.copy()}

    @property
    def nb(self) -> int:
        return self.B.shape[0]

    def alive(self) -> np.ndarray:
        return np.isfinite(self.v["cap"])

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Current inverse times ``x`` (dead rows of ``x`` must be zero)."""
        y = lapack64.symv(self.B, x)
        if self.k:
            U = self.U[: self.nb, : self.k]
            y -= U @ (U.T @ x)
        return y

    def remove(self, j: int) -> np.ndarray:
        """Remove row ``j``; returns the column :math:`c` of the inverse before the removal."""
        B, nb, k = self.B, self.nb, self.k
        c = np.empty(nb)
        c[:j] = B[j, :j]
        c[j:] = B[j:, j]
        if k:
            c -= self.U[:nb, :k] @ self.U[j, :k]
        cj = c[j]
        if not cj > 0:
            raise NumericalError("lost positive definiteness in the inverse update")
        self.U[:nb, k] = c * (1.0 / math.sqrt(cj))
        self.k += 1
        self.v["cap"][j] = math.inf
        self.n_alive -= 1
        return c

    def full(self) -> bool:
        return self.k == self.block

    def flush(self) -> None:
        """Apply the pending removals to the stored inverse; compact when worthwhile."""
        if self.k:
            lapack64.syrk_update(self.B, self.U[: self.nb, : self.k], -1.0)
            self.k = 0
        if self.n_alive < 0.75 * self.nb:
            keep = np.flatnonzero(self.alive())
            self.B = _compact(self.buf, self.nb, keep)
            self.v = {name: vec[keep] for name, vec in self.v.items()}


def _break_inverse(b: _Bonds, opt: PullOptions, t0: float) -> SlipResult:
    """Exact break law with :class:`_InverseSweep`: :math:`O(n)` per break plus blocked
    BLAS-3 updates; :math:`\varphi` is certified against the FFT operator after each block."""
    tol, block = opt.tol, opt.block
    curve = _Curve(b, opt.early_stop)
    sw = _InverseSweep(b, block)
    sw.v["phi"] = sw.apply(np.ones(b.n))
    cap_sum = float(b.cap.sum())
    worst, refinements, ok = 0.0, 0, True
    while sw.n_alive:
        phi, cap, pos = sw.v["phi"], sw.v["cap"], sw.v["pos"]
        j, m = _select(phi, cap)
        live = np.isfinite(cap)
        curve.record(float(phi.sum()), m, pos[j],
                     lambda p=pos, f=phi, lv=live: (p[lv], f[lv]))
        cap_sum -= float(cap[j])
        if curve.should_stop(cap_sum) or sw.n_alive == 1:
            break
        c = sw.remove(j)
        phi -= c * (phi[j] / c[j])
        phi[j] = 0.0
        if sw.full():
            sw.flush()
            res, nref = _certify(b, sw, "phi", None, tol)
            worst, refinements = max(worst, res), refinements + nref
            ok &= res <= tol
    if curve.peak_state is not None:  # the state that gives the friction force, certified
        pos, f, dx = curve.peak_state
        _, res = _stick_residual(b, pos, f / dx, 1.0)
        worst, ok = max(worst, res), ok and res <= tol
    return curve.result(t0, "inverse", converged=bool(ok), residual=worst,
                        solves=refinements,
                        message=f"{b.n} bonds, block {block}, {refinements} refinements")


def _stick_residual(b: _Bonds, pos: np.ndarray, v: np.ndarray, rhs: np.ndarray | float
                    ) -> tuple[np.ndarray, float]:
    r"""Residual :math:`r = \mathrm{rhs} - G_{xx}[S,S]\,v` on the stick set ``pos`` (bond
    positions), by the FFT operator, and its norm relative to that of ``rhs``."""
    u = b.restricted(pos).matvec(v)
    rhs = np.broadcast_to(np.asarray(rhs, dtype=float), u.shape)
    r = rhs - u
    return r, float(np.linalg.norm(r)) / max(float(np.linalg.norm(rhs)), 1e-300)


def _certify(b: _Bonds, sw: _InverseSweep, name: str, load: np.ndarray | None, tol: float
             ) -> tuple[float, int]:
    r"""Check a tracked solution against the FFT operator, refining it if needed.

    ``v = sw.v[name]`` must satisfy :math:`(G_{xx} v)_i = 1` on the live sites
    (:math:`\varphi`, ``load`` None) or :math:`(G_{xx} v)_i = (G_{xx} f_L)_i` for the grid field
    ``load`` :math:`= f_L` of fixed slip forces (:math:`\psi`). Returns the relative residual
    and the number of refinements.
    """
    v, live = sw.v[name], sw.alive()
    pos = sw.v["pos"][live]
    rhs = 1.0 if load is None else b.apply(load, np.empty(b.shape)).ravel()[b.sites[pos]]
    nref = 0
    while True:
        r, res = _stick_residual(b, pos, v[live], rhs)
        if res <= tol or nref >= 3:
            return res, nref
        full = np.zeros(sw.nb)
        full[live] = r
        v[live] += sw.apply(full)[live]
        nref += 1


def _break_batch(b: _Bonds, opt: PullOptions, t0: float) -> SlipResult:
    """Approximate: break the ``batch_size`` largest-ratio bonds per solve (biased low).

    It has no error estimate (``error_estimate`` is NaN). Its error is a staircase in the
    batch size, not a smooth function of it: on the rough verify scenes one size gives the
    exact friction force and the next -18 %, so no comparison of batch sizes estimates it
    (docs/methods.rst#estimates-against-truth).
    """
    res = _batch_pass(b, opt, t0, opt.batch_size)
    return replace(res, error_estimate=math.nan,
                   message=res.message + "; approximate, no error estimate")


def _batch_pass(b: _Bonds, opt: PullOptions, t0: float, size: int) -> SlipResult:
    """One batch pass with ``size`` bonds broken per solve."""
    tol, max_iter = opt.tol, opt.max_iter
    curve = _Curve(b, opt.early_stop)
    alive = np.arange(b.n)
    phi = None
    ok, solves, worst = True, 0, 0.0
    cap_sum = float(b.cap.sum())
    while alive.size:
        phi, r = _solve_phi(b, alive, tol, phi, max_iter)
        solves += 1
        worst = max(worst, r.residual)
        ok &= r.converged
        j, m = _select(phi, b.cap[alive])
        curve.record(float(phi.sum()), m, alive[j], lambda a=alive, p=phi: (a.copy(), p))
        ratio = np.abs(phi) / b.cap[alive]
        order = np.argsort(-ratio, kind="stable")[:size]
        cap_sum -= float(b.cap[alive[order]].sum())
        if curve.should_stop(cap_sum):
            break
        keep = np.ones(alive.size, bool)
        keep[order] = False
        alive, phi = alive[keep], phi[keep]
    return curve.result(t0, "batch", converged=bool(ok), solves=solves, residual=worst,
                        message=f"{solves} CG solves, {size} bonds per solve")


# ----------------------------------------------------------------------------------------------
# Coulomb law
# ----------------------------------------------------------------------------------------------


def _coulomb(b: _Bonds, opt: PullOptions, t0: float) -> SlipResult:
    r"""Event-driven Coulomb slip: the exact piecewise-linear :math:`F_x(D_x)` to full sliding.

    With stick set :math:`S` and slip set :math:`L` carrying :math:`f_x = s\,\lambda f_z`
    (:math:`s = \pm 1`, monotonic loading, no re-sticking), the stick forces are
    :math:`f_S = D\,\varphi - \psi` with :math:`\varphi = G_{SS}^{-1}1` and
    :math:`\psi = G_{SS}^{-1}G_{SL}f_L`. The next stick site to reach :math:`\pm\lambda f_z`
    slips; if that happens below the current :math:`D` it slips at once (an avalanche). When
    site :math:`k` moves to :math:`L`, :math:`\varphi \leftarrow \varphi - c\varphi_k/c_k`
    and :math:`\psi \leftarrow \psi - c(\psi_k + s_k\lambda f_{z,k})/c_k`
    (:class:`_InverseSweep`). Both are certified against the FFT operator after each block.
    """
    n, tol = b.n, opt.tol
    sw = _InverseSweep(b, opt.block)
    sw.v["phi"] = sw.apply(np.ones(n))
    sw.v["psi"] = np.zeros(n)
    sign = np.zeros(n)  # slip direction per bond position
    dx, fx, sites = [], [], []
    D, slip_sum = 0.0, 0.0
    worst, refinements, ok = 0.0, 0, True
    while sw.n_alive:
        phi, psi, cap, pos = sw.v["phi"], sw.v["psi"], sw.v["cap"], sw.v["pos"]
        with np.errstate(divide="ignore", invalid="ignore"):
            d_pos = np.where(phi > 0, (cap + psi) / phi, np.inf)
            d_neg = np.where(phi < 0, (psi - cap) / phi, np.inf)
        d_pos[~np.isfinite(cap)] = np.inf
        d_neg[~np.isfinite(cap)] = np.inf
        dk = np.minimum(d_pos, d_neg)
        k = int(np.argmin(dk))
        if not math.isfinite(float(dk[k])):
            raise NumericalError("Coulomb pull: no stick site can reach its bound")
        D = max(D, float(dk[k]))
        s_k = 1.0 if d_pos[k] <= d_neg[k] else -1.0
        F = D * float(phi.sum()) - float(psi.sum()) + slip_sum
        dx.append(D)
        fx.append(F)
        sites.append(int(b.sites[pos[k]]))
        capk = float(cap[k])
        sign[pos[k]] = s_k
        slip_sum += s_k * capk
        if sw.n_alive == 1:
            break
        c = sw.remove(k)
        phi -= c * (phi[k] / c[k])
        psi -= c * ((psi[k] + s_k * capk) / c[k])
        phi[k] = psi[k] = 0.0
        if sw.full():
            sw.flush()
            r1, n1 = _certify(b, sw, "phi", None, tol)
            r2, n2 = _certify(b, sw, "psi", b.field(sign * b.cap), tol)
            worst, refinements = max(worst, r1, r2), refinements + n1 + n2
            ok &= max(r1, r2) <= tol
    total = float((sign * b.cap).sum())
    return SlipResult(
        friction_force=total, peak_index=len(fx) - 1, dx_lim=np.array(dx),
        fx_lim=np.array(fx), broken_site=np.array(sites, dtype=np.int64),
        stick_at_peak=np.zeros(b.shape, bool), fx_at_peak=b.field(sign * b.cap),
        converged=bool(ok), seconds=time.perf_counter() - t0, method="inverse",
        slip_law="coulomb", lam=b.lam, n_bonds=n, steps=len(fx), residual=worst,
        solves=refinements, normal_force=b.normal.normal_force,
        message="exact event sequence to full sliding",
    )


def coulomb_force_at(result: SlipResult, dx: float | np.ndarray) -> np.ndarray:
    """Pull force :math:`Q(D_x)` on the exact piecewise-linear Coulomb curve.

    Before the first slip event :math:`Q = K D_x` with the full-stick stiffness.
    """
    if result.slip_law != "coulomb":
        raise InputError("coulomb_force_at needs a Coulomb-law result")
    xs = np.concatenate([[0.0], result.dx_lim])
    ys = np.concatenate([[0.0], result.fx_lim])
    return np.interp(dx, xs, ys, right=result.friction_force)


#: relative tolerance of the correction solve in :func:`refinement_estimate` (the squeeze's
#: correction in :func:`normal_share` has its own, ``SQUEEZE_REFINE_TOL``)
REFINE_TOL = 1e-2


def _peak_force(phi: np.ndarray, cap: np.ndarray) -> float:
    r""":math:`F_{x,\rm lim} = \sum_S\varphi \,/\, \max_i |\varphi_i|/(\lambda f_{z,i})`."""
    return float(phi.sum()) / float(np.max(np.abs(phi) / cap))


def refinement_estimate(normal: NormalResult, result: SlipResult, *,
                        tol: float = REFINE_TOL) -> float:
    r"""A-posteriori estimate of the relative error of a break-law friction force.

    At the peak the stick set :math:`S` carries :math:`\varphi` with
    :math:`G_{xx}[S,S]\varphi \approx 1_S`, and the friction force is
    :math:`F = \sum_S\varphi / \max_i |\varphi_i|/(\lambda f_{z,i})` (module docstring).
    One step of iterative refinement (Higham, *Accuracy and Stability of Numerical
    Algorithms*, 2nd ed. 2002, ch. 12): the residual :math:`r = 1_S - G_{xx}[S,S]\varphi`
    by the FFT operator, the correction
    :math:`\delta = G_{xx}[S,S]^{-1} r` by CG to the relative residual ``tol``, and

    .. math:: \hat e = \frac{|F(\varphi) - F(\varphi + \delta)|}{F(\varphi + \delta)}.

    What it is
        An *estimate*, first-order accurate: :math:`\varphi + \delta` differs from the exact
        solution by at most :math:`\kappa\,` ``tol`` times :math:`\|\delta\|`, so
        :math:`\hat e` is the true error of the peak state up to that fraction. It does not see
        a wrong choice of peak state (a break order changed by the solver's error) by
        itself, but such a change moves the friction force by about as much as the error
        of the states: on 90 pulls of 9 rough scenes (N = 32-96, methods ``literal`` and
        ``cg``, tolerances 1e-3 to 1e-10; ``scripts/estimate_check.py``), 25 of them with a
        break order other than the exact one, the estimate was 0.49-1.74 times the true
        error wherever that exceeded 1e-13. With ``"inverse"`` both lie at the rounding
        level (below 3e-15).

        It is the error of the pull *given* the normal forces :math:`f_z`: the squeeze's
        error enters the friction force through :math:`\lambda f_z` and is not in it
        (:func:`normal_share` estimates that part).

    Returns
    -------
    float
        :math:`\hat e`; 0 when the peak state has no stick sites.
    """
    if result.slip_law != "break":
        raise InputError("refinement_estimate needs a break-law result")
    stick = np.asarray(result.stick_at_peak, dtype=bool)
    if not stick.any() or not result.peak_dx > 0:
        return 0.0
    A = normal.problem.restricted("xx", stick)
    phi = A.gather(result.fx_at_peak) / result.peak_dx
    cap = result.lam * A.gather(normal.fz)
    r = 1.0 - A.matvec(phi)
    delta = A.gather(cg(A, A.scatter(r), tol=tol).x)
    refined = _peak_force(phi + delta, cap)
    return abs(_peak_force(phi, cap) - refined) / refined


def normal_share(normal: NormalResult, result: SlipResult, *,
                 tol: float = SQUEEZE_REFINE_TOL) -> float:
    r"""Estimated relative error of a friction force caused by the error of the squeeze's
    normal forces, signed: :math:`(F - F^{\rm exact})/F^{\rm exact}`.

    :math:`\delta \approx f_z^{\rm exact} - f_z` is
    :func:`~roughslip.contact.estimates.squeeze_correction`. The stick forces
    :math:`\varphi` depend on the stick set only, so with the same break sequence:

    - break law: :math:`F = \lambda f_{z,k}\sum_S\varphi/|\varphi_k|` with :math:`k` the
      bond that breaks at the peak, and the share is
      :math:`-\delta_k / (f_{z,k} + \delta_k)`;
    - Coulomb law: :math:`F = \lambda\sum_i s_i f_{z,i}`, and the share is
      :math:`-\sum_i s_i\delta_i / \sum_i s_i (f_{z,i} + \delta_i)`.

    What it is
        An *estimate*, first order in the squeeze's error, for the same contact and stick
        sets. On 32 pulls of 4 rough scenes (N = 32 and 64, squeeze tolerances 1e-4 to 1e-10,
        both laws, ``inverse`` at 1e-10) it was 0.999 to 1.01 times the true error against a
        squeeze and pull at 1e-13, also where the break order differed. A site wrongly in or
        out of contact is not seen.
    """
    delta = squeeze_correction(normal, tol=tol).ravel()
    fz = normal.fz.ravel()
    if result.slip_law == "coulomb":
        s = np.sign(np.asarray(result.fx_at_peak).ravel())
        total = float((s * (fz + delta)).sum())
        return -float((s * delta).sum()) / total if total else 0.0
    if result.steps == 0:
        return 0.0
    k = int(result.broken_site[result.peak_index])
    return -float(delta[k]) / float(fz[k] + delta[k])


# ----------------------------------------------------------------------------------------------
# Public entry point
# ----------------------------------------------------------------------------------------------


#: seed of the fixed Lanczos start vector: the estimate is a pure function of the bonds
LANCZOS_SEED = 20030101


def bond_spectrum(normal: NormalResult, *, rtol: float = 1e-2, threads: int | None = None
                  ) -> tuple[float, float]:
    r"""Estimates :math:`(\theta_{\min}, \theta_{\max})` of the extreme eigenvalues of
    :math:`A_0 = G_{xx}[S_0,S_0]` on the bonds :math:`S_0` of a squeeze.

    Small sets (at most 500 bonds) use a dense symmetric eigensolver (exact to rounding);
    larger ones Lanczos (ARPACK) on the FFT operator, started from a fixed, seeded vector
    (:data:`LANCZOS_SEED`), so that the result is bitwise reproducible for a given thread
    count and FFT backend.

    What is an estimate and what is a bound
        *Estimate.* Every Ritz value is a Rayleigh quotient of :math:`A_0`, hence
        :math:`\lambda_{\min} \le \theta_{\min}` and :math:`\theta_{\max} \le
        \lambda_{\max}`: the estimate :math:`\hat\kappa = \theta_{\max}/\theta_{\min}`
        never exceeds the true condition number :math:`\kappa(A_0)`. How far below it lies is
        not bounded rigorously: ARPACK's ``tol`` bounds the Ritz residual
        :math:`\|A_0y-\theta y\| \le` ``rtol`` :math:`|\theta|`, which places *an*
        eigenvalue within ``rtol`` :math:`|\theta|` of :math:`\theta`, not necessarily the
        extreme one. Measured against dense eigenvalues (tests): within ``rtol``.

        *Bound (exact eigenvalues).* For every stick set :math:`S \subseteq S_0` the pull
        visits, :math:`\kappa(G_{xx}[S,S]) \le \kappa(A_0)`. Proof: :math:`G_{xx}[S,S]` is a
        principal submatrix of the symmetric positive definite :math:`A_0`. For
        :math:`x \ne 0` supported on :math:`S`, with :math:`\tilde x` its extension by zeros,
        :math:`x^T G_{xx}[S,S] x / x^T x = \tilde x^T A_0 \tilde x / \tilde x^T\tilde x
        \in [\lambda_{\min}(A_0), \lambda_{\max}(A_0)]`, so every eigenvalue of
        :math:`G_{xx}[S,S]` (a Rayleigh quotient at its eigenvector) lies in that interval
        (Cauchy interlacing, e.g. Horn & Johnson, *Matrix Analysis*, 2nd ed. 2013,
        Thm. 4.3.28). Then for :math:`G\varphi = 1_S` solved with residual :math:`r`,
        :math:`\|\delta\varphi\|/\|\varphi\| \le \kappa\,\|r\|/\|1_S\|`, and the
        same holds for :math:`\sum_S\varphi`: :math:`|1^T\delta\varphi| =
        |\varphi^T r| \le \|\varphi\|\|r\|`, :math:`\|\varphi\| \le
        \sqrt{n}/\lambda_{\min}` and :math:`\sum\varphi = 1^T G^{-1} 1 \ge
        n/\lambda_{\max}`.

        ``pull(..., estimate_error=True)`` multiplies :math:`\hat\kappa` by the worst
        certified residual: an *estimate* of that bound.

    Measured on a rough surface (H = 0.8, :math:`\nu = 0.3`): 3 275 bonds, estimate 64
    (dense: 64.3); 52 259 bonds, estimate 231, about 930 operator applications.

    Returns
    -------
    (theta_min, theta_max) : tuple of float
        Dense eigenvalues (small sets) or Ritz values converged to ``rtol``.

    Raises
    ------
    NumericalError
        When Lanczos does not converge or the smallest estimate is not positive.
    """
    from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, eigsh

    b = _Bonds(normal, 1.0, threads)
    if b.n == 0:
        raise InputError("bond_spectrum: the squeeze has no contact sites")
    if b.n <= 500:
        with blas_threads(1):
            w = np.linalg.eigvalsh(b.dense())
        lo, hi = float(w[0]), float(w[-1])
    else:
        A = b.restricted()
        v0 = np.random.default_rng(LANCZOS_SEED).standard_normal(b.n)
        try:
            with blas_threads(1):
                hi = float(eigsh(A, k=1, which="LA", tol=rtol, v0=v0,
                                 return_eigenvectors=False)[0])
                lo = float(eigsh(A, k=1, which="SA", tol=rtol, v0=v0,
                                 return_eigenvectors=False)[0])
        except (ArpackError, ArpackNoConvergence) as exc:
            raise NumericalError(f"bond_spectrum: Lanczos did not converge ({exc})") from None
    if not (lo > 0 and math.isfinite(hi)):
        raise NumericalError(f"G_xx on the bonds is not positive definite (smallest "
                             f"eigenvalue estimate {lo:.3e})")
    return lo, hi


def check_friction(lam: float, slip_law: str) -> None:
    """Raise :class:`InputError` unless ``lam`` is a finite number > 0 and ``slip_law`` one of
    :data:`SLIP_LAWS` (the pull, the coupled model and the indentation share the rule)."""
    if not (isinstance(lam, int | float) and math.isfinite(lam) and lam > 0):
        raise InputError(f"lam = {lam!r}: must be a finite number > 0")
    if slip_law not in SLIP_LAWS:
        raise InputError(f"slip_law = {slip_law!r}: must be 'break' or 'coulomb'")


def methods_for(slip_law: str) -> list[str]:
    """The pull methods that accept ``slip_law`` (``auto`` chooses among them)."""
    return [n for n in METHODS.names() if METHODS.get(n).run is None
            or slip_law in METHODS.get(n).laws]


def choose_method(n: int, memory: int | None = None, slip_law: str = "break") -> str:
    """The exact method ``"auto"`` picks for ``n`` bonds given ``memory`` bytes.

    The inverse (about n^3 flops, n^2 doubles) whenever it fits in memory and the LAPACK can
    index it (for 3 271 bonds it was about 100 times faster than one warm-started CG solve
    per break, docs/benchmarks.md); otherwise the matrix-free exact method.
    Tiny contacts use the literal algorithm. The Coulomb law has the inverse only, which
    checks its memory itself.
    """
    if slip_law == "coulomb":
        return "inverse"
    memory = available_bytes() if memory is None else memory
    if n <= 12:
        return "literal"
    limit = lapack64.max_n()
    if inverse_memory_bytes(n) <= memory and (limit is None or n <= limit):
        return "inverse"
    return "cg"


def pull(
    normal: NormalResult,
    *,
    lam: float = 0.2,
    slip_law: str = "break",
    method: str = "auto",
    tol: float = 1e-10,
    early_stop: bool = True,
    batch_size: int = 16,
    block: int = 128,
    max_iter: int = 10_000,
    threads: int | None = None,
    estimate_error: bool = False,
) -> SlipResult:
    r"""Pull a squeezed contact sideways until it slides (docs/theory/pull.rst#break-law).

    Parameters
    ----------
    normal : NormalResult
        The squeeze result; its contact sites (``f_z > 0``) are the initial bonds, and its
        problem (grid, material, operator) defines :math:`G_{xx}`.
    lam : float
        Local friction coefficient :math:`\lambda > 0`: a bond breaks (or slips) when
        :math:`|f_x| > \lambda f_z`.
    slip_law : {"break", "coulomb"}
        ``"break"``: a broken bond carries no force (the report). ``"coulomb"``: a slipping
        site carries :math:`\lambda f_z`.
    method : str
        A name from :data:`METHODS`: ``"auto"``, ``"literal"``, ``"inverse"``, ``"cg"`` or
        ``"batch"`` (module docstring). ``"auto"`` picks an exact method by bond count and
        memory (:func:`choose_method`).
    tol : float
        Relative residual of the tangential solves (and of the certification of ``inverse``).
    early_stop : bool
        Stop once :math:`\lambda\sum_S f_z` falls below the best :math:`F_{x,\rm lim}`
        (exact). ``method="literal"`` always runs to the last bond, as the report does.
    batch_size : int
        Bonds broken per solve by ``method="batch"``.
    block : int
        Removals per blocked update of ``method="inverse"``.
    threads : int, optional
        BLAS threads of the dense methods (default: the problem's threads).
    estimate_error : bool
        Also estimate the error of the friction force (``error_estimate``: the pull's own part
        by :func:`refinement_estimate`, one CG solve on the peak state, and the squeeze's part
        by :func:`normal_share`, one CG solve on the contact set) and the condition number
        of :math:`G_{xx}` on the bonds (``condition``, :func:`bond_spectrum`, a few hundred
        operator applications; deterministic) with the bound estimate ``error_bound``
        :math:`= \hat\kappa\rho`. Both are estimates (docs/methods.rst#estimates-against-truth
        compares them with the true error).

    Returns
    -------
    SlipResult
    """
    t0 = time.perf_counter()
    check_friction(lam, slip_law)
    impl = METHODS.get(method)
    if not 0 < tol < 1:
        raise InputError(f"tol = {tol!r}: must satisfy 0 < tol < 1")
    if int(batch_size) < 1 or int(block) < 1:
        raise InputError("batch_size and block must be >= 1")
    threads = normal.problem.threads if threads is None else int(threads)
    if threads < 1:
        raise InputError(f"threads = {threads!r}: must be >= 1")
    opt = PullOptions(slip_law=slip_law, tol=float(tol), early_stop=bool(early_stop),
                      batch_size=int(batch_size), block=int(block), max_iter=int(max_iter))
    b = _Bonds(normal, float(lam))
    if b.n == 0:
        return _Curve(b, early_stop).result(t0, method, converged=True,
                                            message="no contact: nothing to pull",
                                            slip_law=slip_law)
    chosen = choose_method(b.n, slip_law=slip_law) if impl.run is None else method
    impl = METHODS.get(chosen)
    if slip_law not in impl.laws:
        raise InputError(f"slip_law = {slip_law!r} supports methods "
                         f"{', '.join(methods_for(slip_law))}, not {chosen!r}")
    if impl.dense:
        # Dense linear algebra gets the threads, and the certification's FFTs run on one
        # thread beside it; FFT-bound CG loops keep BLAS single-threaded (competing FFTW and
        # OpenBLAS thread pools made CG iterations 60x slower).
        b = _Bonds(normal, float(lam), threads=1)
    with blas_threads(threads if impl.dense else 1):
        run = _coulomb if slip_law == "coulomb" else impl.run
        res = run(b, opt, t0)
    if method != chosen:
        res = replace(res, message=f"auto chose {chosen} for {b.n} bonds; " + res.message)
    if estimate_error:
        lo, hi = bond_spectrum(normal, threads=threads)
        kappa = hi / lo
        res = replace(res, condition=kappa, error_bound=kappa * res.residual,
                      seconds=time.perf_counter() - t0)
        if res.method != "batch":  # batch has no estimate (NaN)
            solve = 0.0 if slip_law == "coulomb" else refinement_estimate(normal, res)
            part = abs(normal_share(normal, res))
            res = replace(res, error_estimate=solve + part, solve_error_estimate=solve,
                          normal_error_estimate=part, seconds=time.perf_counter() - t0,
                          message=f"{res.message}; estimated error {solve + part:.2e} "
                                  f"(solves {solve:.1e}, normal forces {part:.1e})")
    return res


METHODS.register("auto", "an exact method chosen by bond count and memory")(
    PullMethod(None, exact=True, dense=False, laws=SLIP_LAWS))
METHODS.register("literal", "the report's algorithm, one CG solve from zero per break")(
    PullMethod(_break_literal, exact=True, dense=False))
METHODS.register("inverse", "exact, an updated inverse of G_xx on the bonds (O(n^2) memory)")(
    PullMethod(_break_inverse, exact=True, dense=True, laws=SLIP_LAWS))
METHODS.register("cg", "exact and matrix-free, a warm-started CG solve per break")(
    PullMethod(_break_cg, exact=True, dense=False))
METHODS.register("batch", "approximate, several bonds broken per solve")(
    PullMethod(_break_batch, exact=False, dense=False))
