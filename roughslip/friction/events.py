r"""The event loop of the exact, piecewise-linear models (docs/theory/coupled.rst#coupled).

Between events every force, displacement and gap is affine in the loop's parameter :math:`D`
(the pull :math:`D_x`, or the depth :math:`D_z` of an indentation). A state says on which
interval of :math:`D` it is admissible and which constraint ends it (its event table); the
loop moves to that event, applies it, re-solves, and resolves any violation at constant drive
(an avalanche) before the drive moves on. :func:`argext` is the package's one tie rule: among
values within a relative ``TIE`` of the extreme, the lowest flat index.
"""

from __future__ import annotations

import enum
import functools
import hashlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from roughslip.errors import NumericalError
from roughslip.linalg import jit

TIE = 1e-9
#: a slipping bond sticks again when its slip rate (per unit pull) opposes its force by more
RATE_TIE = 1e-9
#: the visits of one discrete state at one drive that end a path as a cycle
#: (:func:`follow_events`)
VISITS = 3


class EventKind(enum.StrEnum):
    """The kinds of event of the exact models: the one vocabulary of the event loop, the
    pull curves and the laws (each member is its string, as stored and printed)."""

    #: the state the pull starts from (site -1)
    START = "start"
    #: a bond reaches :math:`f_x = +\lambda f_z` (or ``-``) and fails by its slip law
    SLIP_PLUS = "slip+"
    SLIP_MINUS = "slip-"
    #: a bond of the break law's sequence breaks (the decoupled pull's curve)
    BREAK = "break"
    #: a slipping bond sticks again where it is (the reversal rule)
    STICK = "stick"
    #: a slipping bond's force reaches a corner of the faceted Coulomb cone, or leaves one
    #: along a facet (:mod:`roughslip.friction.cone`)
    TURN = "turn"
    #: a contact's normal force reaches zero, a gap closes (coupled model)
    LOST = "lost"
    GAINED = "gained"
    #: a weakening bond reaches its residual strength (slip-weakening)
    RESIDUAL = "residual"
    #: the state a burst lands in, at the drive that set it off (site -1)
    JUMP = "jump"
    #: a driven depth reaches its end (site -1)
    END = "end"

    @classmethod
    def slip(cls, force: float) -> EventKind:
        """The failure of a bond whose tangential force is ``force``: in its direction."""
        return cls.SLIP_PLUS if force > 0 else cls.SLIP_MINUS


#: the direction of the pulls the models drive: the x axis of the surface plane, as the unit
#: vector :math:`(\hat e_x, \hat e_y)`
X_AXIS: tuple[float, float] = (1.0, 0.0)


def plane_direction(degrees: float) -> tuple[float, float]:
    r"""The unit vector :math:`(\cos\theta, \sin\theta)` of the angle ``degrees`` from the x
    axis toward y in the surface plane, exact at multiples of 90 degrees (the axes)."""
    theta = float(degrees) % 360.0
    exact = {0.0: (1.0, 0.0), 90.0: (0.0, 1.0), 180.0: (-1.0, 0.0), 270.0: (0.0, -1.0)}
    if theta in exact:
        return exact[theta]
    rad = math.radians(theta)
    return (math.cos(rad), math.sin(rad))


#: the tangential force components of a site in the models, the last axis of a slip direction
#: :math:`\boldsymbol\sigma` (:meth:`roughslip.friction.laws.SlipLaw.failed_direction`): the
#: x component alone, the report's model, in which a unit vector is :math:`\pm 1`
TANGENTIAL: tuple[str, ...] = ("x",)


def tangential(v: tuple[float, float]) -> np.ndarray:
    """The plane vector ``v = (x, y)`` in the :data:`TANGENTIAL` components."""
    return np.array([v[("x", "y").index(c)] for c in TANGENTIAL], dtype=float)


#: the index of the x component in :data:`TANGENTIAL`
X = TANGENTIAL.index("x")
#: the rigid surface's tangential rate in a pull along x, per unit of the drive, in the
#: :data:`TANGENTIAL` components
X_DRIVE = tangential(X_AXIS)


