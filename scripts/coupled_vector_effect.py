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
from coulomb_vector_effect import LAM, run_study, study_arguments  # shared with that study

from roughslip import Problem, couple


def half_drive(drive: np.ndarray, along: np.ndarray, peak: float) -> float:
    """The drive at which the piecewise-linear pull force first reaches half its peak."""
    k = int(np.argmax(along >= 0.5 * peak))
    return float(np.interp(0.5 * peak, along[:k + 1], drive[:k + 1]))


def main() -> None:
    args = study_arguments(__doc__, 10, [2.5], 32)

    def pair(h: np.ndarray, nu: float, depth: float):
        problem = Problem.from_arrays(h, nu=nu)
        d = depth * float(np.std(h))
        t0 = time.perf_counter()
        x = couple(problem, depth=d, lam=LAM, slip_law="coulomb", history="indent")
        t1 = time.perf_counter()
        v = couple(problem, depth=d, lam=LAM, slip_law="coulomb", history="indent",
                   components="xy", facets=args.facets)
        t2 = time.perf_counter()
        mx = (x.normal_force, x.friction_force,
              half_drive(x.curve.dx, x.curve.fx, x.friction_force))
        mv = (v.normal_force, v.friction_force,
              half_drive(v.curve.drive, v.curve.along, v.friction_force))
        return ([b / a for a, b in zip(mx, mv, strict=True)], float(x.start.contact.mean()),
                t1 - t0, t2 - t1)

    run_study(args, "history indent, drive along x; ratios vector / x-only",
              "F_n | friction force | D at 50 %", pair)

if __name__ == "__main__":
    main()
