r"""Squeeze histories of the coupled model: how the contacts come to carry their bonds before
the pull (docs/theory/coupled.rst#squeeze-histories).

Under coupling a normal load already needs tangential forces (:math:`G_{xz} f_z \ne 0`), so
the state the pull starts from depends on how the surfaces came together. A history takes the
problem to :math:`D_x = 0` at the squeeze's depth or force and leaves a
:class:`~roughslip.coupling.state.ContactState` there, admissible and certified (every
contact :math:`f_z \ge 0`, every gap :math:`\ge 0`, every bond within its slip law), from which
:func:`~roughslip.coupling.coupled.couple` pulls. The histories are registered in
:data:`HISTORIES` (``coupling.history`` of a run):

* ``"bonded"``: every contact bonded at the final depth with :math:`u_x = 0`, then the bonds
  the coupling overloads released one at a time, most overloaded first (the report's steps 3-6
  with the release it misses, erratum T25);
* ``"simultaneous"``: the same bonded squeeze, then every overloaded bond released at once and
  the state solved again, until none is overloaded (the report's step 7, which removes every
  tensile contact at once, applied to the bonds);
* ``"indent"``: the frictional indentation from first touch (:func:`indent_to`): a site bonds
  where it touches, fails by the slip law and, under the Coulomb law, sticks again;
* ``"frictionless"``: the frictionless squeeze, then every contact bonds where it is (offset
  :math:`o = u_x` of the squeeze), so the pull starts with no tangential force.

At :math:`\nu = 1/2` (:math:`G_{zx} = 0`) all four leave the frictionless contact with every
contact bonded and :math:`f_x = 0`: the decoupled model's start.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from roughslip.contact.problem import Problem
from roughslip.coupling.state import ContactState
from roughslip.errors import NumericalError
from roughslip.friction.events import TIE, follow_events
from roughslip.registry import Registry


@dataclass
class Setup:
    """What a history needs besides the problem and the block solver."""

    lam: float
    depth: float | None  # the squeeze's depth (displacement control), or
    force: float | None  # its normal force (load control)
    slip_law: str
    tol: float
    squeeze_method: str  # the frictionless squeeze that starts the sets under load control
    limit: int = 0  # the most states a history may pass through (set from the start set)
    _normal: object = field(default=None, init=False, repr=False)

    def normal(self, problem: Problem):
        """The frictionless squeeze (:class:`~roughslip.contact.squeeze.NormalSolver`, by
        ``squeeze_method``, tolerance 1e-8) at the depth or force; computed once."""
        if self._normal is None:
            from roughslip.contact.squeeze import NormalSolver

            solver = NormalSolver(problem, method=self.squeeze_method, tol=1e-8)
            self._normal = (solver.solve(depth=self.depth) if self.depth is not None
                            else solver.solve(force=self.force))
        return self._normal


@dataclass
class Squeezed:
    """A history's outcome: the state at :math:`D_x = 0`, solved without its rate (the pull
    asks for it), and what it took."""

    state: ContactState
    #: contact sites with no bond holding when the pull starts (released, broken or slipping)
    released: int
    #: states solved on the way (the squeeze's corrections, releases, indentation events)
    states: int


#: the coupled model's squeeze histories, by name (``coupling.history``)
HISTORIES: Registry[Callable[[Problem, object, Setup], Squeezed]] = Registry("squeeze history")


def overlap_start(problem: Problem, setup: Setup) -> np.ndarray:
    """The contact set the bonded squeezes start from: the geometric overlap at the depth,
    or under load control at 1.1 times the depth the frictionless squeeze needs for the
    force. It only shrinks in the squeeze's first passes, then is corrected site by site."""
    if setup.depth is not None:
        return problem.overlap(setup.depth) > 0
    if setup.force == 0:
        return np.zeros(problem.shape, bool)
    r = setup.normal(problem)
    return problem.overlap(1.1 * r.depth + 1e-12 * max(problem.grid.a, 1.0)) > 0