def unit_vector(v: tuple[float, float] | np.ndarray) -> tuple[float, float]:
    r"""The unit vector :math:`v/|v|` of a direction ``v = (x, y)`` in the surface plane.

    Raises
    ------
    ValueError
        When ``v`` is not two finite numbers, or is the zero vector (no direction).
    """
    a = np.asarray(v, dtype=float)
    if a.shape != (2,) or not np.isfinite(a).all():
        raise ValueError(f"a direction in the surface plane is two finite numbers (x, y), "
                         f"not {v!r}")
    norm = math.hypot(float(a[0]), float(a[1]))
    if norm == 0.0:
        raise ValueError("a direction in the surface plane cannot be the zero vector")
    return float(a[0]) / norm, float(a[1]) / norm


@dataclass(frozen=True)
class Event:
    """One recorded state of the pull, driven along x (:data:`X_AXIS`)."""

    dx: float  # the drive D_x
    fx: float  # total tangential force F_x
    fz: float  # total normal force F_z at the same D_x
    kind: str  # an :class:`EventKind`
    site: int  # flat index (-1 for START, JUMP and END)
    dz: float = math.nan  # the depth D_z at the same D_x (it moves when the force is held)


@dataclass(frozen=True)
class Curve:
    r"""A pull curve, one entry per event: the vocabulary of both models
    (:attr:`roughslip.friction.result.PullResult.curve`).

    The drive is a vector in the surface plane, :math:`\mathbf D = D\,\hat{\mathbf e}`: its
    length ``drive`` along the unit vector ``direction`` (:math:`\hat{\mathbf e}`, as
    :math:`(x, y)`). The total tangential force is a vector, ``force[:, 0]`` and
    ``force[:, 1]`` its :math:`x` and :math:`y` components. The one-component model (forces
    along x only, pulled along x; :meth:`x_only`) has ``direction`` :data:`X_AXIS` and
    :math:`F_y = 0`.

    Attributes
    ----------
    drive : numpy.ndarray
        :math:`D`, the drive's displacement along ``direction``, per event.
    force : numpy.ndarray
        ``(n, 2)``: the total tangential force :math:`(F_x, F_y)`.
    fz : numpy.ndarray
        :math:`F_z`, the total normal force at the same drive.
    dz : numpy.ndarray
        :math:`D_z` (NaN where the model does not follow it).
    kind : tuple of str
        The :class:`EventKind` of each event.
    site : numpy.ndarray
        The flat index of each event's site (-1: none).
    direction : tuple of float
        :math:`\hat{\mathbf e}`, the unit vector of the drive.
    """

    drive: np.ndarray
    force: np.ndarray
    fz: np.ndarray
    dz: np.ndarray
    kind: tuple[str, ...]
    site: np.ndarray
    direction: tuple[float, float] = X_AXIS

    def __post_init__(self) -> None:
        n = self.drive.shape[0]
        if self.force.shape != (n, 2):
            raise ValueError(f"a curve of {n} events has a force of shape (n, 2) = ({n}, 2), "
                             f"not {self.force.shape}")
        unit_vector(self.direction)  # two finite numbers, not zero
        if abs(math.hypot(*self.direction) - 1.0) > 4 * np.finfo(float).eps:
            raise ValueError(f"a curve's direction is a unit vector, not {self.direction!r}")

    @property
    def drive_vector(self) -> np.ndarray:
        r"""``(n, 2)``: the drive :math:`\mathbf D = D\,\hat{\mathbf e}` as
        :math:`(D_x, D_y)`."""
        return np.outer(self.drive, self.direction)

    @property
    def dx(self) -> np.ndarray:
        """:math:`D_x`, the drive's x component."""
        return self.drive * self.direction[0]

    @property
    def dy(self) -> np.ndarray:
        """:math:`D_y`, the drive's y component."""
        return self.drive * self.direction[1]

    @property
    def fx(self) -> np.ndarray:
        """:math:`F_x`, the total tangential force's x component."""
        return self.force[:, 0]

    @property
    def fy(self) -> np.ndarray:
        """:math:`F_y`, the total tangential force's y component."""
        return self.force[:, 1]

    @property
    def along(self) -> np.ndarray:
        r""":math:`\mathbf F\cdot\hat{\mathbf e}`, the total tangential force along the
        drive (the pull force)."""
        ex, ey = self.direction
        return self.force[:, 0] * ex + self.force[:, 1] * ey

    @classmethod
    def x_only(cls, dx: np.ndarray, fx: np.ndarray, fz: np.ndarray, dz: np.ndarray,
               kind: tuple[str, ...], site: np.ndarray) -> Curve:
        """The curve of the one-component model: pulled along x, :math:`F_y = 0`."""
        dx = np.asarray(dx, dtype=float)
        force = np.zeros((dx.shape[0], 2))
        force[:, 0] = fx
        return cls(dx, force, np.asarray(fz, dtype=float), np.asarray(dz, dtype=float),
                   tuple(kind), np.asarray(site, dtype=np.int64))

    @classmethod
    def empty(cls) -> Curve:
        """The curve of a pull with nothing to pull (no contact): no event, not even the
        start."""
        z = np.zeros(0)
        return cls.x_only(z, z, z, z, (), np.zeros(0, np.int64))

    @classmethod
    def of(cls, events: list[Event]) -> Curve:
        """The curve of the events of a pull along x."""
        return cls.x_only(np.array([e.dx for e in events]), np.array([e.fx for e in events]),
                          np.array([e.fz for e in events]), np.array([e.dz for e in events]),
                          tuple(e.kind for e in events),
                          np.array([e.site for e in events], dtype=np.int64))


