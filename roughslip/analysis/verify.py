r"""Exact solutions, work-precision diagrams, and every error estimate checked against the truth
(``roughslip verify``; docs/methods.rst#error-vs-time).

Each scene is solved in two series, each a line per method:

``resolution``
    At a tight tolerance (1e-10) and a growing resolution: the discretisation error against
    the closed form (docs/methods.rst#exact-solutions). For the rough pull, which has none, the
    method's error against the exact pull of the same grid.
``tolerance``
    At one resolution and a tolerance from 1e-2 to 1e-10: the solver's error against a solve of
    the same discrete problem at tolerance 1e-13 (the *tight reference*).

The scenes:

``hertz``
    Rigid sphere, apex on a pixel corner: total force :math:`F = \tfrac43 E^*R^{1/2}d^{3/2}`
    (second order in h) and contact radius :math:`\sqrt{Rd}` from the pixel count (first order).
``punch``
    Flat circular punch: :math:`F = 2aE^*d` with :math:`a` from the pixel count (first order).
``wavy``
    Periodic 1-D wavy surface (Westergaard), load control, both periodic kernels: crest
    pressure :math:`2\bar p/\sin(\pi a/\lambda)`.
``cattaneo``
    Cattaneo–Mindlin: Coulomb tangential force at :math:`\delta = \delta_s/2`.
``pull``
    A rough contact (H = 0.8): each pull method against the exact pull (``inverse`` at tol
    1e-13), by grid size and by tolerance.
``coupled``
    The coupled model on the Hertz contact: at :math:`\nu = 1/2` against the decoupled pull,
    which it equals exactly; at :math:`\nu = 0.3` against its dense solve at tol 1e-13.

Timings are medians over repeats after one warm-up run: at least three, and as many as it
takes for their sum to reach ``budget`` seconds (at most 50), so that millisecond solves rise
above the timer's noise. The problem (grid, material, kernel spectra) is built once per scene,
as a run builds it once per process: the times are those of the solves.

Every estimate the product reports is compared with the true error of the same solve
(:class:`Check`): the squeeze's ``residual`` and
:func:`~roughslip.contact.estimates.squeeze_correction`, the pull's ``error_estimate`` (on
squeezes of several tolerances), its part ``solve_error_estimate`` and ``error_bound``, the
absence of an estimate for the ``batch`` pull, and the coupled model's ``residual``. Relative
errors below :data:`FLOOR` are at the level of rounding and of the tight reference: they are
drawn at the floor and compared as equal.

The depth of the Hertz scene is the true approach of the apex: with the apex on a pixel corner
the highest pixel sits :math:`h^2/4R` below it (``depth = d + max(heights)``).
"""

from __future__ import annotations

import json
import math
import re
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from roughslip.contact import analytic
from roughslip.contact.estimates import squeeze_correction
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalResult, squeeze
from roughslip.coupling.coupled import couple
from roughslip.errors import VerificationError
from roughslip.friction.pull import (
    METHODS,
    bond_spectrum,
    coulomb_force_at,
    pull,
    refinement_estimate,
)
from roughslip.friction.result import PullResult
from roughslip.surfaces.synthetic import punch as punch_shape
from roughslip.surfaces.synthetic import sample_rng, self_affine, sinusoid, sphere

#: relative errors below this are rounding (and the tight reference's own error)
FLOOR = 1e-14
#: tolerance of the resolution series, and of the tight references
RES_TOL, REF_TOL = 1e-10, 1e-13
#: the tolerance series
TOLS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)
#: the quantity each scene's diagram shows
PRIMARY = {"hertz": "normal force", "punch": "normal force", "wavy": "crest pressure",
           "cattaneo": "tangential force", "pull": "friction force",
           "coupled": "friction force"}
SERIES = ("resolution", "tolerance")
#: what each kind of estimate claims, and so the relation :meth:`Check.holds` tests
KINDS = {
    "estimate": "within a factor 10 of the true error (both below the floor counts as equal)",
    "bound": "at least the true error",
    "indicator": "a measure of convergence, not of the error: no relation is claimed",
    "none": "the method reports no estimate",
}


@dataclass(frozen=True)
class Point:
    """One solve of a work-precision diagram.

    ``error`` is the signed relative error of ``quantity`` against ``truth`` (the closed form,
    or the tight reference of the same discrete problem); ``seconds`` the median of
    ``repeats`` timed runs.
    """

    scene: str
    quantity: str
    method: str
    series: str
    resolution: str
    size: float
    tol: float
    error: float
    truth: str
    seconds: float
    repeats: int
    converged: bool
    residual: float = math.nan
    iterations: int = -1
    #: what the error comes from, where it is not the solver's tolerance: ``RELEASED`` for a
    #: coupled pull whose squeeze released another set of bonds than the reference's
    note: str = ""

    @property
    def at_floor(self) -> bool:
        """The error is below :data:`FLOOR`: exact to rounding."""
        return abs(self.error) < FLOOR

    def as_dict(self) -> dict:
        return {**asdict(self), "at_floor": self.at_floor}


