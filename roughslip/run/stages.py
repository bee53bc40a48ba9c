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
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalResult, NormalSolver
from roughslip.coupling.coupled import COUPLED_TOL, couple
from roughslip.errors import ConvergenceError, NumericalError
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import pull
from roughslip.friction.result import PullResult, PullState
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

    def _ux(self, s: PullResult) -> np.ndarray:
        r""":math:`u_x` at the peak: :math:`G_{xx} f_x`, plus :math:`G_{xy} f_y` when the bonds
        carry the traction vector."""
        if s.peak.fy is None:
            return self.problem.operator("xx").apply("xx", s.peak.fx)
        op = self.problem.operator("xx", "xy")
        return op.apply("xx", s.peak.fx) + op.apply("xy", s.peak.fy)

    def _pull(self, r: NormalResult, rec: Record, where: str) -> None:
        cfg, want = self.stage.config, self.stage.want
        pl = cfg.pull
        try:
            s = pull(r, lam=pl.lam, slip_law=pl.slip_law, method=pl.method, tol=pl.tol,
                     batch_size=pl.batch_size, estimate_error=pl.error_estimate,
                     early_stop=pl.early_stop, lam_dynamic=pl.lam_dynamic,
                     slip_distance=pl.slip_distance, precision=pl.precision,
                     components=pl.components, direction=pl.direction, facets=pl.facets)
        except NumericalError as exc:
            raise NumericalError(f"{where}: pull: {exc}") from None
        if cfg.execution.strict and not s.converged:
            raise ConvergenceError(f"{where}: pull did not converge: {s.message}")
        rec.solvers.update(pull_method=s.method, **({"precision": s.details.precision}
                                                    if s.details.precision else {}))
        add_pull(rec, s, want, lambda: self._ux(s), estimate=pl.error_estimate, what="pull",
                 with_start=False)
        if s.peak.fy is not None:
            fx, fy = s.friction_vector
            rec.scalars.update(friction_force_x=fx, friction_force_y=fy)
            if "fy" in want:
                rec.fields["fy"] = s.peak.fy


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
        pl = cfg.pull
        vector = ({"components": pl.components, "direction": pl.direction,
                   "facets": pl.facets} if pl.components != "x" else {})
        try:
            r = couple(pb, **by, lam=pl.lam, pull_control=cfg.coupling.pull_control,
                       gained=cfg.coupling.gained, history=cfg.coupling.history,
                       slip_law=pl.slip_law, lam_dynamic=pl.lam_dynamic,
                       slip_distance=pl.slip_distance,
                       tol=min(pl.tol, COUPLED_TOL), squeeze_method=cfg.squeeze.method,
                       **vector)
        except NumericalError as exc:
            raise NumericalError(f"{where}: {exc}") from None
        if cfg.execution.strict and not r.converged:
            raise ConvergenceError(f"{where}: coupled model did not converge: {r.message}")
        failed = LAWS.get(r.slip_law).failed
        d = r.details
        # one solve gives squeeze and pull: the squeeze has no iteration count of its own, and
        # its time is the part of the solve before the pull starts
        rec = Record(
            scalars=dict(depth_length=d.depth, normal_force=r.normal_force,
                         contact_area=d.contact_area, residual=r.residual,
                         converged=r.converged, seconds=d.squeeze_seconds,
                         released_bonds=d.released),
            notes=[f"{d.released} bond(s) {failed} at D_x = 0"] + ([d.fallback] if d.fallback
                                                                   else []),
            contact=r.start.contact, solvers={"coupled_solver": r.method},
        )
        f = rec.fields
        if "fz" in want:
            f["fz"] = r.start.fz
        if "contact" in want:
            f["contact"] = r.start.contact
        if "uz" in want or "gap" in want:
            uz = _displacement(pb, "z", r.start)
            if "uz" in want:
                f["uz"] = uz
            if "gap" in want:
                f["gap"] = uz - pb.overlap(d.depth)
        add_pull(rec, r, want, lambda: _displacement(pb, "x", r.peak),
                 estimate=False, what="coupled solve", with_start=True)
        if r.peak.fy is not None:
            fx, fy = r.friction_vector
            rec.scalars.update(friction_force_x=fx, friction_force_y=fy)
            if "fy" in want:
                f["fy"] = r.peak.fy
        return rec


def _displacement(pb: Problem, c: str, state: PullState) -> np.ndarray:
    """The displacement component ``c`` of a coupled state's forces, by FFT: its
    :math:`f_z` and :math:`f_x`, and its :math:`f_y` when it has one."""
    if state.fy is None:
        return pb.operator("zz", "zx", "xx").apply_block(state.fz, state.fx)["zx".index(c)]
    forces = {"z": state.fz, "x": state.fx, "y": state.fy}
    op = pb.operator(*(c + n for n in "zxy"))
    return sum(op.apply(c + n, forces[n]) for n in "zxy")


def add_pull(rec: Record, r: PullResult, want: set[str], ux: Callable[[], np.ndarray], *,
             estimate: bool, what: str, with_start: bool) -> None:
    """Write a pull's columns into ``rec``, the one place for both models: the friction
    force, :math:`F_z` at the peak, the pull's seconds, convergence and events, the error
    estimate (``estimate``, where the result has one), and of the fields asked for
    (``want``) the peak's :math:`f_x`, stick set and :math:`u_x` (``ux``, computed only if
    asked) and the pull curve. ``with_start``: the stored curve and its count of events
    begin with the start at :math:`D_x = 0`, and carry :math:`F_z` and :math:`D_z` (the
    coupled model's columns); otherwise they begin with the first event (the decoupled
    pull, whose :math:`F_z` and :math:`D_z` do not move). ``what`` names the solve in the
    note of a result that did not converge."""
    c = r.curve
    rec.scalars.update(friction_force=r.friction_force,
                       friction_normal_force=r.normal_force_at_peak,
                       pull_seconds=r.pull_seconds,
                       pull_converged=r.converged,
                       pull_steps=c.dx.size if with_start else r.steps)
    if not r.converged:
        rec.notes.append(f"{what} not converged ({r.message}); left out of the means")
    est = getattr(r.details, "error_estimate", math.nan)
    if estimate and math.isfinite(est):  # batch has none: the column is filled with NaN
        rec.scalars["pull_error_estimate"] = est
    f = rec.fields
    if "fx" in want:
        f["fx"] = r.peak.fx
    if "stick" in want:
        f["stick"] = r.peak.stick
    if "ux" in want:
        f["ux"] = ux()
    if "pull_curve" in want:
        k = 0 if with_start else 1
        f.update(dx_lim=c.dx[k:], fx_lim=c.fx[k:], broken_site=c.site[k:])
        if with_start:
            f.update(fz_lim=c.fz, dz_lim=c.dz)


def stage_for(scene: Scene) -> DecoupledStage | CoupledStage:
    """The stage of a scene: coupled when the coupled model runs (:attr:`Scene.coupled`)."""
    return CoupledStage(scene) if scene.coupled else DecoupledStage(scene)
