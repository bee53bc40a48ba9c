"""How far the x-only model's Coulomb pull curve is from the traction vector's on rough surfaces
(docs/results.md, "The Coulomb cone at nu > 0").

Under the Coulomb law both models end at lambda F_n; what differs is how the pull force
rises with the drive. For rough surfaces (H = 0.8, rms height 1, seeds of the ensemble
``sample_rng(1, s)``) squeezed to each depth (from the highest point, in rms heights) and
pulled along x, it prints per nu and depth the ratios vector / x-only of

* the initial tangential stiffness K_0 = dF/dD at D = 0 (every bond sticks), and
* the drive at which the pull force reaches 50 % and 90 % of lambda F_n (the pre-sliding
  displacements),

each the mean over samples with the bootstrap standard deviation of that mean (1000
resamples, seed 0), and the range over samples.

    python scripts/coulomb_vector_effect.py --size 64 --samples 20 --nu 0.25 0.45 \\
        --depths 2.5 3.5 --facets 64
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from coupling_effect import bootstrap_std  # the same statistics as the coupling study

from roughslip.contact.squeeze import squeeze
from roughslip.friction.pull import pull
from roughslip.surfaces.synthetic import sample_rng, self_affine

LAM = 0.2


def measures(force: np.ndarray, drive: np.ndarray, full: float) -> tuple[float, ...]:
    """K_0 and the drives at 50 % and 90 % of ``full`` on a piecewise-linear curve."""
    k0 = float(force[1] / drive[1])
    d50, d90 = (float(np.interp(f * full, force, drive)) for f in (0.5, 0.9))
    return k0, d50, d90


def study_arguments(doc: str, samples: int, depths: list[float], facets: int
                    ) -> argparse.Namespace:
    """The command line of a vector / x-only study on rough surfaces (this one and
    ``coupled_vector_effect.py``): size, samples, Poisson ratios, depths and facets."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--samples", type=int, default=samples)
    ap.add_argument("--nu", type=float, nargs="+", default=[0.25, 0.45])
    ap.add_argument("--depths", type=float, nargs="+", default=depths)
    ap.add_argument("--facets", type=int, default=facets)
    return ap.parse_args()


def run_study(args: argparse.Namespace, title: str, columns: str,
              pair: Callable[[np.ndarray, float, float], tuple[list[float], float, float,
                                                               float]]) -> None:
    """Print a vector / x-only study's table: for each nu and depth, over the samples (H =
    0.8, rms height 1, seeds ``sample_rng(1, s)``), the mean, bootstrap error and range of
    each ratio ``pair(heights, nu, depth)`` returns, with the contact fraction and the
    seconds of each model it returns."""
    n = args.size
    print(f"N = {n}, {args.samples} samples, lambda = {LAM}, {args.facets} facets, {title}\n")
    print(f"| nu | depth (rms) | contact | {columns} | seconds x-only / vector |")
    print("|---|---|---|" + "---|" * (columns.count("|") + 1) + "---|")
    for nu in args.nu:
        for depth in args.depths:
            ratios, area, tx, tv = [], [], 0.0, 0.0
            for s in range(args.samples):
                h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(1, s))
                r, contact, sx, sv = pair(h, nu, depth)
                ratios.append(r)
                area.append(contact)
                tx, tv = tx + sx, tv + sv
            r = np.array(ratios)
            cells = [f"{c.mean():.4f} ± {bootstrap_std(c):.4f} ({c.min():.3f} to "
                     f"{c.max():.3f})" for c in r.T]
            print(f"| {nu} | {depth:g} | {np.mean(area):.1%} | {' | '.join(cells)} | "
                  f"{tx:.0f} / {tv:.0f} |", flush=True)


def main() -> None:
    args = study_arguments(__doc__, 20, [2.5, 3.5], 64)

    def pair(h: np.ndarray, nu: float, depth: float):
        normal = squeeze(h, depth=depth, nu=nu, tol=1e-12)
        full = LAM * normal.normal_force
        t0 = time.perf_counter()
        x = pull(normal, lam=LAM, slip_law="coulomb", threads=1)
        t1 = time.perf_counter()
        v = pull(normal, lam=LAM, slip_law="coulomb", components="xy", facets=args.facets,
                 threads=1)
        t2 = time.perf_counter()
        mx = measures(x.curve.fx, x.curve.dx, full)
        mv = measures(v.curve.along, v.curve.drive, full)
        return ([b / a for a, b in zip(mx, mv, strict=True)], float(normal.contact.mean()),
                t1 - t0, t2 - t1)

    run_study(args, "drive along x; ratios traction vector / x-only",
              "K_0 | D at 50 % | D at 90 %", pair)

if __name__ == "__main__":
    main()
