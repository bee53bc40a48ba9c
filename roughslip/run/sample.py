"""One sample at every target: the pure function that every executor runs.

:func:`run_sample` is a pure function of ``(config, sample)``: its numbers do not depend on
where or alongside what it runs (FFT and BLAS use ``execution.threads`` threads; all randomness
comes from the sample's seed). The executors (:mod:`roughslip.run.executor`, with
:mod:`roughslip.run.pool` and :mod:`roughslip.run.cluster`) send it to where it runs and give
its result to the single writer of :mod:`roughslip.run.store`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from roughslip.contact.problem import Problem
from roughslip.errors import NumericalError
from roughslip.run import schema
from roughslip.run.config import RunConfig
from roughslip.run.partial import DepthRecord
from roughslip.run.scene import Scene
from roughslip.run.stages import stage_for
from roughslip.run.store import SampleResult

#: receives the events of a run: ``{"kind": "start"|"depth"|"sample"|"done", ...}``
Progress = Callable[[dict[str, Any]], None]


class _Context(threading.local):
    """What a thread keeps between the samples of one configuration: the scene, the problem
    whose operator (and kernels) every sample shares, and the stage. One configuration at a
    time: another one replaces it, so nothing has to be reset by hand.

    One per thread: a Dask worker runs tasks in several threads at once, of one run or of
    several runs that share the scheduler, and a task must neither see another
    configuration's scene nor share the FFT plans of a problem another thread is solving."""

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


def run_sample(config: RunConfig, sample: int, progress: Callable[[int, int], None] | None = None,
               *, done: Sequence[DepthRecord] = (),
               finished: Callable[[DepthRecord], None] | None = None) -> SampleResult:
    """Compute one sample at every target (depth or load) of the configuration, in order.

    Parameters
    ----------
    config : RunConfig
    sample : int
        Global sample number (its surfaces come from ``SeedSequence(seed, spawn_key=(sample,))``).
    progress : callable ``(sample, depth_index)``, optional
        Called after each target.
    done : sequence of DepthRecord
        The first targets, already finished (journalled by an interrupted run,
        :mod:`roughslip.run.partial`): taken as they are, and the next target starts from
        what the last of them carries, so the rest is bitwise what it would have been.
    finished : callable ``(DepthRecord)``, optional
        Called with each target finished here but the last (to journal it).

    Returns
    -------
    SampleResult
        With the digest of ``config``, which the writer checks against its own run's.

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
    for old in done:  # finished by an earlier, interrupted run
        k = old.index
        schema.put(rows, k, old.scalars)
        notes.extend(f"depth index {k}: {n}" for n in old.notes)
        fields.append(old.fields)
        solvers.append(old.solvers)
        if progress is not None:
            progress(sample, k)
    if done:
        runner.restore(done[-1].carry)
    for k, t in enumerate(targets):
        if k < len(done):
            continue
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
        if finished is not None and k + 1 < len(targets):
            finished(DepthRecord(k, dict(rec.scalars), dict(rec.fields), list(rec.notes),
                                 dict(rec.solvers), runner.carry()))
        if progress is not None:
            progress(sample, k)
    surfaces = {"rigid_surface": surf.rigid}
    if surf.elastic is not None:
        surfaces["elastic_surface"] = surf.elastic
    return SampleResult(sample, rows, fields, surfaces, notes, solvers,
                        digest=config.digest())


def _check_voids(contact: np.ndarray | None, valid: np.ndarray | None, where: str) -> None:
    """A void (missing point) never carries force; one in contact means the run is wrong."""
    if contact is not None and valid is not None and np.any(contact & ~valid):
        raise NumericalError(f"{where}: {int(np.sum(contact & ~valid))} void point(s) came "
                             "into contact; the depth reaches below the voids' stand-in "
                             "height (use surface.missing = 'interpolate')")

