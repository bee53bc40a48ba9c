r"""The coupled normal–tangential model with exact event tracking (docs/theory/coupled.rst#coupled).

For a contact set :math:`C` (:math:`u_z = \bar u_z` imposed, :math:`f_z` unknown) and a stick
set :math:`S \subseteq C` (:math:`u_x = D_x` imposed, :math:`f_x` unknown; other sites carry
:math:`f_x = 0`, the break law)

.. math::

    \begin{bmatrix} G_{zz}(C,C) & G_{zx}(C,S) \\ G_{xz}(S,C) & G_{xx}(S,S) \end{bmatrix}
    \begin{bmatrix} f_z(C) \\ f_x(S) \end{bmatrix}
    = \begin{bmatrix} \bar u_z(C) \\ 0 \end{bmatrix}
    + D_x \begin{bmatrix} 0 \\ 1(S) \end{bmatrix},

an SPD principal block of the full operator (docs/theory/halfspace.rst#matrix-properties). Between
events every force, displacement and gap is exactly affine in :math:`D_x`: :math:`f = f^0 + D_x
f^1`, :math:`g = g^0 + D_x g^1`. The next event is the smallest root beyond the current :math:`D_x`
of: a bond reaching :math:`f_x = \pm\lambda f_z` (stick to slip, either direction), a contact force
reaching zero (contact lost), a gap closing (contact gained; the new contact is not bonded). After
an event the state is re-solved at the same :math:`D_x` and any violations are resolved one at a
time (contact lost, then penetration, then the most overloaded bond; ties to the lowest flat index)
before the pull continues: an avalanche.

The squeeze at :math:`D_x = 0` keeps every contact bonded (:math:`u_x = 0`), as the report proposes;
under coupling this already needs tangential forces, and bonds that violate :math:`|f_x| \le \lambda
f_z` there are released, most violated first, before pulling (the report misses this, erratum T25
(docs/theory/errata.rst#erratum-t25)). The friction force is the largest :math:`F_x` on the path,
reported with :math:`F_z` at the same :math:`D_x` (erratum T26
(docs/theory/errata.rst#erratum-t26)). At :math:`\nu = 1/2`, :math:`G_{zx} = 0` and the model
reduces exactly to the decoupled one.

The squeeze goes to a depth or to a normal force, and the pull holds either the depth (the
report's pull) or the normal force, with the depth following
(:class:`~roughslip.coupling.state.ContactState`, docs/theory/coupled.rst#coupled-load-control).

Under the Coulomb law a failed bond slips, carrying :math:`f_x = \sigma\lambda f_z` in the
direction :math:`\sigma` of its force as :math:`f_z` changes (the system is then not
symmetric: :meth:`~roughslip.coupling.blocksolvers.BlockSolver.solve_slip`), and a slipping
bond whose slip the pull would turn around sticks again where it is (the law's reversal rule,
:meth:`~roughslip.friction.laws.SlipLaw.turned_back`; docs/theory/coupled.rst#coupled-coulomb).

Solvers (registered in :data:`~roughslip.coupling.blocksolvers.SOLVERS`): ``"dense"`` assembles
the reduced block from the closed-form kernels and keeps its inverse up to date, O(m) per
removed unknown, while it fits in memory (docs/theory/coupled.rst#coupled-solvers); ``"cg"``
runs conjugate gradients
(:func:`roughslip.linalg.cg.cg`) on the restricted FFT block operator
(:meth:`roughslip.contact.problem.Problem.restricted_block`). Both follow the same event logic,
and every solve is certified against the FFT operator.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from roughslip.contact.problem import Problem, finite
from roughslip.coupling.blocksolvers import (  # noqa: F401  (the coupled model's public names)
    DENSE_BYTES_PER_UNKNOWN2,
    SOLVERS,
    BlockSolver,
    choose_solver,
    dense_memory_bytes,
    make_solver,
)
from roughslip.coupling.histories import HISTORIES, Setup, indent_to, overlap_start
from roughslip.errors import InputError, NumericalError
from roughslip.friction.events import (  # noqa: F401  (TIE, RATE_TIE: public here too)
    RATE_TIE,
    TIE,
    Curve,
    Event,
    EventPath,
    Snapshot,
    X,
    follow_events,
)
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import check_friction
from roughslip.friction.result import CoupledDetails, PullResult, PullState, renamed
from roughslip.linalg.threads import blas_threads
from roughslip.registry import AUTO


def __getattr__(name: str) -> type:
    """``CoupledResult``, the result type of earlier versions (deprecated)."""
    if name == "CoupledResult":
        return renamed(__name__, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: the largest tolerance a run gives the coupled model (``pull.tol``, at most this)
COUPLED_TOL = 1e-10

#: what a coupled pull can hold constant
PULL_CONTROLS = ("depth", "force")
#: how contacts gained during the pull enter (the first is the default)
GAINED_RULES = ("unbonded", "bonded")


def _event_limit(max_events: int | None, overlap: np.ndarray) -> int:
    """``max_events``, by default 20 events per site of the geometric overlap, plus 100."""
    return max_events if max_events is not None else 20 * int(overlap.sum()) + 100


@dataclass(frozen=True)
class _Outcome:
    """How a coupled solve ended: the worst residual, whether it converged, the message, and
    the solver that finished it."""

    residual: float
    converged: bool
    message: str
    method: str

    @classmethod
    def of(cls, solver: BlockSolver, path: EventPath, tol: float) -> _Outcome:
        residual = solver.residual()
        problem = path.message or (f"worst block-solve residual {residual:.2e}"
                                   if residual > 10 * tol else "")
        summary = problem or f"{len(path.events)} events, {path.transient} transient state(s)"
        return cls(residual, not problem, "; ".join(filter(None, [solver.fallback, summary])),
                   solver.method)


def _check_finite(where: str, **fields: np.ndarray) -> None:
    """A non-finite result field is an error, never a silent NaN."""
    for name, arr in fields.items():
        if not np.all(np.isfinite(arr)):
            raise NumericalError(f"{where}: non-finite {name}")


def couple(
    problem: Problem,
    *,
    depth: float | None = None,
    force: float | None = None,
    lam: float = 0.2,
    pull_control: str = "depth",
    gained: str = "unbonded",
    slip_law: str = "break",
    method: str = "auto",
    tol: float = 1e-12,
    max_iter: int = 20_000,
    max_events: int | None = None,
    reference: bool = False,
    record_states: bool = False,
    squeeze_method: str = "pk",
    history: str = "bonded",
    lam_dynamic: float | None = None,
    slip_distance: float | None = None,
    components: str = "x",
    direction: float = 0.0,
    facets: int | None = None,
) -> PullResult:
    r"""Squeeze a problem with bonded contacts and pull it with the coupled model until every
    bond has broken (module docstring; [Report2003] §6.1 with errata T25 and T26).

    Parameters
    ----------
    problem : Problem
        Heights, grid and material; its operator gets the ``zz``, ``zx`` and ``xx`` spectra.
    depth : float, optional
        Squeeze to the penetration :math:`D_z` from first touch (displacement control).
    force : float, optional
        Squeeze to the total normal force :math:`F_z` (load control). Exactly one of ``depth``
        and ``force``.
    lam : float
        Local friction coefficient.
    pull_control : {"depth", "force"}
        What the pull holds constant: ``"depth"``, the depth reached by the squeeze (the
        report's pull; :math:`F_z` changes as the contact changes), or ``"force"``, the normal
        force after the squeeze, as a dead weight does; then :math:`D_z` follows (recorded per
        event as ``Event.dz``).
    gained : {"unbonded", "bonded"}
        How a site that comes into contact during the pull enters: ``"unbonded"`` (the
        default: in the report's model the bonds are the contacts of the squeeze, and the pull
        only breaks them), carrying a normal force and no tangential one; or ``"bonded"``, with
        a new bond that holds the elastic point where it is when the gap closes (so no force
        jumps) and fails by the same law. Contacts gained while the squeeze corrects its
        sets, at :math:`D_x = 0`, always enter unbonded.
    slip_law : {"break", "coulomb", "slip-weakening"}
        What a bond carries once :math:`|f_x|` reaches :math:`\lambda f_z`: nothing
        (``"break"``, the report's law), or :math:`f_x = \pm\lambda f_z` in the direction
        of its force, following :math:`f_z` as it changes (``"coulomb"``; a slipping bond
        whose slip the pull would turn around sticks again where it is, event ``"stick"``),
        or its strength :math:`\lambda(\delta) f_z` falling with its slip
        (``"slip-weakening"``, :mod:`roughslip.coupling.weakening`: a certified
        path-follower; the pull runs until every bond is at its residual strength).
    method : str
        ``"auto"`` or a name from :data:`SOLVERS`. The dense solver checks the memory of
        its inverse (:func:`dense_memory_bytes`) before each factorisation: ``dense``
        refuses with :class:`MemoryLimitError` when it does not fit, ``auto`` goes on with
        ``cg`` and says so in the message.
    tol : float
        Relative residual of every block solve (CG's tolerance; the dense solver's
        certification against the FFT operator).
    max_events : int, optional
        Stop after this many events (default ``20 x overlap sites + 100``).
    reference : bool
        With ``dense``: also compute displacements by dense sums (no FFT at all).
    record_states : bool
        Keep the full state at every event (for checks on small grids).
    squeeze_method : str
        The frictionless squeeze (a name of :data:`roughslip.contact.squeeze.METHODS`) that
        finds the starting contact set under load control (and the frictionless history's),
        at tolerance 1e-8; the coupled squeeze then corrects that set exactly.
    history : str
        How the contacts come to carry their bonds before the pull, a name of
        :data:`~roughslip.coupling.histories.HISTORIES`: ``"bonded"`` (bonded at the final
        depth, the overloaded bonds released one at a time), ``"simultaneous"`` (released all
        at once, repeatedly), ``"indent"`` (the frictional indentation from first touch) or
        ``"frictionless"`` (the frictionless squeeze, then bonded where it is);
        docs/theory/coupled.rst#squeeze-histories.
    lam_dynamic, slip_distance : float, optional
        The slip-weakening law's :math:`\lambda_d` and :math:`d_c` (that law only).
    components : {"x", "xy"}
        The tangential force of each site: :math:`f_x` alone (the report's model), or the
        vector :math:`(f_x, f_y)` (:func:`~roughslip.coupling.cone.couple_cone`: the
        Coulomb law's faceted cone, the ``"indent"`` history, a depth, the depth held;
        other choices are refused in one line).
    direction : float
        The drive's angle from x in degrees (``components = "xy"`` only).
    facets : int, optional
        The facets of the cone (``components = "xy"``; default
        :data:`~roughslip.friction.cone.FACETS`).

    Returns
    -------
    PullResult
        The curve from :math:`D_x = 0` (the state after the squeeze), the peak, and the
        diagnostics; the squeeze and the block solver's in its
        :class:`~roughslip.friction.result.CoupledDetails`.
    """
    t0 = time.perf_counter()
    _check_couple(problem, depth, force, lam, pull_control, gained, slip_law, squeeze_method)
    if components != "x" or direction != 0 or facets is not None:
        _check_vector(components, direction, slip_law, history, depth, pull_control, method,
                      record_states, reference)
        from roughslip.coupling.cone import FACETS, couple_cone

        return couple_cone(problem, finite(depth, "depth"), lam=lam, direction=direction,
                           facets=FACETS if facets is None else facets, gained=gained,
                           tol=max(tol, 1e-14), max_events=max_events)
    law = LAWS.get(slip_law, "slip_law").bind(lam, lam_dynamic=lam_dynamic,
                                                slip_distance=slip_distance)
    run_history = HISTORIES.get(history, "history")
    depth = None if depth is None else finite(depth, "depth")
    force = None if force is None else finite(force, "force")
    setup = Setup(float(lam), depth, force, slip_law, tol, squeeze_method)
    geo = overlap_start(problem, setup)
    if not geo.any():
        z = np.zeros(problem.shape)
        none = PullState(z, z, geo, geo)
        return PullResult(
            friction_force=0.0, normal_force_at_peak=0.0, normal_force=0.0,
            curve=Curve.empty(), peak_event=0, peak=none, start=none, converged=True,
            seconds=time.perf_counter() - t0, method=choose_solver(method), slip_law=slip_law,
            residual=0.0, solves=0, message="no overlap: no contact",  # nothing to solve
            details=CoupledDetails(depth=0.0 if depth is None else depth,
                                   pull_control=pull_control, history=history,
                                   squeeze_seconds=time.perf_counter() - t0))
    solver, method = make_solver(problem, method, reference, tol, max_iter)
    limit = _event_limit(max_events, geo)
    setup.limit = limit
    if law.lands:
        return _couple_weakening(problem, solver, setup, law, history, pull_control, gained,
                                 t0)
    with blas_threads(1):  # the dense solver raises it for its BLAS-3 work
        try:
            sq = run_history(problem, solver, setup)
            st = sq.state
            start = Snapshot.of(st, 0.0)
            squeezed_depth = st.depth_at(0.0)
            t_squeeze = time.perf_counter() - t0
            # the pull holds what it is asked to: switch the control if the squeeze used the
            # other one (the state at D_x = 0 is the same); the pull needs the rates in D_x
            if pull_control == "depth" and force is not None:
                st.hold_depth(squeezed_depth)
            elif pull_control == "force" and depth is not None:
                st.hold_force(start.fz_total)
            st.begin_pull(gained)
            st.solve()
            path = follow_events(st, limit, record_states)
        except NumericalError as exc:
            raise NumericalError(f"coupled model: {exc}") from None
    peak = path.peak
    _check_finite("coupled model", fz=start.fz, fx=start.fx, **{"fz at peak": peak.fz})
    out = _Outcome.of(solver, path, tol)
    return PullResult(
        friction_force=float(peak.fx_total), normal_force_at_peak=float(peak.fz_total),
        normal_force=float(start.fz.sum()), curve=Curve.of(path.events),
        peak_event=path.peak_event, peak=PullState(peak.fz, peak.fx, peak.contact, peak.stick),
        start=PullState(start.fz, start.fx, start.contact, start.stick),
        converged=out.converged, seconds=time.perf_counter() - t0, method=out.method,
        slip_law=slip_law, residual=out.residual, solves=solver.solves, message=out.message,
        details=CoupledDetails(
            contact_area=float(start.contact.sum()) / start.contact.size, released=sq.released,
            depth=float(squeezed_depth), pull_control=pull_control, history=history,
            squeeze_states=sq.states, squeeze_seconds=t_squeeze,
            blas_seconds=solver.blas_seconds, fallback=solver.fallback,
            slip_iterations=solver.slip_iterations, states=path.states))


def _couple_weakening(problem: Problem, solver: BlockSolver, setup: Setup, law, history: str,
                      pull_control: str, gained: str, t0: float) -> PullResult:
    """:func:`couple` under slip-weakening (:mod:`roughslip.coupling.weakening`)."""
    from roughslip.coupling.weakening import Weakening, squeeze_weakening

    w = Weakening(float(law.lam), float(law.lam_dynamic), float(law.slip_distance))
    with blas_threads(1):
        try:
            sq = squeeze_weakening(problem, solver, setup, w, history)
            wc = sq.state
            if pull_control == "depth" and wc.force is not None:
                wc.depth, wc.force = wc.depth_now(), None
            elif pull_control == "force" and wc.force is None:
                wc.depth, wc.force = None, wc.totals()[1]
            wc.gained = gained
            wc.relinearize()
            start = wc.snapshot()
            squeezed_depth = wc.depth_now()
            t_squeeze = time.perf_counter() - t0
            path = wc.run(setup.limit)
        except NumericalError as exc:
            raise NumericalError(f"coupled model: {exc}") from None
    peak = path.peak
    _check_finite("coupled model", fz=start.fz, fx=start.fx, **{"fz at peak": peak.fz})
    residual = max(wc.worst, solver.residual())
    weak = (f", {wc.weak_landings} of them landed by Newton's method (a weak mode)"
            if wc.weak_landings else "")
    message = path.message or (f"{len(path.events)} events, {wc.bursts} burst(s){weak}, "
                               f"{wc.steps} certified steps")
    return PullResult(
        friction_force=float(peak.fx_total), normal_force_at_peak=float(peak.fz_total),
        normal_force=float(start.fz_total), curve=Curve.of(path.events),
        peak_event=path.peak_event, peak=PullState(peak.fz, peak.fx, peak.contact, peak.stick),
        start=PullState(start.fz, start.fx, start.contact, start.stick),
        converged=not path.message and residual <= 10 * setup.tol,
        seconds=time.perf_counter() - t0, method=solver.method, slip_law=law.name,
        residual=residual, solves=solver.solves, message=message,
        details=CoupledDetails(
            contact_area=float(start.contact.sum()) / start.contact.size, released=sq.released,
            depth=float(squeezed_depth), pull_control=pull_control, history=history,
            squeeze_states=sq.states, squeeze_seconds=t_squeeze,
            blas_seconds=solver.blas_seconds, fallback=solver.fallback))


def _check_couple(problem: Problem, depth: float | None, force: float | None, lam: float,
                  pull_control: str, gained: str, slip_law: str, squeeze_method: str = "pk"
                  ) -> None:
    """Validate the arguments of :func:`couple`."""
    check_friction(lam, slip_law, coupled=True)
    if (depth is None) == (force is None):
        raise InputError("give exactly one of depth and force")
    if pull_control not in PULL_CONTROLS:
        raise InputError(f"pull_control = {pull_control!r}: must be 'depth' or 'force'")
    if gained not in GAINED_RULES:
        raise InputError(f"gained = {gained!r}: must be 'unbonded' or 'bonded'")
    if depth is not None:
        problem.check_depth(depth)
        return
    force = finite(force, "force")
    if force < 0:
        raise InputError(f"force = {force:g}: must be >= 0")


def _check_vector(components: str, direction: float, slip_law: str, history: str,
                  depth: float | None, pull_control: str, method: str,
                  record_states: bool, reference: bool) -> None:
    """The choices :func:`couple` takes with the traction vector; each other one refused in
    one line that names it."""
    if components not in ("x", "xy"):
        raise InputError(f"components = {components!r}: must be 'x' or 'xy'")
    if components == "x":
        raise InputError(f"direction = {direction!r}, facets: the x-only model (components = "
                         "'x') pulls along x alone and has no cone; use components = 'xy'")
    vector = "components = 'xy' (the coupled model with the traction vector)"
    if not LAWS.get(slip_law, "slip_law").couples_vector:
        have = ", ".join(repr(n) for n in LAWS.names() if LAWS.get(n).couples_vector)
        raise InputError(f"slip_law = {slip_law!r}: {vector} holds slip_law {have} only; "
                         "use components = 'x'")
    if history != "indent":
        raise InputError(f"history = {history!r}: {vector} starts from the frictional "
                         "indentation; use history = 'indent'")
    if depth is None:
        raise InputError(f"force: {vector} squeezes to a depth; give depth instead")
    if pull_control != "depth":
        raise InputError(f"pull_control = {pull_control!r}: {vector} holds the depth")
    if choose_solver(method) != choose_solver(AUTO):
        raise InputError(f"method = {method!r}: {vector} is solved dense; use "
                         f"{AUTO!r} or {choose_solver(AUTO)!r}")
    if record_states:
        raise InputError(f"record_states = True: {vector} does not record its states")
    if reference:
        raise InputError(f"reference = True: {vector} has no dense-sum reference (its tests "
                         "check it against dense kernels)")


@dataclass(frozen=True)
class IndentResult:
    """Outcome of :func:`indent` (fields indexed ``[iy, ix]``, at the final depth)."""

    depth: float
    normal_force: float
    tangential_force: float  # F_x: zero for a surface symmetric in x
    events: list[Event]  # Event.dz is the depth of each event (Event.dx = 0)
    contact_counts: np.ndarray  # contact sites at every event
    stick_counts: np.ndarray  # stick sites at every event
    fz: np.ndarray
    fx: np.ndarray
    contact: np.ndarray
    stick: np.ndarray
    slip: np.ndarray  # slip direction (+1, -1) of slipping sites, 0 elsewhere
    converged: bool
    seconds: float
    solves: int
    method: str
    residual: float
    slip_law: str = "coulomb"
    message: str = ""
    #: with ``record_states=True``: (D_z, f_z, f_x, gap, contact, stick) at every event
    states: list | None = None

    @property
    def dz(self) -> np.ndarray:
        return np.array([e.dz for e in self.events])


def indent(
    problem: Problem,
    *,
    depth: float,
    lam: float = 0.2,
    slip_law: str = "coulomb",
    method: str = "auto",
    tol: float = 1e-12,
    max_iter: int = 20_000,
    max_events: int | None = None,
    reference: bool = False,
    record_states: bool = False,
    lam_dynamic: float | None = None,
    slip_distance: float | None = None,
) -> IndentResult:
    r"""Frictional indentation: the rigid surface approaches from first touch to ``depth``,
    with no tangential motion (:math:`D_x = 0`), under the coupled model
    (docs/theory/coupled.rst#coupled-indentation).

    Every site sticks where it touches (a bond holding the elastic point where it met the
    rigid surface), and the bonds fail by the slip law as the normal forces and the coupling
    load them: under ``"coulomb"`` they slip with :math:`f_x = \pm\lambda f_z` and stick
    again when their slip would reverse; under ``"break"`` they carry nothing after. The
    events are found exactly as in the pull, with the depth as the parameter: every force is
    affine in :math:`D_z` between events. This is the setting of Spence's frictional Hertz
    problem; on a profile that does not depend on y, on a grid periodic in y, it is the plane
    (cylinder) problem.

    Parameters
    ----------
    problem : Problem
    depth : float
        Final penetration :math:`D_z` from first touch.
    lam : float
        Local friction coefficient.
    slip_law : {"coulomb", "break", "slip-weakening"}
    method, tol, max_iter, reference, record_states, lam_dynamic, slip_distance
        As in :func:`couple` (``record_states`` has no effect under slip-weakening).
    max_events : int, optional
        Stop after this many events (default ``20 x overlap sites + 100``).

    Returns
    -------
    IndentResult
    """
    t0 = time.perf_counter()
    check_friction(lam, slip_law, coupled=True)
    law = LAWS.get(slip_law, "slip_law").bind(lam, lam_dynamic=lam_dynamic,
                                                slip_distance=slip_distance)
    depth = problem.check_depth(depth)
    if depth < 0:
        raise InputError(f"depth = {depth:g}: must be >= 0")
    solver, method = make_solver(problem, method, reference, tol, max_iter)
    setup = Setup(float(lam), depth, None, slip_law, tol, "pk",
                  _event_limit(max_events, problem.overlap(depth) > 0))
    if law.lands:
        return _indent_weakening(problem, solver, setup, law, t0)
    with blas_threads(1):
        try:
            st, path = indent_to(problem, solver, setup, record_states)
        except NumericalError as exc:
            raise NumericalError(f"coupled indentation: {exc}") from None
    D = path.events[-1].dz
    fz, fx, _ = st.at(D)
    _check_finite("coupled indentation", fz=fz, fx=fx)
    out = _Outcome.of(solver, path, tol)
    counts = np.array(path.counts, dtype=np.int64).reshape(-1, 2)
    return IndentResult(
        depth=float(D), normal_force=float(fz.sum()), tangential_force=float(fx.sum()),
        events=path.events, contact_counts=counts[:, 0], stick_counts=counts[:, 1],
        fz=fz, fx=fx, contact=st.C.copy(), stick=st.S.copy(),
        slip=np.where(st.C & ~st.S, st.sigma[..., X], 0.0).astype(np.int8),
        converged=out.converged,
        seconds=time.perf_counter() - t0, solves=solver.solves, method=out.method,
        residual=out.residual, slip_law=slip_law, message=out.message, states=path.states)


def _indent_weakening(problem: Problem, solver: BlockSolver, setup: Setup, law, t0: float
                      ) -> IndentResult:
    """:func:`indent` under slip-weakening (:mod:`roughslip.coupling.weakening`)."""
    from roughslip.coupling.weakening import STICK, Weakening, WeakeningContact

    w = Weakening(float(law.lam), float(law.lam_dynamic), float(law.slip_distance))
    top = (problem.base >= 0.0).ravel()
    wc = WeakeningContact(solver, problem, w, top, np.zeros(problem.base.size),
                          depth=setup.depth, drive="z", gained="bonded", tol=setup.tol)
    with blas_threads(1):
        try:
            path = wc.run(setup.limit, end=("depth", float(setup.depth)))
        except NumericalError as exc:
            raise NumericalError(f"coupled indentation: {exc}") from None
    snap = wc.snapshot()
    _check_finite("coupled indentation", fz=snap.fz, fx=snap.fx)
    counts = np.array(path.counts, dtype=np.int64).reshape(-1, 2)
    moving = wc.Q & (wc.phase != STICK)
    residual = max(wc.worst, solver.residual())
    return IndentResult(
        depth=float(wc.D), normal_force=float(snap.fz_total),
        tangential_force=float(snap.fx_total), events=path.events,
        contact_counts=counts[:, 0], stick_counts=counts[:, 1], fz=snap.fz, fx=snap.fx,
        contact=snap.contact, stick=snap.stick,
        slip=np.where(moving, wc.sigma, 0.0).reshape(problem.shape).astype(np.int8),
        converged=not path.message and residual <= 10 * setup.tol,
        seconds=time.perf_counter() - t0, solves=solver.solves, method=solver.method,
        residual=residual, slip_law=law.name, message=path.message or
        f"{len(path.events)} events, {wc.bursts} burst(s), {wc.steps} certified steps")


def squeeze_pull_coupled(
    heights: np.ndarray | Problem,
    *,
    depth: float | None = None,
    force: float | None = None,
    lam: float = 0.2,
    pull_control: str = "depth",
    gained: str = "unbonded",
    slip_law: str = "break",
    a: float = 1.0,
    E: float = 1.0,
    nu: float = 0.3,
    boundary: str = "open",
    periodic_kernel: str = "pixel",
    method: str = "auto",
    tol: float = 1e-12,
    max_iter: int = 20_000,
    max_events: int | None = None,
    fft: str = "auto",
    threads: int = 1,
    reference: bool = False,
    record_states: bool = False,
    history: str = "bonded",
    lam_dynamic: float | None = None,
    slip_distance: float | None = None,
) -> PullResult:
    """:func:`couple` on a problem built from plain numbers (or given, ignoring ``a`` ...
    ``threads``)."""
    problem = heights if isinstance(heights, Problem) else Problem.from_arrays(
        heights, a=a, E=E, nu=nu, boundary=boundary, periodic_kernel=periodic_kernel, fft=fft,
        threads=threads)
    return couple(problem, depth=depth, force=force, lam=lam, pull_control=pull_control,
                  gained=gained, slip_law=slip_law, method=method, tol=tol, max_iter=max_iter,
                  max_events=max_events, reference=reference, record_states=record_states,
                  history=history, lam_dynamic=lam_dynamic, slip_distance=slip_distance)
