"""Kill a run at random moments, resume it, and check that nothing differs and nothing is left.

Each trial starts ``roughslip run CONFIG --workers W`` in a new session, sends SIGKILL to its
main process at a random moment of the run (uniform over the wall time of an uninterrupted
run, so every stage is hit: start-up, file creation, samples, the end), checks that every
process of the session has ended within ``--deadline`` seconds, and in a third of the trials
also kills the resume at a random moment. Then ``--resume`` runs to the end, and the file is
compared with the uninterrupted run, dataset by dataset, bitwise (timings excepted). The kill
moments come from a seeded generator (``--seed``).

    python scripts/kill_storm.py                  # 20 kills, 2 workers, demo scene at 48^2
    python scripts/kill_storm.py -n 50 --workers 1
    python scripts/kill_storm.py -n 50 --window 0.5 2   # kills 0.5 to 2 s after the start

``--window LO HI`` draws the kill moments from [LO, HI] seconds instead: early kills hit the
workers while they start up. The summary also gives the longest time the processes of a
killed run took to end (the kernel ends workers at once once they are armed; a slow end means
a worker was not armed yet).

Prints one summary line (and one line per failed trial); exits 1 when a trial failed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from roughslip.testing import differences, wait_gone

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SET = ["grid.n=48", "ensemble.samples=8",
               "squeeze.depths={start = 0.3, stop = 1.5, num = 3, spacing = 'log'}"]


def start(args: argparse.Namespace, out: Path, *extra: str) -> subprocess.Popen:
    sets = [x for s in args.set for x in ("--set", s)]
    return subprocess.Popen(
        [sys.executable, "-m", "roughslip", "run", str(args.config), "-o", str(out),
         "--workers", str(args.workers), "--quiet", *sets, *extra],
        start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def kill_at(proc: subprocess.Popen, moment: float, deadline: float
            ) -> tuple[bool, list[int], float]:
    """SIGKILL ``proc`` ``moment`` seconds after it started (if it is still running); return
    whether it was killed, the pids of its session still alive after ``deadline`` and the
    seconds its session took to end."""
    try:
        proc.wait(timeout=moment)
        killed = False
    except subprocess.TimeoutExpired:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        killed = True
    t0 = time.monotonic()
    alive = wait_gone(proc.pid, deadline)
    ended = time.monotonic() - t0
    for pid in alive:  # clean up, counted as orphans
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return killed, alive, ended


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("-n", type=int, default=20, help="number of trials (kills)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--config", type=Path, default=ROOT / "configs" / "demo.toml")
    p.add_argument("--set", action="append", default=None, metavar="KEY=VALUE",
                   help=f"config overrides (default: {' '.join(DEFAULT_SET)})")
    p.add_argument("--seed", type=int, default=0, help="seed of the kill moments")
    p.add_argument("--deadline", type=float, default=5.0,
                   help="seconds the processes of a killed run may take to end")
    p.add_argument("--window", type=float, nargs=2, metavar=("LO", "HI"),
                   help="kill LO to HI seconds after the start (default: over the whole run)")
    p.add_argument("--keep", action="store_true", help="keep the work folder")
    args = p.parse_args()
    if args.set is None:
        args.set = DEFAULT_SET
    rng = np.random.default_rng(args.seed)
    work = Path(tempfile.mkdtemp(prefix="kill_storm_"))
    ref = work / "ref.h5"
    t0 = time.monotonic()
    proc = start(args, ref)
    _, err = proc.communicate()
    wall = time.monotonic() - t0
    if proc.returncode != 0:
        print(f"kill_storm: the reference run failed: {err.decode().strip()}")
        return 1
    lo, hi = args.window or (0.0, wall)
    identical = orphans = killed = second = 0
    slowest = 0.0
    failures = []
    for i in range(args.n):
        out = work / f"t{i:03d}.h5"
        moment = float(rng.uniform(lo, hi))
        k, alive, ended = kill_at(start(args, out), moment, args.deadline)
        killed += k
        orphans += len(alive)
        slowest = max(slowest, ended)
        if rng.uniform() < 1 / 3:  # a second kill, during the resume
            k2, alive2, ended2 = kill_at(start(args, out, "--resume"),
                                         float(rng.uniform(lo, hi)), args.deadline)
            second += k2
            orphans += len(alive2)
            slowest = max(slowest, ended2)
        res = start(args, out, "--resume")
        _, err = res.communicate()
        if res.returncode != 0:
            failures.append(f"trial {i} (kill at {moment:.2f} s): resume exited "
                            f"{res.returncode}: {err.decode().strip()}")
            continue
        diff = differences(ref, out)
        left = [q.name for q in work.iterdir() if q.name.startswith(out.name + ".")]
        if diff or left:
            failures.append(f"trial {i} (kill at {moment:.2f} s): differs in {diff[:5]}, "
                            f"leftovers {left}")
            continue
        identical += 1
        out.unlink()
    for line in failures:
        print("kill_storm:", line)
    when = (f"kills uniform in {lo:g} to {hi:g} s of the {wall:.1f} s run" if args.window
            else f"kills uniform over the {wall:.1f} s run")
    print(f"kill_storm: {identical}/{args.n} resumed identical, {orphans} orphaned processes "
          f"(workers {args.workers}, {killed} killed mid-run, {second} resumes killed too, "
          f"{when}, the slowest killed run's processes ended after {slowest:.2f} s, seed "
          f"{args.seed}, {os.cpu_count()} cores, {time.monotonic() - t0:.0f} s)")
    if not args.keep and not failures:
        shutil.rmtree(work, ignore_errors=True)
    elif failures:
        print(f"kill_storm: files kept in {work}")
    return 0 if identical == args.n and orphans == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
