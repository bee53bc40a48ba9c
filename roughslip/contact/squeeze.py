r"""Vertical squeeze: frictionless normal contact of a rigid rough surface
(docs/theory/squeeze.rst#squeeze-problem).

The rigid surface with heights :math:`h` (positive toward the elastic body) is pushed down by
:math:`D_z`, measured from first touch of its highest point. The imposed overlap is

.. math:: \bar u_i = D_z - (\max h - h_i).

Find pixel forces :math:`f \ge 0` with :math:`u = G_{zz} * f`, gap :math:`g = u - \bar u \ge 0`
and :math:`f\,g = 0`. This is the minimum of :math:`\tfrac12 f^T G f - \bar u^T f` over
:math:`f \ge 0`. Load control prescribes :math:`F_n = \sum f` instead; :math:`D_z` becomes an
unknown (the Lagrange multiplier of the force constraint).

Methods (registered in :data:`METHODS`)
---------------------------------------
``"pk"``
    Polonsky & Keer (1999), *Wear* 231:206: conjugate gradients that add and remove contact
    sites inside one run, on the FFT operator.
``"active-set"``
    The report's loop ([Report2003] §4.5.3): start from the geometric overlap, solve
    :math:`G_{KK} f_K = \bar u_K` by CG, drop the sites with :math:`f < 0`, repeat. Kept as a
    reference. It can only remove sites, so it checks for penetration off contact at the end.

Residual (dimensionless, reported as ``residual``)
    .. math::

        \epsilon = \frac{\max\big(\max_{f_i>0}|g_i|,\ \max_{f_i=0}\max(-g_i, 0)\big)}{D_z},

    the worst gap error in contact and the worst penetration off contact, relative to the
    overlap scale :math:`D_z = \max_i \bar u_i`. Forces are non-negative by construction, and
    under load control :math:`\sum f = F_n` holds to round-off (reported as ``force_error``).
    It measures convergence, not the error of the forces: on the verify scenes it is 0.26 to
    :math:`10^4` times that error (docs/methods.rst#estimates-against-truth);
    :func:`roughslip.contact.estimates.squeeze_correction` estimates the error itself.

Periodic grids
    The symbol has :math:`\hat K(0)=0` (docs/theory/boundaries.rst#periodic-boundary): a uniform
    pressure produces no displacement, and :math:`D_z` is measured against the mean plane of the
    deformed elastic surface. Then :math:`F_n \to \infty` as :math:`D_z \to \max h - \bar h`, and
    displacement control needs :math:`D_z < \max h - \bar h`; load control has no such limit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from roughslip.contact import pk_passes
from roughslip.contact.problem import Problem, check_heights, finite
from roughslip.elastic.operators import Grid, Material
from roughslip.errors import ConvergenceError, InputError, NumericalError
from roughslip.linalg.cg import cg
from roughslip.linalg.threads import blas_threads
from roughslip.registry import Registry

__all__ = ["METHODS", "NormalResult", "NormalSolver", "check_heights", "squeeze"]

_SYNC = 64  # PK: recompute u = G p from scratch at least this often


@dataclass(frozen=True)
class NormalResult:
    """Solution of one squeeze (all fields indexed ``[iy, ix]``).

    Attributes
    ----------
    fz : ndarray
        Normal pixel forces (>= 0).
    uz : ndarray
        Normal surface displacement (indentation > 0).
    gap : ndarray
        :math:`g = u_z - \\bar u` (0 in contact, >= 0 elsewhere up to the residual).
    contact : ndarray of bool
        ``fz > 0``.
    normal_force : float
        :math:`F_n = \\sum f_z`.
    contact_area : float
        Fraction of the grid in contact (real area = fraction x nominal area).
    depth : float
        :math:`D_z` (given, or found under load control).
    converged, iterations, residual, seconds, method :
        Solver record (``residual`` as defined in the module docstring).
    problem : Problem
        The problem that was solved (grid, material, heights, operator).
    """

    fz: np.ndarray
    uz: np.ndarray
    gap: np.ndarray
    contact: np.ndarray
    normal_force: float
    contact_area: float
    depth: float
    converged: bool
    iterations: int
    residual: float
    seconds: float
    method: str
    problem: Problem
    control: str = "depth"
    message: str = ""
    force_error: float = 0.0
    penetration: float = 0.0
    convolutions: int = 0
    fft_seconds: float = 0.0

    @property
    def grid(self) -> Grid:
        """The problem's grid."""
        return self.problem.grid

    @property
    def material(self) -> Material:
        """The problem's material."""
        return self.problem.material

    @property
    def heights(self) -> np.ndarray:
        """The problem's heights."""
        return self.problem.heights

    @property
    def n_contact(self) -> int:
        """Number of contact pixels."""
        return int(np.count_nonzero(self.contact))

    @property
    def real_area(self) -> float:
        """Real contact area :math:`A = a^2\\,\\#\\{f_z > 0\\}`."""
        return self.n_contact * self.grid.a**2


