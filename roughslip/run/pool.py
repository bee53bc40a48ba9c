"""The process pool: samples computed in worker processes that end with the main process.

:func:`run_pool` runs pending samples in spawned worker processes and writes each finished one
as it arrives; :func:`die_with_parent` is how a worker ends with the main process, however
that ends.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing as mp
import os
import queue as queue_mod
import signal
import sys
import time
from collections.abc import Iterator

from roughslip.errors import WorkerError, io_cause
from roughslip.linalg import memory
from roughslip.run.config import RunConfig
from roughslip.run.sample import Progress, run_sample
from roughslip.run.signals import STOP_SIGNALS
from roughslip.run.store import RunWriter, SampleResult

#: What a worker runs first: the pool's initializer is Python's ``exec`` of this text, with the
#: names it uses given as its globals. An initializer of roughslip's own would reach the worker
#: by import, of the whole package (about a second, several on a busy machine), before a line of
#: it could run; a worker whose main process was killed in that time lived on until its import
#: ended. This text uses the standard library only, so the worker is armed about 50 ms after its
#: start: the kernel's parent-death signal (Linux), then the check that the parent is still the
#: one that started it (it may have died between the fork and the arming; the worker then
#: belongs to init or a subreaper), then the stop signals, which the main process blocked for
#: the worker's start, set to be ignored (see run_pool). Only then is roughslip imported.
_BOOT = """
import os, signal, sys
if sys.platform.startswith("linux"):
    import ctypes
    ctypes.CDLL(None).prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
if os.getppid() != parent:
    os._exit(1)
for signum in stop_signals:
    signal.signal(signum, signal.SIG_IGN)
if hasattr(signal, "pthread_sigmask"):
    signal.pthread_sigmask(signal.SIG_UNBLOCK, stop_signals)
from roughslip.run.pool import _worker_init
_worker_init(budget, q, parent)
"""


def _worker_init(budget: int, q, parent: int) -> None:
    """The rest of a worker's set-up, once :data:`_BOOT` has armed it."""
    die_with_parent(parent)  # on Linux armed already; elsewhere, the watching thread
    memory.set_limit(budget / 2**30)
    global _QUEUE
    _QUEUE = q


def die_with_parent(parent: int) -> None:
    """End this process as soon as the process ``parent`` is gone, however it ended.

    On Linux the kernel delivers SIGKILL when the parent exits (``prctl(PR_SET_PDEATHSIG)``;
    the pool's workers are started from the main thread, whose end is the process's end).
    Elsewhere a daemon thread checks the parent every half second. Either way a parent that
    died before this call is caught by comparing ``os.getppid()``. (The pool's workers arm the
    signal earlier, before they import roughslip: :data:`_BOOT`.)

    Parameters
    ----------
    parent : int
        The PID of the process that started this one.
    """
    armed = False
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(1, signal.SIGKILL, 0, 0, 0) == 0  # PR_SET_PDEATHSIG = 1
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent:
        os._exit(1)
    if not armed:
        import threading

        def watch() -> None:
            while os.getppid() == parent:
                time.sleep(0.5)
            os._exit(1)

        threading.Thread(target=watch, name="roughslip-parent-watch", daemon=True).start()


_QUEUE = None


def _pool_task(config: RunConfig, sample: int) -> SampleResult:
    q = _QUEUE

    def report(si: int, k: int) -> None:
        if q is not None:
            q.put((si, k))

    return run_sample(config, sample, report)


def _hold_stop_signals() -> None:
    """Block the stop signals in this thread (they wait until they are unblocked)."""
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)


