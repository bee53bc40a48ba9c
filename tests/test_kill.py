"""Runs against kills: every state a SIGKILL can leave resumes to the same numbers, bitwise,
with one and two workers, and no process outlives a killed run; SIGTERM, SIGHUP and SIGINT
stop a run in one line that says how to continue it.

Kills happen at named checkpoints of the writer (:mod:`roughslip.run.checkpoints`, armed by
``tests/inject.py``), so each state is reached at a fixed moment, whatever the machine's
speed.
"""

from __future__ import annotations

import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from roughslip.cli import cli
from roughslip.run import checkpoints
from roughslip.run.checkpoints import CHECKPOINTS
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.executor import run
from roughslip.run.lock import lock_path
from roughslip.run.store import journal_dir, read_run
from roughslip.testing import differences, session_processes, wait_gone, wait_stopped

INJECT = str(Path(__file__).with_name("inject.py"))

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="kills and process sessions are tested on Linux")

CFG = {
    "grid": {"n": 16},
    "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0},
    "squeeze": {"depths": [0.5, 1.5], "depth_unit": "rms"},
    "pull": {"enabled": True, "lam": 0.2},
    "ensemble": {"samples": 4, "seed": 17},
    "output": {"fields": ["contact", "fz", "fx", "pull_curve"]},
}
ORPHAN_DEADLINE = 10.0  # seconds; the kernel ends the workers at once (PR_SET_PDEATHSIG)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    d = tmp_path_factory.mktemp("ref")
    cfg_path = d / "run.toml"
    cfg_path.write_text(dumps_toml(CFG))
    ref = d / "ref.h5"
    run(load_config(cfg_path), ref)
    return cfg_path, ref


def _killed_run(point: str, count: int, cfg_path: Path, out: Path, workers: int,
                *extra: str) -> None:
    """Run the CLI, SIGKILLed at ``point``; check it died there and left no process."""
    log = out.with_name("stderr.txt")  # a file, not a pipe: a survivor could hold a pipe
    with open(log, "wb") as err:
        proc = subprocess.Popen(
            [sys.executable, INJECT, point, str(count), "run",
             str(cfg_path), "-o", str(out), "--workers", str(workers), "--quiet", *extra],
            start_new_session=True, stdout=subprocess.DEVNULL, stderr=err)
        proc.wait(timeout=300)
    assert proc.returncode == -signal.SIGKILL, log.read_text()
    assert wait_gone(proc.pid, ORPHAN_DEADLINE) == []


def _resume(cfg_path: Path, out: Path, workers: int) -> str:
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(out), "--resume",
                                 "--workers", str(workers)])
    assert r.exit_code == 0, r.output
    return r.output


def _assert_finished_like(ref: Path, out: Path) -> None:
    assert differences(ref, out) == []
    assert read_run(out).complete.all()
    leftovers = [p.name for p in out.parent.iterdir() if p.name.startswith(out.name + ".")]
    assert leftovers == []  # no journal, temporary file or retired journal


STATES = [("start", 1), ("creating", 1), ("journal-entry", 2), ("main-write", 2),
          ("sample-done", 2), ("finish", 1)]


def test_every_checkpoint_is_covered():
    # "depth-entry": a one-sample run's finished depths (test_a_kill_keeps_...)
    assert {p for p, _ in STATES} | {"rebuild", "depth-entry"} == set(CHECKPOINTS)


def test_every_checkpoint_is_reached(tmp_path):
    """The writer reaches every checkpoint the kill tests name, in a run and in a resume from
    a journal: a checkpoint renamed, moved out of the writer's path or no longer called fails
    here instead of disarming its kill test."""
    seen: list[str] = []
    stop = {"after": 2}

    def listener(name: str) -> None:
        seen.append(name)
        if name == "sample-done" and seen.count(name) == stop["after"]:
            raise KeyboardInterrupt  # a Ctrl-C: the journal is kept
    previous = checkpoints.listen(listener)
    try:
        cfg = load_config(data=CFG)
        out = tmp_path / "r.h5"
        with pytest.raises(KeyboardInterrupt):
            run(cfg, out)
        stop["after"] = 0
        run(cfg, out, resume=True)
    finally:
        checkpoints.listen(previous)
    assert set(seen) == set(CHECKPOINTS) | {p for p, _ in STATES}
    assert seen.count("rebuild") == 2  # the two journalled samples
    with pytest.raises(KeyError, match="unknown checkpoint"):
        checkpoints.reached("no-such-point")


@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize(("point", "count"), STATES)
def test_resume_after_a_kill_gives_the_same_numbers(reference, tmp_path, point, count,
                                                    workers):
    cfg_path, ref = reference
    out = tmp_path / "killed.h5"
    _killed_run(point, count, cfg_path, out, workers)
    if point == "start":
        assert not out.exists() and not journal_dir(out).exists()
    if point in ("main-write", "sample-done"):
        assert len(list(journal_dir(out).glob("s*.h5"))) == count
    if point == "journal-entry":
        assert len(list(journal_dir(out).glob("s*.tmp"))) == 1
    said = _resume(cfg_path, out, workers)
    if point == "start":
        assert "started a new run" in said
    if point in ("creating", "journal-entry", "main-write", "sample-done"):
        assert "from its journal" in said
    _assert_finished_like(ref, out)