@dataclass(frozen=True)
class Outcome:
    """What a squeeze method returns: the forces, displacement and depth it found."""

    fz: np.ndarray
    uz: np.ndarray
    depth: float
    iterations: int
    converged: bool
    message: str


class SqueezeMethod(Protocol):
    """A squeeze method: built once per :class:`NormalSolver`, then solved at many targets.
    ``removes_only``: it can only take sites out of contact, never add them, so its result
    is checked for penetration off contact."""

    removes_only: bool

    def __init__(self, solver: NormalSolver) -> None: ...

    def at_depth(self, depth: float, x0: np.ndarray | None) -> Outcome: ...

    def at_force(self, force: float, x0: np.ndarray | None) -> Outcome: ...


#: the squeeze methods, by name (the configuration's ``squeeze.method``)
METHODS: Registry[type[SqueezeMethod]] = Registry("squeeze method")


class NormalSolver:
    """Reusable squeeze solver for one problem (operator and work arrays built once).

    Parameters
    ----------
    problem : Problem
        Heights, grid and material; its operator gets the ``"zz"`` spectrum.
    method : str
        A name from :data:`METHODS` (``"pk"`` or ``"active-set"``).
    tol : float
        Tolerance on the dimensionless residual (module docstring).
    max_iter : int
        Iteration limit (PK iterations, or CG iterations summed over the active-set loop).
    """

    def __init__(self, problem: Problem, *, method: str = "pk", tol: float = 1e-10,
                 max_iter: int = 20_000) -> None:
        if not isinstance(problem, Problem):
            raise InputError("NormalSolver takes a Problem (roughslip.contact.problem.Problem); "
                             "for plain arrays use roughslip.squeeze")
        impl = METHODS.get(method)
        if not (isinstance(tol, float | int) and 0 < tol < 1):
            raise InputError(f"tol = {tol!r}: must satisfy 0 < tol < 1")
        if int(max_iter) < 1:
            raise InputError(f"max_iter = {max_iter!r}: must be >= 1")
        problem.grid.boundary.check_squeeze(problem.grid.shape)
        self.problem = problem
        self.grid = problem.grid
        self.method = method
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.op = problem.operator("zz")
        self._impl = impl(self)

    def apply(self, v: np.ndarray, out: np.ndarray) -> np.ndarray:
        """:math:`u = G_{zz} * v`."""
        return self.op.apply("zz", v, out=out)

    # ------------------------------------------------------------------------------ public
    def solve(self, depth: float | None = None, force: float | None = None,
              x0: np.ndarray | None = None, strict: bool = False) -> NormalResult:
        """Solve at one depth (displacement control) or one total force (load control).

        Parameters
        ----------
        depth : float, optional
            :math:`D_z` from first touch.
        force : float, optional
            Total normal force :math:`F_n` (exactly one of ``depth`` and ``force``).
        x0 : ndarray, optional
            Warm start (a previous ``fz``).
        strict : bool
            Raise :class:`ConvergenceError` instead of returning ``converged=False``.
        """
        if (depth is None) == (force is None):
            raise InputError("give exactly one of depth and force")
        pb = self.problem
        if depth is not None:
            depth = pb.check_depth(depth)
        else:
            force = finite(force, "force")
            if force < 0:
                raise InputError(f"force = {force:g}: must be >= 0")
        if x0 is not None:
            x0 = np.asarray(x0, float)
            if x0.shape != self.grid.shape:
                raise InputError(f"x0 shape {x0.shape} != grid shape {self.grid.shape}")
            if not np.all(np.isfinite(x0)):
                raise InputError("x0: contains non-finite values")
        t0 = time.perf_counter()
        conv0, fft0 = self.op.applications, self.op.fft_seconds
        # FFT-bound loop: BLAS stays single-threaded (an FFTW and an OpenBLAS thread pool
        # competing for the same cores made CG iterations 60x slower)
        with blas_threads(1):
            if (depth is not None and depth <= 0) or (force is not None and force == 0):
                z = np.zeros(self.grid.shape)
                out = Outcome(z, z.copy(), 0.0 if depth is None else depth, 0, True,
                              "no overlap: no contact")
            elif depth is not None:
                out = self._impl.at_depth(depth, x0)
            else:
                out = self._impl.at_force(force, x0)
        res = self._finish(out, force)
        res = _with_record(res, seconds=time.perf_counter() - t0,
                           convolutions=self.op.applications - conv0,
                           fft_seconds=self.op.fft_seconds - fft0)
        if strict and not res.converged:
            raise ConvergenceError(f"squeeze did not converge: {res.message}")
        return res

    # ------------------------------------------------------------------------------ helpers
    def _finish(self, out: Outcome, force: float | None) -> NormalResult:
        """The result of a method's outcome: gap, residual and the checks."""
        fz, uz, depth = out.fz, out.uz, out.depth
        if not (np.all(np.isfinite(fz)) and np.all(np.isfinite(uz)) and math.isfinite(depth)):
            raise NumericalError(f"squeeze ({self.method}): non-finite value in the solution")
        gap = uz - self.problem.overlap(depth)
        res, pen = _residual(fz, gap, depth)
        contact = fz > 0
        F = float(fz.sum())
        load = force is not None
        message = out.message
        if self._impl.removes_only and pen > self.tol:
            message = (f"{message}; penetration off contact {pen:.2e} (relative to the depth) "
                       "exceeds the tolerance: the removal-only loop missed contact sites")
        return NormalResult(
            fz=fz, uz=uz, gap=gap, contact=contact, normal_force=F,
            contact_area=float(np.count_nonzero(contact)) / self.grid.size, depth=float(depth),
            converged=bool(out.converged and res <= self.tol), iterations=int(out.iterations),
            residual=float(res), seconds=0.0, method=self.method, problem=self.problem,
            control="force" if load else "depth", message=message,
            force_error=float(abs(F - force) / force) if load and force else 0.0,
            penetration=float(pen),
        )


