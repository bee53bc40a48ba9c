"""The report's study ([Report2003] §5.1-5.4), reproduced at its sizes and extended to larger ones.

    python scripts/report_study.py [--out runs/study] [--workers 2] [--quick]

Hertz (configs/hertz.toml, sphere R = 1 on a 1.28 x 1.28 patch): N = 24 and 32 (the report's
sizes), then 64, 128 and 256, one sample each: exponents beta of F_n ~ D_z^beta (exact: 1.5)
and alpha of F_friction ~ F_n^alpha.

Rough surfaces (configs/rough_h06.toml, rough_h08.toml): N = 24 with 5 samples (the report's
setting), then N = 128 and 256 with 50 samples: beta and alpha with bootstrap and regression
uncertainties, and the area exponent gamma of A ~ F_n^gamma.

Prints Markdown tables (docs/results.md holds the output of a full run). Nothing here is tuned
to the report's numbers.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

from roughslip.analysis.fit import fit_files
from roughslip.run.config import load_config
from roughslip.run.executor import run

ROOT = Path(__file__).resolve().parents[1]


def fit_row(path: Path, x: str, y: str) -> str:
    f = fit_files([path], x, y)[0].fit
    boot = "n/a" if math.isnan(f.alpha_bootstrap_std) else f"{f.alpha_bootstrap_std:.3f}"
    return f"{f.alpha:.3f} | {boot} | {f.alpha_stderr:.3f} | {f.r2:.4f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "study")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="small sizes only (a smoke test)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()
    print(f"# cores: {os.cpu_count()}, workers: {args.workers}\n")

    print("## Hertz (sphere R = 1, patch 1.28, nu = 0.3, lambda = 0.2, 8 depths 0.005-0.1)\n")
    print("| N | a | beta (F_n ~ D_z^beta) | +-reg | R2 | alpha (F_friction ~ F_n^alpha) "
          "| +-reg | R2 | seconds |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in ([24, 32] if args.quick else [24, 32, 64, 128, 256]):
        a = 1.28 / n
        cfg = load_config(ROOT / "configs" / "hertz.toml", [f"grid.n={n}", f"grid.pixel_size={a}"])
        p = args.out / f"hertz_N{n}.h5"
        t0 = time.perf_counter()
        run(cfg, p, workers=1, overwrite=True)
        dt = time.perf_counter() - t0
        fb = fit_files([p], "depth", "normal_force", n_boot=0)[0].fit
        fa = fit_files([p], "normal_force", "friction_force", n_boot=0)[0].fit
        print(f"| {n} | {a:.4g} | {fb.alpha:.3f} | {fb.alpha_stderr:.3f} | {fb.r2:.4f} | "
              f"{fa.alpha:.3f} | {fa.alpha_stderr:.3f} | {fa.r2:.4f} | {dt:.1f} |", flush=True)

    print("\n## Rough surfaces (10 depths 0.1-2 rms from first touch, nu = 0.3, lambda = 0.2)\n")
    print("| H | N | samples | quantity | exponent | +-bootstrap | +-regression | R2 | seconds |")
    print("|---|---|---|---|---|---|---|---|---|")
    sizes = [(24, 5), (64, 20)] if args.quick else [(24, 5), (128, 50), (256, 50)]
    for hurst, name in ((0.6, "rough_h06.toml"), (0.8, "rough_h08.toml")):
        for n, samples in sizes:
            cfg = load_config(ROOT / "configs" / name, [f"grid.n={n}",
                                                        f"ensemble.samples={samples}"])
            p = args.out / f"rough_H{hurst}_N{n}.h5"
            t0 = time.perf_counter()
            run(cfg, p, workers=args.workers, overwrite=True)
            dt = time.perf_counter() - t0
            for label, x, y in (("beta: F_n ~ D_z", "depth_length", "normal_force"),
                                ("alpha: F_friction ~ F_n", "normal_force", "friction_force"),
                                ("gamma: A ~ F_n", "normal_force", "contact_area")):
                print(f"| {hurst} | {n} | {samples} | {label} | {fit_row(p, x, y)} | "
                      f"{dt:.0f} |", flush=True)
    print(f"\ntotal {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
