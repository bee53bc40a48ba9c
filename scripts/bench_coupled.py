"""Time the coupled model against the decoupled pull on the same scenes.

    python scripts/bench_coupled.py [--sizes 64 128] [--areas 0.05 0.175] [--methods auto cg]
                                    [--slip-law break|coulomb] [--histories bonded ...]
    python scripts/bench_coupled.py --floor [--sizes 128] [--areas 0.05 0.175] [--repeat 3]
    python scripts/bench_coupled.py --gap-bound [--sizes 128] [--areas 0.05 0.175] [--near 0 128]

Scenes: a self-affine surface (H = 0.8, rms height 1, seed 1, oversampled twice), nu = 0.25,
lam = 0.2, open grid, at the depth where the frictionless squeeze has the given contact
fraction. For each: the decoupled exact pull (``auto``) and the coupled model with each
``--methods`` solver and each squeeze history (``--histories``, default all), their seconds,
the states before the pull and the pull's events, the ratio coupled / decoupled pull (``ratio``;
the decoupled pull's time is the median of ``--repeat`` runs after one to warm up, a short run
whose single timings scatter by a third)
and coupled / decoupled squeeze and pull (``ratio2``: the coupled time includes its squeeze),
and the shares of the coupled time spent before the pull starts (the squeeze history), inside
FFT calls and in dense linear algebra (BLAS/LAPACK: the dense solver's factorisation, products
with its inverse and updates). ``--slip-law coulomb`` times both models under the Coulomb law.
Threads: BLAS and FFT use ``--threads``.

``--slip-law slip-weakening`` times both under slip-weakening (``--law lam_dynamic:slip_distance``,
default 0.1:0.05; the coupled model's path-follower and bursts; its ``blas%`` is left out, the
dense solver's timer seeing only the squeeze). ``--profile`` runs each coupled
solve a second time under the profiler and prints where its time goes: the path between events
(the certified steps), the bursts (their flows), and, across both, the dense linear algebra
(LAPACK: inverses, eigenvalues, factorisations, the flows' LU) and the FFT products.

``--floor`` times instead what any exact coupled pull on the explicit inverse of the block
must do once, against the decoupled pull (medians of ``--repeat``): assembling the order-2n
block of every contact site, f_z and f_x, which is where the pull starts after the
``frictionless`` and, with fewer bonds, the other histories, and inverting it (Cholesky and
LAPACK's inverse from it).

``--gap-bound`` measures instead what a bound on the gaps would save the ``frictionless`` pull
(break law). Today each state it solves takes one block product over the whole grid, for the
gaps of every site out of contact and their rates, which are affine in D_x until the next
event. With a bound, a product would make its state the reference. A later state would be
compared with the reference's forces continued along their rate: over the state's stretch of
D_x, the gap of a site ``i`` out of contact differs from the reference's continued gap by at
most ``R_i |df|``. Here ``R_i`` is the norm of its row of the block (``u_z`` at ``i`` due to
``f_z`` and ``f_x`` at the contact sites), and ``df`` is the difference of the contact forces
from the continued ones. The ``--near K`` sites nearest to closing at the reference (smallest
``gap_i / R_i``) would be followed exactly by their rows. A state needs a product of its own
when the bound lets a gap of another site close at either end of its stretch, or when the
contact set has changed. The table counts those products against the states.
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import os
import pstats
import statistics
import time

import numpy as np
from benchlib import (  # the same scenes as the squeeze benchmark
    add_law_arguments,
    depth_for_area,
    law_keywords,
    median_times,
)

from roughslip import couple, pull
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.coupling.blocksolvers import DenseBlockSolver
from roughslip.coupling.histories import HISTORIES
from roughslip.coupling.state import ContactState
from roughslip.elastic.operators import Grid, Material
from roughslip.linalg import lapack64
from roughslip.linalg.threads import blas_threads
from roughslip.surfaces import sample_rng, self_affine


def _scenes(sizes: list[int], areas: list[float], threads: int):
    """The scenes of the module docstring: ``(problem, frictionless solver, area, depth)`` for
    each size and contact fraction."""
    for n in sizes:
        h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(1, 0), oversample=2)
        problem = Problem(h, Grid((n, n)), Material(1.0, 0.25), threads=threads)
        solver = NormalSolver(problem, tol=1e-12)
        for area in areas:
            yield problem, solver, area, depth_for_area(solver, area, hi=float(h.max() - h.min()))


def floor(sizes: list[int], areas: list[float], threads: int, repeat: int) -> None:
    """The ``--floor`` table (module docstring)."""
    print(f"# cores: {os.cpu_count()}, threads {threads}; H = 0.8, nu = 0.25, lam = 0.2, "
          f"open grid; medians of {repeat}")
    print(f"{'N':>5} {'area':>6} {'sites':>6} {'unknowns':>8} {'pull s':>7} {'assemble s':>10} "
          f"{'invert s':>9} {'GFlop/s':>8} {'invert/pull':>11} {'both/pull':>9}")
    for problem, solver, _, depth in _scenes(sizes, areas, threads):
        block = DenseBlockSolver(problem, threads=threads)
        normal = solver.solve(depth=depth)
        t_pull = median_times([lambda normal=normal: pull(normal, lam=0.2)], repeat)[0]
        sites = np.flatnonzero(normal.contact)
        ids = np.concatenate([2 * sites, 2 * sites + 1])
        t_asm, t_inv = [], []
        for _ in range(repeat):
            t0 = time.perf_counter()
            A = block.entries(ids, ids, "F")
            t1 = time.perf_counter()
            with blas_threads(threads):
                lapack64.cholesky_inverse(A)
            t_asm.append(t1 - t0)
            t_inv.append(time.perf_counter() - t1)
            del A
        a, v = statistics.median(t_asm), statistics.median(t_inv)
        print(f"{problem.shape[0]:>5} {normal.contact_area:>6.3f} {sites.size:>6} "
              f"{ids.size:>8} {t_pull:>7.3f} {a:>10.3f} {v:>9.3f} "
              f"{ids.size ** 3 / v / 1e9:>8.0f} {v / t_pull:>11.2f} {(a + v) / t_pull:>9.2f}",
              flush=True)


def gap_bound(sizes: list[int], areas: list[float], threads: int, near: list[int]) -> None:
    """The ``--gap-bound`` table (module docstring)."""
    print(f"# cores: {os.cpu_count()}, threads {threads}; H = 0.8, nu = 0.25, lam = 0.2, "
          "open grid, slip law break, history frictionless")
    print(f"{'N':>5} {'area':>6} {'sites':>6} {'events':>7} {'states':>7} "
          + " ".join(f"{'K=' + str(k):>7}" for k in near) + "  (block products needed)")
    for problem, _, area, depth in _scenes(sizes, areas, threads):
        result, states = _pull_states(problem, depth)
        norms = _RowNorms(DenseBlockSolver(problem, threads=threads))
        needed = [_products_needed(states, norms, k) for k in near]
        print(f"{problem.shape[0]:>5} {area:>6.3f} {int(result.start.contact.sum()):>6} "
              f"{len(result.events):>7} {len(states):>7} "
              + " ".join(f"{x:>7}" for x in needed), flush=True)


class _RowNorms:
    """``R_i`` of every site out of contact, by contact set (computed once per set)."""

    def __init__(self, block: DenseBlockSolver) -> None:
        self.block, self.known = block, {}

    def __call__(self, C: np.ndarray) -> np.ndarray:
        key = C.tobytes()
        if key not in self.known:
            on, off = np.flatnonzero(C), np.flatnonzero(~C)
            G = self.block.entries(2 * off, np.concatenate([2 * on, 2 * on + 1]), "C")
            self.known[key] = np.sqrt(np.einsum("ij,ij->i", G, G))
        return self.known[key]


def _products_needed(states: list[tuple], row_norms: _RowNorms, near: int) -> int:
    """The block products a pull through ``states`` would need with the gap bound and the
    ``near`` sites nearest to closing followed exactly (module docstring)."""
    products, ref = 0, None
    for k, (D, f, rate, gap, gap_rate, C) in enumerate(states):
        ends = (D,) if k + 1 == len(states) else (D, states[k + 1][0])  # the state's piece
        if ref is not None and np.array_equal(C, ref[5]) and all(
                _safe(ref, e, f + (e - D) * rate) for e in ends):
            continue
        products += 1  # a product here: this state becomes the reference
        off = np.flatnonzero(~C)
        R = row_norms(C)
        far = np.sort(np.argsort(gap[off] / R, kind="stable")[near:])
        on = np.flatnonzero(C)
        ref = (D, f, rate, gap, gap_rate, C, np.concatenate([on, on + C.size]), off[far], R[far])
    return products


def _safe(ref: tuple, D: float, f: np.ndarray) -> bool:
    """Whether the bound keeps every far site out of contact at ``D`` with the forces ``f``:
    the reference's gaps continued along its rate, less ``R_i`` times the change of the
    contact forces from the reference's continued along its rate."""
    D0, f0, rate0, gap0, gap_rate0, _, on, far, R = ref
    df = f[on] - (f0[on] + (D - D0) * rate0[on])
    return bool(np.all(gap0[far] + (D - D0) * gap_rate0[far] > R * np.linalg.norm(df)))


