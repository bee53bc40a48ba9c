"""Runs beside other runs, repeated: what each trial must give, and how many did.

    python scripts/concurrent_runs.py dask -n 10      # two configurations, one Dask scheduler
    python scripts/concurrent_runs.py one-file -n 10  # two runs, one output file

``dask``: one Dask scheduler in this process (one worker with two threads, reached over TCP)
serves two ``roughslip run --scheduler`` commands of different configurations with the same
sample numbers, started together. Each file must hold its own configuration's samples,
bitwise those of a run of that configuration alone (timings excepted), and both commands must
exit with 0.

``one-file``: two ``roughslip run`` commands of one configuration on one output file, started
together, with the options of the trial (in turn: none; ``--overwrite`` for both over a
finished file; ``--resume`` for both; none and ``--overwrite``; ``--resume`` and
``--overwrite``). Exactly one must be refused, with exit code 2 and one line naming the file and
the run holding it; the other must exit with 0 and leave every sample, bitwise those of an
undisturbed run, and no lock file, journal or temporary file.

Prints one line per failed trial and a summary line; exits 1 when a trial failed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from roughslip.testing import differences

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "configs" / "demo.toml"
#: small runs of the demo scene: a few seconds each on 2 cores
SMALL = ["grid.n=32", "ensemble.samples=6",
         "squeeze.depths={start = 0.3, stop = 1.5, num = 3, spacing = 'log'}"]
#: a second configuration: the same sample numbers, other surfaces
OTHER = [*SMALL, "surface.hurst=0.6"]


def command(out: Path, sets: list[str], *extra: str) -> list[str]:
    """``roughslip run`` of the demo configuration with ``sets`` into ``out``."""
    return [sys.executable, "-m", "roughslip", "run", str(CONFIG), "-o", str(out), "--quiet",
            *(x for s in sets for x in ("--set", s)), *extra]


def together(commands: list[list[str]]) -> list[tuple[int, str]]:
    """Start the commands at once; their exit codes and standard errors."""
    procs = [subprocess.Popen(c, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
             for c in commands]
    return [(p.wait(), p.stderr.read().decode().strip()) for p in procs]


def dask_trials(n: int, work: Path) -> tuple[int, list[str]]:
    """Two configurations on one scheduler, ``n`` times."""
    from distributed import LocalCluster

    refs = {}
    for name, sets in (("a", SMALL), ("b", OTHER)):
        refs[name] = work / f"ref_{name}.h5"
        code, err = together([command(refs[name], sets, "--workers", "1")])[0]
        if code != 0:
            raise SystemExit(f"concurrent_runs: the reference run {name} failed: {err}")
    failures = []
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp",
                      dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        for i in range(n):
            outs = {"a": work / f"t{i:03d}_a.h5", "b": work / f"t{i:03d}_b.h5"}
            results = together([command(outs["a"], SMALL, "--scheduler", address),
                                command(outs["b"], OTHER, "--scheduler", address)])
            wrong = [f"{name}: exit {code}: {err}" for name, (code, err)
                     in zip(outs, results, strict=True) if code != 0]
            wrong += [f"{name}: differs from the run alone in {diff[:3]}"
                      for name in outs if not wrong
                      and (diff := differences(refs[name], outs[name]))]
            if wrong:
                failures.append(f"trial {i}: " + "; ".join(wrong))
            else:
                for p in outs.values():
                    p.unlink()
    return n - len(failures), failures


#: the options of the two runs, trial by trial (in turn), and whether the file exists before
VARIANTS = [([], [], False), (["--overwrite"], ["--overwrite"], True),
            (["--resume"], ["--resume"], False), ([], ["--overwrite"], False),
            (["--resume"], ["--overwrite"], False)]
#: the runs of one-file trials: long enough that both have started before either ends
LONGER = ["grid.n=48", "ensemble.samples=8",
          "squeeze.depths={start = 0.3, stop = 1.5, num = 3, spacing = 'log'}"]


def one_file_trials(n: int, work: Path) -> tuple[int, list[str]]:
    """Two runs on one output, ``n`` times."""
    ref = work / "ref.h5"
    code, err = together([command(ref, LONGER, "--workers", "1")])[0]
    if code != 0:
        raise SystemExit(f"concurrent_runs: the reference run failed: {err}")
    failures = []
    for i in range(n):
        first, second, exists = VARIANTS[i % len(VARIANTS)]
        out = work / f"t{i:03d}.h5"
        if exists:
            shutil.copyfile(ref, out)
        results = together([command(out, LONGER, "--workers", "1", *first),
                            command(out, LONGER, "--workers", "1", *second)])
        codes = sorted(code for code, _ in results)
        refused = [err for code, err in results if code == 2]
        wrong = []
        if codes != [0, 2]:
            wrong.append(f"exit codes {[c for c, _ in results]}: "
                         + " | ".join(err for _, err in results))
        elif len(refused[0].splitlines()) != 1 or \
                f"{out}: another run is writing this file (PID " not in refused[0]:
            wrong.append(f"the refusal is not one line naming the file and holder: "
                         f"{refused[0]!r}")
        else:
            diff = differences(ref, out)
            left = [q.name for q in work.iterdir() if q.name.startswith(out.name + ".")]
            if diff or left:
                wrong.append(f"differs in {diff[:3]}, leftovers {left}")
        if wrong:
            failures.append(f"trial {i} ({' '.join(first) or 'plain'} and "
                            f"{' '.join(second) or 'plain'}): " + "; ".join(wrong))
        else:
            out.unlink()
    return n - len(failures), failures


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("mode", choices=["dask", "one-file"])
    p.add_argument("-n", type=int, default=10, help="number of trials")
    p.add_argument("--keep", action="store_true", help="keep the work folder")
    args = p.parse_args()
    work = Path(tempfile.mkdtemp(prefix="concurrent_runs_"))
    t0 = time.monotonic()
    trials = dask_trials if args.mode == "dask" else one_file_trials
    ok, failures = trials(args.n, work)
    for line in failures:
        print("concurrent_runs:", line)
    print(f"concurrent_runs {args.mode}: {ok}/{args.n} trials as required "
          f"({os.cpu_count()} cores, {time.monotonic() - t0:.0f} s)")
    if failures:
        print(f"concurrent_runs: files kept in {work}")
    elif not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0 if not failures else 1


if __name__ == "__main__":
    sys.exit(main())
