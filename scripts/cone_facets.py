"""How the Coulomb cone's pull curve converges in the number of facets (docs/results.md,
"The Coulomb cone").

A rough scene (H = 0.8, rms height 1, seed 1) is squeezed to a depth and pulled with the Coulomb
law and the traction vector at a drive angle, with 8 to 256 facets. For each, the largest error
of the pull force along the curve against the most facets, relative to lambda P, beside the
polygon's strength bound 1 - cos(pi/m); the events and the time (one thread).

    python scripts/cone_facets.py --size 64 --depth 3.0 --nu 0.45 --direction 20
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from roughslip.contact.squeeze import squeeze
from roughslip.friction.pull import pull
from roughslip.surfaces.synthetic import sample_rng, self_affine


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--depth", type=float, default=3.0)
    ap.add_argument("--nu", type=float, default=0.45)
    ap.add_argument("--direction", type=float, default=20.0)
    ap.add_argument("--lam", type=float, default=0.2)
    ap.add_argument("--facets", type=int, nargs="+", default=[8, 16, 32, 64, 128, 256])
    args = ap.parse_args()
    h = self_affine((args.size, args.size), hurst=0.8, rms_height=1.0, rng=sample_rng(1, 0))
    normal = squeeze(h, depth=args.depth, nu=args.nu, tol=1e-12)
    P = normal.normal_force
    t0 = time.perf_counter()
    x = pull(normal, lam=args.lam, slip_law="coulomb", threads=1)
    tx = time.perf_counter() - t0
    runs = {}
    for m in args.facets:
        t0 = time.perf_counter()
        r = pull(normal, lam=args.lam, slip_law="coulomb", components="xy",
                 direction=args.direction, facets=m, threads=1)
        runs[m] = (r, time.perf_counter() - t0)
    ref = runs[max(args.facets)][0]
    D = np.linspace(0.0, ref.curve.drive[-1], 400)
    q_ref = np.interp(D, ref.curve.drive, ref.curve.along)
    q_x = np.interp(D, x.curve.dx, x.curve.fx)
    print(f"{x.details.n_bonds} bonds ({normal.contact.mean():.1%} contact), nu = {args.nu}, "
          f"drive {args.direction} degrees; x-only Coulomb: {x.curve.drive.size - 1} events, "
          f"{tx:.2f} s, its largest difference from the vector curve "
          f"{np.abs(q_x - q_ref).max() / (args.lam * P):.2e} lambda P")
    print("| facets | largest error / (lambda P) | 1 - cos(pi/m) | events | seconds |")
    print("|---|---|---|---|---|")
    for m, (r, t) in runs.items():
        err = np.abs(np.interp(D, r.curve.drive, r.curve.along) - q_ref).max() / (args.lam * P)
        shown = "(reference)" if r is ref else f"{err:.2e}"
        print(f"| {m} | {shown} | {1 - math.cos(math.pi / m):.2e} | "
              f"{r.curve.drive.size - 1} | {t:.2f} |")


if __name__ == "__main__":
    main()
