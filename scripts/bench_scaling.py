"""Time and peak memory of the exact pull against the bond count, for every inverse, in one
sitting, with the fitted growth exponents.

    python scripts/bench_scaling.py [--sizes 80 128 192 256 384 512] [--area 0.2]
                                    [--variants double single hierarchical hierarchical-single]
                                    [--repeat-below 20000 --repeat 3] [--threads 2]
                                    [--out runs/bench_scaling.jsonl] [--resume]
                                    [--fit-from 10000] [--skip N:variant ...]

The scene and the variants are bench_precision.py's (rough, H = 0.8, open, nu = 0.3, break
law, lambda = 0.2, tol = 1e-10): ``double`` and ``single`` are the dense inverse in each
precision, ``hierarchical`` and ``hierarchical-single`` the compressed one. Each run is a fresh
process (bench_precision.py's child), so that its peak resident memory is its own; the sizes go
from small to large and the variants alternate within a size. Below ``--repeat-below`` bonds
each variant runs ``--repeat`` times and the median is kept. Every run is appended to
``--out`` as one JSON line as soon as it ends; ``--resume`` keeps the runs already there, so
an interrupted sitting can be continued (its table then mixes two sittings, which it says).

Prints, per size: the bonds, the breaks, and per variant the seconds and the peak resident
memory (GiB), and whether its break sequence equals the first variant's. Then each variant's
growth exponents of time and of the pull's memory (the rise of the peak over the resident set
before the pull) against the bonds, by least squares in log-log over the sizes with at least
``--fit-from`` bonds. ``--skip N:variant`` leaves a run out of the fit (one that shared the
machine with other work, say); the table marks it with ``*``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
#: column labels of the variants
LABELS = {"double": "dense f64", "single": "dense f32", "hierarchical": "compr f64",
          "hierarchical-single": "compr f32"}


def _run(size: int, area: float, variant: str, threads: int, tmp: str) -> dict:
    subprocess.run([sys.executable, os.path.join(HERE, "bench_precision.py"), "--size",
                    str(size), "--area", str(area), "--threads", str(threads), "--child",
                    variant, tmp], check=True)
    with open(tmp + ".json") as f:
        rec = json.load(f)
    seq = np.load(tmp + ".npy")
    rec["sequence"] = seq.tolist()
    for ext in (".npy", ".json"):
        os.remove(tmp + ext)
    return rec


def _slope(x: list[float], y: list[float]) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0]) if len(x) > 1 else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[80, 128, 192, 256, 384, 512])
    ap.add_argument("--area", type=float, default=0.2)
    ap.add_argument("--variants", nargs="+",
                    default=["double", "single", "hierarchical", "hierarchical-single"])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--repeat-below", type=int, default=20000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--fit-from", type=int, default=10000)
    ap.add_argument("--out", default="runs/bench_scaling.jsonl")
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--skip", nargs="*", default=[], metavar="N:VARIANT",
                    help="runs left out of the fit")
    a = ap.parse_args()
    done: list[dict] = []
    if a.resume and os.path.exists(a.out):
        with open(a.out) as f:
            done = [json.loads(line) for line in f if line.strip()]
    elif os.path.exists(a.out):
        sys.exit(f"{a.out}: exists; pass --resume to continue it or remove it")
    os.makedirs(os.path.dirname(a.out) or ".", exist_ok=True)
    tmp = f"/tmp/bench_scaling_{os.getpid()}"
    for size in a.sizes:
        for rep in range(a.repeat):
            for v in a.variants:
                have = [r for r in done if r["size"] == size and r["variant"] == v]
                if len(have) > rep:
                    continue
                if rep and have and have[0]["bonds"] >= a.repeat_below:
                    continue
                rec = _run(size, a.area, v, a.threads, tmp)
                rec.update(size=size, variant=v, area=a.area, threads=a.threads,
                           started=time.strftime("%Y-%m-%d %H:%M:%S"))
                done.append(rec)
                with open(a.out, "a") as f:
                    f.write(json.dumps(rec) + "\n")
                print(f"N = {size} {v}: {rec['sec']:.2f} s, peak {rec['peak'] / 2**30:.3f} GiB",
                      flush=True)
    _report(done, a)


def _report(done: list[dict], a: argparse.Namespace) -> None:
    days = sorted({r["started"][:10] for r in done if r["size"] in a.sizes})
    print(f"# cores: {os.cpu_count()}, BLAS threads {a.threads}; area {a.area}; break law; "
          f"runs started on {', '.join(days)}; medians where a size ran more than once")
    ref = a.variants[0]
    head = f"{'N':>5} {'bonds':>6} {'breaks':>6}"
    for v in a.variants:
        head += f" {LABELS.get(v, v) + ' s':>14} {'GiB':>6}"
    print(head + "  same breaks")
    fit: dict[str, list[tuple[int, float, float]]] = {v: [] for v in a.variants}
    for size in a.sizes:
        rs = {v: [r for r in done if r["size"] == size and r["variant"] == v]
              for v in a.variants}
        if not all(rs.values()):
            continue
        first = rs[ref][0]
        line = f"{size:>5} {first['bonds']:>6} {first['steps']:>6}"
        same = []
        for v in a.variants:
            sec = statistics.median(r["sec"] for r in rs[v])
            peak = statistics.median(r["peak"] for r in rs[v])
            pull = statistics.median(r["pull"] for r in rs[v])
            skip = f"{size}:{v}" in a.skip
            line += f" {sec:>13.2f}{'*' if skip else ' '} {peak / 2**30:>6.2f}"
            same.append(all(r["sequence"] == first["sequence"] for r in rs[v]))
            if not skip:
                fit[v].append((first["bonds"], sec, max(pull, 1.0)))
        print(line + "  " + ("yes" if all(same) else "NO: " + " ".join(
            v for v, s in zip(a.variants, same, strict=True) if not s)))
    for v, pts in fit.items():
        pts = [p for p in pts if p[0] >= a.fit_from]
        n = [p[0] for p in pts]
        print(f"growth exponent of {v} against the bonds ({len(n)} sizes from {a.fit_from}): "
              f"time {_slope(n, [p[1] for p in pts]):.2f}, "
              f"pull memory {_slope(n, [p[2] for p in pts]):.2f}")


if __name__ == "__main__":
    main()
