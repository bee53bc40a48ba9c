r"""The break law's exact pull on an inexact inverse, with certified decisions: a
single-precision one (``pull(..., precision="single")``; docs/theory/pull.rst#single-precision)
or a compressed one (``pull(..., method="hierarchical")``, whose error
:math:`\delta \ge \|G_{SS} - \tilde A\|_2` is measured once, :func:`_compression_error`,
and bounds the column ratio and the growth rate below; docs/theory/pull.rst#hierarchical-inverse).

The inverse of :math:`G_{xx}` on the bonds is stored in float32
(:func:`~roughslip.friction.bonds.bond_inverse`): half the memory of the double-precision
method, and its factorisation and folding run at the single-precision flop rate. Everything
else is double: the tracked :math:`\tilde\varphi`, its residual against the FFT operator,
the refinement and the pending rank-one terms. Only the stored matrix carries the
single-precision rounding, so a removal moves :math:`\tilde\varphi` by a column
:math:`\tilde c` of relative error about :math:`\kappa\,\epsilon_{32}`.

The error bound
    With :math:`r = 1_S - G_{SS}\tilde\varphi` the residual on the stick set :math:`S`,
    :math:`\tilde\varphi - \varphi = -G_{SS}^{-1} r`, so every entry obeys

    .. math:: |\tilde\varphi_i - \varphi_i| \le \|G_{SS}^{-1} e_i\|_2\,\|r\|_2
              \le \sqrt{\nu\, d_i}\;\|r\|_2, \qquad
              \nu \ge \|G_{SS}^{-1}\|_2 = 1/\lambda_{\min}(G_{SS}),

    (:math:`\|M e_i\|^2 = e_i^T M^2 e_i \le \lambda_{\max}(M) M_{ii}` for positive definite
    :math:`M`), with :math:`d_i \ge (G_{SS}^{-1})_{ii}` the diagonal of the stored inverse at
    the last fold times :math:`1 +` :data:`DIAG_PAD` (a removal only lowers the diagonal).
    By Cauchy interlacing one :math:`\nu` for the initial bonds serves every later stick
    set. A removal of row :math:`k` with the column :math:`\tilde c` of the stored inverse
    (residual :math:`\rho = e_k - G_{SS}\tilde c`) changes the residual by
    :math:`-\alpha\rho` with :math:`\alpha = \tilde\varphi_k/\tilde c_k`, so between
    certifications

    .. math:: \|r\|_2 \le R_c + \hat g \sum |\alpha|\,\|\tilde c\|_2,

    :math:`R_c` the residual measured at the last check. :math:`\hat g` bounds the growth
    per unit of the sum: at most :math:`\hat\gamma \ge \|\rho\|/\|\tilde c\|`, far less
    in practice because the removals' errors partly cancel. It is :data:`GROWTH_SAFETY`
    times the largest growth rate measured so far (at every certification and sharpening),
    and :data:`GAMMA_SAFETY` times the largest column ratio :math:`\hat\gamma` before the first
    measurement; a measurement above the bound is counted in the message. :math:`\nu` is a
    Lanczos estimate (dense for small sets) times :data:`NU_SAFETY`; :math:`\hat\gamma` is
    measured on sampled columns (two per certification, by FFT). These are estimates, so the
    bound is an estimate of a bound; the decisions it certifies are compared with the
    double-precision path in the tests.

Certified decisions
    The next bond is the one with the largest :math:`|\varphi_i|/(\lambda f_{z,i})`, ties
    within a relative :data:`~roughslip.friction.events.TIE` to the lowest index
    (:func:`~roughslip.friction.events.argext`). When the bound leaves more than one row able
    to be that bond, the candidates are *sharpened*: one FFT gives :math:`r`, and
    :math:`\hat\varphi_i = \tilde\varphi_i + \tilde c_i^T r` for each candidate (error
    :math:`\le \nu\,\|\rho_i\|\,\|r\| \le \nu\hat\gamma\|\tilde c_i\|\,\|r\|`, second
    order, with :data:`GAMMA_SAFETY` times the largest measured column ratio as
    :math:`\hat\gamma`). Only if that still leaves
    the choice open is :math:`\tilde\varphi` refined to the rounding level and the bond
    chosen as the double-precision path chooses it.

The peak
    Each break is recorded with the bound on its :math:`F_{x,\rm lim}`; every state that can
    still be the peak (its upper bound at least the best lower bound) is kept, and at the end
    (or when the early stop is in doubt) each is solved again by CG on the FFT operator from
    its :math:`\tilde\varphi`, so the friction force, the peak's curve point and the peak
    state carry double-precision accuracy. The other points of the curve carry the bound
    (reported in the message).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from scipy.sparse.linalg import LinearOperator, eigsh

from roughslip.errors import NumericalError
from roughslip.friction.bonds import (
    Bonds,
    BreakCurve,
    PullOptions,
    stick_residual,
)
from roughslip.friction.events import TIE, argext
from roughslip.friction.result import PullResult
from roughslip.friction.sliding import TangentialState
from roughslip.linalg import jit
from roughslip.linalg.stick import StickSolver

#: safety factor on the Lanczos estimate of :math:`\lambda_{\max}(G_0^{-1})` (a Ritz value,
#: never above it; ARPACK's tolerance 1e-2)
NU_SAFETY = 1.25
#: safety factor on the largest measured column-residual ratio (the sharpening's error, and
#: the growth rate before one is realised)
GAMMA_SAFETY = 8.0
#: safety factor on the largest realised growth rate of the residual
GROWTH_SAFETY = 4.0
#: candidates sharpened one by one at most; more take a full refinement
MAX_SHARPEN = 32
#: compact once this share of the rows is dead: the folds' flops follow the stored order,
#: and at half the bytes compaction is cheap
COMPACT_DEAD = 0.15
#: the certification refines to this fraction of ``tol``
CERT_FRACTION = 1e-2
#: relative pad on the diagonal of the stored inverse (its float32 rounding and the
#: rounding of the rank-one updates between folds)
DIAG_PAD = 1e-3
#: the peak candidates are solved to this fraction of ``tol`` (near the rounding level)
PEAK_FRACTION = 1e-4
#: the rounding of a residual by the FFT operator, in units of eps log2(FFT points) times the
#: norms it is made of (:meth:`_Bound.rounding`): a forward and a backward transform of
#: relative 2-norm error below 4 eps log2 M each, the spectrum's product and the subtraction
ROUNDING = 10.0


def _largest_eigenvalue(inv: StickSolver, sites: np.ndarray, nx: int) -> float:
    """The largest eigenvalue of the stored inverse: dense for small orders, else Lanczos
    (ARPACK's tolerance 1e-2) from the checkerboard over the rows' ``sites`` (flat indices on
    a grid ``nx`` wide; deterministic). The largest eigenvalue of the inverse is the smallest
    of :math:`G_{SS}`, whose mode alternates from pixel to pixel: from there Lanczos needs
    fewer products than from the vector of ones (measured on four scenes: 21 against 31-41,
    the Ritz value within 0.12 % below the eigenvalue, against 0.8 %)."""
    if inv.m <= 500:
        buf = getattr(inv, "buf", None)  # the dense inverse: its stored lower part
        low = (inv.apply(np.eye(inv.m)) if buf is None
               else buf[: inv.m, : inv.m].astype(np.float64))
        return float(np.linalg.eigvalsh(low, UPLO="L")[-1])
    op = LinearOperator((inv.m, inv.m), matvec=lambda v: inv.apply(np.ravel(v)),
                        dtype=np.float64)
    iy, ix = np.divmod(sites, nx)
    start = np.where((iy + ix) % 2 == 0, 1.0, -1.0)
    return float(eigsh(op, k=1, which="LA", v0=start, tol=1e-2,
                       return_eigenvectors=False)[0])


def _kernel_sum(b: Bonds) -> float:
    r"""A bound on the largest modulus of the FFT operator's spectrum: four times the largest
    absolute sum of the response to a unit force at the corner, over its components. The
    operator is a circulant on the FFT grid whose row is the kernel on at most four quadrants
    of the corner's window (the grid itself when periodic), and a circulant's eigenvalues are
    at most its absolute row sum."""
    shape = b.shape if b.k == 1 else (b.k, *b.shape)
    worst = 0.0
    for a in range(b.k):
        v = np.zeros(shape)
        v[(0, 0) if b.k == 1 else (a, 0, 0)] = 1.0
        worst = max(worst, float(np.abs(b.apply(v, np.empty(shape))).sum()))
    return 4.0 * worst


def _compression_error(b: Bonds, inv: StickSolver) -> float:
    r"""An estimate of a bound on the 2-norm of :math:`G_{SS} - \tilde A`, the exact matrix
    less the one a compressed inverse holds
    (:meth:`~roughslip.linalg.hierarchical.HierarchicalInverse.compressed_product`), with the
    rounding of its products, :math:`m\,\epsilon\,\|G_{SS}\|_2`, added; times
    :data:`NU_SAFETY`. Dense for small orders, else Lanczos on the difference and on
    :math:`G_{SS}` by the FFT operator (ARPACK's tolerance 1e-2, deterministic starts)."""
    live = inv.live
    pos = inv.ids[live]
    m = int(live.sum())
    eps = float(np.finfo(float).eps)
    if m <= 500:
        G = b.dense(pos)
        E = G - inv.compressed_product(np.eye(inv.m)[:, live])[live]
        err = float(np.abs(np.linalg.eigvalsh((E + E.T) / 2)).max())
        return NU_SAFETY * (err + m * eps * float(np.linalg.eigvalsh(G)[-1]))

    def diff(v: np.ndarray) -> np.ndarray:
        v = np.ravel(v)
        full = np.zeros(inv.m)
        full[live] = v
        return b.product(pos, v) - inv.compressed_product(full)[live]

    start = np.random.default_rng(0).standard_normal(m)
    norms = [float(abs(eigsh(LinearOperator((m, m), matvec=f, dtype=np.float64), k=1,
                             which="LM", v0=start, tol=1e-2,
                             return_eigenvectors=False)[0]))
             for f in (diff, lambda v: b.product(pos, np.ravel(v)))]
    return NU_SAFETY * (norms[0] + m * eps * norms[1])


class _Bound:
    r"""The running bound :math:`\nu(R_c + \hat g A)` on :math:`|\tilde\varphi_i -
    \varphi_i|` (module docstring) and the counters of the certified decisions."""

    def __init__(self, b: Bonds, inv: StickSolver, tol: float) -> None:
        self.b, self.inv, self.tol = b, inv, tol
        self.nu = NU_SAFETY * _largest_eigenvalue(inv, b.sites[inv.ids[: inv.m] // b.k],
                                                  b.shape[1])
        self.gamma = 0.0  # largest measured ||rho|| / ||c||
        self.growth = 0.0  # largest measured (||r|| - R_c) / A over a stretch of removals
        self.R, self.A = 0.0, 0.0
        self.d = self.d_max = None  # the inverse's diagonal on the rows, and its maximum
        self.worst, self.refinements = 0.0, 0
        self.sharpened = self.full = self.exceeded = self.states = 0
        #: the smallest lambda f_z of a live row, or below it (rows only leave)
        self.cap_min = float(b.cap.min())
        #: a bound on the FFT operator's largest eigenvalue (:meth:`rounding`)
        self.kernel_sum = _kernel_sum(b)
        self.log_points = math.log2(math.prod(b.op.padded_shape))
        #: a compressed inverse's error, the estimate of ||G_SS - A~||_2 with its rounding
        #: floor and safety factor (:func:`_compression_error`; zero for a float32 inverse,
        #: whose stored matrix is the inverse of the exact one, rounded)
        self.delta = (_compression_error(b, inv) if hasattr(inv, "compressed_product")
                      else 0.0)
        if self.delta:
            # nu and the diagonal are the held inverse's; the exact matrix's smallest
            # eigenvalue is at least the held one's less delta (Weyl), and its inverse's
            # entries within nu_G nu delta of the held one's
            if self.nu * self.delta >= 0.5:
                raise NumericalError(
                    f"pull: the compressed inverse is too coarse for certified decisions "
                    f"(nu delta = {self.nu * self.delta:.2g} >= 0.5)")
            self.nu = self.nu / (1.0 - self.nu * self.delta)

    @property
    def gamma_hat(self) -> float:
        r""":math:`\hat\gamma`: :data:`GAMMA_SAFETY` times the largest measured column
        ratio :math:`\|\rho\|/\|\tilde c\|`, and at least a compressed inverse's
        :math:`\delta` (which bounds that ratio, :func:`_compression_error`)."""
        return max(GAMMA_SAFETY * self.gamma, self.delta)

    @property
    def g_hat(self) -> float:
        r""":math:`\hat g`, the growth rate of the residual per unit of
        :math:`\sum|\alpha|\,\|\tilde c\|`: :data:`GROWTH_SAFETY` times the largest
        realised rate once one is measured, :math:`\hat\gamma` before that; at least
        :math:`\delta`."""
        learned = GROWTH_SAFETY * self.growth if self.growth else self.gamma_hat
        return max(learned, self.delta)

    def rounding(self, x_norm: float, rhs_norm: float) -> float:
        r"""A bound on the 2-norm of the rounding in a residual :math:`b - G x` computed by the
        FFT operator, with :math:`\|x\|_2` = ``x_norm`` and :math:`\|b\|_2` = ``rhs_norm``:
        :data:`ROUNDING` :math:`\epsilon \log_2 M\,(\|b\|_2 + \bar\lambda\|x\|_2)`, the
        transforms' error (relative in the 2-norm; Higham, *Accuracy and Stability of Numerical
        Algorithms*, 2002, ch. 24) amplified by at most
        the spectrum's largest modulus :math:`\bar\lambda` (:func:`_kernel_sum`)."""
        return (ROUNDING * np.finfo(float).eps * self.log_points
                * (rhs_norm + self.kernel_sum * x_norm))

    def residual_bound(self) -> float:
        """The bound on the 2-norm of the tracked solution's residual now."""
        return self.R + self.g_hat * self.A

    def measured(self, rn: float) -> None:
        """A residual norm ``rn`` measured after the removals counted in ``A``: check the
        bound, learn the rate, restart the count from it."""
        if self.A > 0:
            if rn > (1 + 1e-6) * self.residual_bound():
                self.exceeded += 1
            self.growth = max(self.growth, (rn - self.R) / self.A)
        self.R, self.A = rn, 0.0

    def refresh(self) -> None:
        r"""Take the diagonal :math:`d_i = (G_{SS}^{-1})_{ii}` from the stored inverse (after a
        fold, when no removal is pending)."""
        self.d = (np.maximum(self.inv.diagonal().astype(np.float64), 0.0) * (1 + DIAG_PAD)
                  + self.nu * self.nu * self.delta)
        self.d_max = float(self.d[self.inv.live].max()) if self.inv.live.any() else 0.0

    def beta(self, rows: np.ndarray | int) -> np.ndarray | float:
        r"""The bound on :math:`|\tilde\varphi_i - \varphi_i|` for ``rows`` now:
        :math:`\sqrt{\nu d_i}` times the residual bound (module docstring)."""
        return np.sqrt(self.nu * self.d[rows]) * self.residual_bound()

    def _residual_on_rows(self, first: list[float] | None = None
                          ) -> Callable[[np.ndarray], tuple[np.ndarray, float]]:
        """``residual(x)`` for :meth:`~roughslip.linalg.inverse.UpdatableInverse.refine`: the
        residual of ``x`` on the rows (zero on dead rows) by the FFT operator and its relative
        norm; the first relative norm is appended to ``first``."""
        inv = self.inv
        live = inv.live
        pos = inv.ids[live]

        def residual(x: np.ndarray) -> tuple[np.ndarray, float]:
            r, res = stick_residual(self.b, pos, x[live], self.b.drive_rows(pos))
            full = np.zeros(inv.m)
            full[live] = r
            if first is not None and not first:
                first.append(res)
            return full, res

        return residual

    def _rhs_norm(self) -> float:
        r"""The 2-norm of the right-hand side on the live rows, which turns a relative
        residual into :math:`\|r\|_2`: the square root of the live rows with the x component
        alone, of the live bonds with the traction vector (each bond's
        :math:`\hat{\mathbf e}` has norm 1)."""
        live = int(self.inv.live.sum())
        return math.sqrt(live) if self.b.k == 1 else math.sqrt(live / self.b.k)

    def residual(self) -> tuple[np.ndarray, float]:
        """The residual of the tracked solution on the rows and its 2-norm."""
        r, res = self._residual_on_rows()(self.inv.tracked["phi"].x)
        return r, res * self._rhs_norm()

    def removed(self, alpha: float, column: np.ndarray) -> None:
        r"""A row leaves with the column ``column`` of the inverse and the step ``alpha``:
        the residual's count grows by :math:`|\alpha|\,\|\tilde c\|`. The diagonal is
        left as it is: a removal only lowers it (:math:`d_i - \tilde c_i^2/\tilde c_k`), so
        the one taken at the last fold stays an upper bound."""
        self.A += abs(alpha) * float(np.linalg.norm(column[self.inv.live]))

    def certify(self, cap: np.ndarray) -> None:
        r"""Refine the tracked solution to ``CERT_FRACTION x tol``, check the bound against the
        residual found, and sample the column ratio on the two leading rows (``cap``:
        :math:`\lambda f_z` on the rows, infinite on dead ones)."""
        scale = self._rhs_norm()
        first: list[float] = []
        t = self.inv.tracked["phi"]
        t.x, res, n = self.inv.refine(t.x, self._residual_on_rows(first), CERT_FRACTION
                                      * self.tol, 4)
        self.measured(first[0] * scale)
        self.refinements += n
        self.worst = max(self.worst, res)
        self.R, self.A = res * scale, 0.0
        self.refresh_and_sample(cap)

    def refresh_and_sample(self, cap: np.ndarray) -> None:
        r"""After a fold: the diagonal afresh (:meth:`refresh`) and the column ratio sampled on
        the two rows of largest :math:`|\varphi_i|/(\lambda f_{z,i})` (``cap``: infinite on
        dead rows)."""
        self.refresh()
        live = self.inv.live
        ratio = np.abs(self.inv.tracked["phi"].x) / cap
        ratio[~live] = -1.0
        for row in np.argsort(-ratio, kind="stable")[:min(2, int(live.sum()))]:
            self._sample(int(row))

    def _sample(self, row: int) -> None:
        r"""Measure :math:`\|\rho\|/\|\tilde c\|` for the column of ``row`` (one FFT)."""
        inv, live = self.inv, self.inv.live
        c = inv.column(row)
        u = self.b.product(inv.ids[live], c[live])
        rho = -u
        rho[int(np.count_nonzero(live[:row]))] += 1.0
        self.gamma = max(self.gamma, float(np.linalg.norm(rho) /
                                           max(np.linalg.norm(c[live]), 1e-300)))

    def decide(self, phi: np.ndarray, cap: np.ndarray) -> tuple[int, float, float]:
        r"""The row of the next break (with several components per bond, its bond's first
        row), the largest ratio :math:`m` and the bound on the error of :math:`m` (module
        docstring). A bond's ratio is :math:`|\boldsymbol\varphi_i|/(\lambda f_{z,i})`, whose
        error is at most the norm of its components' bounds,
        :math:`\sqrt{\nu \sum_c d_{i,c}}\,R`."""
        self.states += 1
        k = self.b.k
        Rb = self.residual_bound()
        d = self.d if k == 1 else self.d.reshape(-1, k).sum(axis=1)
        wide = math.sqrt(self.nu * (self.d_max if k == 1 else k * self.d_max)) * Rb
        if k == 1:
            found = _candidates(phi, cap, d, self.nu, Rb, wide / self.cap_min)
        else:
            found = _candidates(self.b.bond_values(phi), np.ascontiguousarray(cap[::k]), d,
                                self.nu, Rb, wide / self.cap_min)
        if found is None:
            raise NumericalError("pull: non-finite tangential force ratio")
        j, m, dm, cand = found
        low = m - dm
        if cand.size <= 1:
            return j * k, m, dm
        if cand.size <= MAX_SHARPEN:
            picked = self._sharpen(phi, cap, cand, low)
            if picked is not None:
                return picked
        self.full += 1
        t = self.inv.tracked["phi"]
        t.x, res, n = self.inv.refine(t.x, self._residual_on_rows(), CERT_FRACTION * self.tol,
                                      6)
        self.refinements += n
        self.R, self.A = res * self._rhs_norm(), 0.0
        ratio = self.b.bond_values(t.x) / cap[::k]
        j = argext(ratio, None, "max")
        if k == 1:
            return j, float(ratio[j]), float(self.beta(j)) / cap[j]
        beta = self.beta(np.arange(j * k, j * k + k))
        return j * k, float(ratio[j]), float(np.sqrt(np.sum(np.square(beta)))) / cap[j * k]

    def _sharpen(self, phi: np.ndarray, cap: np.ndarray, cand: np.ndarray, low: float
                 ) -> tuple[int, float, float] | None:
        """Sharpen the candidates (one FFT); the decision, or None when still open."""
        self.sharpened += 1
        r, rn = self.residual()
        x = self.inv.tracked["phi"].x
        slack = self.rounding(float(np.linalg.norm(x[self.inv.live])), self._rhs_norm())
        rn += slack
        self.measured(rn)
        vals, errs = np.empty(cand.size), np.empty(cand.size)
        live = self.inv.live
        comps = self.b.k
        for k, bond in enumerate(cand):
            v, e = np.empty(comps), np.empty(comps)
            for c_ in range(comps):
                i = int(bond) * comps + c_
                c = self.inv.column(i)
                c[~live] = 0.0
                v[c_] = phi[i] + float(c @ r)
                norm = float(np.linalg.norm(c))
                e[c_] = (self.nu * self.gamma_hat * norm * rn + norm * slack
                         + 4 * np.finfo(float).eps * abs(phi[i]))
            i = int(bond) * comps
            if comps == 1:
                vals[k], errs[k] = abs(v[0]) / cap[i], e[0] / cap[i]
            else:  # the norm's error is at most the norm of its components' errors
                vals[k] = math.sqrt(float(v @ v)) / cap[i]
                errs[k] = math.sqrt(float(e @ e)) / cap[i]
        lower, upper = vals - errs, vals + errs
        rest = (1 - TIE) * low  # above every upper bound outside the candidates
        for k in range(cand.size):  # rows in increasing order: the tie rule's order
            others = np.delete(np.arange(cand.size), k)
            hi = max(float(upper[others].max()) if others.size else -math.inf, rest)
            lo = max(float(lower[others].max()) if others.size else -math.inf, 0.0)
            # row k ties with the extreme iff rho_k >= (1 - TIE) max of the others
            if upper[k] < (1 - TIE) * lo:
                continue  # certainly out of the tie set
            if lower[k] >= (1 - TIE) * hi:
                top = int(np.argmax(vals))
                return int(cand[k]) * comps, float(vals[top]), float(errs[top])
            return None
        return None


def _candidates_np(phi: np.ndarray, cap: np.ndarray, d: np.ndarray, nu: float, Rb: float,
                   spread: float) -> tuple[int, float, float, np.ndarray] | None:
    r"""The leading row ``j`` (ties: :func:`~roughslip.friction.events.argext`), its ratio
    :math:`m = |\varphi_j|/c_j`, the bound :math:`\delta m = \sqrt{\nu d_j}\,R/c_j` and the
    rows whose upper bound reaches :math:`(1 - \text{TIE})(m - \delta m)`; None when
    :math:`m` is not finite. ``spread`` (the largest :math:`\sqrt{\nu d_i} R` over the
    smallest :math:`c_i`) prefilters the rows; the exact test then runs on those it keeps."""
    ratio = np.abs(phi) / cap
    if not math.isfinite(float(ratio.max())):
        return None
    j = argext(ratio, None, "max")
    m = float(ratio[j])
    dm = float(np.sqrt(nu * d[j]) * Rb) / cap[j]
    low = m - dm
    pre = np.flatnonzero(ratio >= (1 - TIE) * low - spread)
    cand = pre[ratio[pre] + np.sqrt(nu * d[pre]) * Rb / cap[pre] >= (1 - TIE) * low]
    return j, m, dm, cand


@functools.cache
def _compiled_candidates():
    """:func:`_candidates_np` in three compiled passes over the rows (the same IEEE operations
    in the same order); the ratios are divided once."""
    @jit.njit()
    def scan(phi, cap, d, nu, Rb, spread, tie, tiny):
        n = phi.size
        ratio = np.empty(n)
        for i in range(n):
            ratio[i] = abs(phi[i]) / cap[i]
        ext = -np.inf
        nan = False
        for i in range(n):
            r = ratio[i]
            nan |= r != r
            ext = r if r > ext else ext
        cand = np.empty(0, np.int64)
        if nan or not (ext - ext == 0.0):  # not finite: left to the numpy path
            return -1, ext, 0.0, cand
        close = tie * max(abs(ext), tiny)
        j = 0
        for i in range(n):
            if abs(ratio[i] - ext) <= close:
                j = i
                break
        m = ratio[j]
        dm = (np.sqrt(nu * d[j]) * Rb) / cap[j]
        low = m - dm
        thr = (1 - tie) * low
        pre = thr - spread
        count = 0
        out = np.empty(n, np.int64)
        for i in range(n):
            r = ratio[i]
            if r >= pre and r + np.sqrt(nu * d[i]) * Rb / cap[i] >= thr:
                out[count] = i
                count += 1
        return j, m, dm, out[:count].copy()

    return scan


def _candidates(phi: np.ndarray, cap: np.ndarray, d: np.ndarray, nu: float, Rb: float,
                spread: float, compiled: bool | None = None
                ) -> tuple[int, float, float, np.ndarray] | None:
    """:func:`_candidates_np`, by one compiled kernel or by numpy (``compiled``: default
    :data:`roughslip.linalg.jit.ENABLED`): the same numbers either way."""
    if not (jit.ENABLED if compiled is None else compiled):
        return _candidates_np(phi, cap, d, nu, Rb, spread)
    j, m, dm, cand = _compiled_candidates()(phi, cap, d, float(nu), float(Rb), float(spread),
                                            TIE, float(np.finfo(float).tiny))
    if j < 0:
        return _candidates_np(phi, cap, d, nu, Rb, spread)
    return int(j), float(m), float(dm), cand


class _Peaks:
    """The break states that can still be the peak, kept until they are solved exactly."""

    def __init__(self, b: Bonds, curve: BreakCurve, tol: float, max_iter: int) -> None:
        self.b, self.curve, self.tol, self.max_iter = b, curve, tol, max_iter
        self.kept: list[tuple[int, np.ndarray, np.ndarray, float, float]] = []
        self.low = -math.inf  # the largest lower bound of a recorded F_x,lim
        self.high = -math.inf  # the largest upper bound among the kept states
        self.solved = 0
        self.worst = 0.0
        self.curve_error = 0.0

    def add(self, step: int, F: float, err: float,
            state: Callable[[], tuple[np.ndarray, np.ndarray]]) -> None:
        """Record break ``step`` with its bound; if it can still be the peak keep its state,
        ``state()`` (the stick positions and the tracked solution on them, new arrays)."""
        self.curve_error = max(self.curve_error, err / max(abs(F), 1e-300))
        if F + err < self.low:
            return
        self.low = max(self.low, F - err)
        self.kept = [k for k in self.kept if k[3] + k[4] >= self.low]
        self.kept.append((step, *state(), F, err))
        self.high = max(k[3] + k[4] for k in self.kept)

    def solve(self) -> None:
        """Solve every kept state by CG from its tracked solution; the curve takes the exact
        values and the best of them becomes the peak."""
        b, curve = self.b, self.curve
        best = -math.inf
        done = []
        for step, pos, phi, _, err in self.kept:
            if err == 0.0:  # solved before
                done.append((step, pos, phi, curve.fx[step], 0.0))
                best = max(best, curve.fx[step])
                continue
            phi = b.solve_stick(pos, phi, PEAK_FRACTION * self.tol, self.max_iter)
            _, rel = stick_residual(b, pos, phi, b.drive_rows(pos))
            self.worst = max(self.worst, rel)
            self.solved += 1
            m = float(np.max(b.bond_values(phi) / b.cap[pos[:: b.k] // b.k]))
            dx = 1.0 / m
            F = b.along(phi) * dx
            curve.dx[step], curve.fx[step] = dx, F
            done.append((step, pos, phi, F, 0.0))
            best = max(best, F)
        self.kept = [k for k in done if k[3] >= best]
        step, pos, phi, F, _ = self.kept[0]
        curve.best, curve.peak = F, step
        curve.peak_state = (pos, phi * curve.dx[step], curve.dx[step])
        self.low = self.high = F

    def stop(self, cap_sum_after: float) -> bool:
        """The exact early stop (every later F_x,lim <= lambda sum f_z over the stick set),
        solving the kept states first when the bounds leave it open."""
        if not self.curve.early_stop or cap_sum_after > self.high:
            return False
        if cap_sum_after > self.low:
            self.solve()
        if cap_sum_after <= self.low:
            self.curve.stopped = True
        return self.curve.stopped


class SingleSequence:
    r"""The break law on a float32 inverse with certified decisions (module docstring), a
    strategy of :class:`~roughslip.friction.sliding.TangentialState` (whose stick solver holds
    the inverse in float32 under ``precision = "single"``): the same break sequence as the
    double-precision method, and the friction force to its accuracy. It records its curve
    itself (each point with its bound) and settles the peak by the kept candidates
    (:class:`_Peaks`); it tells the state's observers nothing."""

    def run(self, st: TangentialState, t0: float) -> PullResult:
        b, opt, inv, rows = st.b, st.opt, st.inv, st.rows
        tol = opt.tol
        curve = BreakCurve(b, opt.early_stop)
        bound = _Bound(b, inv, tol)
        bound.certify(rows.cap)
        peaks = _Peaks(b, curve, tol, opt.max_iter)
        cap_sum = float(b.cap.sum())
        while rows.alive:
            phi, cap, pos = inv.tracked["phi"].x, rows.cap, inv.ids
            j, m, dm = bound.decide(phi, cap)
            phi = inv.tracked["phi"].x  # a full refinement replaces it
            live = np.isfinite(cap)
            on = phi[live]
            dx = 1.0 / m
            # the force along the drive; its error, e.(sum of errors) = -phi^T r, at most
            # |phi| |r| (the adjoint of the stick solve)
            F = b.along(on) * dx
            R = bound.residual_bound()
            err = (math.sqrt(float(on @ on)) * R * dx + abs(F) * dm / m) * 1.01
            curve.dx.append(dx)
            curve.fx.append(F)
            curve.site.append(int(b.sites[pos[j] // b.k]))
            peaks.add(len(curve.fx) - 1, F, err, lambda p=pos, lv=live, o=on: (p[lv], o))
            cap_sum -= float(cap[j])
            if peaks.stop(cap_sum) or rows.alive == b.k:
                break
            for row in range(j, j + b.k):  # the bond's rows, each with its current column
                c = inv.column(row)
                bound.removed(inv.tracked["phi"].x[row] / c[row], c)
                rows.remove(inv, row, c)
            if rows.fold(inv, dead=COMPACT_DEAD):
                bound.certify(rows.cap)
        if peaks.kept:
            peaks.solve()
        worst = max(bound.worst, peaks.worst)
        ok = worst <= tol
        what = ("single precision" if opt.precision == "single"
                else f"{inv.kind} inverse")
        msg = (f"{b.n} bonds, block {inv.block}, {what}: {bound.refinements} "
               f"refinements, {bound.sharpened} of {bound.states} decisions sharpened, "
               f"{bound.full} refined in full, bound exceeded {bound.exceeded} times, "
               f"{peaks.solved} peak candidates solved; curve points within "
               f"{peaks.curve_error:.1e} relative, the peak exact")
        return curve.result(t0, opt.method_name, converged=bool(ok), residual=worst,
                            solves=bound.refinements + peaks.solved, message=msg,
                            precision=opt.precision)


def break_inverse_single(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    r"""The break law on a float32 inverse with certified decisions: the tangential state in
    single precision advanced by :class:`SingleSequence`."""
    return TangentialState(b, replace(opt, precision="single")).run(SingleSequence(), t0)
