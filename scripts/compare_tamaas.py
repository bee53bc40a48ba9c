"""The Coulomb cone's partial-slip state against Tamaas's frictional solvers (docs/results.md,
"The Coulomb cone at nu > 0").

A Hertz contact (R = 1, approach 1/16, mu = lambda = 0.3) is loaded tangentially along x to
Q = 0.5 mu P. At nu = 0.5 the half-space does not couple the normal and tangential problems
(G_zx vanishes), while G_xy is at its largest: the decoupled pull with the traction vector is
the whole elastic problem, and Tamaas's frictional solvers (PolonskyKeerTan, Kato and Condat,
one load step with the isotropic cone) solve the same physics independently. Tamaas's grid is
periodic, so its box is 4 a wide; roughslip's is open and 2.4 a wide. Tamaas collocates the
continuous kernels at pixel centres; roughslip integrates them over pixels. The comparison is
on the pixels both grids share:

* the stick zone of each (|q| < mu p, to 1e-4 in Tamaas's), its equal-area radius and the
  pixels where the two differ;
* the relative L2 differences of q_x, q_y and p over the common contact, the correlation of
  the two q_y fields, and |q_y| / |q_x| of each (the lateral traction the x-only model lacks).

Needs Tamaas beside roughslip (``pip install tamaas==2.9.0``)::

    python scripts/compare_tamaas.py --sizes 8 16 32
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from roughslip.analysis.verify import hertz_scene
from roughslip.contact.squeeze import squeeze
from roughslip.friction.bonds import Bonds, PullOptions
from roughslip.friction.cone import STICK, ConeState

NU, MU, FRACTION, R, APPROACH = 0.5, 0.3, 0.5, 1.0, 1 / 16
#: Tamaas's iterations per solve (its solvers stop at 1e-12 or here; PolonskyKeerTan stalls
#: near 1e-6 on this contact)
MAX_ITERATIONS = 10_000
#: a site of Tamaas's solution sticks when |q| < mu p (1 - SLIP_TIE): its solvers stop short
#: of the rounding level, so a slipping site is on the cone only to their tolerance
SLIP_TIE = 1e-4


def roughslip_state(a_over_h: int, facets: int) -> dict:
    """The traction, pressure and stick zone of the vector Coulomb pull when the pull force
    reaches ``FRACTION`` mu P (the event path followed to that force, the state affine in
    the drive inside its last interval)."""
    heights, h, depth, _ = hertz_scene(a_over_h, R, APPROACH)
    normal = squeeze(heights, depth=depth, a=h, nu=NU, tol=1e-13)
    Q = FRACTION * MU * normal.normal_force
    b = Bonds(normal, MU, components=("x", "y"))
    st = ConeState(b, PullOptions(slip_law="coulomb"), facets)
    F = st.force(st.run_to(Q))
    return {"qx": b.field(F[:, 0]) / h**2, "qy": b.field(F[:, 1]) / h**2,
            "p": normal.fz / h**2, "stick": b.mask(np.flatnonzero(st.mode == STICK)),
            "h": h, "shape": heights.shape}


def tamaas_state(a_over_h: int, solver: str, shape: tuple[int, int]) -> dict:
    """Tamaas's solution of the same contact at the mean tractions (Q, 0, P), P Hertz's, on a
    periodic box 4 a wide, cut to roughslip's grid (the apex on the same pixel corner)."""
    import tamaas as tm

    tm.set_log_level(tm.LogLevel.warning)  # not every iteration
    a = math.sqrt(R * APPROACH)
    h = a / a_over_h
    n = round(4 * a / h)
    n += n % 2
    L = n * h
    x = (np.arange(n) - n / 2 + 0.5) * h
    X, Y = np.meshgrid(x, x, indexing="ij")
    surface = -(X**2 + Y**2) / (2 * R)
    surface -= surface.max()
    model = tm.ModelFactory.createModel(tm.model_type.surface_2d, [L, L], [n, n])
    model.E, model.nu = 1.0, NU
    P = 4 / 3 / (1 - NU**2) * math.sqrt(R) * APPROACH**1.5
    kind = {"PolonskyKeerTan": tm.PolonskyKeerTan, "Kato": tm.Kato, "Condat": tm.Condat}[solver]
    s = kind(model, surface, 1e-12, MU)
    s.max_iter = MAX_ITERATIONS
    s.solve([FRACTION * MU * P / L**2, 0.0, P / L**2])
    t = np.array(model.traction)
    ny, nx = shape
    o = (n - ny) // 2
    T = t[o:o + ny, o:o + nx]  # Tamaas's arrays are [ix, iy]
    qx, qy, p = T[..., 0].T, T[..., 1].T, T[..., 2].T
    stick = (p > 0) & (np.hypot(qx, qy) < MU * p * (1 - SLIP_TIE))
    return {"qx": qx, "qy": qy, "p": p, "stick": stick}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[8, 16])
    ap.add_argument("--facets", type=int, default=64)
    ap.add_argument("--solvers", nargs="+", default=["PolonskyKeerTan", "Kato", "Condat"])
    args = ap.parse_args()
    print("| a/h | solver | c/h ours | c/h theirs | c/h Mindlin | stick pixels differing | "
          "L2 dq_x/q_x | L2 dq_y/q_y | L2 dp/p | corr(q_y) | q_y/q_x ours | q_y/q_x theirs |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        ours = roughslip_state(n, args.facets)
        mindlin = n * (1 - FRACTION) ** (1 / 3)
        for solver in args.solvers:
            th = tamaas_state(n, solver, ours["shape"])
            c = (ours["p"] > 0) & (th["p"] > 0)

            def l2(v, c=c):
                return float(np.sqrt((v[c] ** 2).sum()))

            def radius(stick):
                return math.sqrt(stick.sum() / math.pi)

            corr = float(np.corrcoef(ours["qy"][c], th["qy"][c])[0, 1])
            print(f"| {n} | {solver} | {radius(ours['stick']):.2f} | "
                  f"{radius(th['stick']):.2f} | {mindlin:.2f} | "
                  f"{int((ours['stick'] != th['stick']).sum())} of {int(c.sum())} | "
                  f"{l2(th['qx'] - ours['qx']) / l2(ours['qx']):.3f} | "
                  f"{l2(th['qy'] - ours['qy']) / l2(ours['qy']):.3f} | "
                  f"{l2(th['p'] - ours['p']) / l2(ours['p']):.3f} | {corr:.3f} | "
                  f"{l2(ours['qy']) / l2(ours['qx']):.4f} | "
                  f"{l2(th['qy']) / l2(th['qx']):.4f} |", flush=True)


if __name__ == "__main__":
    main()
