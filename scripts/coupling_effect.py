"""How much does neglecting the normal-tangential coupling change the friction law?

    python scripts/coupling_effect.py [--sizes 64] [--samples 10] [--nu 0.0 0.25 0.45]
                                      [--depths 8] [--no-hertz] [--out runs/coupling]
                                      [--slip-law break|coulomb|slip-weakening]
                                      [--law 0.1:0.05] [--resume]
                                      [--histories bonded simultaneous indent frictionless]

The report's own open question ([Report2003] §6.1). For each nu (default 0, 0.25, 0.45) it
runs the decoupled model (the report's) and the coupled model with exact event tracking on rough
surfaces (H = 0.8, ``--samples`` samples, ``--depths`` depths 0.3-2 rms, one grid per
``--sizes``) and on the Hertz sphere (configs/hertz.toml), and prints the friction exponent alpha
of F_friction ~ F_n^alpha for both, the mean ratio of the friction forces, and the fraction of
bonds released already at D_x = 0 under coupling (slipping, under ``--slip-law coulomb``, which
runs both models with the Coulomb law; under ``--slip-law slip-weakening``, with
``--law lam_dynamic:slip_distance``, the bonds weakening or at their residual strength).
``--histories`` runs the coupled model once per squeeze
history (``coupling.history``), one row each; the friction ratio is the mean over samples of
each sample's mean ratio over depths, with the bootstrap standard deviation of that mean over
resamples of the samples (1000 resamples, seed 0); a depth whose coupled or decoupled pull did
not converge is left out of its sample's mean, and the seconds column counts them. Prints
Markdown (docs/results.md holds the output of a run). ``--resume`` continues the run files an
interrupted invocation with the same options left in ``--out`` (their completed samples are
kept; the seconds column then counts this invocation's work only).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import h5py
import numpy as np
from benchlib import add_law_arguments, law_keywords  # the scripts' shared helpers

from roughslip.analysis.fit import fit_files
from roughslip.run.config import load_config
from roughslip.run.executor import run
from roughslip.run.store import read_run

ROOT = Path(__file__).resolve().parents[1]


def released_fraction(path: Path) -> float:
    """Bonds released at D_x = 0 over the contact sites, summed over samples and depths."""
    run_data = read_run(path)
    done = run_data.complete
    released = run_data.scalars["released_bonds"][done]
    sites = run_data.scalars["contact_area"][done] * grid_sites(path)
    total = float(np.rint(sites).sum())
    return float(released.sum()) / total if total else float("nan")


def grid_sites(path: Path) -> int:
    """Number of grid sites of a run (the contact area is a fraction of it)."""
    with h5py.File(path, "r") as f:
        name = next(iter(f["samples"]))
        return int(f["samples"][name]["rigid_surface"].size)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[64], help="rough grids N")
    ap.add_argument("--samples", type=int, default=10)
    ap.add_argument("--nu", type=float, nargs="+", default=[0.0, 0.25, 0.45])
    ap.add_argument("--depths", type=int, default=8, help="depths from 0.3 to 2 rms")
    ap.add_argument("--no-hertz", action="store_true", help="skip the Hertz scene")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "coupling")
    add_law_arguments(ap)
    ap.add_argument("--resume", action="store_true",
                    help="continue the run files of an interrupted invocation")
    ap.add_argument("--histories", nargs="+", default=["bonded"],
                    help="squeeze histories of the coupled model (coupling.history)")
    args = ap.parse_args()
    law = args.slip_law
    extra, tag = [], "" if law == "break" else f"_{law}"
    kw = law_keywords(args)
    if kw:
        ld, dc = kw["lam_dynamic"], kw["slip_distance"]
        extra = [f"pull.lam_dynamic={ld!r}", f"pull.slip_distance={dc!r}"]
        tag += f"_{ld:g}_{dc:g}"
        law = f"{law} (lam_d {ld:g}, d_c {dc:g})"
    args.out.mkdir(parents=True, exist_ok=True)
    print(f"# cores: {os.cpu_count()}; rough: N = {args.sizes}, {args.samples} samples, "
          f"H = 0.8, {args.depths} depths 0.3-2 rms; Hertz: N = 64; lambda = 0.2; slip law {law}\n")
    print("| scene | N | nu | history | alpha decoupled | alpha coupled "
          "| F_fric coupled / decoupled | bonds released at D_x = 0 | seconds (dec / coup) |")
    print("|---|---|---|---|---|---|---|---|---|")
    scenes = [
        (f"rough{n}", "rough_h08.toml", [f"grid.n={n}", f"ensemble.samples={args.samples}",
                                         "squeeze.depths={start = 0.3, stop = 2.0, num = "
                                         f"{args.depths}, spacing = 'log'}}"])
        for n in args.sizes
    ]
    if not args.no_hertz:
        scenes.append(("hertz", "hertz.toml", []))
    for scene, name, base in scenes:
        for nu in args.nu:
            paths, secs = {}, {}
            for history in [None, *args.histories]:
                coupled = history is not None
                cfg = load_config(ROOT / "configs" / name, [*base, f"material.nu={nu}",
                                  f"coupling.enabled={'true' if coupled else 'false'}",
                                  f"pull.slip_law='{args.slip_law}'", *extra]
                                  + ([f"coupling.history='{history}'"] if coupled else []))
                kind = "decoupled" if not coupled else (
                    "coupled" if history == "bonded" else f"coupled_{history}")
                p = args.out / f"{scene}_nu{nu}{tag}_{kind}.h5"
                t0 = time.perf_counter()
                resume = args.resume and p.exists()
                run(cfg, p, workers=args.workers, resume=resume, overwrite=not resume)
                secs[history] = time.perf_counter() - t0
                paths[history] = p
            fd = fit_files([paths[None]])[0].fit
            rd = read_run(paths[None])
            n = grid_sites(paths[None])
            for history in args.histories:
                fc = fit_files([paths[history]])[0].fit
                rc = read_run(paths[history])
                done = rc.complete & rd.complete
                ratios = (rc.scalars["friction_force"][done]
                          / rd.scalars["friction_force"][done])
                out = _unconverged(rc, done) | _unconverged(rd, done)
                kept = (~out).sum(axis=1)  # a sample with every depth left out drops out
                per_sample = (np.where(out, 0.0, ratios).sum(axis=1)[kept > 0]
                              / kept[kept > 0])
                ratio, err = per_sample.mean(), bootstrap_std(per_sample)
                left = f" ({int(out.sum())} unconverged left out)" if out.any() else ""
                print(f"| {scene.rstrip('0123456789')} | {round(n ** 0.5)} | {nu} | {history} "
                      f"| {fmt(fd)} | {fmt(fc)} | {ratio:.3f} ± {err:.3f} | "
                      f"{released_fraction(paths[history]):.2f} | {secs[None]:.0f} / "
                      f"{secs[history]:.0f}{left} |", flush=True)


def _unconverged(r, done: np.ndarray) -> np.ndarray:
    """The (sample, depth) entries of the samples ``done`` whose pull did not converge (a
    coupled path that ends in a cycle, say): left out of the ratio, as the fit leaves them
    out of alpha."""
    flags = r.scalars.get("pull_converged")
    if flags is None:
        return np.zeros((int(done.sum()), r.scalars["friction_force"].shape[1]), bool)
    return np.asarray(flags[done], dtype=float) == 0


def fmt(f) -> str:
    e = f.alpha_stderr if math.isnan(f.alpha_bootstrap_std) else f.alpha_bootstrap_std
    return f"{f.alpha:.3f} ± {e:.3f}"


def bootstrap_std(values: np.ndarray, resamples: int = 1000) -> float:
    """Standard deviation of the mean of ``values`` over resamples with replacement."""
    if values.size < 2:
        return float("nan")
    rng = np.random.default_rng(0)
    idx = rng.integers(0, values.size, size=(resamples, values.size))
    return float(values[idx].mean(axis=1).std(ddof=1))

if __name__ == "__main__":
    main()
