"""How much does the x-only model (f_x alone, u_y free) change the friction law against bonds
that carry the traction vector (f_x, f_y) and stick in both directions?

    python scripts/traction_effect.py [--sizes 64] [--samples 20] [--nu 0.25 0.45]
                                      [--depths 6] [--directions 0 90] [--workers 2]
                                      [--anisotropy 1] [--out runs/traction] [--resume]

For each nu and grid, rough surfaces (configs/rough_h08.toml: H = 0.8, ``--samples`` samples,
``--depths`` depths 0.3-2 rms, break law, lambda = 0.2) are pulled along x by the report's
model (``pull.components = "x"``) and with the traction vector (``"xy"``) at each of
``--directions`` (degrees). It prints one Markdown row per model and direction: the friction
exponent alpha of F_friction ~ F_n^alpha with its bootstrap error, and the ratio of the friction
force to the x-only model's (the mean over samples of each sample's mean ratio over depths,
with the bootstrap standard deviation of that mean over 1000 resamples, seed 0), and the
least and largest ratio of one sample at one depth. On an
isotropic surface the ensemble does not depend on the direction; the samples do, and the
ratio at 90 degrees is the control that shows by how much. ``--resume`` continues the run files
of an interrupted invocation with the same options left in ``--out``. ``--anisotropy``
generates anisotropic surfaces (``surface.anisotropy``, the ratio of the correlation lengths
along y and x: ridges along y when > 1), to see how the friction depends on the drive's angle
to the ridges.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from coupling_effect import bootstrap_std, fmt  # the same statistics as the coupling study

from roughslip.analysis.fit import fit_files
from roughslip.run.config import load_config
from roughslip.run.executor import run
from roughslip.run.store import read_run

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[64], help="rough grids N")
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--nu", type=float, nargs="+", default=[0.25, 0.45])
    ap.add_argument("--depths", type=int, default=6, help="depths from 0.3 to 2 rms")
    ap.add_argument("--directions", type=float, nargs="+", default=[0.0, 90.0],
                    help="drive angles of the traction-vector model, degrees from x")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--anisotropy", type=float, default=1.0,
                    help="surface.anisotropy: xi_y / xi_x of the generated surfaces")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "traction")
    ap.add_argument("--resume", action="store_true",
                    help="continue the run files of an interrupted invocation")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"# cores: {os.cpu_count()}; rough: H = 0.8, anisotropy {args.anisotropy:g}, "
          f"{args.samples} samples, {args.depths} depths 0.3-2 rms; break law, lambda = 0.2\n")
    print("| N | nu | model | drive | alpha | F_fric / x-only model | range over scenes "
          "| seconds |")
    print("|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        base = [f"grid.n={n}", f"ensemble.samples={args.samples}",
                f"surface.anisotropy={args.anisotropy}",
                f"squeeze.depths={{start = 0.3, stop = 2.0, num = {args.depths}, "
                "spacing = 'log'}"]
        for nu in args.nu:
            rows = [("x", 0.0), *(("xy", d) for d in args.directions)]
            paths, secs = {}, {}
            for comps, d in rows:
                cfg = load_config(ROOT / "configs" / "rough_h08.toml",
                                  [*base, f"material.nu={nu}", f"pull.components='{comps}'",
                                   f"pull.direction={d}"])
                tag = "" if args.anisotropy == 1 else f"_g{args.anisotropy:g}"
                p = args.out / f"rough{n}{tag}_nu{nu}_{comps}_{d:g}.h5"
                t0 = time.perf_counter()
                resume = args.resume and p.exists()
                run(cfg, p, workers=args.workers, resume=resume, overwrite=not resume)
                secs[comps, d] = time.perf_counter() - t0
                paths[comps, d] = p
            ref = read_run(paths["x", 0.0])
            for key in rows:
                r = read_run(paths[key])
                done = r.complete & ref.complete
                each = (r.scalars["friction_force"][done]
                        / ref.scalars["friction_force"][done])
                ratio = each.mean(axis=1)
                fit = fit_files([paths[key]])[0].fit
                comps, d = key
                model = "x only (the report's)" if comps == "x" else "traction vector"
                print(f"| {n} | {nu} | {model} | {d:g}° | {fmt(fit)} | {ratio.mean():.4f} ± "
                      f"{bootstrap_std(ratio):.4f} | {each.min():.4f} to {each.max():.4f} | "
                      f"{secs[key]:.0f} |", flush=True)


if __name__ == "__main__":
    main()
