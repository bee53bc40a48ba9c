"""Runs beside other runs: two configurations on one Dask scheduler keep their own samples,
the writer refuses a sample of another configuration, and a second run on a file that a run
is writing is refused at once."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from roughslip.cli import cli
from roughslip.errors import OutputBusyError, OutputError
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.executor import run
from roughslip.run.lock import RunLock, holding, lock_path
from roughslip.run.sample import run_sample
from roughslip.run.store import journal_dir, read_run
from roughslip.testing import differences, wait_stopped

INJECT = str(Path(__file__).with_name("inject.py"))

BASE = {
    "grid": {"n": 16},
    "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0},
    "squeeze": {"depths": [0.5, 1.5], "depth_unit": "rms"},
    "pull": {"enabled": True, "lam": 0.2},
    "ensemble": {"samples": 6, "seed": 17},
    "output": {"fields": ["contact", "fz", "pull_curve"]},
}
#: another configuration of the same shape: same sample numbers, other numbers in them
OTHER = {**BASE, "surface": {**BASE["surface"], "hurst": 0.6}, "ensemble": {"samples": 6,
                                                                            "seed": 18}}


@pytest.fixture(scope="module")
def references(tmp_path_factory):
    """Each configuration run in this process, alone."""
    d = tmp_path_factory.mktemp("alone")
    out = []
    for name, data in (("a", BASE), ("b", OTHER)):
        cfg = load_config(data=data)
        ref = d / f"{name}.h5"
        run(cfg, ref, workers=1)
        out.append((cfg, ref))
    return out


def run_side_by_side(jobs: list[tuple], address: str) -> list[BaseException]:
    """``run(cfg, out, scheduler=address)`` for each ``(cfg, out)`` in its own thread; the
    runs submit their samples together (a barrier at their start events). Returns the errors
    raised."""
    barrier = threading.Barrier(len(jobs), timeout=60)
    errors: list[BaseException] = []

    def progress(event: dict) -> None:
        if event["kind"] == "start":
            barrier.wait()

    def one(cfg, out) -> None:
        try:
            run(cfg, out, scheduler=address, progress=progress)
        except BaseException as exc:  # reported by the test
            errors.append(exc)
            barrier.abort()

    threads = [threading.Thread(target=one, args=job) for job in jobs]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    return errors


def test_two_configurations_on_one_scheduler_keep_their_own_samples(references, tmp_path,
                                                                    blas_restored):
    """Two runs of different configurations with the same sample numbers, submitted together
    to one scheduler whose two workers share this process: each file holds its own
    configuration's samples, bitwise those of the run alone; the process's Dask settings are
    as they were (two overlapping clients would otherwise restore them out of order)."""
    distributed = pytest.importorskip("distributed", reason="the dask extra is not installed")
    import dask

    scheduler_before = dask.config.get("scheduler", None)
    (cfg_a, ref_a), (cfg_b, ref_b) = references
    out_a, out_b = tmp_path / "a.h5", tmp_path / "b.h5"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        errors = run_side_by_side([(cfg_a, out_a), (cfg_b, out_b)], cluster.scheduler_address)
    assert errors == []
    assert differences(ref_a, out_a) == []
    assert differences(ref_b, out_b) == []
    assert read_run(out_a).complete.all() and read_run(out_b).complete.all()
    assert dask.config.get("scheduler", None) == scheduler_before


def test_the_writer_refuses_a_sample_of_another_configuration(references, tmp_path,
                                                               monkeypatch):
    """A sample computed for another configuration reaches the writer: the run stops with an
    error naming the sample and both digests, and nothing of that sample is written."""
    import roughslip.run.executor as executor

    (cfg_a, _), (cfg_b, _) = references
    monkeypatch.setattr(executor, "run_sample",
                        lambda config, sample, progress=None, **kw: run_sample(cfg_b, sample))
    out = tmp_path / "mixed.h5"
    with pytest.raises(OutputError) as info:
        run(cfg_a, out, workers=1)
    message = str(info.value)
    assert "\n" not in message
    assert f"{out}: sample 0 " in message
    assert cfg_a.digest()[:12] in message and cfg_b.digest()[:12] in message
    assert not list(journal_dir(out).glob("s*"))
    assert read_run(out).n_complete == 0


def test_task_keys_name_the_configuration_and_the_output(references, tmp_path):
    from roughslip.run.cluster import output_identity, task_prefix

    (cfg_a, _), (cfg_b, _) = references
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    assert cfg_a.digest()[:16] in task_prefix(cfg_a, a)
    assert output_identity(a) in task_prefix(cfg_a, a)
    assert output_identity(a) != output_identity(b)
    assert output_identity(a) == output_identity(Path(tmp_path / "." / "a.h5"))
    assert task_prefix(cfg_a, a) != task_prefix(cfg_b, a)
    assert task_prefix(cfg_a, a) != task_prefix(cfg_a, a)  # each run its own tasks


# -- one writer per file ---------------------------------------------------------------------


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_second_run_on_a_file_being_written_is_refused_in_one_line(references, tmp_path):
    """A run holds its output's lock from start to end. Stopped (SIGSTOP) after its first
    sample, it still holds it: a second run on the same file, plain, with --overwrite or with
    --resume, is refused at once with one line naming the file and the holder, exit code 2,
    and touches nothing. Continued, the first run completes every sample, bitwise those of an
    undisturbed run, and removes its lock file."""
    (_, ref), _ = references
    cfg_path = tmp_path / "run.toml"
    cfg_path.write_text(dumps_toml(BASE))
    out = tmp_path / "shared.h5"
    first = subprocess.Popen(
        [sys.executable, INJECT, "--signal", "STOP", "sample-done", "1", "run", str(cfg_path),
         "-o", str(out), "--workers", "1", "--quiet"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        assert wait_stopped(first.pid, 120), first.communicate()[1].decode()
        assert lock_path(out).exists()
        journal = sorted(p.name for p in journal_dir(out).iterdir())
        for extra in ([], ["--overwrite"], ["--resume"]):
            r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(out), "--workers", "1",
                                         *extra])
            assert r.exit_code == 2, r.output
            assert r.output.count("\n") == 1, r.output
            assert r.output.startswith(f"roughslip: error: {out}: another run is writing this "
                                       f"file (PID {first.pid} on {socket.gethostname()}, ")
            assert sorted(p.name for p in journal_dir(out).iterdir()) == journal
    finally:
        os.kill(first.pid, signal.SIGCONT)
        _, err = first.communicate(timeout=300)
    assert first.returncode == 0, err.decode()
    assert differences(ref, out) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.toml", "shared.h5"]


def test_the_lock_is_exclusive_released_and_not_blocked_by_a_stale_file(references,
                                                                          tmp_path):
    """In one process too, a second lock on a file is refused and names this process; after
    the release the file can be locked again and the lock file is gone. A lock file that a
    killed run left (naming a process that has ended) blocks nothing."""
    out = tmp_path / "x.h5"
    with holding(out) as lock:
        assert lock.note == "" and lock_path(out).exists()
        with pytest.raises(OutputBusyError, match=rf"PID {os.getpid()} on "):
            RunLock.acquire(out)
    assert not lock_path(out).exists()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    lock_path(out).write_text(f'{{"pid": {dead}, "host": "{socket.gethostname()}", '
                              '"since": "2000-01-01 00:00:00"}\n')
    (cfg, ref), _ = references
    run(cfg, out, workers=1)
    assert differences(ref, out) == [] and not lock_path(out).exists()


def test_a_file_system_without_locks_runs_on_with_a_note(references, tmp_path, monkeypatch):
    """Where flock is refused (ENOLCK: NFS without its lock manager), the run goes on and its
    notes say that a second run would not be refused."""
    import errno

    import roughslip.run.lock as lock

    class NoLocks:
        LOCK_EX, LOCK_NB = 2, 4

        @staticmethod
        def flock(fd: int, operation: int) -> None:
            raise OSError(errno.ENOLCK, os.strerror(errno.ENOLCK))

    monkeypatch.setattr(lock, "fcntl", NoLocks)
    (cfg, ref), _ = references
    out = tmp_path / "unlocked.h5"
    events: list[dict] = []
    run(cfg, out, workers=1, progress=events.append)
    notes = events[0]["notes"]
    assert [n for n in notes if "lock" in n] == [
        f"{lock_path(out)}: the file system does not lock files ({os.strerror(errno.ENOLCK)}); "
        "a second run on unlocked.h5 would not be refused"]
    assert differences(ref, out) == [] and not lock_path(out).exists()