@pytest.mark.parametrize("workers", [1, 2])
def test_kills_during_resumes(reference, tmp_path, workers):
    """A kill during the rebuild of the file, then during the computation of the resumed
    run, then a resume that completes."""
    cfg_path, ref = reference
    out = tmp_path / "twice.h5"
    _killed_run("sample-done", 1, cfg_path, out, workers)
    _killed_run("rebuild", 1, cfg_path, out, workers, "--resume")
    assert out.with_name(out.name + ".rebuilding").exists()
    _killed_run("sample-done", 1, cfg_path, out, workers, "--resume")
    assert len(list(journal_dir(out).glob("s*.h5"))) == 2
    _resume(cfg_path, out, workers)
    _assert_finished_like(ref, out)


def test_file_left_open_by_an_earlier_version_is_started_anew(reference, tmp_path):
    """Files written with HDF5's newest format keep a 'file is open' flag that a kill leaves
    set; without a journal nothing was completed, so the run starts anew."""
    cfg_path, ref = reference
    out = tmp_path / "flagged.h5"
    code = ("import h5py, os, signal, sys\n"
            "f = h5py.File(sys.argv[1], 'w', libver='latest')\n"
            "f.attrs['format'] = 'roughslip-run'\nf.flush()\n"
            "os.kill(os.getpid(), signal.SIGKILL)\n")
    subprocess.run([sys.executable, "-c", code, str(out)], check=False)
    said = _resume(cfg_path, out, 1)
    assert "started it anew" in said
    _assert_finished_like(ref, out)


def test_resume_never_replaces_a_foreign_file(reference, tmp_path):
    cfg_path, _ref = reference
    out = tmp_path / "precious.h5"
    out.write_bytes(b"precious")
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(out), "--resume"])
    assert r.exit_code == 2 and "not a readable HDF5 file" in r.output
    assert out.read_bytes() == b"precious"


