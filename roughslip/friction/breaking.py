r"""The break law's pull methods: a bond whose :math:`|f_x|` reaches :math:`\lambda f_z` breaks
and carries nothing after (docs/theory/pull.rst#break-law; [Report2003] §4.6-4.7 with errata
T17 and T18).

On the stick set :math:`S`, :math:`G_{xx}[S,S]\,\varphi = 1_S` and :math:`f_x = D_x\varphi`;
the next bond breaks at :math:`D_{x,\rm lim} = 1/\max_i |\varphi_i|/(\lambda f_{z,i})`. The
methods differ in how they get :math:`\varphi` for each stick set (:mod:`roughslip.friction.pull`
lists them).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from roughslip.friction.bonds import (
    Bonds,
    BreakCurve,
    PullOptions,
    select,
)
from roughslip.friction.breaking_single import SingleSequence
from roughslip.friction.result import PullResult
from roughslip.friction.sliding import BreakSequence, TangentialState
from roughslip.linalg.cg import CGResult, cg


def _solve_phi(b: Bonds, alive_pos: np.ndarray, tol: float, x0: np.ndarray | None,
               max_iter: int) -> tuple[np.ndarray, CGResult]:
    r""":math:`\varphi` on the stick set: :math:`G_{xx}[S,S]\varphi = 1_S` by CG."""
    A = b.restricted(alive_pos)
    x0f = None if x0 is None else b.field(x0, alive_pos)
    r = cg(A, A.weights, x0=x0f, tol=tol, max_iter=max_iter)
    return A.gather(r.x), r


def break_literal(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    """The report's algorithm: one CG solve from zero per break, every bond."""
    return _break_solves(b, opt, t0, warm=False)


def break_cg(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    """Matrix-free exact: one warm-started CG solve per break, with the early stop."""
    return _break_solves(b, opt, t0, warm=True)


def _break_solves(b: Bonds, opt: PullOptions, t0: float, *, warm: bool) -> PullResult:
    """One CG solve per break (cold from zero, or warm from the previous solution)."""
    tol, max_iter = opt.tol, opt.max_iter
    curve = BreakCurve(b, opt.early_stop and warm)
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
        j, m = select(phi, b.cap[alive])
        curve.record(float(phi.sum()), m, alive[j], lambda a=alive, p=phi: (a.copy(), p))
        cap_sum -= float(b.cap[alive[j]])
        if curve.should_stop(cap_sum):
            break
        alive = np.delete(alive, j)
        phi = np.delete(phi, j)
    return curve.result(t0, opt.method_name, converged=bool(ok), solves=solves,
                        residual=worst, message=f"{solves} CG solves, {iters} iterations")


def break_sequence(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    r"""Exact break law on the stick solver of ``opt.method``: the tangential state
    (:class:`~roughslip.friction.sliding.TangentialState`) advanced by the break law's fast
    path (:class:`~roughslip.friction.sliding.BreakSequence`): :math:`O(n)` per break plus the
    solver's blocked updates, :math:`\varphi` certified against the FFT operator after each
    fold, and the exact early stop once :math:`\lambda\sum_S f_z` falls below the best.
    ``opt.precision == "single"``, or a method whose inverse is inexact (a compressed one,
    :attr:`~roughslip.friction.pull.PullMethod.inexact`): certified decisions
    (:class:`~roughslip.friction.breaking_single.SingleSequence`).
    """
    inexact = opt.method is not None and opt.method.inexact
    strategy = SingleSequence() if opt.precision == "single" or inexact else BreakSequence()
    return TangentialState(b, opt).run(strategy, t0)


#: the break sequence on the dense inverse (the name of earlier versions)
break_inverse = break_sequence


def break_batch(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    """Approximate: break the ``batch_size`` largest-ratio bonds per solve (biased low).

    It has no error estimate (``details.error_estimate`` is NaN). Its error is a staircase in the
    batch size, not a smooth function of it: on the rough verify scenes one size gives the
    exact friction force and the next -18 %, so no comparison of batch sizes estimates it
    (docs/methods.rst#estimates-against-truth).
    """
    res = _batch_pass(b, opt, t0, opt.batch_size)
    return replace(res, message=res.message + "; approximate, no error estimate")


def _batch_pass(b: Bonds, opt: PullOptions, t0: float, size: int) -> PullResult:
    """One batch pass with ``size`` bonds broken per solve."""
    tol, max_iter = opt.tol, opt.max_iter
    curve = BreakCurve(b, opt.early_stop)
    alive = np.arange(b.n)
    phi = None
    ok, solves, worst = True, 0, 0.0
    cap_sum = float(b.cap.sum())
    while alive.size:
        phi, r = _solve_phi(b, alive, tol, phi, max_iter)
        solves += 1
        worst = max(worst, r.residual)
        ok &= r.converged
        j, m = select(phi, b.cap[alive])
        curve.record(float(phi.sum()), m, alive[j], lambda a=alive, p=phi: (a.copy(), p))
        ratio = np.abs(phi) / b.cap[alive]
        order = np.argsort(-ratio, kind="stable")[:size]
        cap_sum -= float(b.cap[alive[order]].sum())
        if curve.should_stop(cap_sum):
            break
        keep = np.ones(alive.size, bool)
        keep[order] = False
        alive, phi = alive[keep], phi[keep]
    return curve.result(t0, opt.method_name, converged=bool(ok), solves=solves, residual=worst,
                        message=f"{solves} CG solves, {size} bonds per solve")