@dataclass(frozen=True)
class Check:
    """An error estimate the product reports, against the true error of the same solve.

    ``kind`` is a key of :data:`KINDS`; ``error`` the true relative error (absolute value) of
    ``quantity``.
    """

    scene: str
    method: str
    series: str
    resolution: str
    tol: float
    name: str
    kind: str
    quantity: str
    estimate: float
    error: float

    @property
    def ratio(self) -> float:
        """Estimate over true error, both raised to :data:`FLOOR`; NaN without an estimate."""
        if not math.isfinite(self.estimate):
            return math.nan
        return max(self.estimate, FLOOR) / max(self.error, FLOOR)

    @property
    def holds(self) -> bool | None:
        """The relation its kind claims (:data:`KINDS`); None for an indicator."""
        if self.kind == "indicator":
            return None
        if self.kind == "none":
            return math.isnan(self.estimate)
        if self.kind == "bound":
            return self.ratio >= 1.0
        return 0.1 <= self.ratio <= 10.0

    def as_dict(self) -> dict:
        return {**asdict(self), "ratio": self.ratio, "holds": self.holds}


@dataclass
class Study:
    """The points of the diagrams and the checks of the estimates."""

    points: list[Point] = field(default_factory=list)
    checks: list[Check] = field(default_factory=list)

    def __iadd__(self, other: Study) -> Study:
        self.points += other.points
        self.checks += other.checks
        return self

    def scenes(self) -> list[str]:
        return list(dict.fromkeys(p.scene for p in self.points))

    def line(self, scene: str, series: str, method: str,
             quantity: str | None = None) -> list[Point]:
        """The points of one line of a diagram, in their order: growing resolution, or
        tightening tolerance."""
        quantity = quantity or PRIMARY[scene]
        pts = [p for p in self.points if (p.scene, p.series, p.method, p.quantity)
               == (scene, series, method, quantity)]
        if series == "resolution":
            return sorted(pts, key=lambda p: p.size)
        return sorted(pts, key=lambda p: -p.tol)

    def methods(self, scene: str, series: str) -> list[str]:
        return list(dict.fromkeys(p.method for p in self.points
                                  if (p.scene, p.series) == (scene, series)))

    def as_dict(self) -> dict:
        return {"floor": FLOOR, "primary": PRIMARY, "kinds": KINDS,
                "points": [p.as_dict() for p in self.points],
                "checks": [c.as_dict() for c in self.checks]}


# ------------------------------------------------------------------------------ timing


def timed(fn: Callable[[], object], budget: float) -> tuple[object, float, int]:
    """``(result, median seconds, repeats)`` of ``fn`` after one untimed warm-up run.

    At least three timed runs, and more until their sum reaches ``budget`` (at most 50).
    """
    fn()
    times: list[float] = []
    out = None
    while len(times) < 3 or (sum(times) < budget and len(times) < 50):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times), len(times)


def _rel(got: float, want: float) -> float:
    return (got - want) / want


# ------------------------------------------------------------------------------ squeeze scenes


def hertz_scene(a_over_h: int, R: float = 1.0, d: float = 1 / 16
                ) -> tuple[np.ndarray, float, float, float]:
    r"""A sphere of radius ``R`` on a grid ``2.4 a_c`` wide with ``a_c / h = a_over_h``.

    Returns ``(heights, h, depth, a_c)``: the depth from first touch that gives the Hertz
    approach ``d`` of the apex (the apex sits on a pixel corner, ``-max(heights)`` above the
    highest pixel centre, so the depth is ``d + max(heights)``; docs/methods.rst#hertz), and the
    Hertz contact radius :math:`a_c = \sqrt{R d}`.
    """
    ac = math.sqrt(R * d)
    h = ac / a_over_h
    n = math.ceil(2.4 * ac / h)
    n += n % 2
    heights = sphere((n, n), radius=R, a=h)
    return heights, h, d + float(heights.max()), ac


@dataclass(frozen=True)
class _SqueezeScene:
    """A squeeze scene at one resolution: ``solve(method, tol)`` and its exact values."""

    name: str
    label: str
    size: float
    solve: Callable[[str, float], NormalResult]
    exact: Callable[[NormalResult], dict[str, float]]  # quantity -> exact value
    measure: Callable[[NormalResult], dict[str, float]]  # quantity -> computed value
    shared_reference: bool = True  # all methods solve the same discrete problem


