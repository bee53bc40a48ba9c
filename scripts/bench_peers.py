"""Time the squeeze beside two peer codes, on the same surfaces, in one process.

    python scripts/bench_peers.py [--size 512] [--repeat 5] [--threads 2]
                                  [--areas 0.067 0.28] [--hertz-area 0.05]

* Tamaas (``pip install tamaas``): its Polonsky-Keer-Rey solver on a periodic self-affine
  surface (H = 0.8, rms height 1, seed 2024), force control, at the mean pressures where
  roughslip's squeeze has the contact fractions ``--areas``. Both codes get ``--threads``.
  Tamaas samples the continuum (Westergaard) kernel, roughslip integrates it over the pixel,
  so the contact areas differ slightly: both are printed.
* ContactMechanics (``pip install ContactMechanics``): its constrained conjugate gradients on
  an open Hertz sphere (radius 2N, the pixel-integrated kernel, as roughslip's), displacement
  control at the depth where roughslip's contact fraction is ``--hertz-area``. It runs on one
  thread, and so does roughslip here.

Each peer is optional: a missing one prints a line saying so. The two codes run alternately,
``--repeat`` times each after one untimed call, and the best (least) time of each is kept.
Tolerances: roughslip 1e-8 (its residual: the worst gap error relative to the depth); Tamaas
1e-8 (its own relative criterion); ContactMechanics ``pentol`` = 1e-8 x depth. ``ratio`` is
roughslip's time over the peer's: below 1, roughslip is faster.
"""

from __future__ import annotations

import argparse
import os
import time
from importlib.metadata import version

import numpy as np
from benchlib import depth_for_area

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.elastic.operators import Grid, Material
from roughslip.surfaces.synthetic import sample_rng, self_affine, sphere

E, NU = 1.0, 0.3


def best(fn, repeat: int):
    """The least time of ``repeat`` calls and the last result."""
    out, times = None, []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def alternate(ours, peer, repeat: int):
    """Run the two alternately, ``repeat`` times each, after one untimed call of each (numba
    loads a compiled pass at its first call): (best ours, result), (best peer, result)."""
    ours()
    peer()
    a, b = [], []
    ra = rb = None
    for _ in range(repeat):
        t, ra = best(ours, 1)
        a.append(t)
        t, rb = best(peer, 1)
        b.append(t)
    return (min(a), ra), (min(b), rb)


def row(peer, case, threads, ours_area, peer_area, dforce, t_ours, t_peer, it_ours, it_peer):
    print(f"{peer:>17} {case:>24} {threads:>3} {ours_area:>7.4f} {peer_area:>7.4f} "
          f"{dforce:>9.1e} {t_ours:>8.3f} {t_peer:>8.3f} {t_ours / t_peer:>6.3f} "
          f"{it_ours:>5} {it_peer:>5}", flush=True)


def tamaas_rows(n: int, areas: list[float], threads: int, repeat: int) -> None:
    try:
        import tamaas as tm
    except ImportError:
        print(f"{'tamaas':>17}  not installed (pip install tamaas)")
        return
    tm.set_log_level(tm.LogLevel.error)
    tm.initialize(threads)
    h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(2024, 0))
    solver = NormalSolver(Problem(h, Grid((n, n), 1.0, "periodic"), Material(E, NU),
                                  fft="pyfftw", threads=threads), tol=1e-8)
    surface = np.ascontiguousarray(h - h.max())
    for area in areas:
        depth = depth_for_area(solver, area, 0.999 * (h.max() - h.mean()))
        force = solver.solve(depth=depth).normal_force

        def peer(force=force):
            model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [float(n), float(n)],
                                                [n, n])
            model.E, model.nu = E, NU
            pkr = tm.PolonskyKeerRey(model, surface, 1e-8, tm.PolonskyKeerRey.pressure,
                                     tm.PolonskyKeerRey.pressure)
            pkr.max_iter = 100_000
            pkr.solve(force / (n * n))
            return np.array(model.traction).reshape(n, n)

        (t_o, r), (t_p, p) = alternate(lambda force=force: solver.solve(force=force), peer,
                                       repeat)
        if not r.converged:
            print(f"  roughslip did not converge: {r.message}")
        # Tamaas gives pressures; on unit pixels a pixel's force is its pressure
        dforce = abs(float(p.sum()) - r.normal_force) / r.normal_force
        row("tamaas " + tm.__version__, f"periodic rough {n}^2, F", threads, r.contact_area,
            float((p > 0).mean()), dforce, t_o, t_p, r.iterations, "-")


def contactmechanics_rows(n: int, area: float, repeat: int) -> None:
    try:
        from ContactMechanics import FreeFFTElasticHalfSpace, make_system
        from SurfaceTopography import Topography
    except ImportError:
        print(f"{'contactmechanics':>17}  not installed (pip install ContactMechanics)")
        return
    h = sphere((n, n), radius=2.0 * n)
    solver = NormalSolver(Problem(h, Grid((n, n)), Material(E, NU), fft="pyfftw", threads=1),
                          tol=1e-8)
    depth = depth_for_area(solver, area, float(h.max() - h.min()))
    system = make_system(
        substrate=FreeFFTElasticHalfSpace((n, n), E / (1 - NU**2), physical_sizes=(n, n)),
        surface=Topography(h - h.max(), physical_sizes=(n, n), periodic=False))

    def peer():
        res = system.minimize_proxy(offset=depth, pentol=1e-8 * depth, maxiter=100_000)
        if not res.success:
            raise RuntimeError(f"ContactMechanics did not converge: {res.message}")
        return res

    (t_o, r), (t_p, res) = alternate(lambda: solver.solve(depth=depth), peer, repeat)
    f = np.asarray(res.jac)
    dforce = abs(f.sum() - r.normal_force) / r.normal_force
    row("contactmech " + version("ContactMechanics"), f"open Hertz {n}^2, D", 1,
        r.contact_area, float((f > 0).mean()), dforce, t_o, t_p, r.iterations, res.nit)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--threads", type=int, default=os.cpu_count())
    ap.add_argument("--areas", type=float, nargs="+", default=[0.067, 0.28])
    ap.add_argument("--hertz-area", type=float, default=0.05)
    args = ap.parse_args()
    print(f"# cores: {os.cpu_count()}; best of {args.repeat}, alternating; E = {E}, nu = {NU}, "
          "tol 1e-8")
    print(f"{'peer':>17} {'case':>24} {'thr':>3} {'area':>7} {'peer':>7} {'dforce':>9} "
          f"{'ours s':>8} {'peer s':>8} {'ratio':>6} {'it':>5} {'p.it':>5}")
    tamaas_rows(args.size, args.areas, args.threads, args.repeat)
    contactmechanics_rows(args.size, args.hertz_area, args.repeat)


if __name__ == "__main__":
    main()