def test_workers_die_with_a_killed_manager(tmp_path):
    """SIGKILL to the main process of `run --workers 2` while both workers compute: every
    process of the run (workers, queue feeder, resource tracker) ends within the deadline."""
    data = {**CFG, "grid": {"n": 48}, "ensemble": {"samples": 12, "seed": 3}}
    cfg_path = tmp_path / "long.toml"
    cfg_path.write_text(dumps_toml(data))
    out = tmp_path / "orphans.h5"
    proc = subprocess.Popen(
        [sys.executable, "-m", "roughslip", "run", str(cfg_path), "-o", str(out),
         "--workers", "2", "--quiet"], start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while not list(journal_dir(out).glob("s*.h5")):
        assert proc.poll() is None, proc.stderr.read().decode()
        assert time.monotonic() < deadline, "no sample finished"
        time.sleep(0.02)
    family = session_processes(proc.pid)
    assert len(family) >= 3  # the manager and two workers at least
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    alive = wait_gone(proc.pid, ORPHAN_DEADLINE)
    for pid in alive:  # do not leave them behind on failure
        os.kill(pid, signal.SIGKILL)
    assert alive == []


@pytest.mark.parametrize(("name", "workers", "group"), [
    ("TERM", 1, False), ("TERM", 2, True), ("HUP", 2, True), ("INT", 2, True)])
def test_a_signal_stops_the_run_in_one_line_and_the_resume_gives_the_same_numbers(
        reference, tmp_path, name, workers, group):
    """SIGTERM (a cluster scheduler at the wall time), SIGHUP (a closed terminal) and SIGINT,
    sent to the main process, or to every process of the job as schedulers and terminals do,
    once a sample is journalled: the run exits with 128 + the signal's number and one line
    that gives the command to continue it; no process is left, nor the lock; that command
    completes the run, bitwise like an uninterrupted one.

    The run stops itself (SIGSTOP) after its first sample, the signal is sent while it is
    stopped and reaches it when it continues: it comes mid-run on any machine, and never after
    the run's end."""
    cfg_path, ref = reference
    signum = getattr(signal, "SIG" + name)
    out = tmp_path / "signalled.h5"
    log = tmp_path / "stderr.txt"  # a file, not a pipe: a survivor could hold a pipe
    with open(log, "wb") as err:
        proc = subprocess.Popen(
            [sys.executable, INJECT, "--signal", "STOP", "sample-done", "1", "run",
             str(cfg_path), "-o", str(out), "--workers", str(workers), "--quiet"],
            start_new_session=True, stdout=subprocess.DEVNULL, stderr=err)
        try:
            assert wait_stopped(proc.pid, 120), log.read_text()
            assert len(list(journal_dir(out).glob("s*.h5"))) == 1
            (os.killpg if group else os.kill)(proc.pid, signum)
        finally:
            os.kill(proc.pid, signal.SIGCONT)
        proc.wait(timeout=120)
    said = log.read_text()
    assert proc.returncode == 128 + signum, said
    lines = said.splitlines()
    assert len(lines) == 1, said
    assert lines[0].startswith(f"roughslip: interrupted (SIG{name}); completed samples are "
                               "kept; continue with: roughslip run ")
    assert wait_gone(proc.pid, ORPHAN_DEADLINE) == []
    assert not lock_path(out).exists()
    # the manager stops after its first sample; a second worker may still finish one
    assert 1 <= read_run(out).n_complete <= workers
    command = shlex.split(lines[0].split("continue with: ", 1)[1])
    assert command[:2] == ["roughslip", "run"] and command[-1] == "--resume"
    r = CliRunner().invoke(cli, command[1:])
    assert r.exit_code == 0, r.output
    _assert_finished_like(ref, out)


#: makes the spawned workers (their command line ends in --multiprocessing-fork) slow to import
#: roughslip: at that import each one writes its pid into the folder named by
#: ROUGHSLIP_SLOW_IMPORT, then sleeps
SLOW_IMPORT = """
import os, sys, time
if os.environ.get("ROUGHSLIP_SLOW_IMPORT") and "--multiprocessing-fork" in sys.argv:
    class SlowImport:
        @staticmethod
        def find_spec(name, path=None, target=None):
            if name == "roughslip":
                folder = os.environ["ROUGHSLIP_SLOW_IMPORT"]
                open(os.path.join(folder, str(os.getpid())), "w").close()
                time.sleep(60)
            return None
    sys.meta_path.insert(0, SlowImport)
"""


def test_workers_die_with_a_manager_killed_while_they_start(tmp_path):
    """SIGKILL to the main process while both workers are still importing roughslip (made
    slow here, as on a busy machine): the workers end at once. They are armed (parent-death
    signal, parent check) before that import, with the standard library only."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(SLOW_IMPORT)
    starting = tmp_path / "starting"
    starting.mkdir()
    env = {**os.environ, "ROUGHSLIP_SLOW_IMPORT": str(starting),
           "PYTHONPATH": os.pathsep.join([str(hook), os.environ.get("PYTHONPATH", "")])}
    cfg_path = tmp_path / "run.toml"
    cfg_path.write_text(dumps_toml(CFG))
    proc = subprocess.Popen(
        [sys.executable, "-m", "roughslip", "run", str(cfg_path), "-o", str(tmp_path / "r.h5"),
         "--workers", "2", "--quiet"], start_new_session=True, env=env,
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while len(list(starting.iterdir())) < 2:
        assert proc.poll() is None, proc.stderr.read().decode()
        assert time.monotonic() < deadline, "the workers did not start"
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    alive = wait_gone(proc.pid, ORPHAN_DEADLINE)
    for pid in alive:  # do not leave them behind on failure
        os.kill(pid, signal.SIGKILL)
    assert alive == []


ONE = {**CFG, "squeeze": {"depths": [0.3, 0.6, 1.0, 1.5, 2.2], "depth_unit": "rms"},
       "ensemble": {"samples": 1, "seed": 17}}


@pytest.fixture(scope="module")
def one_sample(tmp_path_factory):
    """A run of one sample at five depths, and its uninterrupted result."""
    d = tmp_path_factory.mktemp("one")
    cfg_path = d / "one.toml"
    cfg_path.write_text(dumps_toml(ONE))
    ref = d / "ref.h5"
    run(load_config(cfg_path), ref)
    return cfg_path, ref


def test_a_kill_keeps_the_finished_depths_of_a_sample_in_progress(one_sample, tmp_path):
    """A run of one large sample journals each finished depth: killed while it journals the
    third, it keeps the first two, --resume computes only the rest (it says so by what it
    writes), and the sample is bitwise that of an uninterrupted run; the depth entries go
    once the sample is written whole."""
    cfg_path, ref = one_sample
    out = tmp_path / "one.h5"
    _killed_run("depth-entry", 3, cfg_path, out, 1)
    depths = journal_dir(out) / "depths"
    assert sorted(p.name for p in depths.glob("*.h5")) == ["s000000.d000.h5",
                                                           "s000000.d001.h5"]
    assert len(list(depths.glob("*.tmp"))) == 1
    seen: list[str] = []
    previous = checkpoints.listen(seen.append)
    try:
        run(load_config(cfg_path), out, resume=True)
    finally:
        checkpoints.listen(previous)
    assert seen.count("depth-entry") == 2  # depths 2 and 3 journalled, 4 is the last
    _assert_finished_like(ref, out)
    assert not journal_dir(out).exists()


def test_ctrl_c_says_which_finished_depths_it_keeps(one_sample, tmp_path):
    cfg_path, ref = one_sample
    out = tmp_path / "one.h5"
    r = subprocess.run([sys.executable, INJECT, "--signal", "INT", "depth-entry", "3", "run",
                        str(cfg_path), "-o", str(out), "--quiet"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 130, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "completed samples and 2 finished depth(s) of sample 0 are " \
        "kept; continue with:" in lines[0], r.stderr
    _resume(cfg_path, out, 1)
    _assert_finished_like(ref, out)
