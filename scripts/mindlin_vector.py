"""Cattaneo-Mindlin with the traction vector: what the Coulomb cone gives at nu > 0 against the
closed form, and against the x-only model (docs/results.md, "Cattaneo-Mindlin at nu > 0").

Mindlin's solution takes the traction of the stick zone along the load; at nu > 0 the half-space
couples x and y (G_xy), so the closed form is an approximation of the elastic problem. This
script pulls a Hertz contact (R = 1, approach 1/16, lambda = 0.3) along x with the Coulomb law in
both models and prints, at delta / delta_s = 0.3, 0.5 and 0.7:

* the pull force Q / (lambda P) of each model and of the closed form;
* the stick zone: its equal-area radius c against Mindlin's, and its radii along x and y
  from its second moments (2 sqrt(<x^2>), which is c for a disc).

    python scripts/mindlin_vector.py --sizes 8 16 --nu 0 0.25 0.45 --facets 64
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from roughslip.analysis.verify import hertz_scene
from roughslip.contact.analytic import cattaneo_mindlin
from roughslip.contact.squeeze import squeeze
from roughslip.friction.pull import coulomb_force_at, pull

LAM = 0.3
FRACTIONS = (0.3, 0.5, 0.7)


def stick_sites(res, D: float) -> np.ndarray:
    """The sites that still stick at the drive ``D``: those whose first slip comes later (no
    site of these scenes sticks again; checked)."""
    kinds = np.array(res.curve.kind)
    if "stick" in kinds:
        raise SystemExit("a site stuck again: the stick zone is not read off the first slips")
    first = kinds == "slip+"
    sites, drive = res.curve.site[first], res.curve.drive[first]
    contact = np.flatnonzero((res.start.contact & (res.start.fz > 0)).ravel())
    return np.setdiff1d(contact, sites[drive <= D])


def row(a_over_h: int, nu: float, facets: int) -> list[str]:
    heights, h, depth, ac = hertz_scene(a_over_h, 1.0, 1 / 16)
    normal = squeeze(heights, depth=depth, a=h, nu=nu, tol=1e-12)
    P = normal.normal_force
    cm = cattaneo_mindlin(P, ac, LAM, nu=nu)
    x = pull(normal, lam=LAM, slip_law="coulomb")
    v = pull(normal, lam=LAM, slip_law="coulomb", components="xy", facets=facets)
    ny, nx = heights.shape
    # the apex sits on the pixel corner at the grid's centre (hertz_scene)
    cy, cx = ny / 2 - 0.5, nx / 2 - 0.5
    lines = []
    for frac in FRACTIONS:
        D = frac * cm.delta_s
        qx = float(coulomb_force_at(x, D)) / (LAM * P)
        qv = float(np.interp(D, v.curve.drive, v.curve.along)) / (LAM * P)
        qc = cm.force(D) / (LAM * P)
        c_cm = cm.stick_radius(cm.force(D)) / h
        out = []
        for res in (x, v):
            s = stick_sites(res, D)
            iy, ix = np.divmod(s, nx)
            c_eq = math.sqrt(s.size / math.pi)
            # a uniform disc of radius c has <x^2> = c^2 / 4 (pixels as points: + 1/12)
            wx = 2 * math.sqrt(max(float(np.mean((ix - cx) ** 2)) - 1 / 12, 0.0))
            wy = 2 * math.sqrt(max(float(np.mean((iy - cy) ** 2)) - 1 / 12, 0.0))
            out.append(f"{c_eq:.2f} ({wx:.2f}, {wy:.2f})")
        lines.append(f"| {a_over_h} | {nu:g} | {frac:g} | {qc:.4f} | {qx:.4f} | {qv:.4f} | "
                     f"{c_cm:.2f} | {out[0]} | {out[1]} |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[8, 16])
    ap.add_argument("--nu", type=float, nargs="+", default=[0.0, 0.25, 0.45])
    ap.add_argument("--facets", type=int, default=64)
    args = ap.parse_args()
    print("| a/h | nu | delta/delta_s | Q/(lam P) closed form | x-only | vector | "
          "c/h Mindlin | x-only c/h (c_x, c_y) | vector c/h (c_x, c_y) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        for nu in args.nu:
            for line in row(n, nu, args.facets):
                print(line, flush=True)


if __name__ == "__main__":
    main()
