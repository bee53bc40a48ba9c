r"""Vertical squeeze: frictionless normal contact of a rigid rough surface
(docs/theory/squeeze.rst#squeeze-problem).

The rigid surface with heights :math:`h` (positive toward the elastic body) is pushed down by
:math:`D_z`, measured from first touch of its highest point. The imposed overlap is

.. math:: \bar u_i = D_z - (\max h - h_i).

Find pixel forces :math:`f \ge 0` with :math:`u = G_{zz} * f`, gap :math:`g = u - \bar u \ge 0`
and :math:`f\,g = 0`. This is the minimum of :math:`\tfrac12 f^T G f - \bar u^T f` over
:math:`f \ge 0`. Load control prescribes :math:`F_n = \sum f` instead; :math:`D_z` becomes an
unknown (the Lagrange multiplier of the force constraint).

Methods
-------
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

Periodic grids
    The symbol has :math:`\hat K(0)=0` (docs/theory/boundaries.rst#periodic-boundary): a uniform
    pressure produces no displacement, and :math:`D_z` is measured against the mean plane of the
    deformed elastic surface. Then :math:`F_n \to \infty` as :math:`D_z \to \max h - \bar h`, and
    displacement control needs :math:`D_z < \max h - \bar h`; load control has no such limit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from roughslip.elastic.operators import ElasticOperator, Grid, Material
from roughslip.errors import ConvergenceError, InputError, NumericalError
from roughslip.linalg.cg import masked_cg
from roughslip.linalg.threads import blas_threads

METHODS = ("pk", "active-set")
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
    control: str = "depth"
    message: str = ""
    force_error: float = 0.0
    penetration: float = 0.0
    convolutions: int = 0
    fft_seconds: float = 0.0
    grid: Grid = field(default_factory=lambda: Grid((1, 1)))
    material: Material = field(default_factory=Material)
    heights: np.ndarray | None = field(default=None, repr=False)

    @property
    def n_contact(self) -> int:
        """Number of contact pixels."""
        return int(np.count_nonzero(self.contact))

    @property
    def real_area(self) -> float:
        """Real contact area :math:`A = a^2\\,\\#\\{f_z > 0\\}`."""
        return self.n_contact * self.grid.a**2


def check_heights(heights: np.ndarray, name: str = "heights") -> np.ndarray:
    """Return ``heights`` as a float64 2-D array, or raise :class:`InputError`."""
    h = np.asarray(heights)
    if h.ndim != 2:
        raise InputError(f"{name}: must be a 2-D array, got {h.ndim} dimension(s)")
    if h.size == 0:
        raise InputError(f"{name}: is empty")
    if not np.issubdtype(h.dtype, np.number) or np.iscomplexobj(h):
        raise InputError(f"{name}: must be real numbers, got dtype {h.dtype}")
    h = np.ascontiguousarray(h, dtype=float)
    if not np.all(np.isfinite(h)):
        bad = np.argwhere(~np.isfinite(h))[0]
        raise InputError(f"{name}: non-finite value at [iy, ix] = {bad.tolist()}")
    return h


class NormalSolver:
    """Reusable squeeze solver for one topography (operator and work arrays built once).

    Parameters
    ----------
    heights : ndarray
        Composite heights of the rigid surface (positive toward the elastic body).
    grid : Grid
        Pixel size and boundary; its shape must equal ``heights.shape``.
    material : Material
    method : {"pk", "active-set"}
    tol : float
        Tolerance on the dimensionless residual (module docstring).
    max_iter : int
        Iteration limit (PK iterations, or CG iterations summed over the active-set loop).
    operator : ElasticOperator, optional
        A prebuilt operator with the ``"zz"`` component (shared between solvers).
    """

    def __init__(
        self,
        heights: np.ndarray,
        grid: Grid,
        material: Material,
        *,
        method: str = "pk",
        tol: float = 1e-10,
        max_iter: int = 20_000,
        fft: str = "auto",
        threads: int = 1,
        operator: ElasticOperator | None = None,
    ) -> None:
        self.heights = check_heights(heights)
        if self.heights.shape != grid.shape:
            raise InputError(f"heights shape {self.heights.shape} != grid shape {grid.shape}")
        if method not in METHODS:
            raise InputError(f"method = {method!r}: must be one of {', '.join(METHODS)}")
        if not (isinstance(tol, float | int) and 0 < tol < 1):
            raise InputError(f"tol = {tol!r}: must satisfy 0 < tol < 1")
        if int(max_iter) < 1:
            raise InputError(f"max_iter = {max_iter!r}: must be >= 1")
        if grid.boundary == "periodic" and grid.size < 2:
            raise InputError("a periodic 1x1 grid has no non-uniform mode: use an open grid")
        self.grid = grid
        self.material = material
        self.method = method
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        if operator is None:
            operator = grid.operator(material, ("zz",), fft=fft, threads=threads)
        self.op = operator
        self.hmax = float(self.heights.max())
        self.hmean = float(self.heights.mean())
        # geometric overlap at D = 0 (first touch): ubar(D) = D + self._base
        self._base = self.heights - self.hmax
        self._diag = float(self.op.apply("zz", _unit(grid.shape))[0, 0])

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
        if depth is not None:
            depth = _finite(depth, "depth")
            if self.grid.boundary == "periodic" and depth >= self.hmax - self.hmean:
                raise InputError(
                    f"depth = {depth:g}: on a periodic grid displacement control needs "
                    f"depth < max(h) - mean(h) = {self.hmax - self.hmean:g} (the force diverges "
                    "as the mean gap closes); use load control (force=...) instead"
                )
        else:
            force = _finite(force, "force")
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
                out = self._no_contact(0.0 if depth is None else depth)
            elif self.method == "pk":
                out = self._pk(depth, force, x0)
            elif depth is not None:
                out = self._active_set(depth, x0)
            else:
                out = self._active_set_load(force, x0)
        fz, uz, d, it, conv, msg = out
        res = self._finish(fz, uz, d, it, conv, msg, depth is None, force, t0, conv0, fft0)
        if strict and not res.converged:
            raise ConvergenceError(f"squeeze did not converge: {res.message}")
        return res

    # ------------------------------------------------------------------------------ helpers
    def _apply(self, v: np.ndarray, out: np.ndarray) -> np.ndarray:
        return self.op.apply("zz", v, out=out)

    def _no_contact(self, depth: float):
        z = np.zeros(self.grid.shape)
        return z, z.copy(), depth, 0, True, "no overlap: no contact"

    def _residual(self, fz: np.ndarray, g: np.ndarray, scale: float) -> tuple[float, float]:
        """(residual, penetration), both relative to ``scale``."""
        c = fz > 0
        gap_err = float(np.max(np.abs(g[c]))) if np.any(c) else 0.0
        pen = float(max(0.0, -np.min(g[~c]))) if np.any(~c) else 0.0
        scale = max(scale, np.finfo(float).tiny)
        return max(gap_err, pen) / scale, pen / scale

    def _finish(self, fz, uz, depth, iterations, converged, message, load, force, t0, conv0,
                fft0) -> NormalResult:
        if not (np.all(np.isfinite(fz)) and np.all(np.isfinite(uz)) and math.isfinite(depth)):
            raise NumericalError(f"squeeze ({self.method}): non-finite value in the solution")
        ubar = self._base + depth
        gap = uz - ubar
        res, pen = self._residual(fz, gap, depth)
        contact = fz > 0
        F = float(fz.sum())
        ferr = abs(F - force) / force if load and force else 0.0
        if self.method == "active-set" and pen > self.tol:
            message = (f"{message}; penetration off contact {pen:.2e} (relative to the depth) "
                       "exceeds the tolerance: the removal-only loop missed contact sites")
        return NormalResult(
            fz=fz, uz=uz, gap=gap, contact=contact, normal_force=F,
            contact_area=float(np.count_nonzero(contact)) / self.grid.size, depth=float(depth),
            converged=bool(converged and res <= self.tol), iterations=int(iterations),
            residual=float(res), seconds=time.perf_counter() - t0, method=self.method,
            control="force" if load else "depth", message=message, force_error=float(ferr),
            penetration=float(pen), convolutions=self.op.applications - conv0,
            fft_seconds=self.op.fft_seconds - fft0, grid=self.grid, material=self.material,
            heights=self.heights,
        )

    # ------------------------------------------------------------------------------ PK
    def _workspace(self) -> dict[str, np.ndarray]:
        ws = self.__dict__.get("_ws")
        if ws is None:
            shape = self.grid.shape
            ws = {k: np.zeros(shape) for k in ("p", "u", "g", "gs", "t", "r", "Sf", "ubar",
                                               "tmp", "tmp_g")}
            ws["mb"] = np.zeros(shape, dtype=bool)
            self._ws = ws
        return ws

    def _pk(self, depth: float | None, force: float | None, x0: np.ndarray | None):
        """Polonsky–Keer constrained CG (displacement or load control).

        One convolution per iteration (``r = G t``): the displacement is carried along as
        ``u -= tau r``, and the projection's changes (clipped forces, new overlap sites) are
        added exactly, by direct sums when they are few and by a fresh ``u = G p`` otherwise.
        ``u`` is recomputed from scratch every ``_SYNC`` iterations and before convergence is
        declared, so round-off cannot accumulate into the answer.
        """
        load = force is not None
        ws = self._workspace()
        p, u, g, gs, t, r, Sf, ubar = (ws[k] for k in ("p", "u", "g", "gs", "t", "r", "Sf",
                                                        "ubar"))
        mb, tmp, tmp_g = ws["mb"], ws["tmp"], ws["tmp_g"]
        np.add(self._base, 0.0 if load else depth, out=ubar)
        p.fill(0.0)
        if x0 is not None:
            np.maximum(x0, 0.0, out=p)
        if not np.any(p):
            np.copyto(p, self._initial(ubar, force))
        elif load:
            p *= force / p.sum()
        pf, tf, rf, gsf, Sff = (a.ravel() for a in (p, t, r, gs, Sf))
        self._apply(p, u)
        stale = 0  # iterations since u was last computed from p
        limit = self.op.direct_sum_limit
        t.fill(0.0)
        delta, g_old, shift, it = 0.0, 1.0, 0.0, 0
        scale = 0.0 if load else depth
        message, converged = "", False
        while True:
            np.subtract(u, ubar, out=g)
            np.sign(p, out=Sf)  # p >= 0: the contact mask as 0.0 / 1.0 in one pass
            n_s = int(np.count_nonzero(Sf))
            np.multiply(g, Sf, out=gs)
            if load:
                shift = float(gs.sum()) / n_s  # the unknown approach D_z
                np.subtract(g, shift, out=g)
                np.multiply(g, Sf, out=gs)
                scale = shift
            gap_err = max(float(gs.max()), -float(gs.min()))
            np.subtract(g, gs, out=tmp_g)  # g off the contact set, 0 on it
            pen = max(0.0, -float(tmp_g.min()))
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
                np.multiply(t, beta, out=t)
                np.multiply(t, Sf, out=t)
                np.add(t, gs, out=t)
            else:
                np.copyto(t, gs)
            g_old = g_norm if g_norm > 0 else 1.0
            self._apply(t, r)
            rt = float(np.dot(rf, tf))
            if load:  # r - mean_S(r), without forming it
                rt -= float(np.dot(rf, Sff)) / n_s * float(tf.sum())
            tau = float(np.dot(gsf, tf)) / rt if rt > 0 else 1.0 / self._diag
            np.multiply(t, tau, out=tmp)
            np.subtract(p, tmp, out=p)
            np.multiply(r, tau, out=tmp)
            np.subtract(u, tmp, out=u)
            stale += 1
            sites, vals = [], []
            clipped = None
            if float(p.min()) < 0.0:  # clip: these contact sites lift off
                clipped = np.flatnonzero(pf < 0.0)
                sites.append(clipped)
                vals.append(-pf[clipped])
                pf[clipped] = 0.0
            # overlap: sites with p = 0 and g < 0 enter contact; conjugacy restarts. Off the
            # old contact set this is tmp < 0 (tmp = g off S); add clipped sites with g < 0.
            np.less(tmp_g, 0.0, out=mb)
            idx = np.flatnonzero(mb)
            if clipped is not None:
                idx = np.concatenate([idx, clipped[g.ravel()[clipped] < 0.0]])
            delta = 0.0 if idx.size else 1.0
            if idx.size:
                v = -tau * g.ravel()[idx]
                pf[idx] += v
                sites.append(idx)
                vals.append(v)
            if sites:
                n_changed = sum(x.size for x in sites)
                if n_changed <= limit:
                    self.op.add_sources("zz", u, np.concatenate(sites), np.concatenate(vals))
                else:
                    self._apply(p, u)
                    stale = 0
            if load:
                s_ = force / float(p.sum())
                p *= s_
                u *= s_
            if stale >= _SYNC:
                self._apply(p, u)
                stale = 0
        d = shift if load else depth
        return p.copy(), u.copy(), d, it, converged, message or f"converged in {it} iterations"

    def _initial(self, ubar: np.ndarray, force: float | None) -> np.ndarray:
        """Cold start: forces proportional to the positive overlap, best scale along it."""
        if force is not None:
            return np.full(self.grid.shape, force / self.grid.size)
        v = np.maximum(ubar, 0.0)
        gv = self._apply(v, np.empty_like(v))
        c = float(np.dot(ubar.ravel(), v.ravel())) / float(np.dot(v.ravel(), gv.ravel()))
        return c * v

    # ------------------------------------------------------------------------------ active set
    def _active_set(self, depth: float, x0: np.ndarray | None, budget: int | None = None):
        """The report's removal-only loop ([Report2003] §4.5.3) at a fixed depth."""
        ubar = self._base + depth
        K = ubar > 0  # the geometric overlap: a superset of the contact set
        f = None if x0 is None else np.where(K, x0, 0.0)
        total = 0
        budget = self.max_iter if budget is None else budget
        message = ""
        ok = True
        while True:
            r = masked_cg(self._apply, ubar, K, x0=f, tol=self.tol * 1e-2,
                          max_iter=max(1, budget - total))
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
        u = self._apply(f, np.empty_like(f))
        return f, u, depth, total, ok, message or f"{total} CG iterations"

    def _active_set_load(self, force: float, x0: np.ndarray | None):
        """Load control for the reference method: a bracketed secant search on D_z."""
        from scipy.optimize import brentq

        iters = [0]
        last = {}

        def excess(d: float) -> float:
            f, u, _, it, ok, msg = self._active_set(d, None)
            iters[0] += it
            last[d] = (f, u, ok, msg)
            return float(f.sum()) - force

        lo, hi = 0.0, max(self.hmax - self.heights.min(), self.grid.a) * 1e-3
        limit = (self.hmax - self.hmean) if self.grid.boundary == "periodic" else math.inf
        while excess(hi) < 0:
            lo = hi
            hi = min(2 * hi, 0.5 * (hi + limit)) if math.isfinite(limit) else 2 * hi
            if hi > 1e12 * max(self.grid.a, 1.0):
                raise InputError(f"force = {force:g}: no depth reaches it")
        d = brentq(excess, lo, hi, xtol=1e-15 * hi, rtol=4 * np.finfo(float).eps, maxiter=200)
        if d not in last:
            excess(d)
        f, u, ok, msg = last[d]
        return f, u, d, iters[0], ok, msg


def _unit(shape: tuple[int, int]) -> np.ndarray:
    e = np.zeros(shape)
    e[0, 0] = 1.0
    return e


def _finite(v, name: str) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise InputError(f"{name} = {v!r}: must be a number") from None
    if not math.isfinite(x):
        raise InputError(f"{name} = {v!r}: must be finite")
    return x


def squeeze(
    heights: np.ndarray,
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

    Parameters
    ----------
    heights : ndarray, shape (ny, nx)
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
    h = check_heights(heights)
    grid = Grid(h.shape, a, boundary, periodic_kernel)
    solver = NormalSolver(h, grid, Material(E, nu), method=method, tol=tol, max_iter=max_iter,
                          fft=fft, threads=threads)
    return solver.solve(depth=depth, force=force, x0=x0, strict=strict)
