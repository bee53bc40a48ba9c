"""Spence's frictional indentation of a sphere: the stick radius against the friction.

    python scripts/spence_sphere.py [--ratios 6 8 12 16] [--lams 0.2986] [--facets 64]

A rigid sphere (R = 1) on an open grid 2.4 a wide is pressed into the half-space at nu = 0
(beta = 1/2) from first touch to the Hertz approach d = 1/16, with a/h pixels across the
final contact radius, by the coupled model under the faceted Coulomb cone with the traction
vector (:func:`roughslip.coupling.cone.indent_cone`): every site sticks where it touches and
slips, in any direction, when its force reaches the polygon. Under monotonic loading the
continuum stick zone keeps a constant fraction c/a of the contact (self-similarity); Spence
(1975) gives c/a = 0.5 at lam = 0.2986 for nu = 0.

For each a/h and lam it prints c/a over the second half of the loading (in depth): the
square root of the stick fraction of the contact area averaged over the depth
(:meth:`~roughslip.coupling.cone.ConeIndentation.loading_ratio`), the least and largest
c/a of the states there, c/a at the end, the events and the seconds.
"""

from __future__ import annotations

import argparse
import os
import time

from roughslip.analysis.verify import hertz_scene
from roughslip.contact.problem import Problem
from roughslip.coupling.cone import indent_cone


def stick_ratios(ah: int, lam: float, facets: int, nu: float = 0.0) -> dict[str, float]:
    """c/a over the second half of the loading of one sphere, and what it took."""
    heights, h, depth, _ = hertz_scene(ah)
    problem = Problem.from_arrays(heights, a=h, E=1.0, nu=nu)
    t = time.perf_counter()
    r = indent_cone(problem, depth, lam=lam, facets=facets)
    seconds = time.perf_counter() - t
    ratio, low, high = r.loading_ratio(depth / 2)
    return {"mean": ratio, "min": low, "max": high, "end": r.stick_ratio,
            "contact": int(r.contact.sum()), "events": r.events, "seconds": seconds,
            "residual": r.residual}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ratios", type=int, nargs="+", default=[6, 8, 12, 16])
    parser.add_argument("--lams", type=float, nargs="+", default=[0.2986])
    parser.add_argument("--facets", type=int, default=64)
    parser.add_argument("--nu", type=float, default=0.0)
    args = parser.parse_args()
    print(f"nu = {args.nu}, {args.facets} facets, {os.cpu_count()} cores")
    print("| lam | a/h | contact sites | c/a, second half (min-max) | c/a at the end "
          "| events | s |")
    print("|---|---|---|---|---|---|---|")
    for lam in args.lams:
        for ah in args.ratios:
            s = stick_ratios(ah, lam, args.facets, args.nu)
            print(f"| {lam:g} | {ah} | {s['contact']} | {s['mean']:.4f} "
                  f"({s['min']:.4f}-{s['max']:.4f}) | {s['end']:.4f} | {s['events']} | "
                  f"{s['seconds']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
