"""Samples x depths: the main job, on one process, a process pool or a Dask cluster.

:func:`run_sample` is a pure function of ``(config, sample)``: its numbers do not depend on
where or alongside what it runs (FFT and BLAS use ``execution.threads`` threads; all randomness
comes from the sample's seed). :func:`run` sends pending samples to an executor and writes each
finished one through the single writer of :mod:`roughslip.run.store`.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
import queue as queue_mod
import shlex
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from roughslip._version import __version__
from roughslip.contact.problem import Problem
from roughslip.elastic.fft import library_versions, resolve_backend
from roughslip.elastic.operators import ElasticOperator
from roughslip.errors import (
    InputError,
    MemoryLimitError,
    NumericalError,
    WorkerError,
    io_cause,
)
from roughslip.linalg import memory
from roughslip.run import schema
from roughslip.run.config import RunConfig
from roughslip.run.scene import Scene
from roughslip.run.stages import stage_for
from roughslip.run.store import RunWriter, SampleResult
from roughslip.run.titles import render
from roughslip.run.units import Units

Progress = Callable[[dict[str, Any]], None]


class _Context:
    """What a process keeps between the samples of one configuration: the scene, the problem
    whose operator (and kernels) every sample shares, and the stage. One configuration at a
    time: another one replaces it, so nothing has to be reset by hand."""

    def __init__(self) -> None:
        self.key: str | None = None

    def get(self, config: RunConfig) -> _Context:
        key = config.digest() + config.source + repr(config.execution)
        if key != self.key:
            scene = Scene.from_config(config)
            ex = config.execution
            self.scene = scene
            self.problem = Problem(np.zeros(scene.grid.shape), scene.grid, scene.material,
                                   fft=ex.fft, threads=ex.threads)
            self.stage = stage_for(scene)
            self.key = key
        return self


_CONTEXT = _Context()


def run_sample(config: RunConfig, sample: int, progress: Callable[[int, int], None] | None = None
               ) -> SampleResult:
    """Compute one sample at every target (depth or load) of the configuration, in order.

    Parameters
    ----------
    config : RunConfig
    sample : int
        Global sample number (its surfaces come from ``SeedSequence(seed, spawn_key=(sample,))``).
    progress : callable ``(sample, depth_index)``, optional
        Called after each target.

    Raises
    ------
    ConvergenceError
        In strict mode, when a solve misses its tolerance.
    NumericalError
        When a non-finite value appears (naming the sample and depth).
    """
    ctx = _CONTEXT.get(config)
    scene = ctx.scene
    surf = scene.surfaces(sample)
    targets = scene.targets(surf.composite, surf.valid)
    runner = ctx.stage.start(ctx.problem.with_heights(surf.composite))
    rows = schema.empty(scene.columns, len(targets))
    fields: list[dict[str, np.ndarray]] = []
    solvers: list[dict[str, str]] = []
    notes = list(scene.notes)
    for k, t in enumerate(targets):
        where = f"sample {sample}, depth index {k}"
        rec = runner.step(float(t), where)
        bad = [n for n, v in rec.scalars.items() if not np.isfinite(float(v))]
        if bad:  # a stage gives only what it computed: NaN there is a failure, not a gap
            raise NumericalError(f"{where}: non-finite {', '.join(bad)}")
        _check_voids(rec.contact, surf.valid, where)
        schema.put(rows, k, rec.scalars)
        notes.extend(f"depth index {k}: {n}" for n in rec.notes)
        for name, a in rec.fields.items():
            if np.issubdtype(np.asarray(a).dtype, np.floating) and not np.all(np.isfinite(a)):
                raise NumericalError(f"{where}: non-finite values in field {name!r}")
        fields.append(rec.fields)
        solvers.append(rec.solvers)
        if progress is not None:
            progress(sample, k)
    surfaces = {"rigid_surface": surf.rigid}
    if surf.elastic is not None:
        surfaces["elastic_surface"] = surf.elastic
    return SampleResult(sample, rows, fields, surfaces, notes, solvers)


def _check_voids(contact: np.ndarray | None, valid: np.ndarray | None, where: str) -> None:
    """A void (missing point) never carries force; one in contact means the run is wrong."""
    if contact is not None and valid is not None and np.any(contact & ~valid):
        raise NumericalError(f"{where}: {int(np.sum(contact & ~valid))} void point(s) came "
                             "into contact; the depth reaches below the voids' stand-in "
                             "height (use surface.missing = 'interpolate')")


# ------------------------------------------------------------------------------------------------
# The run
# ------------------------------------------------------------------------------------------------


@dataclass
class RunSummary:
    """What :func:`run` did."""

    path: Path
    samples: int
    computed: int
    skipped: int
    seconds: float
    notes: list[str] = field(default_factory=list)


def provenance(config: RunConfig, command_line: str) -> dict[str, Any]:
    """Root attributes describing how a run file was made."""
    import h5py
    import scipy

    libs = library_versions()
    libs.update({"h5py": h5py.__version__, "scipy": scipy.__version__,
                 "python": sys.version.split()[0]})
    return {
        "version": __version__,
        "command_line": command_line,
        "libraries": libs,
        "fft_backend": resolve_backend(config.execution.fft),
        "threads": config.execution.threads,
        "machine_file": config.machine or "",
        "seed": config.ensemble.seed,
        "units": Units(config.length_unit, config.stress_unit).attributes(),
        **({"title": render(config.title, config.to_dict())} if config.title else {}),
    }


def estimate_memory(scene: Scene) -> int:
    """Bytes one worker needs: its operator (:meth:`ElasticOperator.footprint`), the solver's
    work arrays and one sample's fields.

    The pull's own memory is checked when it starts (it depends on the bond count); each
    worker gets ``budget / workers`` so parallel pulls cannot overcommit together.
    """
    ny, nx = scene.grid.shape
    n = ny * nx
    ops = ElasticOperator.footprint(scene.grid.shape, scene.grid.boundary, scene.components)
    work = 8 * n * 16
    nfields = max(1, len(scene.config.output.fields))
    stored = 8 * n * nfields * scene.n_targets + 8 * n * 3
    return int(ops + work + stored)


def check_memory(scene: Scene, workers: int) -> None:
    """Refuse a run whose estimated peak memory exceeds the budget."""
    per = estimate_memory(scene)
    need = per * workers
    have = memory.available_bytes()
    if need > have:
        fewer = max(1, have // max(per, 1))
        hint = (f"use --workers {fewer}" if fewer < workers
                else "use a smaller grid or an output.fields list with fewer fields")
        raise MemoryLimitError(
            f"the run needs ~{need / 2**30:.2f} GiB ({workers} worker(s) x "
            f"{per / 2**30:.2f} GiB) but {have / 2**30:.2f} GiB are available; {hint}")


def run(
    config: RunConfig,
    out: str | Path,
    *,
    workers: int | None = None,
    resume: bool = False,
    overwrite: bool = False,
    scheduler: str | None = None,
    progress: Progress | None = None,
    command_line: str | None = None,
) -> RunSummary:
    """Run every pending sample of a configuration and write ``out``.

    Parameters
    ----------
    config : RunConfig
    out : path
        The HDF5 run file (see :mod:`roughslip.run.store`).
    workers : int, optional
        Worker processes (default ``execution.workers``); 1 runs in this process.
    resume : bool
        Continue an existing file made with the same configuration.
    overwrite : bool
        Replace an existing file (otherwise it is an error).
    scheduler : str, optional
        Address of a Dask scheduler (default ``execution.scheduler``).
    progress : callable, optional
        Receives events ``{"kind": "start"|"depth"|"sample"|"done", ...}``.
    command_line : str, optional
        Stored in the file's provenance; default: this process's ``sys.argv``.
    """
    t0 = time.perf_counter()
    scene = Scene.from_config(config)  # validates files before any output is touched
    workers = int(workers or config.execution.workers)
    if workers < 1:
        raise InputError(f"--workers {workers}: must be >= 1")
    if resume and overwrite:
        raise InputError("--resume and --overwrite exclude each other")
    with memory.limited(config.execution.memory_limit_gb):
        return _run(config, scene, Path(out), workers, resume, overwrite,
                    scheduler or config.execution.scheduler, progress or (lambda e: None),
                    command_line, t0)


def _run(config: RunConfig, scene: Scene, out: Path, workers: int, resume: bool,
         overwrite: bool, scheduler: str | None, emit: Progress, command_line: str | None,
         t0: float) -> RunSummary:
    if not scheduler:
        check_memory(scene, workers)
    indices = scene.sample_indices
    if command_line is None:
        command_line = shlex.join(sys.argv)
    attrs = provenance(config, command_line)
    attrs["notes"] = list(scene.notes)
    attrs["pixel_size"] = scene.grid.a
    if scene.topography:
        attrs["topography"] = scene.topography
    nd = scene.n_targets
    layout = scene.layout()
    if resume:
        writer = RunWriter.resume(out, layout, indices, nd, attrs)
    else:
        writer = RunWriter.create(out, layout, indices, nd, attrs, overwrite=overwrite)
    notes = list(scene.notes) + ([writer.recovery] if writer.recovery else [])
    done = set(writer.completed())
    pending = [s for s in indices if s not in done]
    emit({"kind": "start", "total": len(pending) * nd, "samples": len(pending),
          "depths": nd, "skipped": len(done), "notes": notes})
    try:
        if scheduler:
            _run_dask(config, pending, writer, emit, scheduler)
        elif workers == 1 or len(pending) <= 1:
            for s in pending:
                res = run_sample(config, s, lambda si, k: emit(
                    {"kind": "depth", "sample": si, "depth_index": k}))
                writer.write_sample(res)
                emit({"kind": "sample", "sample": s})
        else:
            _run_pool(config, pending, writer, emit, workers)
    except BaseException:
        writer.close()
        raise
    writer.finish()
    emit({"kind": "done"})
    return RunSummary(out, len(indices), len(pending), len(done), time.perf_counter() - t0,
                      notes)


def _worker_init(budget: int, q, parent: int) -> None:
    # Ctrl-C reaches the whole process group: only the main process handles it (it stops the
    # pool and keeps what is done)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent)
    memory.set_limit(budget / 2**30)
    global _QUEUE
    _QUEUE = q


def die_with_parent(parent: int) -> None:
    """End this process as soon as the process ``parent`` is gone, however it ended.

    On Linux the kernel delivers SIGKILL when the parent exits (``prctl(PR_SET_PDEATHSIG)``;
    the pool's workers are started from the main thread, whose end is the process's end).
    Elsewhere a daemon thread checks the parent every half second. Either way a parent that
    died before this call is caught by comparing ``os.getppid()``.
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


