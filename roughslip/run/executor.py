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
from roughslip.contact.coupled import squeeze_pull_coupled
from roughslip.contact.pull import SlipResult, pull
from roughslip.contact.squeeze import NormalResult, NormalSolver
from roughslip.elastic.fft import library_versions, resolve_backend
from roughslip.elastic.operators import ElasticOperator
from roughslip.errors import (
    ConvergenceError,
    InputError,
    MemoryLimitError,
    NumericalError,
    WorkerError,
)
from roughslip.linalg import memory
from roughslip.run.config import RunConfig
from roughslip.run.scene import Scene
from roughslip.run.store import RunWriter, SampleResult, scalar_specs

Progress = Callable[[dict[str, Any]], None]

_SCENES: dict[str, Scene] = {}
_OPERATORS: dict[tuple, ElasticOperator] = {}


def _scene(config: RunConfig) -> Scene:
    key = config.digest() + config.source
    sc = _SCENES.get(key)
    if sc is None:
        _SCENES.clear()
        _OPERATORS.clear()
        sc = _SCENES[key] = Scene.from_config(config)
    return sc


def _operator(scene: Scene, components: tuple[str, ...]) -> ElasticOperator:
    ex = scene.config.execution
    key = (id(scene), components, ex.fft, ex.threads)
    op = _OPERATORS.get(key)
    if op is None:
        op = _OPERATORS[key] = scene.grid.operator(scene.material, components, fft=ex.fft,
                                                   threads=ex.threads)
    return op


def run_sample(config: RunConfig, sample: int, progress: Callable[[int, int], None] | None = None
               ) -> SampleResult:
    """Squeeze (and pull) one sample at every depth of the configuration, in increasing order.

    Parameters
    ----------
    config : RunConfig
    sample : int
        Global sample number (its surfaces come from ``SeedSequence(seed, spawn_key=(sample,))``).
    progress : callable ``(sample, depth_index)``, optional
        Called after each depth.

    Raises
    ------
    ConvergenceError
        In strict mode, when a solve misses its tolerance.
    NumericalError
        When a non-finite value appears (naming the sample and depth).
    """
    scene = _scene(config)
    cfg = config
    surf = scene.surfaces(sample)
    targets = scene.targets(surf.composite, surf.valid)
    sq, _pl = cfg.squeeze, cfg.pull
    strict = cfg.execution.strict
    solver = NormalSolver(surf.composite, scene.grid, scene.material, method=sq.method,
                          tol=sq.tol, max_iter=sq.max_iter, threads=cfg.execution.threads,
                          operator=_operator(scene, ("zz",)))
    pull_op = _operator(scene, ("xx",)) if scene.pull else None
    nd = len(targets)
    sc = {name: np.zeros(nd, dtype) for name, (dtype, _) in scalar_specs(cfg).items()}
    fields: list[dict[str, np.ndarray]] = []
    notes = list(scene.notes)
    x0 = None
    want = set(cfg.output.fields)
    if scene.coupled:
        return _coupled_sample(cfg, scene, sample, surf, targets, sc, progress)
    for k, t in enumerate(targets):
        where = f"sample {sample}, depth index {k}"
        try:
            r = (solver.solve(force=float(t), x0=x0) if cfg.control == "force"
                 else solver.solve(depth=float(t), x0=x0))
        except NumericalError as exc:
            raise NumericalError(f"{where}: {exc}") from None
        if strict and not r.converged:
            raise ConvergenceError(f"{where}: squeeze did not converge: {r.message}")
        _check_voids(r.contact, surf.valid, where)
        if not r.converged:
            notes.append(f"depth index {k}: squeeze not converged ({r.message})")
        if sq.warm_start:
            x0 = r.fz
        _put(sc, k, depth_length=r.depth, normal_force=r.normal_force,
             contact_area=r.contact_area, iterations=r.iterations, residual=r.residual,
             converged=r.converged, seconds=r.seconds)
        out: dict[str, np.ndarray] = {}
        for name in ("fz", "uz", "gap", "contact"):
            if name in want:
                out[name] = getattr(r, name)
        if scene.pull:
            s = _pull(cfg, r, pull_op, where)
            if strict and not s.converged:
                raise ConvergenceError(f"{where}: pull did not converge: {s.message}")
            _put(sc, k, friction_force=s.friction_force, friction_normal_force=s.normal_force,
                 pull_seconds=s.seconds, pull_converged=s.converged, pull_steps=s.steps,
                 pull_error_estimate=s.error_estimate)
            if "fx" in want:
                out["fx"] = s.fx_at_peak
            if "stick" in want:
                out["stick"] = s.stick_at_peak
            if "ux" in want:
                out["ux"] = pull_op.apply("xx", s.fx_at_peak)
            if "pull_curve" in want:
                out.update(dx_lim=s.dx_lim, fx_lim=s.fx_lim, broken_site=s.broken_site)
        for name, a in out.items():
            if np.issubdtype(np.asarray(a).dtype, np.floating) and not np.all(np.isfinite(a)):
                raise NumericalError(f"{where}: non-finite values in field {name!r}")
        fields.append(out)
        if progress is not None:
            progress(sample, k)
    for name, a in sc.items():
        if np.issubdtype(a.dtype, np.floating) and not np.all(np.isfinite(a)):
            raise NumericalError(f"sample {sample}: non-finite {name}")
    surfaces = {"rigid_surface": surf.rigid}
    if surf.elastic is not None:
        surfaces["elastic_surface"] = surf.elastic
    return SampleResult(sample, sc, fields, surfaces, notes)