def _state(solver, problem: Problem, setup: Setup, C: np.ndarray, **kw) -> ContactState:
    return ContactState(solver, problem.base, float(setup.lam), C, depth=setup.depth,
                        force=setup.force, slip_law=setup.slip_law, **kw)


def drop_tensile(st: ContactState) -> int:
    """The report's removal of every contact with :math:`f_z < 0` at once, repeated until none
    is left (the set only shrinks, so this ends); bulk solves. Returns the solves."""
    n = 0
    while True:
        st.solve(bulk=True)
        n += 1
        fz, _, _ = st.at(0.0)
        fscale = max(float(np.abs(fz).max()), np.finfo(float).tiny)
        neg = st.C & (fz < -TIE * fscale)
        if not neg.any():
            return n
        st.C &= ~neg
        st.S &= ~neg
        st.sigma[neg] = 0.0


class _Cycle:
    """Refuses a return to sets already visited at :math:`D_x = 0`."""

    def __init__(self, where: str) -> None:
        self.seen: set[bytes] = set()
        self.where = where

    def check(self, st: ContactState) -> None:
        key = hashlib.blake2b(st.C.tobytes() + st.S.tobytes() + st.sigma.tobytes(),
                              digest_size=16).digest()
        if key in self.seen:
            raise NumericalError(f"{self.where}: the contact and stick sets cycle at D_x = 0 "
                                 "(no admissible state reached)")
        self.seen.add(key)


def settle(st: ContactState, limit: int, where: str = "coupled squeeze") -> int:
    """Resolve the violations at :math:`D_x = 0` one at a time, the first of
    :meth:`ContactState.violation` each time (a lost contact leaves, a penetrating site enters
    unbonded, the most overloaded bond fails by the slip law), until the state is
    admissible; returns the states solved."""
    cycle, n = _Cycle(where), 0
    while (v := st.violation(0.0)) is not None:
        if n >= limit:
            raise NumericalError(f"{where}: no admissible state after {limit} states at D_x = 0")
        st.apply(*v)
        cycle.check(st)
        st.solve()
        n += 1
    return n


def _bonded_overlap(problem: Problem, solver, setup: Setup) -> tuple[ContactState, int]:
    """The start of the bonded histories: the geometric overlap bonded with u_x = 0 at
    D_x = 0, its tensile contacts dropped; with the number of states so far."""
    st = _state(solver, problem, setup, overlap_start(problem, setup), slope=False)
    return st, drop_tensile(st)


def _released(st: ContactState) -> int:
    return int((st.C & ~st.S).sum())


def _ready(st: ContactState, n: int, limit: int) -> Squeezed:
    """The outcome of a history whose sets are final up to the one-at-a-time rule: solved
    through the updated inverse (certified), overloaded bonds left by a tie settled
    (:func:`settle`), and the contact sites that hold no bond counted."""
    st.solve()
    n += 1 + settle(st, limit)
    return Squeezed(st, _released(st), n)


@HISTORIES.register("bonded", "bond every contact at the final depth with u_x = 0, then "
                    "release the overloaded bonds one at a time, most overloaded first")
def bonded(problem: Problem, solver, setup: Setup) -> Squeezed:
    """Every contact bonded at the final depth (the report's steps 3-6), the overloaded bonds
    released one at a time, most overloaded first (:func:`settle`); module docstring."""
    st, n = _bonded_overlap(problem, solver, setup)
    return _ready(st, n, setup.limit)  # the updated inverse (the bulk passes may use CG)


@HISTORIES.register("simultaneous", "bond every contact at the final depth with u_x = 0, "
                    "then release every overloaded bond at once and solve again, until none "
                    "is overloaded")