def _hertz(ah: int) -> _SqueezeScene:
    R, d = 1.0, 1 / 16
    heights, h, depth, ac = hertz_scene(ah, R, d)
    F = analytic.hertz(R, d, 1.0, 0.0).force
    pb = Problem.from_arrays(heights, a=h, E=1.0, nu=0.0)
    return _SqueezeScene(
        "hertz", f"a/h={ah}", ah,
        lambda m, tol: squeeze(pb, depth=depth, method=m, tol=tol),
        lambda r: {"normal force": F, "contact radius": ac},
        lambda r: {"normal force": r.normal_force,
                   "contact radius": math.sqrt(r.n_contact * h * h / math.pi)})


def _punch(ah: int) -> _SqueezeScene:
    radius, d = 1.0, 1e-3
    h = radius / ah
    n = 2 * ah + 2
    pb = Problem.from_arrays(punch_shape((n, n), radius=radius, a=h), a=h, E=1.0, nu=0.0)
    return _SqueezeScene(
        "punch", f"a/h={ah}", ah,
        lambda m, tol: squeeze(pb, depth=d, method=m, tol=tol),
        lambda r: {"normal force": analytic.flat_punch_force(
            math.sqrt(r.n_contact * h * h / math.pi), d, E=1.0, nu=0.0)},
        lambda r: {"normal force": r.normal_force})


def _wavy(n: int) -> _SqueezeScene:
    amp, lam, ratio = 0.01, 1.0, 0.6
    a = lam / n
    heights = sinusoid((4, n), amplitude=amp, wavelength=lam, a=a)
    pbar = ratio * analytic.westergaard(0.0, amp, lam, E=1.0, nu=0.0).p_star
    exact = analytic.westergaard(pbar, amp, lam, E=1.0, nu=0.0)

    problems = {kind: Problem.from_arrays(heights, a=a, E=1.0, nu=0.0, boundary="periodic",
                                          periodic_kernel=kind)
                for kind in ("pixel", "continuous")}

    def solve(method: str, tol: float) -> NormalResult:
        return squeeze(problems[method.split("/")[1]], force=pbar * 4 * n * a * a, tol=tol)

    return _SqueezeScene(
        "wavy", f"lambda/h={n}", n, solve,
        lambda r: {"crest pressure": exact.crest_pressure,
                   "contact fraction": exact.contact_fraction},
        lambda r: {"crest pressure": float(r.fz[:, 0].mean()) / a**2,
                   "contact fraction": r.contact_area},
        shared_reference=False)


def _reference(solve: Callable[[], NormalResult | PullResult], what: str):
    r = solve()
    if not r.converged:
        raise VerificationError(f"verify: the tight reference of {what} did not converge "
                                f"(tol {REF_TOL:g})")
    return r


def _squeeze_series(make: Callable[[int], _SqueezeScene], methods: Sequence[str],
                    sizes: Sequence[int], tol_size: int, budget: float) -> Study:
    out = Study()
    for size in sizes:
        sc = make(size)
        for m in methods:
            r, sec, rep = timed(lambda sc=sc, m=m: sc.solve(m, RES_TOL), budget)
            got, exact = sc.measure(r), sc.exact(r)
            for q, want in exact.items():
                out.points.append(Point(sc.name, q, m, "resolution", sc.label, size, RES_TOL,
                                        _rel(got[q], want), "exact solution", sec, rep,
                                        r.converged, r.residual, r.iterations))
    sc = make(tol_size)
    q = PRIMARY[sc.name]
    ref = None
    for m in methods:
        if ref is None or not sc.shared_reference:
            ref_method = "pk" if sc.shared_reference else m
            ref = _reference(lambda rm=ref_method: sc.solve(rm, REF_TOL),
                             f"{sc.name} {sc.label}")
            want = sc.measure(ref)[q]
        for tol in TOLS:
            r, sec, rep = timed(lambda m=m, tol=tol: sc.solve(m, tol), budget)
            err = _rel(sc.measure(r)[q], want)
            out.points.append(Point(sc.name, q, m, "tolerance", sc.label, tol_size, tol, err,
                                    "tight reference", sec, rep, r.converged, r.residual,
                                    r.iterations))
            out.checks.append(Check(sc.name, m, "tolerance", sc.label, tol,
                                    "squeeze residual", "indicator", q, r.residual, abs(err)))
            delta = squeeze_correction(r)
            refined = replace(r, fz=r.fz + delta, normal_force=float((r.fz + delta).sum()))
            got, better = sc.measure(r)[q], sc.measure(refined)[q]
            out.checks.append(Check(sc.name, m, "tolerance", sc.label, tol,
                                    "squeeze_correction", "estimate", q,
                                    abs(got - better) / abs(better), abs(err)))
    return out