def argext(a: np.ndarray, mask: np.ndarray | None, how: str) -> int:
    """The flat index of the extreme (``how``: ``"min"`` or ``"max"``) of ``a`` over ``mask``
    (all of ``a`` when None), ties to the lowest index: the package's one tie rule. Values
    within a relative :data:`TIE` of the extreme tie with it; an infinite extreme ties only
    with itself."""
    if mask is None:
        vals = a.ravel()
        inside = np.ones(vals.shape, dtype=bool)
    else:
        vals = np.where(mask, a, np.inf if how == "min" else -np.inf).ravel()
        inside = mask.ravel()
    ext = vals.min() if how == "min" else vals.max()
    if not math.isfinite(ext):  # an infinite extreme (a bond with no normal force left)
        return int(np.flatnonzero((vals == ext) & inside)[0])
    close = np.abs(vals - ext) <= TIE * max(abs(ext), np.finfo(float).tiny)
    return int(np.flatnonzero(close & inside)[0])


def event_table(cons, D: float, Dref: float, Dscale: float, compiled: bool | None = None
                ) -> tuple[float, float, str, int]:
    r"""The interval ``[lo, hi]`` of the drive on which every constraint row holds, and the
    event (kind, index) that ends it at ``hi``.

    ``cons`` lists rows ``(kind, mask, a, b, scale)``: :math:`a + bD \ge 0` where ``mask``.
    A row is flat when its change over ``Dref`` is below ``TIE x scale``; a violated flat row
    makes the state admissible nowhere (``lo = inf``, ``hi = -inf``). Ties at ``hi`` (within
    a relative ``TIE`` of ``max(|hi|, Dscale)``) go to the lowest index, then to the earlier
    row kind. Each row is scanned in one compiled loop, or by numpy (``compiled``: default
    :data:`roughslip.linalg.jit.ENABLED`); both compare the same IEEE values in the same way.
    """
    use = jit.ENABLED if compiled is None else compiled
    scan = _compiled_scan() if use else _scan_np
    lo, hi, kind, site = -math.inf, math.inf, "", -1
    for name, mask, a, b, scale in cons:
        bad, v, j, w = scan(mask.ravel(), a.ravel(), b.ravel(), TIE * scale, Dref, Dscale, TIE)
        if bad >= 0:
            return math.inf, -math.inf, name, int(bad)
        if j >= 0:
            tol = TIE * max(abs(v), Dscale)
            if v < hi - tol or (abs(v - hi) <= tol and j < site):
                hi, kind, site = v, name, int(j)
        lo = max(lo, w)
    return lo, hi, kind, site


