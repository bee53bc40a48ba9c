"""Benchmark the pull stage (break law) on rough surfaces.

    python scripts/bench_pull.py [--sizes 64 128 256] [--areas 0.05 0.2] [--threads 2]
                                 [--literal-max 4000] [--cg-max 4000] [--extra 512:0.05]

Surface: self-affine, H = 0.8, rms height 1, a = 1, cropped from a 2x periodic grid, open
boundary, nu = 0.3, lambda = 0.2; the depth is chosen by bisection for the contact fraction.
For each case: the number of bonds, seconds per method (one run each: the exact methods are
deterministic and each run takes seconds to minutes), the steps taken (early stop), and the
relative difference of the friction force from the literal algorithm (or from the inverse
method where literal is skipped). ``--extra N:area`` adds cases run with the inverse method
only (e.g. 512:0.05, 512:0.2; ``--sizes --extra 512:0.2`` runs only that case, ~21 GiB and
~37 min). ``resid`` is the worst relative residual of the tangential solves (for ``inverse``:
of its certification against the FFT operator after every block of breaks and at the peak).
``kappa`` estimates the condition number of G_xx on the initial bonds, which bounds that of
every later stick set (``bond_spectrum``, Lanczos from a fixed start, not part of the timed
pull), and ``bound`` = kappa * resid estimates the bound on the relative error of the
tangential forces and of their sum at every certified solve.
"""

from __future__ import annotations

import argparse
import os
import time

from benchlib import depth_for_area

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.elastic.operators import Grid, Material
from roughslip.friction.pull import bond_spectrum, pull
from roughslip.surfaces.synthetic import sample_rng, self_affine


def contact(n: int, area: float):
    """The squeezed rough contact of size n whose contact fraction is close to ``area``."""
    h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(2024, 0), oversample=2)
    s = NormalSolver(Problem(h, Grid((n, n)), Material(1.0, 0.3), fft="pyfftw"), tol=1e-11)
    return s.solve(depth=depth_for_area(s, area, float(h.max() - h.min())))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="*", default=[64, 128, 256])
    ap.add_argument("--areas", type=float, nargs="+", default=[0.05, 0.2])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--literal-max", type=int, default=4000, help="skip literal above")
    ap.add_argument("--cg-max", type=int, default=4000, help="skip cg above")
    ap.add_argument("--extra", nargs="*", default=["512:0.05"], help="N:area, inverse only")
    args = ap.parse_args()
    print(f"# cores: {os.cpu_count()}, BLAS/FFT threads: {args.threads}, lambda 0.2, tol 1e-10")
    print(f"{'N':>5} {'area':>6} {'bonds':>6} {'method':>8} {'sec':>9} {'steps':>6} "
          f"{'F_friction':>14} {'rel.diff':>9} {'resid':>8} {'speedup':>8} {'kappa':>6} "
          f"{'bound':>8}")
    cases = [(n, a, ("literal", "inverse", "cg", "batch")) for n in args.sizes for a in args.areas]
    cases += [(int(e.split(":")[0]), float(e.split(":")[1]), ("inverse",)) for e in args.extra]
    for n, area, methods in cases:
        normal = contact(n, area)
        results = {}
        for m in methods:
            if m == "literal" and normal.n_contact > args.literal_max:
                continue
            if m == "cg" and normal.n_contact > args.cg_max:
                continue
            t0 = time.perf_counter()
            res = pull(normal, lam=0.2, method=m, tol=1e-10, threads=args.threads)
            results[m] = (time.perf_counter() - t0, res)
        lo, hi = bond_spectrum(normal, threads=args.threads)
        ref = results.get("literal", results.get("inverse"))[1]
        t_lit = results["literal"][0] if "literal" in results else None
        for m, (sec, res) in results.items():
            diff = (res.friction_force - ref.friction_force) / ref.friction_force
            speed = f"{t_lit / sec:8.1f}" if t_lit else f"{'-':>8}"
            # batch is approximate: its error is its bias (it has no estimate), not the solves'
            bound = f"{hi / lo * res.residual:>8.1e}" if m != "batch" else f"{'-':>8}"
            print(f"{n:>5} {normal.contact_area:>6.3f} {res.details.n_bonds:>6} {m:>8} {sec:>9.2f} "
                  f"{res.steps:>6} {res.friction_force:>14.10f} {diff:>9.1e} {res.residual:>8.1e} "
                  f"{speed} {hi / lo:>6.1f} {bound}", flush=True)


if __name__ == "__main__":
    main()