# ------------------------------------------------------------------------------ pull scenes


def _cattaneo_state(ah: int):
    nu, lam, R, d = 0.3, 0.3, 1.0, 1 / 16
    heights, h, depth, ac = hertz_scene(ah, R, d)
    normal = squeeze(heights, depth=depth, a=h, nu=nu, tol=1e-12)
    P = normal.normal_force
    return normal, lam, analytic.cattaneo_mindlin(P, ac, lam, nu=nu)


def _cattaneo(sizes: Sequence[int], tol_size: int, budget: float) -> Study:
    """The Coulomb pull of a Hertz contact at :math:`\\delta_s/2` (the squeeze, at tol 1e-12,
    is not timed)."""
    out, method, q = Study(), "coulomb/inverse", "tangential force"

    def solve(normal, lam, tol):
        return pull(normal, lam=lam, slip_law="coulomb", tol=tol)

    def force(res, lam, cm):
        return float(coulomb_force_at(res, 0.5 * cm.delta_s))

    for ah in sizes:
        normal, lam, cm = _cattaneo_state(ah)
        res, sec, rep = timed(lambda n=normal, lam=lam: solve(n, lam, RES_TOL), budget)
        err = (force(res, lam, cm) - cm.force(0.5 * cm.delta_s)) / (lam * normal.normal_force)
        out.points.append(Point("cattaneo", q, method, "resolution", f"a/h={ah}", ah, RES_TOL,
                                err, "exact solution", sec, rep, res.converged, res.residual))
    normal, lam, cm = _cattaneo_state(tol_size)
    ref = _reference(lambda: solve(normal, lam, REF_TOL), "cattaneo")
    for tol in TOLS:
        res, sec, rep = timed(lambda tol=tol: solve(normal, lam, tol), budget)
        err = (force(res, lam, cm) - force(ref, lam, cm)) / (lam * normal.normal_force)
        label = f"a/h={tol_size}"
        out.points.append(Point("cattaneo", q, method, "tolerance", label, tol_size, tol, err,
                                "tight reference", sec, rep, res.converged, res.residual))
        est = pull(normal, lam=lam, slip_law="coulomb", tol=tol, estimate_error=True)
        f_err = abs(_rel(est.friction_force, ref.friction_force))
        out.checks.append(Check("cattaneo", method, "tolerance", label, tol,
                                "pull solve_error_estimate", "estimate", "friction force",
                                est.details.solve_error_estimate, f_err))
    return out


PULL_METHODS = ("literal", "cg", "inverse", "batch")


def rough_contact(n: int, tol: float = 1e-12) -> NormalResult:
    """The rough contact of the ``pull`` scene: H = 0.8, rms 1, depth 1.5, squeezed to
    ``tol``."""
    h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(7, 0), oversample=2)
    return squeeze(h, depth=1.5, tol=tol)


#: squeeze tolerances of the checks of the whole estimate (squeeze and pull)
SQUEEZE_TOLS = (1e-4, 1e-6, 1e-8, 1e-10)


#: the pulls whose whole error estimate is checked on loose squeezes: per law, the (method,
#: tolerance, label) of each
ESTIMATED_PULLS = {"break": (("inverse", 1e-10, "inverse"), ("cg", 1e-6, "cg")),
                   "coulomb": (("inverse", 1e-10, "inverse/coulomb"),)}


def _pull_on_loose_squeezes(n: int) -> Study:
    """Checks of the whole ``error_estimate`` (the squeeze's part and the pull's): pulls on
    squeezes at tolerances 1e-4 to 1e-10 against the pull at 1e-13 on the squeeze at 1e-13."""
    out = Study()
    tight = rough_contact(n, REF_TOL)
    for law, pulls in ESTIMATED_PULLS.items():
        ref = _reference(lambda law=law: pull(tight, method="inverse", tol=REF_TOL,
                                              slip_law=law), f"the {law} pull at N={n}")
        for stol in SQUEEZE_TOLS:
            loose = rough_contact(n, stol)
            for method, tol, name in pulls:
                r = pull(loose, method=method, tol=tol, slip_law=law, estimate_error=True)
                out.checks.append(Check("pull", name, "squeeze tolerance", f"N={n}", stol,
                                        "pull error_estimate", "estimate", "friction force",
                                        r.details.error_estimate,
                                        abs(_rel(r.friction_force, ref.friction_force))))
    return out