def _with_record(res: NormalResult, **kw: float) -> NormalResult:
    return replace(res, **kw)


def _residual(fz: np.ndarray, g: np.ndarray, scale: float) -> tuple[float, float]:
    """(residual, penetration), both relative to ``scale``."""
    c = fz > 0
    gap_err = float(np.max(np.abs(g[c]))) if np.any(c) else 0.0
    pen = float(max(0.0, -np.min(g[~c]))) if np.any(~c) else 0.0
    scale = max(scale, np.finfo(float).tiny)
    return max(gap_err, pen) / scale, pen / scale


# ---------------------------------------------------------------------------------- PK
@METHODS.register("pk", "Polonsky-Keer constrained CG")
class PolonskyKeer:
    """Polonsky & Keer (1999), *Wear* 231:206: conjugate gradients that add and remove contact
    sites inside one run, on the FFT operator; displacement or load control.

    One convolution per iteration (``r = G t``): the displacement is carried along as
    ``u -= tau r``, and the projection's changes (clipped forces, new overlap sites) are
    added exactly, by direct sums when they are few and by a fresh ``u = G p`` otherwise.
    ``u`` is recomputed from scratch every ``_SYNC`` iterations and before convergence is
    declared, so round-off cannot accumulate into the answer.

    This method keeps its own iteration rather than :func:`roughslip.linalg.cg.cg`: its
    contact set changes inside the iteration (a projection after every step, and conjugacy
    restarts when sites enter), so no fixed restricted operator describes it.
    """

    removes_only = False

    def __init__(self, solver: NormalSolver) -> None:
        self.solver = solver
        self.grid = solver.grid
        self.op = solver.op
        self._apply = solver.apply
        self._base = solver.problem.base
        unit = np.zeros(self.grid.shape)
        unit[0, 0] = 1.0
        self._diag = float(self._apply(unit, np.empty_like(unit))[0, 0])
        self._ws: dict[str, np.ndarray] | None = None

    @property
    def tol(self) -> float:
        return self.solver.tol  # read at each solve: the solver's settings may change

    @property
    def max_iter(self) -> int:
        return self.solver.max_iter

    def at_depth(self, depth: float, x0: np.ndarray | None) -> Outcome:
        return self._run(depth, None, x0)

    def at_force(self, force: float, x0: np.ndarray | None) -> Outcome:
        return self._run(None, force, x0)

    def _workspace(self) -> dict[str, np.ndarray]:
        if self._ws is None:
            shape = self.grid.shape
            ws = {k: np.zeros(shape) for k in ("g", "gs", "off", "Sf", "ubar")}
            # the arrays that go through the convolution: the operator's, transformed where
            # they are when it can (every solve sets all four before reading them)
            ws.update({k: self.op.work_buffer(f"pk_{k}") for k in ("p", "u", "t", "r")})
            ws["flags"] = np.zeros(shape, dtype=np.int8)
            self._ws = ws
        return self._ws

    def _run(self, depth: float | None, force: float | None, x0: np.ndarray | None
             ) -> Outcome:
        load = force is not None
        ws = self._workspace()
        p, u, g, gs, t, r, Sf, ubar = (ws[k] for k in ("p", "u", "g", "gs", "t", "r", "Sf",
                                                        "ubar"))
        flags, off = ws["flags"], ws["off"]
        np.add(self._base, 0.0 if load else depth, out=ubar)
        p.fill(0.0)
        if x0 is not None:
            np.maximum(x0, 0.0, out=p)
        if not np.any(p):
            np.copyto(p, self._initial(ubar, force))
        elif load:
            p *= force / p.sum()
        tf, rf, gsf, Sff = (a.ravel() for a in (t, r, gs, Sf))
        self._apply(p, u)
        stale = 0  # iterations since u was last computed from p
        limit = self.op.tables.direct_sum_limit
        t.fill(0.0)
        delta, g_old, shift, it = 0.0, 1.0, 0.0, 0
        scale = 0.0 if load else depth
        message, converged = "", False
        while True:
            # the gap, the contact mask (sign of p >= 0) and the gap on contact: one pass
            n_s, gs_max, gs_min, off_min = pk_passes.gap(u, ubar, p, g, Sf, gs, off)
            if load:
                shift = float(gs.sum()) / n_s  # the unknown approach D_z
                gs_max, gs_min, off_min = pk_passes.shift_gap(g, Sf, gs, off, shift)
                scale = shift
            gap_err = max(gs_max, -gs_min)
            pen = max(0.0, -off_min)
            res = max(gap_err, pen) / max(scale, np.finfo(float).tiny)
            if not math.isfinite(res):
                raise NumericalError(f"squeeze (pk): non-finite gap at iteration {it} (a NaN or "
                                     "inf entered the displacement)")
            if res <= self.tol or it >= self.max_iter:
                if stale:  # confirm with an exact displacement
                    self._apply(p, u)
                    stale = 0
                    continue
                if res <= self.tol:
                    converged = True
                else:
                    message = f"reached max_iter = {self.max_iter} with residual {res:.3e}"
                break
            it += 1
            g_norm = float(np.dot(gsf, gsf))
            beta = delta * g_norm / g_old
            if beta:
                pk_passes.direction(t, beta, Sf, gs)
            else:
                np.copyto(t, gs)
            g_old = g_norm if g_norm > 0 else 1.0
            self._apply(t, r)
            rt = float(np.dot(rf, tf))
            if load:  # r - mean_S(r), without forming it
                rt -= float(np.dot(rf, Sff)) / n_s * float(tf.sum())
            tau = float(np.dot(gsf, tf)) / rt if rt > 0 else 1.0 / self._diag
            clipped, entering = pk_passes.step(p, t, u, r, g, Sf, tau, flags)
            stale += 1
            entered, synced = self._project(p, u, g, clipped, entering, tau, limit)
            delta = 0.0 if entered else 1.0  # conjugacy restarts when sites enter
            if synced:
                stale = 0
            if load:
                pk_passes.scale(p, u, force / float(p.sum()))
            if stale >= _SYNC:
                self._apply(p, u)
                stale = 0
        d = shift if load else depth
        return Outcome(p.copy(), u.copy(), d, it, converged,
                       message or f"converged in {it} iterations")

    def _project(self, p: np.ndarray, u: np.ndarray, g: np.ndarray, clipped: np.ndarray,
                 entering: np.ndarray, tau: float, limit: int) -> tuple[bool, bool]:
        """Project the forces after a step, and carry the displacement along exactly.

        Sites with :math:`p < 0` (``clipped``) lift off, clipped to 0; sites with :math:`p = 0`
        and :math:`g < 0` enter contact with :math:`p = -\\tau g`: those off the old contact set
        (``entering``) and the clipped ones with a negative gap
        (:func:`~roughslip.contact.pk_passes.step` lists both). The changes are added to ``u``
        by direct sums when there are at most ``limit`` of them, else ``u = G p`` afresh.
        Returns (sites entered, ``u`` recomputed).
        """
        if not (clipped.size or entering.size):
            return False, False
        pf = p.ravel()
        sites, vals = [], []
        idx = entering
        if clipped.size:
            sites.append(clipped)
            vals.append(-pf[clipped])
            pf[clipped] = 0.0
            idx = np.concatenate([idx, clipped[g.ravel()[clipped] < 0.0]])
        if idx.size:
            v = -tau * g.ravel()[idx]
            pf[idx] += v
            sites.append(idx)
            vals.append(v)
        synced = False
        if sum(x.size for x in sites) <= limit:
            self.op.tables.add_sources("zz", u, np.concatenate(sites), np.concatenate(vals))
        else:
            self._apply(p, u)
            synced = True
        return bool(idx.size), synced

    def _initial(self, ubar: np.ndarray, force: float | None) -> np.ndarray:
        """Cold start: forces proportional to the positive overlap, best scale along it."""
        if force is not None:
            return np.full(self.grid.shape, force / self.grid.size)
        v = np.maximum(ubar, 0.0)
        gv = self._apply(v, np.empty_like(v))
        c = float(np.dot(ubar.ravel(), v.ravel())) / float(np.dot(v.ravel(), gv.ravel()))
        return c * v



