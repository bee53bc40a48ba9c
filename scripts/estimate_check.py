"""The pull's error estimates against the true error on rough scenes.

    python scripts/estimate_check.py [--sizes 32 64 96] [--seeds 3]

For each self-affine surface (H = 0.8, depth 1.5 rms) the exact reference is the ``inverse``
pull at tol 1e-13 on the same squeeze. The ``literal`` and ``cg`` pulls at tolerances 1e-3 to
1e-10 report ``solve_error_estimate`` (one refinement step on the peak state) and ``error_bound``
(condition estimate x residual); the script prints both against the true relative error of the
friction force, and whether the break order up to the peak matched the reference.
"""

from __future__ import annotations

import argparse

import numpy as np

from roughslip.contact.squeeze import squeeze
from roughslip.friction.pull import pull
from roughslip.surfaces.synthetic import sample_rng, self_affine

FLOOR = 1e-13  # the reference's own accuracy: errors below are not resolved


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 64, 96])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    ratios, bound_ratios, reordered, total = [], [], 0, 0
    print(f"{'N':>4} {'seed':>4} {'method':>8} {'tol':>7} {'true error':>11} {'estimate':>10} "
          f"{'bound':>10} {'order':>6}")
    for n in args.sizes:
        for seed in range(args.seeds):
            h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(7, seed),
                            oversample=2)
            normal = squeeze(h, depth=1.5, tol=1e-12)
            ref = pull(normal, method="inverse", tol=1e-13)
            head = ref.curve.site[: ref.peak_event + 1]
            for method in ("cg", "literal"):
                for tol in (1e-3, 1e-4, 1e-6, 1e-8, 1e-10):
                    r = pull(normal, method=method, tol=tol, estimate_error=True)
                    err = abs(r.friction_force - ref.friction_force) / ref.friction_force
                    same = np.array_equal(r.curve.site[: r.peak_event + 1], head)
                    total += 1
                    reordered += not same
                    if err > FLOOR:
                        ratios.append(r.details.solve_error_estimate / err)
                        bound_ratios.append(r.details.error_bound / err)
                    print(f"{n:>4} {seed:>4} {method:>8} {tol:>7.0e} {err:>11.2e} "
                          f"{r.details.solve_error_estimate:>10.2e} {r.details.error_bound:>10.2e} "
                          f"{'same' if same else 'other':>6}")
    ratios, bound_ratios = np.array(ratios), np.array(bound_ratios)
    print(f"{total} pulls, {reordered} with another break order up to the peak; above the "
          f"floor {FLOOR:g} ({ratios.size}): estimate / true error {ratios.min():.2f} - "
          f"{ratios.max():.2f} (median {np.median(ratios):.2f}), bound / true error "
          f"{bound_ratios.min():.1f} - {bound_ratios.max():.3g}")


if __name__ == "__main__":
    main()