def _pull_point(normal: NormalResult, ref: PullResult, kappa: float, method: str,
                series: str, n: int, tol: float, budget: float) -> Study:
    """One timed pull and the checks of its estimates. The reference shares the squeeze, so
    the pull's own part of the estimate is compared; it and the bound are computed as
    ``pull(..., estimate_error=True)`` computes them, from the timed result and the condition
    estimate ``kappa`` of the bonds (one Lanczos run per squeeze, not per pull)."""
    out = Study()
    res, sec, rep = timed(lambda: pull(normal, method=method, tol=tol, batch_size=8), budget)
    err = _rel(res.friction_force, ref.friction_force)
    label = f"N={n}"
    out.points.append(Point("pull", "friction force", method, series, label, n, tol, err,
                            "exact pull", sec, rep, res.converged, res.residual, res.solves))
    if not METHODS.get(method).exact:
        out.checks.append(Check("pull", method, series, label, tol, "pull error_estimate",
                                "none", "friction force", res.details.error_estimate, abs(err)))
        return out
    for name, kind, value in (("pull solve_error_estimate", "estimate",
                               refinement_estimate(normal, res)),
                              ("pull error_bound", "bound", kappa * res.residual)):
        out.checks.append(Check("pull", method, series, label, tol, name, kind,
                                "friction force", value, abs(err)))
    return out


def _kappa(normal: NormalResult) -> float:
    lo, hi = bond_spectrum(normal)
    return hi / lo


def _pull(sizes: Sequence[int], tol_size: int, budget: float) -> Study:
    out = Study()
    for n in sizes:
        normal = rough_contact(n)
        ref = _reference(lambda normal=normal: pull(normal, method="inverse", tol=REF_TOL),
                         f"the pull at N={n}")
        kappa = _kappa(normal)
        for m in PULL_METHODS:
            out += _pull_point(normal, ref, kappa, m, "resolution", n, RES_TOL, budget)
    normal = rough_contact(tol_size)
    ref = _reference(lambda: pull(normal, method="inverse", tol=REF_TOL),
                     f"the pull at N={tol_size}")
    kappa = _kappa(normal)
    for m in PULL_METHODS:
        for tol in TOLS:
            out += _pull_point(normal, ref, kappa, m, "tolerance", tol_size, tol, budget)
    out += _pull_on_loose_squeezes(tol_size)
    return out


#: :attr:`Point.note` of a coupled pull that starts from another released set than its
#: reference: equally overloaded bonds (a symmetric contact) ordered by the solver's error
RELEASED = "another released set"


def _coupled(sizes: Sequence[int], tol_size: int, budget: float) -> Study:
    r"""The coupled model on the Hertz contact (lambda = 0.3).

    By resolution at :math:`\nu = 1/2`, where :math:`G_{zx} = 0` and the coupled pull is the
    decoupled one exactly: against the ``inverse`` pull at tol 1e-13 of the same grid. By
    tolerance at :math:`\nu = 0.3` (break and Coulomb laws): against the dense solver at tol
    1e-13. The coupled solve is timed whole (bonded squeeze, releases and pull). A pull that
    starts from another set of released bonds than its reference is noted (:data:`RELEASED`):
    on this symmetric contact bonds are overloaded in groups of equal size, and a solver whose
    error exceeds the rounding orders each group by that error, not by site index."""
    out, lam, q = Study(), 0.3, "friction force"
    methods = (("dense", "break"), ("cg", "break"), ("dense", "coulomb"))

    def name(method: str, law: str) -> str:
        return f"{method}/{law}"

    for ah in sizes:
        heights, h, depth, _ = hertz_scene(ah)
        pb = Problem.from_arrays(heights, a=h, E=1.0, nu=0.5)
        normal = squeeze(pb, depth=depth, tol=1e-13)
        ref = _reference(lambda n=normal: pull(n, lam=lam, method="inverse", tol=REF_TOL),
                         f"the decoupled pull at a/h={ah}")
        for method in ("dense", "cg"):
            res, sec, rep = timed(lambda pb=pb, d=depth, m=method: couple(
                pb, depth=d, lam=lam, method=m, tol=RES_TOL), budget)
            out.points.append(Point("coupled", q, name(method, "break"), "resolution",
                                    f"a/h={ah}", ah, RES_TOL,
                                    _rel(res.friction_force, ref.friction_force),
                                    "decoupled pull (nu = 1/2)", sec, rep, res.converged,
                                    res.residual, res.solves))
    heights, h, depth, _ = hertz_scene(tol_size)
    pb = Problem.from_arrays(heights, a=h, E=1.0, nu=0.3)
    label = f"a/h={tol_size}"
    refs = {law: _reference(lambda law=law: couple(pb, depth=depth, lam=lam, method="dense",
                                                   tol=REF_TOL, slip_law=law),
                            f"the coupled {law} pull") for law in ("break", "coulomb")}
    for method, law in methods:
        for tol in TOLS:
            res, sec, rep = timed(lambda m=method, law=law, tol=tol: couple(
                pb, depth=depth, lam=lam, method=m, tol=tol, slip_law=law), budget)
            err = _rel(res.friction_force, refs[law].friction_force)
            same = (np.array_equal(res.start.stick, refs[law].start.stick)
                    and np.array_equal(res.start.contact, refs[law].start.contact))
            out.points.append(Point("coupled", q, name(method, law), "tolerance", label,
                                    tol_size, tol, err, "tight reference", sec, rep,
                                    res.converged, res.residual, res.solves,
                                    "" if same else RELEASED))
            out.checks.append(Check("coupled", name(method, law), "tolerance", label, tol,
                                    "coupled residual", "indicator", q, res.residual,
                                    abs(err)))
    return out