def _pull_states(problem: Problem, depth: float) -> tuple[object, list[tuple]]:
    """Run the ``frictionless`` coupled pull and keep every state it solves, as ``(D_x, f,
    rate of f, gap, rate of the gap, contact set)`` (flat; ``f`` is f_z then f_x), the pull's
    state methods wrapped for the run."""
    states: list[tuple] = []
    apply, solve = ContactState.apply, ContactState.solve

    def applied(st, kind, j, D=0.0):
        st._kept_at = D if st.pulling else None
        return apply(st, kind, j, D)

    def solved(st, bulk=False):
        solve(st, bulk)
        D = getattr(st, "_kept_at", None)
        if D is not None:
            states.append((D, np.concatenate([st.f0[0].ravel(), st.f0[1].ravel()]),
                           np.concatenate([st.f1[0].ravel(), st.f1[1].ravel()]),
                           st.g0.ravel().copy(), st.g1.ravel().copy(), st.C.ravel().copy()))
            st._kept_at = None

    ContactState.apply, ContactState.solve = applied, solved
    try:
        result = couple(problem, depth=depth, lam=0.2, history="frictionless")
    finally:
        ContactState.apply, ContactState.solve = apply, solve
    return result, states


def profile_shares(fn) -> tuple[float, dict[str, float]]:
    """Run ``fn`` under the profiler: its seconds there and the shares of the path between
    events, the bursts, dense linear algebra and FFT (module docstring)."""
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.runcall(fn)
    total = time.perf_counter() - t0
    stats = pstats.Stats(prof).stats
    cum = {"path": 0.0, "bursts": 0.0}
    own = {"dense": 0.0, "fft": 0.0}
    for (path, _, name), (_, _, tt, ct, _) in stats.items():
        if path.endswith("coupling/weakening.py") and name in ("advance", "burst"):
            cum["path" if name == "advance" else "bursts"] += ct
        where = f"{path} {name}"
        if "linalg" in where and "roughslip" not in where:
            own["dense"] += tt
        elif path.endswith("elastic/fft.py") or "pyfftw" in where or "numpy/fft" in where:
            own["fft"] += tt
    return total, {k: v / total for k, v in {**cum, **own}.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    ap.add_argument("--areas", type=float, nargs="+", default=[0.05, 0.175])
    ap.add_argument("--methods", nargs="+", default=["auto"])
    ap.add_argument("--threads", type=int, default=2)
    add_law_arguments(ap)
    ap.add_argument("--profile", action="store_true",
                    help="profile each coupled solve once more and print its shares")
    ap.add_argument("--histories", nargs="+", default=list(HISTORIES.names()),
                    choices=HISTORIES.names())
    ap.add_argument("--floor", action="store_true",
                    help="time the assembly and inversion of the order-2n block instead")
    ap.add_argument("--gap-bound", action="store_true",
                    help="count the whole-grid products a bound on the gaps would leave")
    ap.add_argument("--near", type=int, nargs="+", default=[0, 32, 128, 512],
                    help="sites followed exactly by --gap-bound")
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs per timing of --floor and of the decoupled pull")
    args = ap.parse_args()
    if args.floor:
        floor(args.sizes, args.areas, args.threads, args.repeat)
        return
    if args.gap_bound:
        gap_bound(args.sizes, args.areas, args.threads, args.near)
        return
    law = args.slip_law
    kw = law_keywords(args)
    print(f"# cores: {os.cpu_count()}, threads {args.threads}; H = 0.8, nu = 0.25, lam = 0.2, "
          f"open grid, slip law {law}"
          + (f" (lam_d {kw['lam_dynamic']:g}, d_c {kw['slip_distance']:g})" if kw else ""))
    print(f"{'N':>5} {'area':>6} {'sites':>6} {'squeeze s':>10} {'pull s':>7} {'method':>8} "
          f"{'history':>13} {'coupled s':>10} {'states':>7} {'events':>7} {'solves':>7} "
          f"{'ratio':>6} {'ratio2':>6} {'sq%':>5} {'fft%':>5} {'blas%':>5}")
    for problem, solver, _, depth in _scenes(args.sizes, args.areas, args.threads):
        n = problem.shape[0]
        t0 = time.perf_counter()
        normal = NormalSolver(problem, tol=1e-8).solve(depth=depth)  # a run's squeeze
        t_sq = time.perf_counter() - t0
        normal = solver.solve(depth=depth)
        t_dec = median_times([lambda normal=normal: pull(normal, lam=0.2, slip_law=law, **kw)],
                             args.repeat)[0]
        for method in args.methods:
            for history in args.histories:
                op = problem.operator("zz", "zx", "xx")
                fft0 = op.fft_seconds + op.with_threads(1).fft_seconds
                t0 = time.perf_counter()
                c = couple(problem, depth=depth, lam=0.2, method=method, slip_law=law,
                           history=history, **kw)
                t_c = time.perf_counter() - t0
                fft = op.fft_seconds + op.with_threads(1).fft_seconds - fft0
                print(f"{n:>5} {normal.contact_area:>6.3f} {normal.n_contact:>6} "
                      f"{t_sq:>10.2f} {t_dec:>7.2f} {c.method:>8} {history:>13} "
                      f"{t_c:>10.2f} {c.details.squeeze_states:>7} {len(c.events):>7} "
                      f"{c.solves:>7} {t_c / t_dec:>6.1f} {t_c / (t_dec + t_sq):>6.1f} "
                      f"{100 * c.details.squeeze_seconds / t_c:>4.0f}% {100 * fft / t_c:>4.0f}% "
                      + (f"{'-':>5}" if kw else f"{100 * c.details.blas_seconds / t_c:>4.0f}%")
                      + ("" if c.converged else f"  NOT CONVERGED: {c.message}"),
                      flush=True)
                if args.profile:
                    t_p, sh = profile_shares(functools.partial(
                        couple, problem, depth=depth, lam=0.2, method=method, slip_law=law,
                        history=history, **kw))
                    print(f"#   profiled {t_p:.2f} s: " + ", ".join(
                        f"{k} {100 * v:.0f}%" for k, v in sh.items()), flush=True)


if __name__ == "__main__":
    main()
