"""Frictional indentation by a rigid cylinder (the plane problem of Spence's setting).

    python scripts/frictional_indentation.py [--nu 0 0.25 0.4 0.49] [--ratios 0.4 0.6 ...]

A parabolic profile h = -x^2 / (2R) on a grid of one row, periodic in y (so the fields do not
depend on y: plane strain), is indented with the coupled model (:func:`roughslip.indent`):
every site sticks where it touches, bonds slip by the Coulomb law and stick again when their
slip would reverse. Under monotonic loading the stick zone of the continuum problem keeps a
constant fraction c/a of the contact. The grid is periodic in x too, with a period of about a
thousand contact half-widths (a shorter period biases c/a upwards, by about 1.7 a/L measured).

For each nu and lam / beta (beta = (1 - 2 nu) / (2 (1 - nu)), lam = ratio x beta) and two
resolutions (a of about 37 and 107 pixels), it prints the median, smallest and largest c/a
(stick sites over contact sites) at the contact-gained events of the second half of the
loading, and the continuum value in the limit beta lam -> 0
(:func:`roughslip.contact.analytic.plane_indentation_stick_ratio`).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from roughslip import indent
from roughslip.contact.analytic import plane_indentation_stick_ratio
from roughslip.contact.problem import Problem

#: (period L, radius R, depth) giving contact half-widths of about 37 and 107 pixels, a/L
#: of 0.0011 and 0.0016
GRIDS = ((32768, 4096.0, 1.0), (65536, 16384.0, 2.0))


def stick_ratio(grid: tuple[int, float, float], nu: float, lam: float
                ) -> tuple[float, float, float, float, float]:
    """(a, median, min, max of c/a over the second half of the loading, seconds)."""
    n, radius, depth = grid
    x = np.arange(n) - (n - 1) / 2
    h = (-x**2 / (2 * radius))[None, :]
    t0 = time.perf_counter()
    r = indent(Problem.from_arrays(h, nu=nu, boundary="periodic"), depth=depth, lam=lam)
    if not r.converged:
        raise SystemExit(f"nu = {nu}, lam = {lam}, L = {n}: {r.message}")
    c, s = r.contact_counts, r.stick_counts
    kinds = np.array([e.kind for e in r.events])
    sel = (kinds == "gained") & (c >= c[-1] // 2)
    ratio = s[sel] / c[sel]
    return (c[-1] / 2, float(np.median(ratio)), float(ratio.min()), float(ratio.max()),
            time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--nu", type=float, nargs="+", default=[0.49, 0.4, 0.25, 0.0])
    ap.add_argument("--ratios", type=float, nargs="+", default=[0.4, 0.6, 0.9, 1.2, 1.5, 1.8],
                    help="lam / beta")
    args = ap.parse_args()
    print(f"# cores: {os.cpu_count()}; plane (one row, periodic), grids (L, R, D_z) = {GRIDS}")
    print(f"{'nu':>5} {'beta':>6} {'lam':>7} {'lam/beta':>8} {'beta lam':>8} {'a':>6} "
          f"{'c/a med':>8} {'min':>6} {'max':>6} {'limit':>7} {'s':>5}")
    for nu in args.nu:
        beta = (1 - 2 * nu) / (2 * (1 - nu))
        for ratio in args.ratios:
            lam = ratio * beta
            limit = plane_indentation_stick_ratio(ratio)
            for grid in GRIDS:
                a, med, lo, hi, sec = stick_ratio(grid, nu, lam)
                print(f"{nu:>5.2f} {beta:>6.3f} {lam:>7.4f} {ratio:>8.2f} {beta * lam:>8.4f} "
                      f"{a:>6.0f} {med:>8.3f} {lo:>6.3f} {hi:>6.3f} {limit:>7.4f} {sec:>5.1f}",
                      flush=True)


if __name__ == "__main__":
    main()
