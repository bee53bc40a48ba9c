r"""The decoupled pull as a state of the event loop: every slip law on the bonds of a squeeze
(docs/theory/pull.rst; for a Hertz contact under the Coulomb law this is Cattaneo–Mindlin,
docs/methods.rst#cattaneo-mindlin).

The normal forces are those of the squeeze and do not change. With the stick set :math:`S` and
the slipping set :math:`L`, whose bonds carry fixed forces :math:`f_L = w f_z` (the slip law's
:meth:`~roughslip.friction.laws.SlipLaw.carried`; nothing under the break law), the stick forces
are affine in the pull:

.. math:: f_S = D\,\varphi - \psi, \qquad G_{SS}\varphi = 1_S, \qquad
          G_{SS}\psi = G_{SL} f_L - o_S,

with :math:`o` the offsets of bonds that stuck again. When bond :math:`k` fails,
:math:`\varphi \leftarrow \varphi - c\,\varphi_k/c_k` and
:math:`\psi \leftarrow \psi - c\,(\psi_k + f_{L,k})/c_k` (:math:`c` the column of
:math:`G_{SS}^{-1}`), in :math:`O(n)` on the updated inverse
(:func:`~roughslip.friction.bonds.bond_inverse`); both are certified against the FFT operator
after each block. The events, the avalanches at constant drive and the reversal rule are the
event loop's (:func:`~roughslip.friction.events.follow_events`), the same as in the coupled
model. A bond that sticks again (rare: none on the rough test scenes) changes the stick set
upwards, and the inverse is factorised afresh on it.

One state serves every law (:class:`TangentialState`); a strategy advances it
(:class:`PullStrategy`): the event path (:class:`FollowEvents`), or, under the break law,
whose failed bonds carry nothing and never stick again, the break sequence on :math:`\varphi`
alone (:class:`BreakSequence`, and
:class:`~roughslip.friction.breaking_single.SingleSequence` on a float32 inverse). Both give
the same bonds in the same order; the sequence uses the break law's own arithmetic and stops
exactly once no later state can beat the peak. Its recorder is an observer of the state
(:class:`BreakObserver`), told of each break. Slip-weakening extends the state with a
weakening phase (:class:`~roughslip.friction.weakening.WeakeningState`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from roughslip.errors import NumericalError
from roughslip.friction.bonds import (
    BondRows,
    Bonds,
    BreakCurve,
    PullOptions,
    bond_inverse,
    certify,
    decoupled_result,
    select,
    shrinking_only,
    stick_residual,
    track,
)
from roughslip.friction.cone import cone_slide
from roughslip.friction.events import (
    TANGENTIAL,
    TIE,
    X_DRIVE,
    Curve,
    EventKind,
    EventPath,
    Progress,
    Snapshot,
    X,
    argext,
    digest,
    event_table,
    follow_events,
)
from roughslip.friction.result import PullResult
from roughslip.linalg.inverse import Tracked


class TangentialState:
    r"""The bonds of a squeeze under a slip law, affine in the pull (module docstring): one
    state for every law, advanced by a :class:`PullStrategy`. As it stands it holds the
    stick and slip phases of the break and the Coulomb laws (an
    :class:`~roughslip.friction.events.EventState`);
    :class:`~roughslip.friction.weakening.WeakeningState` adds the weakening phase.

    The inverse of :math:`G_{xx}` on the bonds is held by the stick solver of ``opt.method``
    (:class:`~roughslip.linalg.stick.StickSolver`), in the precision ``opt.precision``.
    :math:`\varphi` is tracked always, :math:`\psi` once a strategy needs it
    (:meth:`track_slip`). Observers (:meth:`observe`) are told of each break of a break
    sequence (:class:`BreakSequence`).
    """

    def __init__(self, b: Bonds, opt: PullOptions) -> None:
        self._common(b, opt)
        n = b.n
        dtype = np.float32 if opt.precision == "single" else np.float64
        self.inv = bond_inverse(b, opt.block, opt.threads, dtype=dtype, solver=opt.solver())
        track(self.inv, "phi", np.ones(n) if b.k == 1 else np.tile(b.drive, n))
        self.rows = BondRows(b)
        self.slip = np.zeros(n)  # f_x carried by each failed bond (bond positions)
        self.offset = np.zeros(n)  # a bond stuck again holds u_x = D + offset
        self.slip_sum = 0.0
        self.fz_total = float(b.normal.fz.sum())
        self.S = self.C.copy()

    def _common(self, b: Bonds, opt: PullOptions) -> None:
        """What the state of every law holds besides its solver and its phases."""
        self.b, self.law, self.opt = b, opt.law, opt
        n = b.n
        #: slip direction per bond position, a unit vector of the law's tangential components
        #: (zero: sticks, or carries nothing)
        self.sigma = np.zeros((n, len(TANGENTIAL)))
        self.position = np.full(b.shape[0] * b.shape[1], -1, dtype=np.int64)
        self.position[b.sites] = np.arange(n)
        self.C = b.mask(np.arange(n))
        self.progress = Progress()
        self.worst, self.refinements, self.ok = 0.0, 0, True
        self.observers: list[BreakObserver] = []
        self._rate: np.ndarray | None = None  # slip rates on the grid, per stick set

    def track_slip(self) -> None:
        r"""Track :math:`\psi` too (the forces of failed bonds that carry force, and offsets),
        from here on: what the event path needs beyond :math:`\varphi`; a break sequence does
        without."""
        if "psi" not in self.inv.tracked:
            m = self.inv.m
            self.inv.tracked["psi"] = Tracked(np.zeros(m), np.zeros(m), shrinking_only)

    def run(self, strategy: PullStrategy, t0: float) -> PullResult:
        """Advance the state by ``strategy`` to the end of the pull; its result."""
        return strategy.run(self, t0)

    def observe(self, observer: BreakObserver) -> BreakObserver:
        """Tell ``observer`` of every break from here (:class:`BreakSequence`); it is
        returned."""
        self.observers.append(observer)
        return observer

    def stops(self, cap_sum_after: float) -> bool:
        """Whether an observer stops the pull (the exact early stop of a break sequence):
        every one is asked."""
        return any([o.should_stop(cap_sum_after) for o in self.observers])

    # -- the affine state ----------------------------------------------------------------------
    def _rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """phi, psi, f_z and the live mask on the rows of the inverse."""
        self.track_slip()
        t = self.inv.tracked
        return t["phi"].x, t["psi"].x, self.b.fz[self.inv.ids], np.isfinite(self.rows.cap)

    def dx_at(self, D: float) -> float:
        return D

    def depth_at(self, D: float) -> float:
        return float(self.b.normal.depth)

    def totals(self, D: float) -> tuple[float, float]:
        phi, psi, _, _ = self._rows()
        return D * float(phi.sum()) - float(psi.sum()) + self.slip_sum, self.fz_total

    def at(self, D: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not math.isfinite(D):
            raise NumericalError(f"the pull reached a non-finite displacement D_x = {D!r}")
        phi, psi, _, live = self._rows()
        fx = self.b.field(self.slip)
        fx.ravel()[self.b.sites[self.inv.ids[live]]] = (D * phi - psi)[live]
        return self.b.field(self.b.fz), fx, np.zeros(self.b.shape)

    def snapshot(self, D: float) -> Snapshot:
        """The totals at ``D``; no fields (the pull's result is the state at full sliding)."""
        F_x, F_z = self.totals(D)
        return Snapshot(F_x, F_z, D, None, None, None, None)

    def signature(self) -> bytes:
        """The stick set and the slip directions."""
        return digest(self.S, self.sigma)

    def _site(self, row: int) -> int:
        return int(self.b.sites[self.inv.ids[row]])

    def interval(self, D: float) -> tuple[float, float, str, int]:
        """The admissible interval of the drive and the event ending it: the stick rows of the
        slip law on the live bonds (:func:`~roughslip.friction.events.event_table`)."""
        phi, psi, fz, live = self._rows()
        Dref = max(self.progress.scale, abs(D))
        fs = max(float(np.abs(fz).max()), np.finfo(float).tiny)
        zero = np.zeros(phi.shape)
        cons = self.law.stick_rows(self.b.lam, live, (fz, -psi), (zero, phi), fs)
        lo, hi, kind, row = event_table(cons, D, Dref, self.progress.scale)
        return lo, hi, kind, (self._site(row) if row >= 0 else -1)

    def violation(self, D: float) -> tuple[str, int] | None:
        phi, psi, fz, live = self._rows()
        fx = D * phi - psi
        over = self.law.overload(self.b.lam, live, fz, fx)
        bad = live & (over > 1 + TIE)
        if not bad.any():
            return None
        j = argext(over, bad, "max")
        return EventKind.slip(fx[j]), self._site(j)

    #: no event changes the forces at constant drive, and no burst hides failures
    discontinuous = False
    failed_inside: tuple[tuple[str, int, float], ...] = ()

    def holds(self) -> bool:
        """Whether any bond still sticks (the pull goes on while one does)."""
        return bool(self.S.any())

    def reversal(self) -> int | None:
        """A slipping bond whose slip the pull would turn around (the slip law's
        :meth:`~roughslip.friction.laws.SlipLaw.turned_back`): one FFT product per stick set,
        only under a law that reverses and while bonds slip."""
        slipping = self.sigma.any(axis=-1)
        if not (self.law.reverses and slipping.any()):
            return None
        pos = self.law.turned_back(slipping, self.sigma, self.rates()[self.b.sites, None],
                                   X_DRIVE)
        return None if pos is None else int(self.b.sites[pos])

    def rates(self) -> np.ndarray:
        r""":math:`\partial u_x/\partial D` on the grid (flat) for the current stick set: one
        FFT product, kept until the next event."""
        if self._rate is None:
            phi, _, _, live = self._rows()
            v = np.zeros(self.b.shape)
            v.ravel()[self.b.sites[self.inv.ids[live]]] = phi[live]
            self._rate = self.b.apply(v, np.empty(self.b.shape)).ravel()
        return self._rate

    # -- events --------------------------------------------------------------------------------
    def apply(self, kind: str, j: int, D: float = 0.0) -> None:
        pos = int(self.position[j])
        self._rate = None
        self.track_slip()
        if kind == EventKind.STICK:
            self._stick_again(pos, j, D)
            return
        if kind not in (EventKind.SLIP_PLUS, EventKind.SLIP_MINUS):
            raise NumericalError(f"decoupled pull: no event {kind!r} (internal error)")
        r = int(self.inv.row[pos])
        s = self.law.failed_direction(kind)
        carried = float(self.law.carried(self.b.lam, s)[X] * self.b.fz[pos])
        # psi <- psi - c (psi_k + f_L,k) / c_k: the removal does it with psi_k so raised
        self.rows.remove(self.inv, r, self._leaving(r, carried), held={"psi": -carried})
        self.sigma[pos], self.slip[pos] = s, carried
        self.slip_sum += carried
        self.S.ravel()[j] = False
        if self.rows.fold(self.inv):
            self.recertify()

    def _leaving(self, row: int, carried: float) -> np.ndarray | None:
        """The column of the inverse at ``row``, which is about to leave the stick set with the
        force ``carried``, when the state needs it itself (else None: the solver takes it)."""
        return None

    def _load(self) -> np.ndarray:
        return self.b.field(self.slip)

    def recertify(self) -> None:
        """Check the tracked solutions against the FFT operator (:func:`certify`)."""
        r1, n1 = certify(self.b, self.inv, "phi", None, self.opt.tol)
        r2, n2 = 0.0, 0
        if "psi" in self.inv.tracked:
            r2, n2 = certify(self.b, self.inv, "psi", self._load(), self.opt.tol,
                             shift=self.offset)
        self.worst = max(self.worst, r1, r2)
        self.refinements += n1 + n2
        self.ok &= max(r1, r2) <= self.opt.tol

    def _stick_again(self, pos: int, j: int, D: float) -> None:
        """Bond ``pos`` sticks where it is: it holds its current u_x from here (offset), and
        the inverse is factorised afresh on the larger stick set."""
        _, fx, _ = self.at(D)
        ux = self.b.apply(fx, np.empty(self.b.shape)).ravel()[j]
        self.offset[pos] = ux - D
        self.slip_sum -= self.slip[pos]
        self.sigma[pos] = 0.0
        self.slip[pos] = 0.0
        self.S.ravel()[j] = True
        stick = self.position[np.flatnonzero(self.S.ravel())]
        self.inv.factor(stick)
        track(self.inv, "phi", np.ones(stick.size))
        rhs = self.b.apply(self._load(), np.empty(self.b.shape)).ravel()[self.b.sites[stick]]
        track(self.inv, "psi", rhs - self.offset[stick])
        self.rows.cap = self.b.cap[stick].copy()
        self.rows.alive = stick.size
        self.recertify()

    def solve(self) -> None:
        """Nothing to do: every event updates the solutions in place."""


    def result(self, path: EventPath, t0: float) -> PullResult:
        """The pull's result once the events have run to full sliding: ``friction_force`` is
        :math:`\\sum_i f_{L,i}` once every bond slips (:math:`\\lambda F_n` under the Coulomb law
        with every force in the pull's direction)."""
        b, opt = self.b, self.opt
        curve = Curve.of(path.events)
        sticks = curve.kind.count(EventKind.STICK)
        return decoupled_result(
            b, friction_force=float(self.slip.sum()), curve=curve,
            peak_event=curve.dx.size - 1, peak_fx=b.field(self.slip),
            peak_stick=np.zeros(b.shape, bool), t0=t0, method=opt.method_name,
            slip_law=opt.slip_law, converged=bool(self.ok) and not path.message,
            residual=self.worst, solves=self.refinements,
            message=path.message or ("exact event sequence to full sliding"
                                     + (f", {sticks} bond(s) stuck again" if sticks else "")))


class PullStrategy(Protocol):
    """How a :class:`TangentialState` advances to the end of its pull: the exact event path
    (:class:`FollowEvents`) or a break law's sequence (:class:`BreakSequence`,
    :class:`~roughslip.friction.breaking_single.SingleSequence`)."""

    def run(self, st: TangentialState, t0: float) -> PullResult:
        """Advance ``st`` to the end of its pull; the result."""
        ...


class BreakObserver(Protocol):
    """Told of each break of a break sequence (:class:`~roughslip.friction.bonds.BreakCurve`
    records the curve and its peak, and decides the exact early stop)."""

    def record(self, phi_sum: float, m: float, site_pos: int,
               stick: Callable[[], tuple[np.ndarray, np.ndarray]]) -> None:
        """A break at :math:`D = 1/m` with :math:`\\sum\\varphi` = ``phi_sum``, of the bond at
        position ``site_pos``; ``stick()`` gives the stick set and its :math:`\\varphi`."""
        ...

    def should_stop(self, cap_sum_after: float) -> bool:
        """Whether the pull may stop, :math:`\\lambda\\sum_S f_z` being ``cap_sum_after``."""
        ...


@dataclass(frozen=True)
class FollowEvents:
    """The exact event path to full sliding (:func:`~roughslip.friction.events.follow_events`;
    its ``landings`` and ``avalanche_peaks``); the state reads its result from the path."""

    landings: bool = False
    avalanche_peaks: bool = True

    def run(self, st: TangentialState, t0: float) -> PullResult:
        path = follow_events(st, 20 * st.b.n + 100, False, landings=self.landings,
                             avalanche_peaks=self.avalanche_peaks)
        return st.result(path, t0)


class BreakSequence:
    r"""The break law's fast path on the state's stick solver: the bond with the largest
    :math:`|\varphi_i|/(\lambda f_{z,i})` breaks next (``select``),
    :math:`O(n)` per break plus the solver's blocked updates; :math:`\varphi` is certified
    against the FFT operator after each fold and the peak state at the end. Each break is told
    to the observers, and the sequence stops exactly once one of them says so (the curve's
    recorder: once :math:`\lambda\sum_S f_z` falls below the best).

    It breaks the bonds the event path (:class:`FollowEvents`) would break, in the same order:
    an avalanche's next failure is the largest ratio too. Its arithmetic is the break law's
    own, :math:`D_{x,\rm lim} = 1/\max_i |\varphi_i|/(\lambda f_{z,i})`.
    """

    def run(self, st: TangentialState, t0: float) -> PullResult:
        b, opt, inv, rows = st.b, st.opt, st.inv, st.rows
        curve = st.observe(BreakCurve(b, opt.early_stop))
        cap_sum = float(b.cap.sum())
        k = b.k
        while rows.alive:
            phi, cap, pos = inv.tracked["phi"].x, rows.cap, inv.ids
            j, m = select(phi, cap, k)
            live = np.isfinite(cap)
            phi_sum = b.along(phi)  # the pull force along the drive, per unit of it
            for o in st.observers:
                o.record(phi_sum, m, pos[j] // k, lambda p=pos, f=phi, lv=live: (p[lv], f[lv]))
            cap_sum -= float(cap[j])
            if st.stops(cap_sum) or rows.alive == k:
                break
            for c in range(k):
                rows.remove(inv, j + c)
            if rows.fold(inv):
                st.recertify()
        if curve.peak_state is not None:  # the state that gives the friction force, certified
            pos, f, dx = curve.peak_state
            _, res = stick_residual(b, pos, f / dx, b.drive_rows(pos))
            st.worst, st.ok = max(st.worst, res), st.ok and res <= opt.tol
        return curve.result(t0, opt.method_name, converged=bool(st.ok), residual=st.worst,
                            solves=st.refinements, precision="double",
                            message=f"{b.n} bonds, block {opt.block}, "
                                    f"{st.refinements} refinements")


def slide(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    r"""The decoupled pull under ``opt.slip_law`` to full sliding, by the event loop: the exact
    piecewise-linear :math:`F_x(D_x)` (module docstring; :meth:`TangentialState.result`).
    With both tangential components, the Coulomb law's faceted cone
    (:func:`~roughslip.friction.cone.cone_slide`)."""
    if b.k > 1:
        return cone_slide(b, opt, t0, opt.facets)
    return TangentialState(b, opt).run(FollowEvents(), t0)