# ------------------------------------------------------------------------------ the study


def study(quick: bool = False, progress: Callable[[str], None] | None = None,
          budget: float | None = None) -> Study:
    """Run the verification study.

    Parameters
    ----------
    quick : bool
        Small sizes (about half a minute on 2 cores) instead of the full study (about two
        minutes).
    progress : callable, optional
        Called with a line per scene.
    budget : float, optional
        Timed seconds per point (default 0.1 quick, 0.3 full; :func:`timed`).
    """
    say = progress or (lambda s: None)
    budget = (0.1 if quick else 0.3) if budget is None else budget
    out = Study()
    ahs = (8, 16, 32) if quick else (8, 16, 32, 64)
    say("hertz")
    out += _squeeze_series(_hertz, ("pk", "active-set"), ahs, 16 if quick else 32, budget)
    say("punch")
    out += _squeeze_series(_punch, ("pk", "active-set"), ahs, 16 if quick else 32, budget)
    say("wavy")
    out += _squeeze_series(_wavy, ("pk/pixel", "pk/continuous"),
                           (32, 64, 128) if quick else (32, 64, 128, 256), 64, budget)
    say("cattaneo")
    out += _cattaneo((8, 16) if quick else (8, 16, 32), 16, budget)
    say("pull")
    out += _pull((32, 48) if quick else (32, 48, 64, 96), 32 if quick else 64, budget)
    say("coupled")
    out += _coupled((4, 6) if quick else (4, 6, 8, 12), 6, budget)
    return out


# ------------------------------------------------------------------------------ output


def format_table(s: Study) -> str:
    """The points and the checks as two fixed-width text tables."""
    lines = [f"{'scene':<9} {'quantity':<17} {'method':<16} {'series':<10} {'resolution':<12} "
             f"{'tol':>7} {'rel. error':>11} {'seconds':>9} {'runs':>4} {'conv':>4}  note"]
    for p in s.points:
        lines.append(f"{p.scene:<9} {p.quantity:<17} {p.method:<16} {p.series:<10} "
                     f"{p.resolution:<12} {p.tol:>7.0e} {p.error:>+11.3e} {p.seconds:>9.2e} "
                     f"{p.repeats:>4} {'yes' if p.converged else 'NO':>4}  {p.note}".rstrip())
    lines += ["", f"estimates against the true error (floor {FLOOR:g}; kinds: "
              + "; ".join(f"{k}: {v}" for k, v in KINDS.items()) + ")",
              f"{'scene':<9} {'method':<16} {'series':<17} {'resolution':<12} {'tol':>7} "
              f"{'estimate of':<25} {'kind':<9} {'estimate':>10} {'true error':>10} "
              f"{'ratio':>9} {'holds':>5}"]
    for c in s.checks:
        lines.append(f"{c.scene:<9} {c.method:<16} {c.series:<17} {c.resolution:<12} "
                     f"{c.tol:>7.0e} {c.name:<25} {c.kind:<9} {c.estimate:>10.2e} "
                     f"{c.error:>10.2e} {c.ratio:>9.2g} {_yes(c.holds):>5}")
    return "\n".join(lines)


def _yes(flag: bool | None) -> str:
    return "-" if flag is None else "yes" if flag else "NO"


def to_json(s: Study) -> str:
    """Everything the diagrams and the tables show, as JSON."""
    return json.dumps(s.as_dict(), indent=1)