def _scan_np(m: np.ndarray, a: np.ndarray, b: np.ndarray, tiny: float, Dref: float,
             Dscale: float, tie: float) -> tuple[int, float, int, float]:
    """One row of :func:`event_table`: the first violated flat entry (or -1); the smallest
    root of the falling entries, the first entry at it (within the tie tolerance; -1 if none
    falls); the largest root of the rising entries (-inf if none)."""
    flat = m & (np.abs(b) * Dref <= tiny)
    viol = flat & (a < -tiny)
    if np.any(viol):
        return int(np.flatnonzero(viol)[0]), math.inf, -1, -math.inf
    with np.errstate(divide="ignore", invalid="ignore"):
        root = -a / b
    up = m & ~flat & (b < 0)
    v, j = math.inf, -1
    if up.any():
        r = np.where(up, root, np.inf)
        v = float(r.min())
        tol = tie * max(abs(v), Dscale)
        j = int(np.flatnonzero(up & (r <= v + tol))[0])
    down = m & ~flat & (b > 0)
    w = float(np.where(down, root, -np.inf).max()) if down.any() else -math.inf
    return -1, v, j, w


@functools.cache
def _compiled_scan():
    """:func:`_scan_np` as one compiled pass and a second one from the first falling entry
    (defined and compiled, or loaded from numba's cache, at first use)."""
    @jit.njit()
    def scan(m, a, b, tiny, Dref, Dscale, tie):
        v, w = np.inf, -np.inf
        first = -1
        for i in range(m.size):
            if not m[i]:
                continue
            bi = b[i]
            if abs(bi) * Dref <= tiny:
                if a[i] < -tiny:
                    return i, np.inf, -1, -np.inf
                continue
            r = -a[i] / bi
            if bi < 0.0:
                if first < 0:
                    first = i
                if r < v:
                    v = r
            elif bi > 0.0:
                if r > w:
                    w = r
        if first < 0:
            return -1, np.inf, -1, w
        tol = tie * max(abs(v), Dscale)
        for i in range(first, m.size):
            falling = m[i] and b[i] < 0.0 and not abs(b[i]) * Dref <= tiny
            if falling and -a[i] / b[i] <= v + tol:
                return -1, v, i, w
        return -1, v, -1, w

    return scan


@dataclass
class Snapshot:
    """The state at one displacement: totals and fields (the fields are None for a state that
    keeps none: the decoupled pull's, whose result is the state at full sliding)."""

    fx_total: float
    fz_total: float
    dx: float
    fz: np.ndarray | None
    fx: np.ndarray | None
    stick: np.ndarray | None
    contact: np.ndarray | None

    @classmethod
    def of(cls, st: EventState, D: float) -> Snapshot:
        fz, fx, _ = st.at(D)
        F_x, F_z = st.totals(D)
        return cls(F_x, F_z, D, fz.copy(), fx.copy(), st.S.copy(), st.C.copy())


@dataclass
class Progress:
    """What the event loop owns and a state reads: the drive's progress. The loop
    (:func:`follow_events`) writes it; a state keeps one (:attr:`EventState.progress`) and never
    writes it."""

    #: the displacement scale of the tolerances: 1 until the first event sets it
    scale: float = 1.0
    #: the drive has started (a state may treat changes before it differently)
    started: bool = False


@dataclass
class EventPath:
    """The pull path: events, the peak, and how the loop ended."""

    events: list[Event]
    states: list | None
    peak: Snapshot
    transient: int = 0
    message: str = ""
    #: the index of the peak in :attr:`events` (0: the start)
    peak_event: int = 0
    #: (contact sites, stick sites) at every recorded event
    counts: list[tuple[int, int]] = field(default_factory=list)


