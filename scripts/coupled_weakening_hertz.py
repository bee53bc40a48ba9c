"""Does the coupled friction force of a Hertz contact converge as the pixels shrink?
Slip-weakening against the break law, under coupling.

    python scripts/coupled_weakening_hertz.py [--ratios 8 16 32] [--nu 0.25 0.45]
        [--histories indent frictionless] [--law 0.1:5e-4]

The scene of scripts/weakening_convergence.py: a rigid sphere (R = 1) pressed to the depth
d = 0.01 (Hertz radius a = 0.1) into a half-space (E = 1), pixels h = a / ratio on an open
grid of 4a, lam_s = 0.2, pulled with the depth held. For each resolution, Poisson ratio and
squeeze history: F_f / (lam_s F_n) under the coupled break law and under slip-weakening
(lam_dynamic:slip_distance), the bonds, the events and the seconds; then, per column, the
change per halving of h and, with three resolutions, the observed order
p = log2(|F_h - F_h/2| / |F_h/2 - F_h/4|) and the Richardson extrapolation.
"""

from __future__ import annotations

import argparse
import math
import os
import time

from roughslip.contact.problem import Problem
from roughslip.coupling.coupled import couple
from roughslip.elastic.operators import Grid, Material
from roughslip.surfaces import sphere


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--ratios", type=int, nargs="+", default=[8, 16, 32])
    ap.add_argument("--nu", type=float, nargs="+", default=[0.25, 0.45])
    ap.add_argument("--histories", nargs="+", default=["indent", "frictionless"])
    ap.add_argument("--law", default="0.1:5e-4", help="lam_dynamic:slip_distance")
    ap.add_argument("--lam", type=float, default=0.2)
    args = ap.parse_args()
    R, d, lam = 1.0, 0.01, args.lam
    a = math.sqrt(R * d)
    ld, dc = (float(v) for v in args.law.split(":"))
    print(f"# cores: {os.cpu_count()}; Hertz R = {R}, d = {d}, a = {a:.3g}, E = 1, "
          f"lam_s = {lam}, slip-weakening lam_d = {ld:g}, d_c = {dc:g}; depth held")
    print("| nu | history | law | a/h | bonds | F_f / (lam_s F_n) | events | seconds |")
    print("|---|---|---|---|---|---|---|---|")
    table: dict[tuple, list[float]] = {}
    for nu in args.nu:
        for ratio in args.ratios:
            h, n = a / ratio, 4 * ratio
            problem = Problem(sphere((n, n), radius=R, a=h), Grid((n, n), h),
                              Material(1.0, nu))
            for history in args.histories:
                for law in ("break", "slip-weakening"):
                    kw = {} if law == "break" else dict(lam_dynamic=ld, slip_distance=dc)
                    t0 = time.perf_counter()
                    r = couple(problem, depth=d, lam=lam, slip_law=law, history=history,
                               **kw)
                    sec = time.perf_counter() - t0
                    ratio_f = r.friction_force / (lam * r.normal_force)
                    table.setdefault((nu, history, law), []).append(ratio_f)
                    bonds = int(r.start.contact.sum())
                    print(f"| {nu} | {history} | {law} | {ratio} | {bonds} | {ratio_f:.5f} | "
                          f"{len(r.curve.dx)} | {sec:.1f} |", flush=True)
    print()
    print("| nu | history | law | change per halving | order p | extrapolated |")
    print("|---|---|---|---|---|---|")
    for (nu, history, law), F in table.items():
        ch = ", ".join(f"{(F[i + 1] - F[i]) / F[i]:+.2%}" for i in range(len(F) - 1))
        p = ext = "-"
        if len(F) >= 3 and F[-1] != F[-2] and F[-2] != F[-3]:
            q = abs(F[-2] - F[-3]) / abs(F[-1] - F[-2])
            if q > 1:
                order = math.log2(q)
                p = f"{order:.2f}"
                ext = f"{F[-1] + (F[-1] - F[-2]) / (2**order - 1):.5f}"
        print(f"| {nu} | {history} | {law} | {ch} | {p} | {ext} |")


if __name__ == "__main__":
    main()
