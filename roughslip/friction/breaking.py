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
    BondRows,
    Bonds,
    BreakCurve,
    PullOptions,
    bond_inverse,
    certify,
    select,
    stick_residual,
    track,
)
from roughslip.friction.breaking_single import break_inverse_single
from roughslip.friction.result import PullResult
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
    r"""Exact break law on the stick solver of ``opt.method`` (the updated inverse,
    :func:`~roughslip.friction.bonds.bond_inverse`): :math:`O(n)` per break plus the solver's
    blocked updates; :math:`\varphi` is certified against the FFT operator after each fold,
    and the sequence stops exactly once :math:`\lambda\sum_S f_z` falls below the best.
    ``opt.precision == "single"``: the float32 inverse with certified decisions
    (:func:`~roughslip.friction.breaking_single.break_inverse_single`).
    """
    if opt.precision == "single":
        return break_inverse_single(b, opt, t0)
    tol, block = opt.tol, opt.block
    curve = BreakCurve(b, opt.early_stop)
    inv = bond_inverse(b, block, opt.threads, solver=opt.solver())
    track(inv, "phi", np.ones(b.n))
    rows = BondRows(b)
    cap_sum = float(b.cap.sum())
    worst, refinements, ok = 0.0, 0, True
    while rows.alive:
        phi, cap, pos = inv.tracked["phi"].x, rows.cap, inv.ids
        j, m = select(phi, cap)
        live = np.isfinite(cap)
        curve.record(float(phi.sum()), m, pos[j],
                     lambda p=pos, f=phi, lv=live: (p[lv], f[lv]))
        cap_sum -= float(cap[j])
        if curve.should_stop(cap_sum) or rows.alive == 1:
            break
        rows.remove(inv, j)
        if rows.fold(inv):
            res, nref = certify(b, inv, "phi", None, tol)
            worst, refinements = max(worst, res), refinements + nref
            ok &= res <= tol
    if curve.peak_state is not None:  # the state that gives the friction force, certified
        pos, f, dx = curve.peak_state
        _, res = stick_residual(b, pos, f / dx, 1.0)
        worst, ok = max(worst, res), ok and res <= tol
    return curve.result(t0, opt.method_name, converged=bool(ok), residual=worst,
                        solves=refinements, precision="double",
                        message=f"{b.n} bonds, block {block}, {refinements} refinements")


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
