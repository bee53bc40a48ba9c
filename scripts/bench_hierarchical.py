"""The compressed inverse of the pull on the benchmark scene: ranks, memory and the cost of its
parts against the bond count.

    python scripts/bench_hierarchical.py [--sizes 128 256 384 512] [--area 0.2] [--dense 16000]
                                         [--precision double] [--threads 2]
                                         [--components x]

The scene is bench_pull.py's (rough, H = 0.8, open, nu = 0.3, 20 % contact by default). For
each grid it builds the compressed inverse of G_xx on all bonds
(:class:`roughslip.linalg.hierarchical.HierarchicalInverse`, the pull's defaults, stored in
``--precision``, BLAS on ``--threads`` as in the pull) and prints:
the bonds, the root's rank and the median and 90th percentile of all blocks' ranks, the memory
held and the estimate the guard checks (MiB), the seconds of the compression and of the
factorisation, of a fold that deletes 1 % of the rows and factorises again, the milliseconds of
one column of the inverse (median of 100), the measured error delta = ||G_SS - A~||_2 relative
to ||G_SS||_2 (Lanczos, as the pull measures it, with its rounding floor, without its safety
factor), and, up to ``--dense`` bonds, the largest
relative error of 40 columns against the dense inverse. Then the growth exponents of the
memory and of the column's time against the bonds (least squares in log-log). ``--components
xy``: the inverse of the traction vector's G_tt (two unknowns per bond at the bond's point;
the column counts are of unknowns).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np
from scipy.sparse.linalg import LinearOperator, eigsh

sys.path.insert(0, os.path.dirname(__file__))
from bench_pull import contact

from roughslip.friction.bonds import Bonds
from roughslip.friction.breaking_single import NU_SAFETY, _compression_error
from roughslip.linalg.hierarchical import HierarchicalInverse, hierarchical_bytes
from roughslip.linalg.threads import blas_threads


def measure(size: int, area: float, dense: int, dtype: type, threads: int,
            components: tuple[str, ...] = ("x",)) -> dict:
    b = Bonds(contact(size, area), 0.2, threads=1, components=components)
    iy, ix = np.divmod(np.repeat(b.sites, b.k), b.shape[1])
    h = HierarchicalInverse(b.entries, b.size, room=lambda m: True,
                            points=np.column_stack([iy, ix]).astype(float), block=128,
                            dtype=dtype, threads=threads)
    with blas_threads(threads):
        return _measure(b, h, dense)


def _measure(b: Bonds, h: HierarchicalInverse, dense: int) -> dict:
    t0 = time.perf_counter()
    h.factor(np.arange(b.size))
    build = time.perf_counter() - t0
    ranks = h.ranks()[h.ranks() > 0]
    out = {"bonds": b.n, "root": int(h.ranks()[0]), "median": float(np.median(ranks)),
           "p90": float(np.percentile(ranks, 90)), "held": h.nbytes() / 2**20,
           "estimate": hierarchical_bytes(b.size, block=128, itemsize=h.dtype.itemsize,
                                          per_point=b.k) / 2**20,
           "compress": h.compress_seconds, "factor": build - h.compress_seconds}
    times = []
    for r in range(0, b.size, max(1, b.size // 100))[:100]:
        t = time.perf_counter()
        h.column(r)
        times.append(time.perf_counter() - t)
    out["column_ms"] = 1e3 * statistics.median(times)
    every = np.arange(b.size)
    norm = float(eigsh(LinearOperator((b.size, b.size),
                                      matvec=lambda v: b.product(every, np.ravel(v)),
                                      dtype=np.float64), k=1, which="LM", tol=1e-2,
                       v0=np.ones(b.size), return_eigenvectors=False)[0])
    out["delta"] = _compression_error(b, h) / NU_SAFETY / norm
    out["column_error"] = float("nan")
    if b.size <= dense:
        Gi = np.linalg.inv(b.dense())
        cols = range(0, b.size, max(1, b.size // 40))
        out["column_error"] = max(float(np.linalg.norm(h.column(r) - Gi[:, r])
                                        / np.linalg.norm(Gi[:, r])) for r in cols)
    for u in np.random.default_rng(0).permutation(b.size)[: b.size // 100]:
        h.remove(int(u))
    t = time.perf_counter()
    h.flush()
    out["fold"] = time.perf_counter() - t
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256, 384, 512])
    ap.add_argument("--area", type=float, default=0.2)
    ap.add_argument("--dense", type=int, default=16000)
    ap.add_argument("--precision", choices=["double", "single"], default="double")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--components", choices=["x", "xy"], default="x")
    a = ap.parse_args()
    dtype = np.float32 if a.precision == "single" else np.float64
    print(f"# cores: {os.cpu_count()}; area {a.area}; {a.precision} precision; "
          f"BLAS threads {a.threads}; components {a.components}")
    print(f"{'N':>5} {'bonds':>6} {'root':>5} {'med':>4} {'p90':>5} {'MiB':>7} {'est':>7} "
          f"{'compress':>8} {'factor':>7} {'fold':>6} {'col ms':>7} {'delta':>8} "
          f"{'col err':>8}")
    rows = []
    for n in a.sizes:
        r = measure(n, a.area, a.dense, dtype, a.threads, tuple(a.components))
        rows.append(r)
        print(f"{n:>5} {r['bonds']:>6} {r['root']:>5} {r['median']:>4.0f} {r['p90']:>5.0f} "
              f"{r['held']:>7.0f} {r['estimate']:>7.0f} {r['compress']:>8.2f} "
              f"{r['factor']:>7.2f} {r['fold']:>6.2f} {r['column_ms']:>7.2f} "
              f"{r['delta']:>8.1e} {r['column_error']:>8.1e}", flush=True)
    if len(rows) > 1:
        x = np.log([r["bonds"] for r in rows])
        for key in ("held", "column_ms", "fold"):
            slope = np.polyfit(x, np.log([r[key] for r in rows]), 1)[0]
            print(f"growth exponent of {key} against the bonds: {slope:.2f}")


if __name__ == "__main__":
    main()
