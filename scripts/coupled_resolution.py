"""Does the coupled friction force converge with resolution? Hertz at a/h = 8, 16, 32, ...

    python scripts/coupled_resolution.py [--ratios 8 16 32] [--nu 0.25 0.45] [--lam 0.2]

One physical problem, a rigid sphere of radius R = 1 pressed to the depth d = 0.01 into a
half-space (E = 1), so that the Hertz contact radius is a = sqrt(R d) = 0.1, discretised with
pixels of side h = a / ratio on a grid of 4 a (open boundary). For each resolution: the
frictionless Hertz force error, the decoupled friction force and the coupled one (both over
lambda F_n), the coupled/decoupled ratio, the bonds released at D_x = 0 and the seconds. A
converged model gives resolution-independent ratios, with differences shrinking as h halves.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from roughslip import couple, pull
from roughslip.contact.analytic import hertz
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.elastic.operators import Grid, Material
from roughslip.surfaces import sphere


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--ratios", type=int, nargs="+", default=[8, 16, 32])
    ap.add_argument("--nu", type=float, nargs="+", default=[0.25, 0.45])
    ap.add_argument("--lam", type=float, default=0.2)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--coupled-max", type=int, default=32,
                    help="skip the coupled model above this a/h (its time grows fast)")
    args = ap.parse_args()
    R, d = 1.0, 0.01
    a = np.sqrt(R * d)
    print(f"# cores: {os.cpu_count()}; Hertz R = {R}, d = {d}, a = {a:.3g}, E = 1, "
          f"lambda = {args.lam}, open grid of 4a")
    print("| nu | a/h | N | F_n / Hertz - 1 | decoupled F_f / (lam F_n) | coupled F_f / (lam F_n) "
          "| coupled / decoupled | released at D_x = 0 | seconds (dec / coup) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for nu in args.nu:
        for ratio in args.ratios:
            h = a / ratio
            n = 4 * ratio
            heights = sphere((n, n), radius=R, a=h)
            problem = Problem(heights, Grid((n, n), h), Material(1.0, nu), threads=args.threads)
            normal = NormalSolver(problem, tol=1e-12).solve(depth=d)
            ref = hertz(R=R, d=d, E=1.0, nu=nu).force
            t0 = time.perf_counter()
            dec = pull(normal, lam=args.lam)
            t_dec = time.perf_counter() - t0
            fd = dec.friction_force / (args.lam * normal.normal_force)
            row = f"| {nu} | {ratio} | {n} | {normal.normal_force / ref - 1:+.2e} | {fd:.4f} "
            if ratio > args.coupled_max:
                print(row + f"| - | - | - | {t_dec:.1f} / - |", flush=True)
                continue
            t0 = time.perf_counter()
            c = couple(problem, depth=d, lam=args.lam)
            t_c = time.perf_counter() - t0
            fc = c.friction_force / (args.lam * c.normal_force_at_peak)
            released = c.details.released / max(int(c.start.contact.sum()), 1)
            print(row + f"| {fc:.4f} | {fc / fd:.4f} | {released:.2f} | {t_dec:.1f} / "
                  f"{t_c:.1f} |", flush=True)


if __name__ == "__main__":
    main()