# ---------------------------------------------------------------------------------- active set
@METHODS.register("active-set", "the report's removal-only loop (a reference)")
class ActiveSet:
    """The report's loop ([Report2003] §4.5.3): start from the geometric overlap, solve
    :math:`G_{KK} f_K = \\bar u_K` by CG (:func:`roughslip.linalg.cg.cg`), drop the sites with
    :math:`f < 0`, repeat. It can only remove sites, so penetration off contact is checked at
    the end. Load control is a bracketed root search on the depth."""

    removes_only = True

    def __init__(self, solver: NormalSolver) -> None:
        self.solver = solver
        self.problem = solver.problem

    def at_depth(self, depth: float, x0: np.ndarray | None) -> Outcome:
        s, pb = self.solver, self.problem
        ubar = pb.overlap(depth)
        K = ubar > 0  # the geometric overlap: a superset of the contact set
        f = None if x0 is None else np.where(K, x0, 0.0)
        total = 0
        message = ""
        ok = True
        while True:
            r = cg(pb.restricted("zz", K), ubar, x0=f, tol=s.tol * 1e-2,
                   max_iter=max(1, s.max_iter - total))
            total += r.iterations
            f = r.x
            if not r.converged:
                ok = False
                message = f"CG on the contact set stopped at residual {r.residual:.2e}"
                break
            neg = K & (f < 0)
            if not np.any(neg):
                break
            K &= ~neg
            f[neg] = 0.0
        f = np.where(K, np.maximum(f, 0.0), 0.0)
        u = s.apply(f, np.empty_like(f))
        return Outcome(f, u, depth, total, ok, message or f"{total} CG iterations")

    def at_force(self, force: float, x0: np.ndarray | None) -> Outcome:
        """Load control: a bracketed root search on D_z (Brent)."""
        from scipy.optimize import brentq

        pb = self.problem
        iters = [0]
        last: dict[float, Outcome] = {}

        def excess(d: float) -> float:
            out = self.at_depth(d, None)
            iters[0] += out.iterations
            last[d] = out
            return float(out.fz.sum()) - force

        lo, hi = 0.0, max(pb.hmax - float(pb.heights.min()), pb.grid.a) * 1e-3
        limit = pb.depth_limit()
        while excess(hi) < 0:
            lo = hi
            hi = min(2 * hi, 0.5 * (hi + limit)) if math.isfinite(limit) else 2 * hi
            if hi > 1e12 * max(pb.grid.a, 1.0):
                raise InputError(f"force = {force:g}: no depth reaches it")
        d = brentq(excess, lo, hi, xtol=1e-15 * hi, rtol=4 * np.finfo(float).eps, maxiter=200)
        if d not in last:
            excess(d)
        out = last[d]
        return Outcome(out.fz, out.uz, d, iters[0], out.converged, out.message)


