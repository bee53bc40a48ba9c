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
"""

from __future__ import annotations

import math

import numpy as np

from roughslip.errors import NumericalError
from roughslip.friction.bonds import (
    BondRows,
    Bonds,
    PullOptions,
    bond_inverse,
    certify,
    decoupled_result,
    shrinking_only,
    track,
)
from roughslip.friction.events import (
    TANGENTIAL,
    TIE,
    X_DRIVE,
    Curve,
    EventKind,
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
    """The bonds of a squeeze under a slip law, affine in the pull (module docstring); an
    :class:`~roughslip.friction.events.EventState`."""

    def __init__(self, b: Bonds, opt: PullOptions) -> None:
        self.b, self.law, self.opt = b, opt.law, opt
        n = b.n
        self.inv = bond_inverse(b, opt.block, opt.threads, solver=opt.solver())
        track(self.inv, "phi", np.ones(n))
        self.inv.tracked["psi"] = Tracked(np.zeros(n), np.zeros(n), shrinking_only)
        self.rows = BondRows(b)
        #: slip direction per bond position, a unit vector of the law's tangential components
        #: (zero: sticks, or carries nothing)
        self.sigma = np.zeros((n, len(TANGENTIAL)))
        self.slip = np.zeros(n)  # f_x carried by each failed bond (bond positions)
        self.offset = np.zeros(n)  # a bond stuck again holds u_x = D + offset
        self.slip_sum = 0.0
        self.fz_total = float(b.normal.fz.sum())
        self.position = np.full(b.shape[0] * b.shape[1], -1, dtype=np.int64)
        self.position[b.sites] = np.arange(n)
        self.C = b.mask(np.arange(n))
        self.S = self.C.copy()
        self.progress = Progress()
        self.worst, self.refinements, self.ok = 0.0, 0, True
        self._rate: np.ndarray | None = None  # u_x rate on the grid, per stick set

    # -- the affine state ----------------------------------------------------------------------
    def _rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """phi, psi, f_z and the live mask on the rows of the inverse."""
        t = self.inv.tracked
        return t["phi"].x, t["psi"].x, self.b.fz[self.inv.ids], np.isfinite(self.rows.cap)

    def dx_at(self, D: float) -> float:
        return D

    def depth_at(self, D: float) -> float:
        return float(self.b.normal.depth)

    def totals(self, D: float) -> tuple[float, float]:
        phi, psi = self.inv.tracked["phi"].x, self.inv.tracked["psi"].x
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

    #: no event changes the forces at constant drive
    discontinuous = False

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
        if self._rate is None:
            phi, _, _, live = self._rows()
            v = np.zeros(self.b.shape)
            v.ravel()[self.b.sites[self.inv.ids[live]]] = phi[live]
            self._rate = self.b.apply(v, np.empty(self.b.shape)).ravel()
        pos = self.law.turned_back(slipping, self.sigma, self._rate[self.b.sites, None],
                                   X_DRIVE)
        return None if pos is None else int(self.b.sites[pos])

    # -- events --------------------------------------------------------------------------------
    def apply(self, kind: str, j: int, D: float = 0.0) -> None:
        pos = int(self.position[j])
        self._rate = None
        if kind == EventKind.STICK:
            self._stick_again(pos, j, D)
            return
        if kind not in (EventKind.SLIP_PLUS, EventKind.SLIP_MINUS):
            raise NumericalError(f"decoupled pull: no event {kind!r} (internal error)")
        r = int(self.inv.row[pos])
        s = self.law.failed_direction(kind)
        carried = float(self.law.carried(self.b.lam, s)[X] * self.b.fz[pos])
        # psi <- psi - c (psi_k + f_L,k) / c_k: the removal does it with psi_k so raised
        self.rows.remove(self.inv, r, held={"psi": -carried})
        self.sigma[pos], self.slip[pos] = s, carried
        self.slip_sum += carried
        self.S.ravel()[j] = False
        if self.rows.fold(self.inv):
            self._certify()

    def _load(self) -> np.ndarray:
        return self.b.field(self.slip)

    def _certify(self) -> None:
        r1, n1 = certify(self.b, self.inv, "phi", None, self.opt.tol)
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
        self._certify()

    def solve(self) -> None:
        """Nothing to do: every event updates the solutions in place."""


def slide(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    r"""The decoupled pull under ``opt.slip_law`` to full sliding, by the event loop: the exact
    piecewise-linear :math:`F_x(D_x)` (module docstring). ``friction_force`` is
    :math:`\sum_i f_{L,i}` once every bond slips (:math:`\lambda F_n` under the Coulomb law with
    every force in the pull's direction)."""
    st = TangentialState(b, opt)
    path = follow_events(st, 20 * b.n + 100, False)
    curve = Curve.of(path.events)
    sticks = curve.kind.count(EventKind.STICK)
    return decoupled_result(
        b, friction_force=float(st.slip.sum()), curve=curve, peak_event=curve.dx.size - 1,
        peak_fx=b.field(st.slip), peak_stick=np.zeros(b.shape, bool), t0=t0,
        method=opt.method_name, slip_law=opt.slip_law,
        converged=bool(st.ok) and not path.message, residual=st.worst, solves=st.refinements,
        message=path.message or ("exact event sequence to full sliding"
                                 + (f", {sticks} bond(s) stuck again" if sticks else "")))