@contextlib.contextmanager
def _stop_signals_held() -> Iterator[None]:
    """Block the stop signals inside the block; the previous mask after it (where the
    platform has signal masks)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def run_pool(config: RunConfig, pending: list[int], writer: RunWriter, emit: Progress,
             workers: int) -> None:
    """Compute ``pending`` samples in ``workers`` spawned processes; write each as it finishes.

    Parameters
    ----------
    config : RunConfig
    pending : list of int
        The global numbers of the samples to compute.
    writer : RunWriter
        The run file's single writer (in this process).
    emit : callable
        Receives the progress events (:data:`roughslip.run.sample.Progress`).
    workers : int
        Worker processes (at most one per pending sample is started).

    Raises
    ------
    WorkerError
        When a worker process died; the samples completed before are kept.
    """
    ctx = mp.get_context("spawn")  # no fork: OpenBLAS and FFTW threads do not survive it
    budget = memory.available_bytes() // workers
    before = {p.pid for p in mp.active_children()}
    pool: cf.ProcessPoolExecutor | None = None
    futures: dict[cf.Future, int] = {}
    try:
        # The processes started here (multiprocessing's resource tracker, the workers) start
        # with the stop signals blocked, so that a Ctrl-C, SIGTERM or SIGHUP sent to the whole
        # job cannot end one before it ignores them; one sent meanwhile reaches this process
        # when the block ends.
        with _stop_signals_held():
            # progress (sample, depth index) from the workers; a plain queue, no server
            # process that could outlive this one
            try:
                q = ctx.Queue()
            except OSError as exc:  # no semaphores or no resource tracker in this environment
                raise WorkerError(f"cannot start worker processes: {io_cause(exc)} (in "
                                  "multiprocessing's set-up); run with --workers 1 to compute "
                                  "in this process") from exc
            _hold_stop_signals()  # starting the resource tracker unblocked SIGINT and SIGTERM
            boot = {"parent": os.getpid(), "budget": budget, "q": q,
                    "stop_signals": tuple(int(s) for s in STOP_SIGNALS)}
            pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(pending)),
                                          mp_context=ctx, initializer=exec,
                                          initargs=(_BOOT, boot))
            for s in pending:
                futures[pool.submit(_pool_task, config, s)] = s
        while futures:
            finished, _ = cf.wait(futures, timeout=0.25, return_when=cf.FIRST_COMPLETED)
            _drain(q, emit)
            broken = []
            for fut in sorted(finished, key=futures.get):
                s = futures.pop(fut)
                try:
                    res = fut.result()
                except cf.process.BrokenProcessPool:
                    broken.append(s)
                    continue
                writer.write_sample(res)  # keep every sample that did finish
                emit({"kind": "sample", "sample": s})
            if broken:
                raise WorkerError(
                    f"a worker process died (out of memory or killed) while sample(s) "
                    f"{broken} were running; completed samples are kept: run again with "
                    "--resume")
    except BaseException:
        if pool is None:
            raise
        # Stop now: cancel what has not started and end every process this pool started,
        # whether it is computing or still starting up (one left running could wait forever
        # on a queue lock held by a worker that was ended, and this process with it). Their
        # samples are recomputed on --resume.
        procs = [p for p in mp.active_children() if p.pid not in before]
        # shutdown() drops these references
        results = getattr(pool, "_result_queue", None)
        thread = getattr(pool, "_executor_manager_thread", None)
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            proc.kill()  # they ignore SIGTERM
        for proc in procs:
            proc.join(timeout=10)
        # A worker ended while it sent a result leaves half a message in the result pipe, and
        # the executor's thread would wait for the rest forever (and this process with it, at
        # exit). With every worker gone, closing this process's write end turns that wait into
        # an end of file, which the executor handles as a broken pool; its thread then cleans
        # up, which must be over before the interpreter's exit handlers wake it.
        end = getattr(results, "_writer", None)
        if end is not None:
            end.close()
        if thread is not None:
            thread.join(timeout=10)
        raise
    pool.shutdown(wait=True)
    _drain(q, emit)
    q.close()


def _drain(q, emit: Progress) -> None:
    """Forward the workers' progress messages to ``emit``."""
    while True:
        try:
            sample, k = q.get_nowait()
        except (queue_mod.Empty, EOFError, OSError):
            return
        emit({"kind": "depth", "sample": sample, "depth_index": k})
