"""Frictional indentation by a rigid cylinder (the plane problem of Spence's setting).

    python scripts/frictional_indentation.py [--nu 0 0.25 0.4] [--lam 0.1 0.2 0.3 0.5]
                                             [--sizes 512 1024 2048]

A parabolic profile h = -x^2 / (2R) on a grid of one row, periodic in y (so the fields do not
depend on y: plane strain) and in x (period N pixels, R = N^2 / 256, so that the contact stays
below a quarter of the period), is indented to D_z = 1 with the coupled model
(:func:`roughslip.indent`): every site sticks where it touches, bonds slip by the Coulomb law
and stick again when their slip would reverse. During such monotonic loading the stick zone of
the continuum problem keeps a constant fraction c/a of the contact. The script prints, per
(nu, lam) and grid, the contact half-width a (pixels) at the end and the median, minimum and
maximum of c/a (stick sites over contact sites) at the contact-gained events of the second half
of the loading, with beta = (1 - 2 nu) / (2 (1 - nu)) and lam / beta, and the seconds.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from roughslip import indent
from roughslip.contact.problem import Problem


def stick_ratio(n: int, nu: float, lam: float) -> tuple[float, float, float, float, float]:
    """(a, median, min, max of c/a over the second half of the loading, seconds)."""
    x = np.arange(n) - (n - 1) / 2
    h = (-x**2 / (2 * n * n / 256))[None, :]
    t0 = time.perf_counter()
    r = indent(Problem.from_arrays(h, nu=nu, boundary="periodic"), depth=1.0, lam=lam)
    if not r.converged:
        raise SystemExit(f"nu = {nu}, lam = {lam}, N = {n}: {r.message}")
    c, s = r.contact_counts, r.stick_counts
    kinds = np.array([e.kind for e in r.events])
    sel = (kinds == "gained") & (c >= c[-1] // 2)
    ratio = s[sel] / c[sel]
    return (c[-1] / 2, float(np.median(ratio)), float(ratio.min()), float(ratio.max()),
            time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--nu", type=float, nargs="+", default=[0.0, 0.25, 0.4])
    ap.add_argument("--lam", type=float, nargs="+", default=[0.1, 0.2, 0.3, 0.5])
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 1024, 2048])
    args = ap.parse_args()
    print(f"# cores: {os.cpu_count()}; plane (one row, periodic), R = N^2/256, D_z = 1")
    print(f"{'nu':>5} {'beta':>6} {'lam':>5} {'lam/beta':>8} {'N':>5} {'a':>6} "
          f"{'c/a med':>8} {'min':>6} {'max':>6} {'s':>6}")
    for nu in args.nu:
        beta = (1 - 2 * nu) / (2 * (1 - nu))
        for lam in args.lam:
            for n in args.sizes:
                a, med, lo, hi, sec = stick_ratio(n, nu, lam)
                print(f"{nu:>5.2f} {beta:>6.3f} {lam:>5.2f} {lam / beta:>8.3f} {n:>5} "
                      f"{a:>6.1f} {med:>8.3f} {lo:>6.3f} {hi:>6.3f} {sec:>6.1f}", flush=True)


if __name__ == "__main__":
    main()
