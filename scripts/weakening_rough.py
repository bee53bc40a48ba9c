"""The report's rough-surface study (H = 0.8) under slip-weakening, beside the break law.

    python scripts/weakening_rough.py [--out runs/weakening] [--workers 2] [--samples 20]
        [--slip-distances 0.01 0.05] [--lam-dynamic 0.1] [--scenes 0 1 2]

configs/rough_h08.toml (E = 1, nu = 0.3, rms height 1, pixel 1 = the short-wavelength
cut-off, lambda_s = 0.2, 10 depths 0.1-2 rms from first touch). For the break law and for
slip-weakening at each slip distance d_c:

* the report's size, N = 128 at pixel 1: the exponent alpha of F_friction ~ F_n^alpha and
  the mean friction coefficient F_f / (lambda_s F_n) at the smallest, middle and largest depth;
* a resolution study on one physical patch (64 x 64 length units, the same surface
  statistics with the cut-off held at wavelength 2): N = 64 at pixel 1 against N = 128 at
  pixel 0.5, the same quantities.

Prints Markdown tables (docs/results.md quotes a run). The samples differ between
resolutions (each grid draws its own surfaces); the comparison is of ensemble means.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np

from roughslip.analysis.fit import fit_files
from roughslip.run.config import load_config
from roughslip.run.executor import run
from roughslip.run.store import read_run

ROOT = Path(__file__).resolve().parents[1]


def friction_coefficients(path: Path, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error over the samples of F_f / (lambda F_n), per depth."""
    r = read_run(path)
    mu = r.scalars["friction_force"] / (lam * r.scalars["normal_force"])
    mu = mu[r.complete.astype(bool)]
    return mu.mean(axis=0), mu.std(axis=0, ddof=1) / math.sqrt(mu.shape[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "weakening")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--slip-distances", type=float, nargs="+", default=[0.01, 0.05])
    ap.add_argument("--lam-dynamic", type=float, default=0.1)
    ap.add_argument("--scenes", type=int, nargs="+", default=[0, 1, 2],
                    help="which scenes (0: N = 128 at pixel 1, 1: N = 64 on the patch, "
                         "2: N = 128 at pixel 0.5 on the patch)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    lam = 0.2
    laws = [("break", [])] + [
        (f"sw d_c={dc:g}", ['pull.slip_law="slip-weakening"',
                            f"pull.lam_dynamic={args.lam_dynamic}",
                            f"pull.slip_distance={dc}"]) for dc in args.slip_distances]
    scenes = [("N=128, h=1", ["grid.n=128", f"ensemble.samples={args.samples}"]),
              ("N=64, h=1 (patch 64)", ["grid.n=64", f"ensemble.samples={args.samples}",
                                        "surface.cutoff_wavelength=2.0"]),
              ("N=128, h=0.5 (patch 64)", ["grid.n=128", "grid.pixel_size=0.5",
                                           f"ensemble.samples={args.samples}",
                                           "surface.cutoff_wavelength=2.0"])]
    print(f"# cores: {os.cpu_count()}, workers: {args.workers}; H = 0.8, lambda_s = {lam}, "
          f"lambda_d = {args.lam_dynamic}\n")
    print("| scene | law | alpha (F_f ~ F_n^alpha) | +-bootstrap | F_f/(lam_s F_n) at "
          "depths 1, 5, 10 (+- s.e.) | seconds |")
    print("|---|---|---|---|---|---|")
    for scene, sets in (scenes[i] for i in args.scenes):
        for law, extra in laws:
            cfg = load_config(ROOT / "configs" / "rough_h08.toml", sets + extra)
            p = args.out / f"{scene.split(' (')[0].replace(', ', '_').replace('=', '')}_" \
                           f"{law.replace(' ', '_').replace('=', '')}.h5"
            t0 = time.perf_counter()
            run(cfg, p, workers=args.workers, overwrite=True)
            dt = time.perf_counter() - t0
            f = fit_files([p], "normal_force", "friction_force")[0].fit
            m, e = friction_coefficients(p, lam)
            mus = ", ".join(f"{m[k]:.3f} ({e[k]:.3f})" for k in (0, len(m) // 2, len(m) - 1))
            print(f"| {scene} | {law} | {f.alpha:.3f} | {f.alpha_bootstrap_std:.3f} | {mus} "
                  f"| {dt:.0f} |", flush=True)


if __name__ == "__main__":
    main()
