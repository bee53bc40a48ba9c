"""Samples x depths: the main job, on one process, a process pool or a Dask cluster.

:func:`run` sends the pending samples of a run to an executor: this process, the process pool
(:mod:`roughslip.run.pool`) or a Dask cluster (:mod:`roughslip.run.cluster`), each computing
:func:`~roughslip.run.sample.run_sample`, and writes each finished one through the single writer
of :mod:`roughslip.run.store`.
"""

from __future__ import annotations

import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from roughslip._version import __version__
from roughslip.elastic.fft import library_versions, resolve_backend
from roughslip.errors import InputError, io_failure
from roughslip.linalg import memory
from roughslip.run import partial
from roughslip.run.blas import blas_libraries
from roughslip.run.budget import check_budget, estimate_memory
from roughslip.run.cluster import run_dask
from roughslip.run.config import RunConfig
from roughslip.run.lock import holding
from roughslip.run.pool import run_pool
from roughslip.run.sample import Progress, run_sample
from roughslip.run.scene import Scene
from roughslip.run.store import RunWriter
from roughslip.run.titles import render
from roughslip.run.units import Units

__all__ = ["Progress", "RunSummary", "check_memory", "estimate_memory", "provenance", "run",
           "run_sample"]


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
    """Root attributes describing how a run file was made: the version, the command, the
    libraries and their versions, the BLAS and its kernel (``blas``,
    :func:`~roughslip.run.blas.blas_libraries`), the FFT backend, threads, machine file, seed
    and units.

    Parameters
    ----------
    config : RunConfig
    command_line : str

    Returns
    -------
    dict
        Attribute name to value (dicts and lists are stored as JSON).
    """
    import h5py
    import scipy

    libs = library_versions()
    libs.update({"h5py": h5py.__version__, "scipy": scipy.__version__,
                 "python": sys.version.split()[0]})
    return {
        "version": __version__,
        "command_line": command_line,
        "libraries": libs,
        "blas": blas_libraries(),
        "fft_backend": resolve_backend(config.execution.fft),
        "threads": config.execution.threads,
        "machine_file": config.machine or "",
        "seed": config.ensemble.seed,
        "units": Units(config.length_unit, config.stress_unit).attributes(),
        **({"title": render(config.title, config.to_dict())} if config.title else {}),
    }


def check_memory(scene: Scene, workers: int) -> None:
    """Refuse a run whose estimated peak memory exceeds the budget, in one line that names the
    key that sets the size and a hint that holds
    (:func:`~roughslip.run.budget.check_budget`, with the resolved scene: a grid that a
    topography file sets is checked too)."""
    check_budget(scene.config, workers, scene)


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

    Raises
    ------
    OutputBusyError
        When another run is writing ``out`` (it holds the file's lock,
        :mod:`roughslip.run.lock`); nothing is touched.
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


def _in_process(config: RunConfig, sample: int, writer: RunWriter, emit: Progress) -> None:
    """Compute ``sample`` here, journalling each finished depth (:mod:`roughslip.run.partial`)
    and starting from the depths an interrupted run journalled; write it whole."""
    digest = config.digest()
    done = partial.read_depths(writer.journal, sample, digest)

    def finished(rec: partial.DepthRecord) -> None:
        try:
            partial.write_depth(writer.journal, sample, rec, digest)
        except (OSError, RuntimeError) as exc:  # h5py reports a failed write as either
            raise io_failure(writer.path, f"cannot write sample {sample}", exc,
                             resume=True) from exc

    res = run_sample(config, sample, lambda si, k: emit(
        {"kind": "depth", "sample": si, "depth_index": k}), done=done, finished=finished)
    writer.write_sample(res)
    partial.drop_depths(writer.journal, sample)
    emit({"kind": "sample", "sample": sample})


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
    # one writer per file: the lock comes before anything touches the output (a new file,
    # --overwrite, --resume, the journal) and goes after the last of it, on every way out
    with holding(out) as lock:
        if resume:
            writer = RunWriter.resume(out, layout, indices, nd, attrs)
        else:
            writer = RunWriter.create(out, layout, indices, nd, attrs, overwrite=overwrite)
        notes = [*scene.notes, *(n for n in (lock.note, writer.recovery) if n)]
        done = set(writer.completed())
        pending = [s for s in indices if s not in done]
        emit({"kind": "start", "total": len(pending) * nd, "samples": len(pending),
              "depths": nd, "skipped": len(done), "notes": notes})
        try:
            if scheduler:
                run_dask(config, pending, writer, emit, scheduler)
            elif workers == 1 or len(pending) <= 1:
                for s in pending:
                    _in_process(config, s, writer, emit)
            else:
                run_pool(config, pending, writer, emit, workers)
        except BaseException:
            writer.close()
            raise
        writer.finish()
    emit({"kind": "done"})
    return RunSummary(out, len(indices), len(pending), len(done), time.perf_counter() - t0,
                      notes)
