"""The stages that compute one sample of a run, target by target.

A stage knows its solvers; the run loop (:func:`roughslip.run.sample.run_sample`) knows only
stages and the output schema (:mod:`roughslip.run.schema`). Two stages exist:

* :class:`DecoupledStage`: the squeeze at each depth or load, then (with ``pull.enabled``) the
  decoupled pull of the squeezed contact;
* :class:`CoupledStage`: the coupled normal-tangential model (``coupling.enabled`` and
  :math:`\\nu < 1/2`), squeeze and pull in one solve per depth.

Each step returns a :class:`Record` of scalars named by the schema and of the fields the
configuration asks for (``output.fields``), computed only when asked for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalResult, NormalSolver
from roughslip.coupling.coupled import COUPLED_TOL, couple
from roughslip.errors import ConvergenceError, NumericalError
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import SlipResult, pull
from roughslip.run.scene import Scene


@dataclass
class Record:
    """What one stage step produces at one target."""

    scalars: dict[str, float]
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    contact: np.ndarray | None = None  # the contact set, for the void check
    #: the methods that solved this target, by role (``pull_method``, ``precision``, ...)
    solvers: dict[str, str] = field(default_factory=dict)


class DecoupledStage:
    """Squeeze, then the decoupled pull (the report's model)."""

    name = "decoupled"

    def __init__(self, scene: Scene) -> None:
        self.config = scene.config
        self.want = set(scene.config.output.fields)
        # the coupled model was asked for at nu = 1/2, where it is this one
        self.coupled_column = "coupled" in scene.stages

    def start(self, problem: Problem) -> _DecoupledSample:
        """The stage's state for one sample (warm starts run from depth to depth)."""
        return _DecoupledSample(self, problem)


class _DecoupledSample:
    def __init__(self, stage: DecoupledStage, problem: Problem) -> None:
        sq = stage.config.squeeze
        self.stage = stage
        self.problem = problem
        self.solver = NormalSolver(problem, method=sq.method, tol=sq.tol, max_iter=sq.max_iter)
        self.x0: np.ndarray | None = None

    def carry(self) -> dict[str, np.ndarray]:
        """What the next target starts from: the squeeze's warm start."""
        return {} if self.x0 is None else {"x0": self.x0}

    def restore(self, carry: dict[str, np.ndarray]) -> None:
        """Start the next target from ``carry`` (:meth:`carry` of a journalled target)."""
        self.x0 = carry.get("x0")

    def step(self, target: float, where: str) -> Record:
        cfg, want = self.stage.config, self.stage.want
        try:
            r = (self.solver.solve(force=target, x0=self.x0) if cfg.control == "force"
                 else self.solver.solve(depth=target, x0=self.x0))
        except NumericalError as exc:
            raise NumericalError(f"{where}: {exc}") from None
        if cfg.execution.strict and not r.converged:
            raise ConvergenceError(f"{where}: squeeze did not converge: {r.message}")
        if cfg.squeeze.warm_start:
            self.x0 = r.fz
        rec = Record(
            scalars=dict(depth_length=r.depth, normal_force=r.normal_force,
                         contact_area=r.contact_area, iterations=r.iterations,
                         residual=r.residual, converged=r.converged, seconds=r.seconds),
            fields={n: getattr(r, n) for n in ("fz", "uz", "gap", "contact") if n in want},
            contact=r.contact,
        )
        if not r.converged:
            rec.notes.append(f"squeeze not converged ({r.message})")
        if self.stage.coupled_column:  # no bond is released before the pull
            rec.scalars["released_bonds"] = 0
        if cfg.pull.enabled:
            self._pull(r, rec, where)
        return rec

    def _pull(self, r: NormalResult, rec: Record, where: str) -> None:
        cfg, want = self.stage.config, self.stage.want
        pl = cfg.pull
        try:
            s: SlipResult = pull(r, lam=pl.lam, slip_law=pl.slip_law, method=pl.method,
                                 tol=pl.tol, batch_size=pl.batch_size,
                                 estimate_error=pl.error_estimate, early_stop=pl.early_stop,
                                 lam_dynamic=pl.lam_dynamic, slip_distance=pl.slip_distance,
                                 precision=pl.precision)
        except NumericalError as exc:
            raise NumericalError(f"{where}: pull: {exc}") from None
        if cfg.execution.strict and not s.converged:
            raise ConvergenceError(f"{where}: pull did not converge: {s.message}")
        rec.solvers.update(pull_method=s.method, **({"precision": s.precision}
                                                    if s.precision else {}))
        rec.scalars.update(friction_force=s.friction_force,
                           friction_normal_force=s.normal_force, pull_seconds=s.seconds,
                           pull_converged=s.converged, pull_steps=s.steps)
        if not s.converged:
            rec.notes.append(f"pull not converged ({s.message}); left out of the means")
        if pl.error_estimate and math.isfinite(s.error_estimate):  # batch has none: fill NaN
            rec.scalars["pull_error_estimate"] = s.error_estimate
        if "fx" in want:
            rec.fields["fx"] = s.fx_at_peak
        if "stick" in want:
            rec.fields["stick"] = s.stick_at_peak
        if "ux" in want:
            rec.fields["ux"] = self.problem.operator("xx").apply("xx", s.fx_at_peak)
        if "pull_curve" in want:
            rec.fields.update(dx_lim=s.dx_lim, fx_lim=s.fx_lim, broken_site=s.broken_site)


class CoupledStage:
    """The coupled normal-tangential model: one event-driven solve per depth."""

    name = "coupled"

    def __init__(self, scene: Scene) -> None:
        self.config = scene.config
        self.want = set(scene.config.output.fields)

    def start(self, problem: Problem) -> _CoupledSample:
        return _CoupledSample(self, problem)


class _CoupledSample:
    def __init__(self, stage: CoupledStage, problem: Problem) -> None:
        self.stage = stage
        self.problem = problem

    def carry(self) -> dict[str, np.ndarray]:
        """Nothing: each target is solved from its own start."""
        return {}

    def restore(self, carry: dict[str, np.ndarray]) -> None:
        """Nothing to restore (:meth:`carry`)."""

    def step(self, target: float, where: str) -> Record:
        cfg, want = self.stage.config, self.stage.want
        pb = self.problem
        by = {"force": target} if cfg.control == "force" else {"depth": target}
        try:
            r = couple(pb, **by, lam=cfg.pull.lam, pull_control=cfg.coupling.pull_control,
                       gained=cfg.coupling.gained, history=cfg.coupling.history,
                       slip_law=cfg.pull.slip_law,
                       tol=min(cfg.pull.tol, COUPLED_TOL), squeeze_method=cfg.squeeze.method)
        except NumericalError as exc:
            raise NumericalError(f"{where}: {exc}") from None
        if cfg.execution.strict and not r.converged:
            raise ConvergenceError(f"{where}: coupled model did not converge: {r.message}")
        failed = LAWS.get(r.slip_law).failed
        # one solve gives squeeze and pull: the squeeze has no iteration count of its own, and
        # its time is the part of the solve before the pull starts
        rec = Record(
            scalars=dict(depth_length=r.depth, normal_force=r.normal_force,
                         contact_area=r.contact_area, residual=r.residual,
                         converged=r.converged, seconds=r.squeeze_seconds,
                         friction_force=r.friction_force,
                         friction_normal_force=r.normal_force_at_peak,
                         pull_seconds=r.seconds - r.squeeze_seconds, pull_converged=r.converged,
                         pull_steps=len(r.events), released_bonds=r.released),
            notes=[f"{r.released} bond(s) {failed} at D_x = 0"] + ([r.fallback] if r.fallback
                                                                   else []),
            contact=r.contact0, solvers={"coupled_solver": r.method},
        )
        if not r.converged:
            rec.notes.append(f"coupled solve not converged ({r.message}); left out of the "
                             "means")
        f = rec.fields
        if "fz" in want:
            f["fz"] = r.fz0
        if "contact" in want:
            f["contact"] = r.contact0
        op = pb.operator("zz", "zx", "xx")
        if "uz" in want or "gap" in want:
            uz = op.apply_block(r.fz0, r.fx0)[0]
            if "uz" in want:
                f["uz"] = uz
            if "gap" in want:
                f["gap"] = uz - pb.overlap(r.depth)
        if "fx" in want:
            f["fx"] = r.fx_peak
        if "stick" in want:
            f["stick"] = r.stick_peak
        if "ux" in want:
            f["ux"] = op.apply_block(r.fz_peak, r.fx_peak)[1]
        if "pull_curve" in want:
            f.update(dx_lim=r.dx, fx_lim=r.fx, fz_lim=r.fz, dz_lim=r.dz,
                     broken_site=np.array([e.site for e in r.events], dtype=np.int64))
        return rec


def stage_for(scene: Scene) -> DecoupledStage | CoupledStage:
    """The stage of a scene: coupled when the coupled model runs (:attr:`Scene.coupled`)."""
    return CoupledStage(scene) if scene.coupled else DecoupledStage(scene)