def squeeze(
    heights: np.ndarray | Problem,
    *,
    depth: float | None = None,
    force: float | None = None,
    a: float = 1.0,
    E: float = 1.0,
    nu: float = 0.3,
    boundary: str = "open",
    periodic_kernel: str = "pixel",
    tol: float = 1e-10,
    method: str = "pk",
    x0: np.ndarray | None = None,
    fft: str = "auto",
    max_iter: int = 20_000,
    threads: int = 1,
    strict: bool = False,
) -> NormalResult:
    r"""Squeeze a rigid surface into an elastic half-space
    (docs/theory/squeeze.rst#squeeze-problem).

    A convenience over :class:`NormalSolver`: it builds the :class:`Problem` from plain numbers
    (or takes one, ignoring ``a`` ... ``threads``) and solves once.

    Parameters
    ----------
    heights : ndarray, shape (ny, nx), or Problem
        Heights of the rigid (composite) surface, positive toward the elastic body.
    depth : float, optional
        Penetration :math:`D_z` from first touch (displacement control).
    force : float, optional
        Total normal force :math:`F_n` (load control). Exactly one of ``depth``, ``force``.
    a, E, nu : float
        Pixel side, Young's modulus, Poisson ratio.
    boundary : {"open", "periodic"}
    periodic_kernel : {"pixel", "continuous"}
    tol : float
        Tolerance on the dimensionless residual (see module docstring).
    method : {"pk", "active-set"}
        A name from :data:`METHODS`.
    x0 : ndarray, optional
        Warm start, e.g. the ``fz`` of a shallower depth.
    fft : {"auto", "pyfftw", "scipy"}

    Returns
    -------
    NormalResult

    Examples
    --------
    >>> import numpy as np, roughslip
    >>> x = (np.arange(32) - 15.5) * 0.05
    >>> h = -(x[None, :] ** 2 + x[:, None] ** 2) / 2       # sphere of radius 1
    >>> r = roughslip.squeeze(h, depth=0.02, a=0.05, E=1.0, nu=0.0)
    >>> r.converged, round(r.normal_force / (4 / 3 * 0.02 ** 1.5), 2)
    (True, 1.0)
    """
    problem = heights if isinstance(heights, Problem) else Problem.from_arrays(
        heights, a=a, E=E, nu=nu, boundary=boundary, periodic_kernel=periodic_kernel, fft=fft,
        threads=threads)
    solver = NormalSolver(problem, method=method, tol=tol, max_iter=max_iter)
    return solver.solve(depth=depth, force=force, x0=x0, strict=strict)
