"""Burst statistics of the pull: sizes and force drops for rough surfaces, before and after the
friction peak, against the exponent 5/2 of fibre bundles with equal load sharing.

    python scripts/burst_study.py [--out runs/bursts] [--workers 2] [--quick]

Runs configs/rough_h08.toml with surface.hurst = 0.6 and 0.8, N = 128 (40 samples) and
N = 256 (20 samples), three depths (1, 1.5 and 2 rms heights from first touch), the exact
pull (inverse) with pull.early_stop = false so that every break after the peak is recorded,
and pull curves stored. Then `roughslip bursts` on each file; prints Markdown tables
(docs/results.md holds the output of a full run) and writes the distributions as
<out>/bursts_H<H>_N<N>.png. Nothing is tuned.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from roughslip.analysis.bursts import burst_report
from roughslip.analysis.plotting import plot_bursts
from roughslip.run.config import load_config
from roughslip.run.executor import run

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "bursts")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="N = 64, 8 samples (a smoke test)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    sizes = [(64, 8)] if args.quick else [(128, 40), (256, 20)]
    print(f"# cores: {os.cpu_count()}, workers: {args.workers}\n")
    print("| H | N | samples | pulls | phase | bursts | size exponent | +- | size range "
          "| n_tail | drop exponent | +- | drop range | n_tail | seconds |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for hurst in (0.6, 0.8):
        for n, samples in sizes:
            cfg = load_config(ROOT / "configs" / "rough_h08.toml", [
                f"surface.hurst={hurst}", f"grid.n={n}", f"ensemble.samples={samples}",
                "squeeze.depths=[1.0, 1.5, 2.0]", "pull.method='inverse'",
                "pull.early_stop=false", "output.fields=['pull_curve']"])
            path = args.out / f"bursts_H{hurst}_N{n}.h5"
            t0 = time.perf_counter()
            run(cfg, path, workers=args.workers, overwrite=True)
            seconds = time.perf_counter() - t0
            sample, fits = burst_report([path])
            plot_bursts(sample, fits, path.with_suffix(".png"))
            for bf in fits:
                cells = []
                for fit in (bf.size, bf.drop):
                    if fit is None:
                        cells.append("- | - | - | -")
                    else:
                        cells.append(f"{fit.alpha:.3f} | {fit.sigma:.3f} | "
                                     f"{fit.xmin:.3g}-{fit.xmax:.3g} | {fit.n_tail}")
                print(f"| {hurst} | {n} | {samples} | {sample.pulls} | {bf.phase} | "
                      f"{bf.bursts} | {cells[0]} | {cells[1]} | {seconds:.0f} |", flush=True)


if __name__ == "__main__":
    main()