def _run_pool(config: RunConfig, pending: list[int], writer: RunWriter, emit: Progress,
              workers: int) -> None:
    ctx = mp.get_context("spawn")  # no fork: OpenBLAS and FFTW threads do not survive it
    budget = memory.available_bytes() // workers
    # progress (sample, depth index) from the workers; a plain queue, no server process that
    # could outlive this one
    try:
        q = ctx.Queue()
    except OSError as exc:  # no semaphores or no resource tracker in this environment
        raise WorkerError(f"cannot start worker processes: {io_cause(exc)} (in "
                          "multiprocessing's set-up); run with --workers 1 to compute in "
                          "this process") from exc
    before = {p.pid for p in mp.active_children()}
    pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(pending)), mp_context=ctx,
                                  initializer=_worker_init,
                                  initargs=(budget, q, os.getpid()))
    futures: dict[cf.Future, int] = {}
    try:
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
            proc.terminate()
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


def _run_dask(config: RunConfig, pending: list[int], writer: RunWriter, emit: Progress,
              address: str) -> None:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError("--scheduler needs the dask extra: pip install 'roughslip[dask]'"
                         ) from None
    try:
        client = Client(address, timeout="20s")
    except OSError as exc:
        raise InputError(f"--scheduler {address}: cannot connect ({exc})") from None
    with client:
        futures = [client.submit(run_sample, config, s, pure=False, key=f"roughslip-{s}")
                   for s in pending]
        nd = len(config.targets)
        try:
            for fut in as_completed(futures):
                res = fut.result()
                writer.write_sample(res)
                for k in range(nd):
                    emit({"kind": "depth", "sample": res.sample, "depth_index": k})
                emit({"kind": "sample", "sample": res.sample})
        except BaseException:
            client.cancel(futures)
            raise