def simultaneous(problem: Problem, solver, setup: Setup) -> Squeezed:
    """The bonded squeeze with the report's step-7 rule for the bonds: each round solves the
    sets and changes all the violations of the first kind found at once (every tensile
    contact leaves; else every penetrating site enters, unbonded; else every overloaded bond
    fails by the slip law), until the state is admissible. A round that changes one site is
    the one-at-a-time rule's step; the rounds end because no set repeats (checked)."""
    st, n = _bonded_overlap(problem, solver, setup)
    cycle = _Cycle("coupled squeeze (simultaneous)")
    while (v := st.violated(0.0)) is not None:
        if n >= setup.limit:
            raise NumericalError("coupled squeeze (simultaneous): no admissible state after "
                                 f"{setup.limit} states at D_x = 0")
        kind, bad, _, _, fx = v
        for j in np.flatnonzero(bad):
            st.apply(st.event_kind(kind, int(j), fx), int(j))
        cycle.check(st)
        st.solve(bulk=True)  # large rounds by CG: the inverse is built for the set they leave
        n += 1
    return _ready(st, n, setup.limit)  # settles nothing unless a bulk solve was off by a tie


@HISTORIES.register("frictionless", "the frictionless squeeze, then every contact bonds "
                    "where it is (offsets = the squeeze's u_x): the pull starts from zero "
                    "tangential force")
def frictionless(problem: Problem, solver, setup: Setup) -> Squeezed:
    r"""The frictionless squeeze, solved exactly on the coupled operator (no stick set, so
    :math:`f_x = 0`; started from the contact set of the frictionless solver and corrected site
    by site), then every contact bonded where it is: offset :math:`o = u_x = G_{xz} f_z`, so
    the bonded state at :math:`D_x = 0` is the same state, with :math:`f_x = 0` (to the
    solver's residual, certified)."""
    if setup.depth is None and setup.force == 0:
        C = np.zeros(problem.shape, bool)
    else:
        C = setup.normal(problem).contact
    st = _state(solver, problem, setup, C, slope=False)
    st.S[:] = False
    st.solve()
    n = 1 + settle(st, setup.limit, "coupled frictionless squeeze")
    fz, fx, _ = st.at(0.0)
    st.offset = np.where(st.C, solver.displacements(fz, fx)[1], 0.0)
    st.S = st.C.copy()
    return _ready(st, n, setup.limit)


@HISTORIES.register("indent", "the frictional indentation from first touch: every site "
                    "sticks where it touches, fails by the slip law (and under Coulomb sticks "
                    "again); the pull starts from that state")
def indent_history(problem: Problem, solver, setup: Setup) -> Squeezed:
    """:func:`indent_to` the setup's depth or force, then the state at that depth (or held at
    that force) with :math:`D_x` as the drive."""
    st, path = indent_to(problem, solver, setup)
    if path.message:
        raise NumericalError(f"coupled indentation: {path.message}")
    D = path.events[-1].dz
    st.end_indentation()
    if setup.force is None:
        st.hold_depth(D)
    else:
        st.hold_force(setup.force)
    st.solve()
    n = len(path.events) + path.transient + settle(st, setup.limit)
    return Squeezed(st, _released(st), n)


def indent_to(problem: Problem, solver, setup: Setup, record_states: bool = False):
    r"""The frictional indentation from first touch (:math:`D_z = 0`, the highest pixels in
    contact, bonded) to the setup's depth, or under load control to the depth at which
    :math:`F_z` reaches the force: every force is affine in :math:`D_z` between events, so that
    depth is read from each admissible state (:func:`follow_events` with a callable end).
    Returns the state, solved at its last event, and the event path."""
    if setup.depth is not None:
        scale_depth = setup.depth
    elif setup.force == 0:
        scale_depth = 0.0
    else:
        scale_depth = setup.normal(problem).depth
    top = problem.base >= 0.0
    st = ContactState(solver, problem.base, float(setup.lam), top, depth=scale_depth,
                      gained="bonded", slip_law=setup.slip_law, drive="z")
    st.solve()
    if setup.depth is not None:
        end: float | Callable[[], float] = setup.depth
    else:
        force = float(setup.force)

        def end() -> float:  # F_z(D) = sum f0_z + D sum f1_z on the current state
            rate = float(st.f1[0].sum())
            if not rate > 0:
                return math.inf
            return max(0.0, (force - float(st.f0[0].sum())) / rate)

    return st, follow_events(st, setup.limit, record_states, end=end)
