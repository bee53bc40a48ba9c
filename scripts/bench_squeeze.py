"""Benchmark the squeeze (Polonsky-Keer CG) on rough and Hertz surfaces.

    python scripts/bench_squeeze.py [--sizes 256 512 1024] [--repeat 3] [--tol 1e-8]

Scenes: a self-affine surface (H = 0.8, rms height 1, a = 1) at depths giving ~5 % and ~20 %
contact, and a Hertz sphere at ~5 % contact; open and periodic boundaries; displacement and
load control (at the force of the displacement-controlled solution). For each: iterations,
convolutions, median seconds over ``--repeat`` runs, milliseconds per iteration, the share of
the time spent inside FFT calls, and the time per iteration (``it/floor``) and per convolution
(``conv/floor``) divided by the floor: one plain convolution (rfft2 . kernel . irfft2,
unpruned) of the same padded size, measured in the same run. ``conv/floor`` is what the
element-wise work adds to the transforms; an iteration does one convolution, plus one when
the projection changes more sites than direct sums can carry. A final table compares a
warm-started depth sweep with cold starts.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
from benchlib import depth_for_area, floor_seconds

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.elastic.operators import Grid, Material
from roughslip.surfaces.synthetic import sample_rng, self_affine, sphere


def scenes(n: int):
    rough_open = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(2024, 0),
                             oversample=2)
    rough_per = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(2024, 0))
    hertz = sphere((n, n), radius=2.0 * n)
    for boundary, rough in (("open", rough_open), ("periodic", rough_per)):
        yield "rough", boundary, rough, (0.05, 0.20)
        yield "hertz", boundary, hertz, (0.05,)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("--sweep-size", type=int, default=512)
    args = ap.parse_args()
    print(f"# cores: {os.cpu_count()}, FFT: pyfftw ESTIMATE, 1 thread, tol {args.tol:g}, "
          f"medians of {args.repeat}")
    print(f"{'N':>5} {'scene':>6} {'bound':>8} {'area':>6} {'ctrl':>5} {'iter':>5} {'conv':>5} "
          f"{'sec':>7} {'ms/it':>7} {'fft%':>5} {'it/floor':>8} {'conv/floor':>10}")
    mat = Material(1.0, 0.3)
    for n in args.sizes:
        for name, boundary, h, areas in scenes(n):
            solver = NormalSolver(Problem(h, Grid((n, n), 1.0, boundary), mat, fft="pyfftw"),
                                  tol=args.tol)
            floor = floor_seconds(solver.op.padded_shape)
            hi = (h.max() - h.min()) if boundary == "open" else 0.999 * (h.max() - h.mean())
            for area in areas:
                d = depth_for_area(solver, area, hi)
                ref = None
                for control in ("depth", "force"):
                    runs = []
                    for _ in range(args.repeat):
                        t0 = time.perf_counter()
                        r = (solver.solve(depth=d) if control == "depth"
                             else solver.solve(force=ref.normal_force))
                        runs.append((time.perf_counter() - t0, r))
                    sec = statistics.median(t for t, _ in runs)
                    r = runs[0][1]
                    ref = ref or r
                    per_it = sec / max(r.iterations, 1)
                    print(f"{n:>5} {name:>6} {boundary:>8} {r.contact_area:>6.3f} "
                          f"{control:>5} {r.iterations:>5} {r.convolutions:>5} {sec:>7.3f} "
                          f"{1e3 * per_it:>7.2f} {r.fft_seconds / runs[0][0]:>5.0%} "
                          f"{per_it / floor:>8.2f} "
                          f"{sec / max(r.convolutions, 1) / floor:>10.2f}", flush=True)
    # warm-started sweep against cold starts, for both methods
    n = args.sweep_size
    h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(2024, 0), oversample=2)
    depths = np.geomspace(0.2, 2.6, 10)
    print(f"\n# depth sweep, N = {n}, open, 10 depths 0.2..2.6 from first touch")
    for method in ("pk", "active-set"):
        solver = NormalSolver(Problem(h, Grid((n, n)), mat, fft="pyfftw"), tol=args.tol,
                              method=method)
        for warm in (False, True):
            x0, its, conv, t0 = None, 0, 0, time.perf_counter()
            for d in depths:
                r = solver.solve(depth=d, x0=x0 if warm else None)
                x0, its, conv = r.fz, its + r.iterations, conv + r.convolutions
            print(f"{method:>10} {'warm' if warm else 'cold':>5}: {its} iterations, {conv} "
                  f"convolutions, {time.perf_counter() - t0:.2f} s (contact "
                  f"{r.contact_area:.3f} at the deepest)", flush=True)

if __name__ == "__main__":
    main()