def summarize_checks(checks: Sequence[dict]) -> list[dict]:
    """Per estimate, kind and scene (of :meth:`Check.as_dict` rows, as ``--json`` prints
    them): the methods, how many checks, how many hold, and the range of the ratio."""
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for c in checks:
        groups.setdefault((c["name"], c["kind"], c["scene"]), []).append(c)
    rows = []
    for (name, kind, scene), cs in groups.items():
        ratios = [c["ratio"] for c in cs if math.isfinite(c["ratio"])]
        rows.append({"estimate": name, "kind": kind, "scene": scene,
                     "methods": sorted({c["method"] for c in cs}), "checks": len(cs),
                     "hold": sum(c["holds"] is True for c in cs),
                     "ratio_min": min(ratios) if ratios else math.nan,
                     "ratio_max": max(ratios) if ratios else math.nan})
    return rows


def _panel(ax, s: Study, scene: str, series: str) -> list[tuple]:
    """One panel of a work-precision diagram; returns the labels of the lines' ends
    ``(ax, x, y, text, colour)``, which :func:`_place_labels` puts where they overlap
    nothing once the figure is laid out."""
    from roughslip.analysis.plotting import log_ticks

    markers = "osD^v<>"
    floor_hit = noted = False
    labels = []
    for i, m in enumerate(s.methods(scene, series)):
        pts = s.line(scene, series, m)
        if not pts:
            continue
        x = np.array([p.seconds for p in pts])
        y = np.array([max(abs(p.error), FLOOR) for p in pts])
        color, mk = f"C{i}", markers[i % len(markers)]
        ax.plot(x, y, "-", color=color, lw=1.2, alpha=0.8)
        floor = np.array([p.at_floor for p in pts])
        floor_hit |= bool(floor.any())
        ax.plot(x[~floor], y[~floor], mk, color=color, ms=5,
                label=m if (~floor).any() else None)
        if floor.any():
            ax.plot(x[floor], y[floor], mk, color=color, ms=5, mfc="none",
                    label=None if (~floor).any() else m)
        other = np.array([p.note == RELEASED for p in pts])
        if other.any():
            noted = True
            ax.plot(x[other], y[other], "o", color="0.2", ms=11, mfc="none", mew=0.8)

        def tag(p: Point) -> str:
            return p.resolution.split("=")[1] if series == "resolution" else f"{p.tol:.0e}"

        # the ends say which way the line runs; ends that coincide get one label
        apart = math.hypot(math.log10(x[-1] / x[0]), math.log10(y[-1] / y[0])) > 0.3
        ends = [(0, tag(pts[0])), (len(pts) - 1, tag(pts[-1]))] if apart else [
            (0, f"{tag(pts[0])} to {tag(pts[-1])}")]
        labels += [(ax, x[j], y[j], text, color) for j, text in ends]
    ax.set_xscale("log")
    ax.set_yscale("log")
    if floor_hit:
        ax.axhline(FLOOR, color="0.4", ls="--", lw=0.8,
                   label=f"floor {FLOOR:.0e}: exact to rounding (open markers)")
        lo, hi = ax.get_ylim()  # room below the floor for the labels of the ends on it
        ax.set_ylim(min(lo, FLOOR * (FLOOR / hi) ** 0.1), hi)
    if noted:
        ax.plot([], [], "o", color="0.2", ms=11, mfc="none", mew=0.8,
                label="ringed: released another set of bonds")
    pts = [p for p in s.points if (p.scene, p.series) == (scene, series)]
    log_ticks(ax.xaxis)
    log_ticks(ax.yaxis)
    # the truth as the terminal writes it ("nu = 1/2"), with its symbols typeset
    what = re.sub(r"\bnu = ", r"$\\nu$ = ", pts[0].truth if pts else "")
    if series == "resolution":
        fixed, legend = f"tol {RES_TOL:g}", pts[0].resolution.split("=")[0] if pts else ""
    else:
        fixed, legend = (pts[0].resolution if pts else ""), "tol"
    ax.set_title(f"{scene}: by {series} ({fixed}),\nagainst the {what}; labels: {legend}",
                 fontsize=9)
    ax.set_xlabel("run time (s, median of repeats)", fontsize=8)
    ax.set_ylabel(f"|relative error| of the {PRIMARY[scene]}", fontsize=8)
    ax.tick_params(labelsize=8)
    ax.grid(True, which="major", alpha=0.3)
    return labels


#: where a line's end label may go, tried in order: offset (points) and alignment; the
#: rings farther out, for ends crowded by another line's end or an edge of the axes
_LABEL_PLACES = ((4, 4, "left", "bottom"), (4, -4, "left", "top"),
                 (-4, 4, "right", "bottom"), (-4, -4, "right", "top"),
                 (0, 7, "center", "bottom"), (0, -7, "center", "top"),
                 (7, 0, "left", "center"), (-7, 0, "right", "center"),
                 (4, 14, "left", "bottom"), (-4, 14, "right", "bottom"),
                 (4, -14, "left", "top"), (-4, -14, "right", "top"),
                 (0, 17, "center", "bottom"), (0, -17, "center", "top"),
                 (-4, 26, "right", "bottom"), (4, 26, "left", "bottom"),
                 (-4, -26, "right", "top"), (4, -26, "left", "top"))