def _check_voids(contact: np.ndarray, valid: np.ndarray | None, where: str) -> None:
    """A void (missing point) never carries force; one in contact means the run is wrong."""
    if valid is not None and np.any(contact & ~valid):
        raise NumericalError(f"{where}: {int(np.sum(contact & ~valid))} void point(s) came "
                             "into contact; the depth reaches below the voids' stand-in "
                             "height (use surface.missing = 'interpolate')")


def _put(sc: dict[str, np.ndarray], k: int, **values: float) -> None:
    """Store scalar results of depth ``k``."""
    for name, v in values.items():
        sc[name][k] = v


def _coupled_sample(cfg: RunConfig, scene: Scene, sample: int, surf, targets, sc, progress
                    ) -> SampleResult:
    """A sample of the coupled model: squeeze with bonded contacts, then the exact event pull."""
    op = _operator(scene, ("zz", "zx", "xx"))
    g = scene.grid
    want = set(cfg.output.fields)
    fields, notes = [], list(scene.notes)
    for k, t in enumerate(targets):
        where = f"sample {sample}, depth index {k}"
        try:
            r = squeeze_pull_coupled(
                surf.composite, depth=float(t), lam=cfg.pull.lam, a=g.a, E=scene.material.E,
                nu=scene.material.nu, boundary=g.boundary, periodic_kernel=g.periodic_kernel,
                tol=min(cfg.pull.tol, 1e-10), fft=cfg.execution.fft,
                threads=cfg.execution.threads, operator=op)
        except NumericalError as exc:
            raise NumericalError(f"{where}: {exc}") from None
        if cfg.execution.strict and not r.converged:
            raise ConvergenceError(f"{where}: coupled model did not converge: {r.message}")
        _check_voids(r.contact0, surf.valid, where)
        _put(sc, k, depth_length=float(t), normal_force=r.normal_force,
             contact_area=r.contact_area, iterations=r.solves, residual=0.0,
             converged=r.converged, seconds=r.seconds, friction_force=r.friction_force,
             friction_normal_force=r.normal_force_at_peak, pull_seconds=r.seconds,
             pull_converged=r.converged, pull_steps=len(r.events), pull_error_estimate=0.0,
             released_bonds=r.released)
        notes.append(f"depth index {k}: {r.released} bond(s) released at D_x = 0")
        out: dict[str, np.ndarray] = {}
        if "fz" in want:
            out["fz"] = r.fz0
        if "contact" in want:
            out["contact"] = r.contact0
        if "uz" in want or "gap" in want:
            uz = op.apply_block(r.fz0, r.fx0)[0]
            if "uz" in want:
                out["uz"] = uz
            if "gap" in want:
                out["gap"] = uz - (float(t) - (surf.composite.max() - surf.composite))
        if "fx" in want:
            out["fx"] = r.fx_peak
        if "stick" in want:
            out["stick"] = r.stick_peak
        if "ux" in want:
            out["ux"] = op.apply_block(r.fz_peak, r.fx_peak)[1]
        if "pull_curve" in want:
            out.update(dx_lim=r.dx, fx_lim=r.fx, fz_lim=r.fz,
                       broken_site=np.array([e.site for e in r.events], dtype=np.int64))
        fields.append(out)
        if progress is not None:
            progress(sample, k)
    surfaces = {"rigid_surface": surf.rigid}
    if surf.elastic is not None:
        surfaces["elastic_surface"] = surf.elastic
    return SampleResult(sample, sc, fields, surfaces, notes)


def _pull(cfg: RunConfig, r: NormalResult, op: ElasticOperator, where: str) -> SlipResult:
    pl = cfg.pull
    try:
        return pull(r, lam=pl.lam, slip_law=pl.slip_law, method=pl.method, tol=pl.tol,
                    batch_size=pl.batch_size, fft=cfg.execution.fft,
                    threads=cfg.execution.threads, operator=op, estimate_error=pl.error_estimate,
                    early_stop=pl.early_stop)
    except NumericalError as exc:
        raise NumericalError(f"{where}: pull: {exc}") from None


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
        "seed": config.ensemble.seed,
        "units": {
            "length": config.length_unit or "the unit of grid.pixel_size (heights, depths, "
                                             "displacements)",
            "stress": "the unit of material.E",
            "force": "stress x length^2 (pixel forces, total forces)",
            "contact_area": "fraction of the nominal area",
        },
    }


def estimate_memory(scene: Scene) -> int:
    """Bytes one worker needs for operators, solver work arrays and one sample's fields.

    The pull's own memory is checked when it starts (it depends on the bond count); each
    worker gets ``budget / workers`` so parallel pulls cannot overcommit together.
    """
    ny, nx = scene.grid.shape
    n = ny * nx
    if scene.grid.boundary == "open":
        m = (2 * ny) * (2 * nx)
    else:
        m = n
    per_op = 8 * m * 2 + 16 * (m // 2 + 1) * 3 + 8 * 4 * n  # buffers, spectra, direct-sum table
    ops = per_op * len(scene.components) + 16 * (m // 2 + 1) * len(scene.components)
    work = 8 * n * 16
    nfields = max(1, len(scene.config.output.fields))
    stored = 8 * n * nfields * len(scene.config.targets) + 8 * n * 3
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
    nd = len(config.targets)
    if resume:
        writer = RunWriter.resume(out, config, indices, nd, attrs)
    else:
        writer = RunWriter.create(out, config, indices, nd, attrs, overwrite=overwrite)
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
    q = ctx.Queue()
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

