"""Does the friction force of a Hertz contact converge as the pixels shrink? Slip-weakening
against the break law.

    python scripts/weakening_convergence.py [--ratios 8 16 32 64] [--nu 0.3]
        [--laws 0.1:5e-4 0:5e-4] [--threads 2]

One physical problem: a rigid sphere (R = 1) pressed to the depth d = 0.01 into a half-space
(E = 1), so that the Hertz contact radius is a = 0.1, discretised with pixels h = a / ratio on
an open grid of 4a, then pulled under lam_s = 0.2. For each resolution: F_f / (lam_s F_n)
under the break law and under slip-weakening (lam_dynamic:slip_distance pairs), the bonds,
the events, the bonds that failed unstably and the seconds. Then, per law, the change per
halving of h, the observed order p = log2(|F_h - F_h/2| / |F_h/2 - F_h/4|) of the last
three resolutions and the Richardson extrapolation F_h/4 + (F_h/4 - F_h/2) / (2^p - 1).
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

from roughslip import pull
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.elastic.operators import Grid, Material
from roughslip.surfaces import sphere


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--ratios", type=int, nargs="+", default=[8, 16, 32, 64])
    ap.add_argument("--nu", type=float, default=0.3)
    ap.add_argument("--lam", type=float, default=0.2)
    ap.add_argument("--laws", nargs="+", default=["0.1:5e-4", "0:5e-4"],
                    help="lam_dynamic:slip_distance pairs")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    R, d, lam = 1.0, 0.01, args.lam
    a = math.sqrt(R * d)
    laws = [tuple(float(v) for v in s.split(":")) for s in args.laws]
    names = ["break"] + [f"sw {ld:g}:{dc:g}" for ld, dc in laws]
    print(f"# cores: {os.cpu_count()}; Hertz R = {R}, d = {d}, a = {a:.3g}, E = 1, "
          f"nu = {args.nu}, lam_s = {lam}, open grid of 4a")
    print("| law | a/h | N | bonds | F_f / (lam_s F_n) | events | unstable failures | seconds |")
    print("|---|---|---|---|---|---|---|---|")
    table: dict[str, list[float]] = {n: [] for n in names}
    for ratio in args.ratios:
        h, n = a / ratio, 4 * ratio
        problem = Problem(sphere((n, n), radius=R, a=h), Grid((n, n), h),
                          Material(1.0, args.nu), threads=args.threads)
        normal = NormalSolver(problem, tol=1e-12).solve(depth=d)
        for name, law in zip(names, [None, *laws], strict=True):
            t0 = time.perf_counter()
            if law is None:
                r = pull(normal, lam=lam)
            else:
                r = pull(normal, lam=lam, slip_law="slip-weakening", lam_dynamic=law[0],
                         slip_distance=law[1])
            t = time.perf_counter() - t0
            mu = r.friction_force / (lam * normal.normal_force)
            table[name].append(mu)
            unstable = r.message.split(", ")[-1].split(" ")[0] if law is not None else "-"
            print(f"| {name} | {ratio} | {n} | {r.details.n_bonds} | {mu:.5f} | {r.steps} | "
                  f"{unstable} | {t:.1f} |", flush=True)
    print()
    print("| law | change per halving of h | observed order p | extrapolated |")
    print("|---|---|---|---|")
    for name, v in table.items():
        x = np.array(v)
        ch = ", ".join(f"{c:+.2%}" for c in x[1:] / x[:-1] - 1)
        p, ext = math.nan, math.nan
        if x.size >= 3:
            e1, e2 = abs(x[-3] - x[-2]), abs(x[-2] - x[-1])
            if e2 > 0 and e1 > 0:
                p = math.log2(e1 / e2)
                if p > 0:
                    ext = x[-1] + (x[-1] - x[-2]) / (2 ** p - 1)
        print(f"| {name} | {ch} | {p:.2f} | {ext:.5f} |")


if __name__ == "__main__":
    main()
