"""Throughput of `roughslip run`: the report's rough-surface friction study.

    python scripts/bench_run.py [--n 128] [--samples 20] [--workers 1 2] [--keep DIR]

Runs configs/rough_h06.toml and configs/rough_h08.toml (H = 0.6 and 0.8, 10 depths, pull
enabled) at grid size ``--n`` with ``--samples`` samples, once per worker count, and prints the
wall time, samples per hour, and the projected time of the 100-samples-per-H study.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from roughslip.run.config import load_config
from roughslip.run.executor import run

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--keep", type=Path, help="write the run files here instead of a tmp dir")
    args = ap.parse_args()
    print(f"# cores: {os.cpu_count()}; N = {args.n}, {args.samples} samples per H, 10 depths, "
          "pull enabled (exact)")
    print(f"{'workers':>7} {'H':>4} {'wall s':>8} {'samples/h':>10} {'100/H projected min':>20}")
    out_dir = args.keep or Path(tempfile.mkdtemp(prefix="roughslip-bench-"))
    out_dir.mkdir(parents=True, exist_ok=True)
    for w in args.workers:
        total = 0.0
        for name, hurst in (("rough_h06.toml", 0.6), ("rough_h08.toml", 0.8)):
            cfg = load_config(ROOT / "configs" / name, [f"grid.n={args.n}",
                                                        f"ensemble.samples={args.samples}"])
            t0 = time.perf_counter()
            run(cfg, out_dir / f"H{hurst}_w{w}.h5", workers=w, overwrite=True)
            dt = time.perf_counter() - t0
            total += dt
            rate = args.samples / dt * 3600
            print(f"{w:>7} {hurst:>4} {dt:>8.1f} {rate:>10.0f} {100 / rate * 60:>20.1f}",
                  flush=True)
        print(f"{w:>7} both {total:>8.1f} {'':>10} "
              f"{total * 100 / args.samples / 60:>20.1f}", flush=True)


if __name__ == "__main__":
    main()
