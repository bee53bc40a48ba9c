"""Same events on every BLAS kernel: a matrix of scenes run under each OpenBLAS core type
this machine can run, each in its own process, compared event by event.

OpenBLAS picks its kernels (SIMD code paths) by CPU at start-up, or by the environment
variable OPENBLAS_CORETYPE. Different kernels round the same products differently, so the
numbers of a run may move at the level of round-off from one machine to another. What must
not move are the events: which bonds break, slip, stick, and which contacts are lost or
gained, in which order, and whether a pull converges. This script checks both:

* the event sequences (kind and site of every event) are identical under every kernel;
* every force differs by at most ``4 kappa tol`` times its scale, ``tol`` the loosest
  tolerance the scene's solves are certified to (the single-precision pull's curve: the
  float32 unit round-off) and ``kappa`` the condition number of the whole grid's (z, x)
  block, which bounds that of every block a solve inverts (interlacing);
* no pull stops unconverged.

The matrix:

* coupled model, 16 x 16 rough surfaces (H = 0.8), nu = 0.25, lam = 0.2, 12 seeds x 2
  depths x 4 squeeze histories, under the break and the Coulomb law, with contacts gained
  during the pull unbonded and bonded (384 pulls), and under load control (96);
* decoupled pull, 32 x 32, 12 seeds x 2 depths: break law (double and single precision),
  Coulomb, slip-weakening (lam_d = 0.1, d_c = 0.05) (384 pulls).

Usage::

    python scripts/kernel_check.py              # every core type the CPU can run
    python scripts/kernel_check.py --quick      # 3 seeds instead of 12
    python scripts/kernel_check.py --markdown   # the tables as Markdown (docs/methods.rst)

Exits with 1 if an event differs, a force is outside its tolerance or a pull did not
converge. Takes about half a minute per kernel on 2 cores. The environment of
this process is left as it is; each kernel runs in a child process with OPENBLAS_CORETYPE
set.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: core types to try, and the CPU flags each needs (Zen runs Haswell's kernels in OpenBLAS)
CORETYPES = {"Haswell": ("avx2", "fma"), "SkylakeX": ("avx512f",), "Sandybridge": ("avx",),
             "Zen": ("avx2", "fma")}
COUPLED_TOL = 1e-10  # what a run gives the coupled solves (pull.tol, at most this)
PULL_TOL, SQUEEZE_TOL = 1e-10, 1e-10  # the decoupled pull's and squeeze's


def cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    for line in text.splitlines():
        if line.startswith("flags"):
            return set(line.split(":", 1)[1].split())
    return set()


def rough(n: int, seed: int) -> np.ndarray:
    from roughslip.surfaces.synthetic import sample_rng, self_affine

    return self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0),
                       oversample=2)


def scenes(quick: bool) -> list[dict]:
    """Every scene of the matrix, as plain data."""
    seeds = range(1, 4) if quick else range(1, 13)
    out = []
    for seed in seeds:
        for depth in (1.0, 1.6):
            for law in ("break", "coulomb"):
                for gained in ("unbonded", "bonded"):
                    for history in ("bonded", "simultaneous", "frictionless", "indent"):
                        out.append(dict(family=f"coupled {law}, {gained} gains", model="coupled",
                                        seed=seed, depth=depth, law=law, gained=gained,
                                        history=history, n=16))
        for force in (2.0, 6.0):
            for law in ("break", "coulomb"):
                for history in ("bonded", "simultaneous", "frictionless", "indent"):
                    out.append(dict(family=f"coupled {law}, load control", model="coupled",
                                    seed=seed, force=force, law=law, gained="unbonded",
                                    history=history, n=16))
        for depth in (1.0, 2.5):
            for law, precision in (("break", "double"), ("break", "single"),
                                   ("coulomb", "double"), ("slip-weakening", "double")):
                out.append(dict(family=f"decoupled {law}, {precision}", model="decoupled",
                                seed=seed, depth=depth, law=law, precision=precision, n=32))
    for i, sc in enumerate(out):
        sc["id"] = i
    return out


def run_scene(sc: dict) -> dict:
    """Events, forces and convergence of one scene."""
    from roughslip.contact.problem import Problem

    pb = Problem.from_arrays(rough(sc["n"], sc["seed"]), nu=0.25)
    if sc["model"] == "coupled":
        from roughslip.coupling.coupled import couple

        by = ({"force": sc["force"], "pull_control": "force"} if "force" in sc
              else {"depth": sc["depth"]})
        r = couple(pb, **by, lam=0.2, history=sc["history"], slip_law=sc["law"],
                   gained=sc["gained"], tol=COUPLED_TOL)
        events = [[e.kind, int(e.site)] for e in r.events]
        forces = np.concatenate([r.curve.fx, r.curve.fz, r.peak.fz.ravel(), r.peak.fx.ravel()])
        return dict(events=events, friction=r.friction_force, forces=forces.tolist(),
                    converged=bool(r.converged), message=r.message)
    from roughslip.contact.squeeze import squeeze
    from roughslip.friction.pull import pull

    normal = squeeze(pb, depth=sc["depth"], tol=SQUEEZE_TOL)
    extra = ({"lam_dynamic": 0.1, "slip_distance": 0.05} if sc["law"] == "slip-weakening"
             else {})
    r = pull(normal, lam=0.2, slip_law=sc["law"], method="inverse", tol=PULL_TOL,
             precision=sc["precision"], **extra)
    c = r.curve
    events = [[k, int(s)] for k, s in zip(c.kind[1:], c.site[1:], strict=True)]
    forces = np.concatenate([c.fx[1:], normal.fz.ravel()])
    return dict(events=events, friction=r.friction_force, forces=forces.tolist(),
                converged=bool(r.converged), message=r.message)


def kernels_in_use() -> str:
    """The kernel names OpenBLAS reports for this process (numpy's and scipy's libraries)."""
    import scipy.linalg  # noqa: F401  (loads scipy's OpenBLAS too)
    import threadpoolctl

    names = sorted({str(i.get("architecture")) for i in threadpoolctl.threadpool_info()
                    if i.get("internal_api") == "openblas"})
    return "/".join(names) or "unknown"


def worker(out: str, quick: bool) -> None:
    t0 = time.perf_counter()
    results = {}
    for sc in scenes(quick):
        try:
            results[sc["id"]] = run_scene(sc)
        except Exception as exc:  # reported as a scene that failed, compared as such
            results[sc["id"]] = dict(events=[], friction=math.nan, forces=[],
                                     converged=False, message=f"{type(exc).__name__}: {exc}")
    Path(out).write_text(json.dumps({"kernel": kernels_in_use(), "results": results,
                                     "seconds": time.perf_counter() - t0}))


def kappa(sc: dict, cache: dict) -> float:
    """The condition number of the whole grid's (z, x) block of the scene's surface."""
    key = (sc["n"], sc["seed"])
    if key not in cache:
        from roughslip.contact.problem import Problem
        from roughslip.testing import dense_block

        w = np.linalg.eigvalsh(dense_block(Problem.from_arrays(rough(sc["n"], sc["seed"]),
                                                               nu=0.25)))
        cache[key] = float(w[-1] / w[0])
    return cache[key]


def probe(coretype: str | None) -> str:
    env = dict(os.environ)
    if coretype is not None:
        env["OPENBLAS_CORETYPE"] = coretype
    here = str(Path(__file__).parent)
    code = (f"import sys; sys.path.insert(0, {here!r}); import kernel_check; "
            "print(kernel_check.kernels_in_use())")
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, check=True).stdout.strip()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="3 seeds instead of 12")
    ap.add_argument("--markdown", action="store_true", help="print the tables as Markdown")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker, args.quick)
        return 0
    flags = cpu_flags()
    default = probe(None)
    runs: dict[str, str | None] = {"default": None}
    seen = {default: "default"}
    skipped = []
    for name, need in CORETYPES.items():
        if not all(f in flags for f in need):
            skipped.append(f"{name} (the CPU lacks {', '.join(f for f in need if f not in flags)})")
            continue
        kern = probe(name)
        if kern in seen:
            skipped.append(f"{name} (runs the {kern} kernels: as {seen[kern]})")
            continue
        seen[kern] = name
        runs[name] = name
    data = {}
    with tempfile.TemporaryDirectory() as tmp:
        for label, coretype in runs.items():
            env = dict(os.environ)
            if coretype is not None:
                env["OPENBLAS_CORETYPE"] = coretype
            out = Path(tmp) / f"{len(data)}.json"
            cmd = [sys.executable, __file__, "--worker", str(out)] + (["--quick"] * args.quick)
            print(f"# running the matrix under {label} ...", file=sys.stderr, flush=True)
            subprocess.run(cmd, env=env, check=True)
            data[label] = json.loads(out.read_text())
    all_scenes = scenes(args.quick)
    ref_label = next(iter(data))
    ref = data[ref_label]["results"]
    cache: dict = {}
    families: dict[str, dict] = {}
    bad = 0
    for label, d in data.items():
        for sc in all_scenes:
            r, r0 = d["results"][str(sc["id"])], ref[str(sc["id"])]
            f = families.setdefault(sc["family"], {}).setdefault(
                label, dict(scenes=0, unconverged=0, events_differ=0, worst=0.0, tol=math.inf))
            f["scenes"] += 1
            f["unconverged"] += not r["converged"]
            f["events_differ"] += r["events"] != r0["events"]
            tol = 4 * kappa(sc, cache) * (
                COUPLED_TOL if sc["model"] == "coupled" else
                float(np.finfo(np.float32).eps) if sc.get("precision") == "single" else
                max(PULL_TOL, SQUEEZE_TOL))
            a, b = np.asarray(r["forces"]), np.asarray(r0["forces"])
            if a.shape == b.shape and a.size:
                diff = float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))
            else:
                diff = math.inf
            f["worst"] = max(f["worst"], diff)
            f["tol"] = min(f["tol"], tol)
            bad += (not r["converged"]) or r["events"] != r0["events"] or diff > tol
    labels = list(data)
    shown = {lab: lab if lab == data[lab]["kernel"] else f"{lab} ({data[lab]['kernel']})"
             for lab in labels}
    print(f"reference: {shown[ref_label]}; each cell: unconverged / event sequences that "
          "differ / worst relative force difference (its tolerance)")
    if args.markdown:
        print("| family | scenes | " + " | ".join(shown[lab] for lab in labels) + " |")
        print("|---|---|" + "---|" * len(labels))
    else:
        print(f"{'family':<36} {'n':>4}   " + "   ".join(shown[lab] for lab in labels))
    for fam, per in families.items():
        n = next(iter(per.values()))["scenes"]
        cells = [f"{per[lab]['unconverged']} / {per[lab]['events_differ']} / "
                 f"{per[lab]['worst']:.1e} (tol {per[lab]['tol']:.0e})" for lab in labels]
        if args.markdown:
            print(f"| {fam} | {n} | " + " | ".join(cells) + " |")
        else:
            print(f"{fam:<36} {n:>4}   " + "   ".join(cells))
    if skipped:
        print("not run: " + "; ".join(skipped))
    print("seconds per kernel: " + ", ".join(f"{lab} {data[lab]['seconds']:.0f}"
                                              for lab in labels))
    print("all kernels: the same events, 0 unconverged, forces within tolerance" if not bad
          else f"{bad} scene(s) differ, are outside tolerance or did not converge")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
