"""Time the coupled model against the decoupled pull on the same scenes.

    python scripts/bench_coupled.py [--sizes 64 128] [--areas 0.05 0.175] [--methods auto cg]
                                    [--slip-law break|coulomb]

Scenes: a self-affine surface (H = 0.8, rms height 1, seed 1, oversampled twice), nu = 0.25,
lam = 0.2, open grid, at the depth where the frictionless squeeze has the given contact
fraction. For each: the decoupled exact pull (``auto``) and the coupled model with each
``--methods`` solver, their seconds, events, the ratio coupled / decoupled, and the shares of the
coupled time spent before the pull starts (the squeeze and the release of the bonds it overloads
at D_x = 0), inside FFT calls and in dense linear algebra (BLAS/LAPACK: the dense solver's
factorisation, products with its inverse and updates). ``--slip-law coulomb`` times both
models under the Coulomb law. Threads: BLAS and FFT use ``--threads``.
"""

from __future__ import annotations

import argparse
import os
import time

from bench_squeeze import depth_for_area  # the same scenes as the squeeze benchmark

from roughslip import couple, pull
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
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
    args = ap.parse_args()
    law = args.slip_law
    print(f"# cores: {os.cpu_count()}, threads {args.threads}; H = 0.8, nu = 0.25, lam = 0.2, "
          f"open grid, slip law {law}")
    print(f"{'N':>5} {'area':>6} {'sites':>6} {'decoupled s':>12} {'method':>8} "
          f"{'coupled s':>10} {'events':>7} {'solves':>7} {'ratio':>7} {'sq%':>5} {'fft%':>5} "
          f"{'blas%':>5}")
    for n in args.sizes:
        h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(1, 0), oversample=2)
        problem = Problem(h, Grid((n, n)), Material(1.0, 0.25), threads=args.threads)
        solver = NormalSolver(problem, tol=1e-12)
        for area in args.areas:
            depth = depth_for_area(solver, area, hi=float(h.max() - h.min()))
            normal = solver.solve(depth=depth)
            t0 = time.perf_counter()
            dec = pull(normal, lam=0.2, slip_law=law)
            t_dec = time.perf_counter() - t0
            for method in args.methods:
                op = problem.operator("zz", "zx", "xx")
                fft0 = op.fft_seconds + op.with_threads(1).fft_seconds
                t0 = time.perf_counter()
                c = couple(problem, depth=depth, lam=0.2, method=method, slip_law=law)
                t_c = time.perf_counter() - t0
                fft = op.fft_seconds + op.with_threads(1).fft_seconds - fft0
                print(f"{n:>5} {normal.contact_area:>6.3f} {normal.n_contact:>6} "
                      f"{t_dec:>12.2f} {c.method:>8} {t_c:>10.2f} {len(c.events):>7} "
                      f"{c.solves:>7} {t_c / t_dec:>7.0f} {100 * c.squeeze_seconds / t_c:>4.0f}% "
                      f"{100 * fft / t_c:>4.0f}% "
                      f"{100 * c.blas_seconds / t_c:>4.0f}%"
                      + ("" if c.converged else f"  NOT CONVERGED: {c.message}"))
            del dec


if __name__ == "__main__":
    main()