class EventState(Protocol):
    """What :func:`follow_events` asks of a state: the coupled model's
    :class:`~roughslip.coupling.state.ContactState` and the decoupled pull's
    :class:`~roughslip.friction.sliding.TangentialState` implement it. Sites are flat grid
    indices."""

    C: np.ndarray  # contact sites (bool grid)
    S: np.ndarray  # stick sites (bool grid)
    progress: Progress  # the loop's progress (:class:`Progress`), written by the loop only
    #: the last event changed the forces at constant drive (a bond that failed unstably)
    discontinuous: bool
    #: the bonds that failed inside the burst the last event set off, in order: (kind, site,
    #: F_x when it failed); the loop records them at the drive
    failed_inside: Sequence[tuple[str, int, float]]

    def interval(self, D: float) -> tuple[float, float, str, int]: ...

    def violation(self, D: float) -> tuple[str, int] | None: ...

    def reversal(self) -> int | None: ...

    def holds(self) -> bool: ...  # whether any bond still holds (the pull goes on)

    def apply(self, kind: str, j: int, D: float = 0.0) -> None: ...

    def solve(self) -> None: ...

    def at(self, D: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def totals(self, D: float) -> tuple[float, float]: ...

    def snapshot(self, D: float) -> Snapshot: ...

    def dx_at(self, D: float) -> float: ...

    def depth_at(self, D: float) -> float: ...

    def signature(self) -> bytes: ...  # the discrete state (sets, slip directions, phases)


def digest(*arrays: np.ndarray) -> bytes:
    """A short digest of the bytes of ``arrays``: a state's :meth:`EventState.signature`."""
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.digest()


def follow_events(st: EventState, limit: int, record_states: bool,
                  end: float | Callable[[], float] = math.inf, *, landings: bool = False,
                  avalanche_peaks: bool = True) -> EventPath:
    """Follow the events from D = 0 (module docstring): for a pull until no bond holds
    (:meth:`EventState.holds`), for a driven depth (:func:`~roughslip.coupling.coupled.indent`)
    until ``end``. A callable ``end`` is asked again after every solve: the end of a drive
    known only through the current state (the depth at which an indentation reaches a normal
    force, :func:`~roughslip.coupling.histories.indent_to`).

    A discrete state (:meth:`EventState.signature`) that comes back at one drive ends the
    path on its :data:`VISITS`-th visit, as a cycle: its ``message`` names the drive and the
    last event's site, and the pull is reported as not converged. In exact arithmetic one
    return would be a cycle already, as the sets decide the next event; a second visit can
    only differ by continuous data (the offset of a bond formed again, the solver's error at
    a loose tolerance), and it is given that chance.

    ``landings``: record the state an avalanche ends in, at the drive that set it off (event
    ``"jump"``), and the state after an event that changed the forces at constant drive
    (:attr:`EventState.discontinuous`). A state that resolves a burst itself reports the
    failures inside it (:attr:`EventState.failed_inside`): they are recorded at the drive,
    each with the force the state gives for it, and never count for the peak.
    ``avalanche_peaks``: whether the states of an avalanche, recorded at their own limits
    below the drive, count for the peak (they cannot exceed it under the break law,
    docs/theory/pull.rst; a law without that bound takes the peak over the stable path and
    the landings only).
    """
    path = EventPath([], [] if record_states else None, st.snapshot(0.0))

    def record(D: float, kind: str, site: int, F: float | None = None) -> None:
        F_x, F_z = st.totals(D)
        F_x = F_x if F is None else F
        path.events.append(Event(st.dx_at(D), F_x, F_z, kind, site, st.depth_at(D)))
        path.counts.append((int(st.C.sum()), int(st.S.sum())))
        if path.states is not None:
            fz, fx, g = st.at(D)
            path.states.append((D, fz.copy(), fx.copy(), g.copy(), st.C.copy(), st.S.copy()))

    def peak(at: float) -> None:
        F_x, _ = st.totals(at)
        if F_x > path.peak.fx_total:
            path.peak = st.snapshot(at)
            path.peak_event = len(path.events) - 1  # every call follows the record of ``at``

    record(0.0, EventKind.START, -1)
    st.progress.started = True
    D = 0.0
    first = True
    falling = False  # inside an avalanche (recorded states below the drive, or transients)
    seen: dict[bytes, int] = {}  # visits of the discrete states met at the current drive
    seen_at = 0.0  # the drive they were met at
    # until no bond holds; under the Coulomb law also until no slipping bond turns back
    # (a bond slipping against the pull sticks again, even when every other one slips)
    while True:
        # a callable end is read from the current state and taken only from an admissible
        # one (an avalanche's states can have other forces at the same drive)
        stop = end() if callable(end) else end
        if not callable(end) and not (D < stop if math.isfinite(stop) else st.holds()
                                      or st.reversal() is not None):
            break
        if len(path.events) + path.transient > limit:
            path.message = f"stopped after {limit} events"
            break
        if D > seen_at + TIE * max(st.progress.scale, abs(D)):
            seen.clear()
            seen_at = D
        key = st.signature()
        seen[key] = seen.get(key, 0) + 1
        if seen[key] >= VISITS:
            last = path.events[-1]
            path.message = (f"the events cycle: the state at D = {D!r} came back "
                            f"{VISITS - 1} times, the last after the {last.kind!r} event at "
                            f"site {last.site}")
            break
        lo, hi, kind, j = st.interval(D)
        if first and math.isfinite(hi) and hi > 0:
            st.progress.scale = hi  # the first event sets the displacement scale
            first = False
        tol_d = TIE * max(st.progress.scale, abs(D))
        if (lo > D + tol_d or lo > hi + tol_d) and st.violation(D) is None:
            # Admissible at D within the value tolerances of every constraint, which the
            # test in D missed: a constraint that changes slowly with D (a gap closing at a
            # small rate, say) puts its root far from D for a violation far below the
            # solver's residual. Take the state as admissible from D on.
            lo = min(lo, D, hi)
        feasible = lo <= hi + tol_d
        if feasible and lo <= D + tol_d and hi >= D - tol_d:
            if falling and landings:  # an avalanche has ended: the state it lands in
                record(D, EventKind.JUMP, -1)
                peak(D)
            falling = False
            # admissible at D, but a slipping bond would turn back: it sticks again, unless
            # an event is due at D itself (a bound reached at once), which goes first (it
            # changes the rates: a new contact that sticks and at once slips would otherwise
            # turn the whole slip zone back and forth)
            j_back = st.reversal() if hi > D + tol_d else None
            if j_back is not None:
                record(D, EventKind.STICK, j_back)
                st.apply(EventKind.STICK, j_back, D)
                st.solve()
                continue
            if hi > stop or (callable(end) and stop <= D):
                D = max(D, stop)  # the driven depth reaches its end before the next event
                record(D, EventKind.END, -1)
                break
            if not math.isfinite(hi):
                path.message = "no further event: the remaining bonds never break"
                break
            D = max(D, hi)  # the next event of a stable state
            at = D
        elif feasible and hi < D:
            at = hi  # an avalanche state, recorded at its own limit (below D)
            falling = True
        else:
            v = st.violation(D)  # transient: admissible at no D up to the current one
            if v is None:
                raise NumericalError("inconsistent state (no violation but no admissible "
                                     "displacement)")
            st.apply(*v, D)
            for k_in, j_in, F_in in st.failed_inside:
                record(D, k_in, j_in, F_in)
            st.solve()
            path.transient += 1
            falling = True
            continue
        record(at, kind, j)
        if avalanche_peaks or not falling:
            peak(at)
        st.apply(kind, j, at)
        for k_in, j_in, F_in in st.failed_inside:
            record(at, k_in, j_in, F_in)
        falling = falling or st.discontinuous
        st.solve()
    if falling and landings and not path.message:  # the last avalanche ends in full sliding
        record(D, EventKind.JUMP, -1)
        peak(D)
    return path
