"""Time the coupled model against the decoupled pull on the same scenes.

    python scripts/bench_coupled.py [--sizes 64 128] [--areas 0.05 0.175] [--methods auto cg]
                                    [--slip-law break|coulomb] [--histories bonded ...]

Scenes: a self-affine surface (H = 0.8, rms height 1, seed 1, oversampled twice), nu = 0.25,
lam = 0.2, open grid, at the depth where the frictionless squeeze has the given contact
fraction. For each: the decoupled exact pull (``auto``) and the coupled model with each
``--methods`` solver and each squeeze history (``--histories``, default all), their seconds,
the states before the pull and the pull's events, the ratio coupled / decoupled pull (``ratio``)
and coupled / decoupled squeeze and pull (``ratio2``: the coupled time includes its squeeze),
and the shares of the coupled time spent before the pull starts (the squeeze history), inside
FFT calls and in dense linear algebra (BLAS/LAPACK: the dense solver's factorisation, products
with its inverse and updates). ``--slip-law coulomb`` times both models under the Coulomb law.
Threads: BLAS and FFT use ``--threads``.
"""

from __future__ import annotations

import argparse
import os
import time

from benchlib import depth_for_area  # the same scenes as the squeeze benchmark

from roughslip import couple, pull
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.coupling.histories import HISTORIES
from roughslip.elastic.operators import Grid, Material
from roughslip.surfaces import sample_rng, self_affine


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    ap.add_argument("--areas", type=float, nargs="+", default=[0.05, 0.175])
    ap.add_argument("--methods", nargs="+", default=["auto"])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--slip-law", choices=["break", "coulomb"], default="break")
    ap.add_argument("--histories", nargs="+", default=list(HISTORIES.names()),
                    choices=HISTORIES.names())
    args = ap.parse_args()
    law = args.slip_law
    print(f"# cores: {os.cpu_count()}, threads {args.threads}; H = 0.8, nu = 0.25, lam = 0.2, "
          f"open grid, slip law {law}")
    print(f"{'N':>5} {'area':>6} {'sites':>6} {'squeeze s':>10} {'pull s':>7} {'method':>8} "
          f"{'history':>13} {'coupled s':>10} {'states':>7} {'events':>7} {'solves':>7} "
          f"{'ratio':>6} {'ratio2':>6} {'sq%':>5} {'fft%':>5} {'blas%':>5}")
    for n in args.sizes:
        h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(1, 0), oversample=2)
        problem = Problem(h, Grid((n, n)), Material(1.0, 0.25), threads=args.threads)
        solver = NormalSolver(problem, tol=1e-12)
        for area in args.areas:
            depth = depth_for_area(solver, area, hi=float(h.max() - h.min()))
            t0 = time.perf_counter()
            normal = NormalSolver(problem, tol=1e-8).solve(depth=depth)  # a run's squeeze
            t_sq = time.perf_counter() - t0
            normal = solver.solve(depth=depth)
            t0 = time.perf_counter()
            dec = pull(normal, lam=0.2, slip_law=law)
            t_dec = time.perf_counter() - t0
            for method in args.methods:
                for history in args.histories:
                    op = problem.operator("zz", "zx", "xx")
                    fft0 = op.fft_seconds + op.with_threads(1).fft_seconds
                    t0 = time.perf_counter()
                    c = couple(problem, depth=depth, lam=0.2, method=method, slip_law=law,
                               history=history)
                    t_c = time.perf_counter() - t0
                    fft = op.fft_seconds + op.with_threads(1).fft_seconds - fft0
                    print(f"{n:>5} {normal.contact_area:>6.3f} {normal.n_contact:>6} "
                          f"{t_sq:>10.2f} {t_dec:>7.2f} {c.method:>8} {history:>13} "
                          f"{t_c:>10.2f} {c.squeeze_states:>7} {len(c.events):>7} "
                          f"{c.solves:>7} {t_c / t_dec:>6.1f} {t_c / (t_dec + t_sq):>6.1f} "
                          f"{100 * c.squeeze_seconds / t_c:>4.0f}% {100 * fft / t_c:>4.0f}% "
                          f"{100 * c.blas_seconds / t_c:>4.0f}%"
                          + ("" if c.converged else f"  NOT CONVERGED: {c.message}"),
                          flush=True)
            del dec


if __name__ == "__main__":
    main()
