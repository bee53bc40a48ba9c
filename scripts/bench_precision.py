"""The exact pull's inverse in double and in single precision, and compressed, side by side.

    python scripts/bench_precision.py [--size 256] [--area 0.2] [--repeat 3] [--threads 2]
                                      [--slip-law break|coulomb|slip-weakening]
                                      [--law 0.1:0.05]
                                      [--variants double single hierarchical
                                                  hierarchical-single vector
                                                  vector-single vector-hierarchical
                                                  vector-hierarchical-single]

The scene is bench_pull.py's (rough, H = 0.8, open, nu = 0.3, lambda = 0.2, tol = 1e-10).
A variant is ``double`` or ``single`` (the ``inverse`` method in that precision),
``hierarchical`` or ``hierarchical-single`` (the compressed inverse, stored in double or in
single precision), or ``vector`` (the traction vector, ``pull.components = "xy"``, on the
double-precision inverse: another model, so its break sequence differs; ``vector-single``,
``vector-hierarchical`` and ``vector-hierarchical-single`` on the others); the first is the
reference (default: double and single). Each run is a fresh process, alternating the
variants, so that its peak resident memory is its own: ``peak`` is the process's, ``pull``
the rise of the peak over the resident set just before the pull. Prints the medians, whether
the break sequences are identical to the reference's, the friction forces' relative
difference and each certified path's counters, then every run's seconds and the time ratio
of each alternating pair (a variant over the reference run just before it), whose spread
shows how far the machine's scatter moves the ratio. ``--slip-law coulomb`` pulls under the
Coulomb law instead (its event sequence, sites and kinds, is compared), ``--slip-law
slip-weakening`` under slip-weakening with ``--law lam_d:d_c`` (double precision only).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

import numpy as np


def _rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


#: variant -> (pull method, precision, tangential model)
VARIANTS = {"double": ("inverse", "double", "x"), "single": ("inverse", "single", "x"),
            "hierarchical": ("hierarchical", "double", "x"),
            "hierarchical-single": ("hierarchical", "single", "x"),
            "vector": ("inverse", "double", "xy"),
            "vector-single": ("inverse", "single", "xy"),
            "vector-hierarchical": ("hierarchical", "double", "xy"),
            "vector-hierarchical-single": ("hierarchical", "single", "xy")}


def child(size: int, area: float, variant: str, threads: int, out: str, law: str,
          params: str = "0.1:0.05") -> None:
    sys.path.insert(0, os.path.dirname(__file__))
    from bench_pull import contact

    from roughslip.friction.pull import pull

    normal = contact(size, area)
    before = _rss()
    t0 = time.perf_counter()
    method, precision, components = VARIANTS[variant]
    kw = {}
    if law == "slip-weakening":
        ld, dc = (float(v) for v in params.split(":"))
        kw = {"lam_dynamic": ld, "slip_distance": dc}
    res = pull(normal, lam=0.2, method=method, tol=1e-10, threads=threads,
               precision=precision, components=components, slip_law=law, **kw)
    sec = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    kinds = np.array([str(k) for k in res.curve.kind[1:]])
    np.save(out + ".npy", np.char.add(res.curve.site[1:].astype(str), kinds))
    with open(out + ".json", "w") as f:
        json.dump({"sec": sec, "peak": peak, "pull": peak - before, "bonds": res.details.n_bonds,
                   "steps": res.steps, "friction": res.friction_force,
                   "converged": res.converged, "message": res.message}, f)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--area", type=float, default=0.2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variants", nargs="+", choices=list(VARIANTS),
                    default=["double", "single"])
    ap.add_argument("--slip-law", default="break",
                    choices=["break", "coulomb", "slip-weakening"])
    ap.add_argument("--law", default="0.1:0.05", help="lam_d:d_c of slip-weakening")
    ap.add_argument("--child", nargs=2, metavar=("VARIANT", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        child(a.size, a.area, a.child[0], a.threads, a.child[1], a.slip_law, a.law)
        return
    runs: dict[str, list[dict]] = {v: [] for v in a.variants}
    seqs: dict[str, np.ndarray] = {}
    tmp = f"/tmp/bench_precision_{os.getpid()}"
    for _ in range(a.repeat):
        for p in runs:
            subprocess.run([sys.executable, __file__, "--size", str(a.size), "--area",
                            str(a.area), "--threads", str(a.threads), "--slip-law",
                            a.slip_law, "--law", a.law, "--child", p, tmp],
                           check=True)
            with open(tmp + ".json") as f:
                runs[p].append(json.load(f))
            seqs[p] = np.load(tmp + ".npy")
    med = {p: {k: statistics.median(r[k] for r in rs) for k in ("sec", "peak", "pull")}
           for p, rs in runs.items()}
    ref = a.variants[0]
    d = runs[ref][0]
    law = a.slip_law + (f" {a.law}" if a.slip_law == "slip-weakening" else "")
    print(f"# cores: {os.cpu_count()}, threads {a.threads}; N = {a.size}, area {a.area}, "
          f"{d['bonds']} bonds, slip law {law}, medians of {a.repeat}")
    w = max(12, *(len(p) for p in runs))
    print(f"{'variant':>{w}} {'sec':>8} {'peak GiB':>9} {'pull GiB':>9} {'steps':>6} "
          f"{'F_friction':>20}")
    for p, rs in runs.items():
        print(f"{p:>{w}} {med[p]['sec']:8.2f} {med[p]['peak'] / 2**30:9.3f} "
              f"{med[p]['pull'] / 2**30:9.3f} {rs[0]['steps']:>6} {rs[0]['friction']:20.15f}")
    secs = {p: [r["sec"] for r in rs] for p, rs in runs.items()}
    print("seconds (each run): " + "; ".join(f"{p} " + " ".join(f"{t:.2f}" for t in ts)
                                             for p, ts in secs.items()))
    for p in a.variants[1:]:
        s = runs[p][0]
        paired = [t / u for t, u in zip(secs[p], secs[ref], strict=True)]
        print(f"ratios {p}/{ref}: time {med[p]['sec'] / med[ref]['sec']:.3f}, "
              f"peak {med[p]['peak'] / med[ref]['peak']:.3f}, "
              f"pull {med[p]['pull'] / med[ref]['pull']:.3f}; alternating pairs "
              + " ".join(f"{r:.3f}" for r in paired))
        rel = (s["friction"] - d["friction"]) / d["friction"]
        what = "break" if a.slip_law == "break" else "event"
        print(f"{p}: same {what} sequence as {ref}: {np.array_equal(seqs[ref], seqs[p])}; "
              f"friction relative difference {rel:.1e}; "
              f"converged {d['converged']} / {s['converged']}")
        print(f"{p}: {s['message']}")
    for ext in (".npy", ".json"):
        os.remove(tmp + ext)


if __name__ == "__main__":
    main()
