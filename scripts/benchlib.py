"""Helpers the benchmark and study scripts share (this folder's only shared module; scripts
import it, never each other)."""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from roughslip.contact.squeeze import NormalSolver
from roughslip.friction.laws import LAWS


def add_law_arguments(ap: argparse.ArgumentParser) -> None:
    """``--slip-law`` (the registry's names, default break) and ``--law
    lam_dynamic:slip_distance`` (the slip-weakening law's numbers, default 0.1:0.05)."""
    ap.add_argument("--slip-law", choices=LAWS.names(), default="break")
    ap.add_argument("--law", default="0.1:0.05",
                    help="lam_dynamic:slip_distance of --slip-law slip-weakening")


def law_keywords(args: argparse.Namespace) -> dict[str, float]:
    """The keywords of ``pull``/``couple`` that ``--law`` gives (none but for slip-weakening)."""
    if args.slip_law != "slip-weakening":
        return {}
    ld, dc = (float(v) for v in args.law.split(":"))
    return {"lam_dynamic": ld, "slip_distance": dc}


def floor_seconds(shape, repeat=9) -> float:
    """Median time of one plain pyfftw convolution of ``shape`` (ESTIMATE plans)."""
    import pyfftw

    a = pyfftw.empty_aligned(shape, dtype="float64")
    a[...] = np.random.default_rng(0).standard_normal(shape)
    b = pyfftw.empty_aligned((shape[0], shape[1] // 2 + 1), dtype="complex128")
    c = pyfftw.empty_aligned(shape, dtype="float64")
    k = np.ones(b.shape, dtype=complex)
    fwd = pyfftw.FFTW(a, b, axes=(0, 1), flags=("FFTW_ESTIMATE",))
    bwd = pyfftw.FFTW(b, c, axes=(0, 1), direction="FFTW_BACKWARD",
                      flags=("FFTW_ESTIMATE", "FFTW_DESTROY_INPUT"))
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fwd.execute()
        np.multiply(b, k, out=b)
        bwd.execute()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def median_times(fns, repeat: int) -> list[float]:
    """Median run time of each function, measured interleaved so they see the same load."""
    for fn in fns:
        fn()  # warm-up (plans, caches)
    ts: list[list[float]] = [[] for _ in fns]
    for _ in range(repeat):
        for fn, t in zip(fns, ts, strict=True):
            t0 = time.perf_counter()
            fn()
            t.append(time.perf_counter() - t0)
    return [statistics.median(t) for t in ts]


def depth_for_area(solver: NormalSolver, target: float, hi: float) -> float:
    """Depth whose contact fraction is close to ``target``: bisection with a solver of the
    same problem and method at a loose tolerance (``solver`` itself is not touched)."""
    loose = NormalSolver(solver.problem, method=solver.method, tol=1e-4)
    lo = 0.0
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        if loose.solve(depth=mid).contact_area < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