def _place_labels(fig, labels: list[tuple]) -> None:
    """The end labels of :func:`_panel` on the laid-out figure, each at the place of
    :data:`_LABEL_PLACES` that covers least: inside its axes before all, then no label placed
    before, then the fewest plotted points and lines (of the other ends too:
    :func:`roughslip.analysis.legends.obstacles`); the first such place in order."""
    from roughslip.analysis.legends import obstacles

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    found = {id(ax): obstacles(ax)[0] for ax, *_ in labels}
    placed = []
    for ax, x, y, text, color in labels:
        anchor = ax.transData.transform((x, y))
        best = None
        for dx, dy, ha, va in _LABEL_PLACES:
            ann = ax.annotate(text, (x, y), textcoords="offset points", xytext=(dx, dy),
                              ha=ha, va=va, fontsize=8, color=color)
            ann.set_in_layout(False)  # the labels do not move the axes
            box = ann.get_window_extent(renderer)
            # inside, clear of the spines by a couple of pixels
            inside = (box.x0 >= ax.bbox.x0 + 2 and box.x1 <= ax.bbox.x1 - 2
                      and box.y0 >= ax.bbox.y0 + 2 and box.y1 <= ax.bbox.y1 - 2)
            hits = 0
            for xy, r in found[id(ax)]:
                near = np.hypot(*(xy - anchor).T) <= r + 1.5  # the labelled point itself
                hits += int(np.sum(~near & (xy[:, 0] > box.x0 - r) & (xy[:, 0] < box.x1 + r)
                                   & (xy[:, 1] > box.y0 - r) & (xy[:, 1] < box.y1 + r)))
            score = (not inside, sum(box.overlaps(b) for b in placed), hits)
            if best is None or score < best[0]:
                if best is not None:
                    best[1].remove()
                best = (score, ann, box)
                if score == (False, 0, 0):
                    break
            else:
                ann.remove()
        placed.append(best[2])


def _figure_legend(fig, axes) -> None:
    """One legend below the figure for the methods and markers of all its panels."""
    found: dict[str, object] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            found.setdefault(label, handle)
    if found:
        fig.legend(list(found.values()), list(found), loc="outside lower center",
                   ncol=min(3, len(found)), fontsize=8, frameon=False)


def plot_scene(s: Study, scene: str, path: str | Path) -> Path:
    """The work-precision diagram of one scene: by resolution (left), by tolerance (right)."""
    from roughslip.analysis.plotting import pyplot, save

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(7.5, 3.6), layout="constrained")
    labels = []
    for ax, series in zip(axes, SERIES, strict=True):
        labels += _panel(ax, s, scene, series)
    _figure_legend(fig, axes)
    _place_labels(fig, labels)
    return save(plt, fig, path)


#: a ``--plot`` path with one of these suffixes is one figure; any other is a folder
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def prepare_plot(path: str | Path) -> Path:
    """Make the folder that :func:`plot` writes ``path`` into (the path itself, or the folder
    of a single figure), or fail in one line; called before the study, so that a folder that
    cannot be written costs no work."""
    from roughslip.analysis.plotting import make_folder

    path = Path(path)
    return make_folder(path.parent if path.suffix.lower() in FIGURE_SUFFIXES else path)


def plot(s: Study, path: str | Path) -> list[Path]:
    """Work-precision diagrams: one file per scene in the folder ``path``
    (``verify-<scene>.png``), or all scenes as one grid when ``path`` ends in one of
    :data:`FIGURE_SUFFIXES`."""
    from roughslip.analysis.plotting import pyplot, save

    path = Path(path)
    scenes = s.scenes()
    prepare_plot(path)
    if path.suffix.lower() in FIGURE_SUFFIXES:
        plt = pyplot()
        fig, axes = plt.subplots(len(scenes), 2, figsize=(7.5, 3.4 * len(scenes)),
                                 squeeze=False, layout="constrained")
        labels = []
        for row, scene in zip(axes, scenes, strict=True):
            for ax, series in zip(row, SERIES, strict=True):
                labels += _panel(ax, s, scene, series)
        _figure_legend(fig, axes.ravel())
        _place_labels(fig, labels)
        return [save(plt, fig, path)]
    return [plot_scene(s, scene, path / f"verify-{scene}.png") for scene in scenes]
