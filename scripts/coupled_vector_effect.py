"""How far the coupled x-only model is from the coupled model with the traction vector on
rough surfaces, under the Coulomb law (docs/results.md, "The coupled model with the traction
vector").

Both models indent the surface frictionally from first touch (history ``indent``) and pull
along x at the depth reached; the x-only model gives each contact f_x alone (u_y free), the
vector model (f_x, f_y) under the faceted cone (:func:`roughslip.coupling.cone.couple_cone`).
For rough surfaces (H = 0.8, rms height 1, seeds ``sample_rng(1, s)``) at each depth (from the
highest point, in rms heights) it prints per nu and depth the ratios vector / x-only of

* the normal force after the indentation,
* the friction force (the peak of the pull force; the depth is held, so F_z moves), and
* the drive at which the pull force reaches 50 % of its peak,

each the mean over samples with the bootstrap standard deviation of that mean (1000
resamples, seed 0) and the range over samples, and the seconds of each model.

    python scripts/coupled_vector_effect.py --size 64 --samples 10 --nu 0.25 0.45 \\
        --depths 2.5 --facets 32
"""

from __future__ import annotations

import time

import numpy as np
from coulomb_vector_effect import study_arguments  # the decoupled study's command line
from coupling_effect import bootstrap_std  # the same statistics as the coupling study

from roughslip import Problem, couple
from roughslip.surfaces.synthetic import sample_rng, self_affine

LAM = 0.2


def half_drive(drive: np.ndarray, along: np.ndarray, peak: float) -> float:
    """The drive at which the piecewise-linear pull force first reaches half its peak."""
    k = int(np.argmax(along >= 0.5 * peak))
    return float(np.interp(0.5 * peak, along[:k + 1], drive[:k + 1]))


def main() -> None:
    args = study_arguments(__doc__, 10, [2.5], 32)
    n = args.size
    print(f"N = {n}, {args.samples} samples, lambda = {LAM}, {args.facets} facets, history "
          "indent, drive along x; ratios vector / x-only\n")
    print("| nu | depth (rms) | contact | F_n | friction force | D at 50 % | seconds x-only / "
          "vector |")
    print("|---|---|---|---|---|---|---|")
    for nu in args.nu:
        for depth in args.depths:
            ratios, area, tx, tv = [], [], 0.0, 0.0
            for s in range(args.samples):
                h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(1, s))
                problem = Problem.from_arrays(h, nu=nu)
                d = depth * float(np.std(h))
                t0 = time.perf_counter()
                x = couple(problem, depth=d, lam=LAM, slip_law="coulomb", history="indent")
                tx += time.perf_counter() - t0
                t0 = time.perf_counter()
                v = couple(problem, depth=d, lam=LAM, slip_law="coulomb", history="indent",
                           components="xy", facets=args.facets)
                tv += time.perf_counter() - t0
                mx = (x.normal_force, x.friction_force,
                      half_drive(x.curve.dx, x.curve.fx, x.friction_force))
                mv = (v.normal_force, v.friction_force,
                      half_drive(v.curve.drive, v.curve.along, v.friction_force))
                ratios.append([b / a for a, b in zip(mx, mv, strict=True)])
                area.append(float(x.start.contact.mean()))
            r = np.array(ratios)
            cells = [f"{c.mean():.4f} ± {bootstrap_std(c):.4f} ({c.min():.3f} to "
                     f"{c.max():.3f})" for c in r.T]
            print(f"| {nu} | {depth:g} | {np.mean(area):.1%} | {' | '.join(cells)} | "
                  f"{tx:.0f} / {tv:.0f} |", flush=True)


if __name__ == "__main__":
    main()
