r"""The contact and stick sets of the coupled model and their solution, affine in the drive.

For a contact set :math:`C` (:math:`u_z = \bar u_z` imposed, :math:`f_z` unknown) and a stick
set :math:`S \subseteq C` (:math:`u_x = D_x` imposed, :math:`f_x` unknown; other sites carry
what the slip law gives them) every force, displacement and gap is affine in :math:`D_x`:
:math:`f = f^0 + D_x f^1`, :math:`g = g^0 + D_x g^1`. :class:`ContactState` solves for both
parts with a :class:`~roughslip.coupling.blocksolvers.BlockSolver` and gives the event loop
(:mod:`roughslip.friction.events`) its constraints (docs/theory/coupled.rst#coupled).
"""

from __future__ import annotations

import math

import numpy as np

from roughslip.errors import NumericalError
from roughslip.friction.events import (
    TANGENTIAL,
    TIE,
    X_DRIVE,
    EventKind,
    Progress,
    Snapshot,
    X,
    argext,
    digest,
    event_table,
)
from roughslip.friction.laws import LAWS


class ContactState:
    r"""The contact and stick sets, and the solution on them as affine functions of D_x.

    Displacement control (``force`` None) holds :math:`D_z`: the normal right-hand side is
    :math:`\bar u = b + D_z` with :math:`b = h - \max h`. Load control holds
    :math:`F_z = \sum_C f_z = F`, and :math:`D_z` becomes an unknown: with the solutions
    :math:`f^b, f^d, f^1` for the right-hand sides :math:`(b, 0)`, :math:`(1_C, 0)` and
    :math:`(0, 1_S)`, the force constraint gives :math:`D_z = d_0 + d_1 D_x` with
    :math:`d_0 = (F - \sum f^b_z)/\sum f^d_z`, :math:`d_1 = -\sum f^1_z/\sum f^d_z`, and
    every force stays affine in :math:`D_x`: :math:`f = (f^b + d_0 f^d) + D_x (f^1 + d_1 f^d)`.
    The events are found exactly as under displacement control.
    """

    def __init__(self, solver, base: np.ndarray, lam: float, C: np.ndarray, *,
                 depth: float | None = None, force: float | None = None,
                 gained: str = "unbonded", slip_law: str = "break", drive: str = "x",
                 slope: bool = True):
        self.solver, self.base, self.lam = solver, base, lam
        self.gained = gained
        self.slip_law = slip_law
        self.law = LAWS.get(slip_law, "slip_law")
        #: slip direction of the sites in C but not in S, on the last axis: a unit vector of
        #: the tangential components, a slipping bond carrying f_t = sigma lam f_z (Coulomb
        #: law); zero, no tangential force (a broken bond, or a contact that never was a bond)
        self.sigma = np.zeros((*base.shape, len(TANGENTIAL)))
        self.u1x: np.ndarray | None = None  # rate of u_x in D_x, with slipping bonds
        #: u_x of each right-hand side's certified solution with slip forces, by key
        self._ux: dict[str, np.ndarray] = {}
        #: the event loop's progress; contacts gained once it has started follow ``gained``
        self.progress = Progress()
        #: bond offsets: a bond formed at D_x = D_g holds u_x = D_x + o, o = u_x(D_g) - D_g
        self.offset = np.zeros(base.shape)
        self.depth, self.force = depth, force
        self.C = C.copy()
        self.S = C.copy()
        self.ones = np.ones(base.shape)
        self.zero = np.zeros(base.shape)
        self.scale_g = float(np.max(base + (depth if depth is not None else 0.0)))
        self.d0, self.d1 = (depth if depth is not None else math.nan), 0.0
        #: solve for the rate in D_x too (the pull); the squeeze at D_x = 0 needs none
        self.slope = slope
        #: what the loop's parameter D moves: "x", the pull D_x (at a depth or force held);
        #: "z", the depth D_z itself at D_x = 0, up to ``depth`` (frictional indentation,
        #: :func:`indent`; ``depth`` then only sets the gap scale)
        self.drive = drive

    def begin_pull(self, gained: str) -> None:
        """The pull starts from this state: contacts gained during it follow ``gained``, and
        every solve gives the rate in :math:`D_x` too (then call :meth:`solve`)."""
        self.gained = gained
        self.slope = True

    def end_indentation(self) -> None:
        """Make the state of an indentation (the depth driven) the start of a pull: the
        drive is :math:`D_x` from here, a fresh event loop will follow it, and no rate is
        solved until :meth:`begin_pull` (hold the depth or the force, then :meth:`solve`)."""
        self.drive = "x"
        self.progress = Progress()
        self.slope = False

    def direction(self, j: int) -> np.ndarray:
        """The slip direction of site ``j`` (flat index): a view of :attr:`sigma`."""
        return self.sigma.reshape(-1, self.sigma.shape[-1])[j]

    @property
    def slipping(self) -> np.ndarray:
        """The slipping bonds: contact sites off the stick set with a slip direction."""
        return self.C & ~self.S & self.sigma.any(axis=-1)

    def hold_depth(self, depth: float) -> None:
        """Switch to displacement control at ``depth`` (then call :meth:`solve`)."""
        self.depth, self.force = depth, None

    def hold_force(self, force: float) -> None:
        """Switch to load control at ``force`` (then call :meth:`solve`)."""
        self.depth, self.force = None, force

    def solve(self, bulk: bool = False) -> None:
        """Solve the current sets (``bulk``: see :meth:`BlockSolver.prepare`). A non-finite
        solution from an updated inverse (round-off grown through many updates) is recomputed
        from a fresh factorisation; one that stays non-finite is an error, never a silent
        NaN."""
        self._solve(bulk)
        if self._finite():
            return
        if self.solver.reset():
            self._solve(bulk)
            if self._finite():
                return
        raise NumericalError("non-finite forces in the solve of the contact and stick sets")

    def _finite(self) -> bool:
        return all(np.all(np.isfinite(a)) for a in (*self.f0, *self.f1, self.g0, self.g1))

    def _solve(self, bulk: bool = False) -> None:
        """Solve for the state at D_x = 0 and, with :attr:`slope`, for its rate in D_x (the
        squeeze's corrections at D_x = 0 need no rate: one solve per state); with slipping
        bonds, also the rate of :math:`u_x` (one more FFT product), for :meth:`reversal`."""
        self._solve_forces(bulk)
        self.u1x = None
        if self.slope and self.slipping.any():
            self.u1x = self._rate_ux()

    def _rate_ux(self) -> np.ndarray:
        """The rate of :math:`u_x` in D, from the displacements that certified the solves
        with slip forces (:meth:`_solve_many`) as the rate :attr:`f1` combines them."""
        ux = self._ux
        u1 = ux["1"] if "1" in ux else self.zero  # no rate solve: an empty stick set
        if self.drive == "x" and self.force is not None:
            return u1 + self.d1 * ux["d"]
        return u1

    def _solve_forces(self, bulk: bool) -> None:
        s = self.solver
        s.prepare(self.C, self.S, bulk=bulk)
        if self.drive == "z":  # u_z = b + D on C: f = f(b) + D f(1_C), g = u_z - b - D
            sols = self._solve_many([(self.base, self.offset, "0"),
                                     (self.ones, self.zero, "1")])
            self.f0, self.g0 = sols[0][:2], sols[0][2] - self.base
            self.f1, self.g1 = sols[1][:2], sols[1][2] - 1.0
            self.d0, self.d1 = 0.0, 1.0
            return
        slope = self.slope and bool(self.S.any())
        tail = [(self.zero, self.ones, "1")] if slope else []
        if self.force is None:
            ubar = self.base + self.depth
            sols = self._solve_many([(ubar, self.offset, "0"), *tail])
            self.f0, self.g0 = sols[0][:2], sols[0][2] - ubar
            self.f1, self.g1 = (sols[1][:2], sols[1][2]) if slope else (
                (self.zero, self.zero), self.zero)
            self.d0, self.d1 = self.depth, 0.0
            return
        sols = self._solve_many([(self.base, self.offset, "b"), (self.ones, self.zero, "d"),
                                 *tail])
        (fbz, fbx, ub), (fdz, fdx, ud) = sols[0], sols[1]
        f1z, f1x, u1 = sols[2] if slope else (self.zero, self.zero, self.zero)
        sd = float(fdz.sum())
        if not sd > 0:
            raise NumericalError("load control: the contact set carries no force under a "
                                 "uniform approach (no contact left)")
        self.d0 = (self.force - float(fbz.sum())) / sd
        self.d1 = -float(f1z.sum()) / sd
        self.f0 = (fbz + self.d0 * fdz, fbx + self.d0 * fdx)
        self.f1 = (f1z + self.d1 * fdz, f1x + self.d1 * fdx)
        self.g0 = ub + self.d0 * ud - self.base - self.d0
        self.g1 = u1 + self.d1 * ud - self.d1
        self.scale_g = max(self.scale_g, float(np.max(self.base)) + self.d0)

    def _solve_many(self, rhs: list[tuple[np.ndarray, np.ndarray, str]]
                    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        r"""(f_z, f_x, u_z) on the grid for each right-hand side ``(r_z, r_x, key)``, with the
        slip forces of the slip law on the slip sites :math:`P` (in C, not in S,
        :math:`\sigma \ne 0`): :math:`f_x = w f_z`, :math:`w` the law's
        :meth:`~roughslip.friction.laws.SlipLaw.carried`. The block solver solves and
        certifies them (:meth:`~roughslip.coupling.blocksolvers.BlockSolver.solve_slip`) and
        gives the displacements :math:`u_x` that :meth:`_rate_ux` reads."""
        P = self.slipping
        self._ux = {}
        if not P.any():
            return self.solver.solve_many(rhs)
        w = self.law.carried(self.lam, self.sigma[P])[:, X]  # the block's one component
        out = self.solver.solve_slip(rhs, self.C, self.S, P, w)
        self._ux = {key: ux for (_, _, key), (_, _, _, ux) in zip(rhs, out, strict=True)}
        return [(fz, fx, uz) for fz, fx, uz, _ in out]

    def depth_at(self, D: float) -> float:
        """:math:`D_z` at pull displacement ``D``."""
        return self.d0 + self.d1 * D

    def dx_at(self, D: float) -> float:
        """:math:`D_x` at the loop's parameter ``D`` (0 when the depth is driven)."""
        return D if self.drive == "x" else 0.0

    def at(self, D: float):
        if not math.isfinite(D):
            raise NumericalError(f"the pull reached a non-finite displacement D_x = {D!r}")
        if not self.slope and D != 0:
            raise NumericalError(f"the state at D_x = {D!r} needs its rate (internal error)")
        fz = self.f0[0] + D * self.f1[0]
        fx = self.f0[1] + D * self.f1[1]
        g = self.g0 + D * self.g1
        return fz, fx, g

    def violated(self, D: float) -> tuple[str, np.ndarray, np.ndarray, str, np.ndarray] | None:
        """The first kind of violation at D that has any, in the order lost contact,
        penetration, overloaded bond: (kind, mask of the violating sites, the values ranking
        them, whether the worst is their ``"min"`` or ``"max"``, f_x), or None."""
        fz, fx, g = self.at(D)
        fscale = max(float(np.max(np.abs(fz))), np.finfo(float).tiny)
        bad = self.C & (fz < -TIE * fscale)
        if bad.any():
            return EventKind.LOST, bad, fz, "min", fx
        bad = ~self.C & (g < -TIE * max(self.scale_g, np.finfo(float).tiny))
        if bad.any():
            return EventKind.GAINED, bad, g, "min", fx
        over = self.law.overload(self.lam, self.S, fz, fx)
        bad = self.S & (over > 1 + TIE)
        if bad.any():
            return "slip", bad, over, "max", fx
        return None

    @staticmethod
    def event_kind(kind: str, j: int, fx: np.ndarray) -> str:
        """The event of a violation of ``kind`` at site ``j``: an overloaded bond fails in the
        direction of its force."""
        if kind != "slip":
            return kind
        return EventKind.slip(fx.ravel()[j])

    def violation(self, D: float):
        """The first violation to resolve at D, the worst of the first kind
        (:meth:`violated`): (event kind, flat index) or None."""
        v = self.violated(D)
        if v is None:
            return None
        kind, bad, values, how, fx = v
        j = argext(values, bad, how)
        return self.event_kind(kind, j, fx), j

    def apply(self, kind: str, j: int, D: float = 0.0) -> None:
        """Update the sets for an event at site ``j`` at pull displacement ``D``."""
        C, S = self.C.ravel(), self.S.ravel()
        if kind == EventKind.LOST:
            C[j] = False
            S[j] = False
            self.direction(j)[:] = 0.0
        elif kind == EventKind.STICK:  # a slipping bond sticks again where it is
            self._bond_here(j, D)
            self.direction(j)[:] = 0.0
        elif kind == EventKind.GAINED:
            C[j] = True
            if self.progress.started and self.gained == "bonded":
                self._bond_here(j, D)
        else:  # a bond fails: what it carries after is the slip law's
            S[j] = False
            self.direction(j)[:] = self.law.failed_direction(kind)

    def _bond_here(self, j: int, D: float) -> None:
        """Bond site ``j`` at the elastic point where it is at ``D``: its offset makes the
        bond hold :math:`u_x = D_x + o` from here, so no force jumps."""
        fz, fx, _ = self.at(D)
        ux = self.solver.displacements(fz, fx)[1]
        self.offset.ravel()[j] = ux.ravel()[j] - self.dx_at(D)
        self.S.ravel()[j] = True

    #: no event changes the forces at constant drive, and no burst hides failures
    discontinuous = False
    failed_inside: tuple[tuple[str, int, float], ...] = ()

    def holds(self) -> bool:
        """Whether any bond still sticks (the pull goes on while one does)."""
        return bool(self.S.any())

    def reversal(self) -> int | None:
        """A slipping bond whose slip would run against its force (the slip law's
        :meth:`~roughslip.friction.laws.SlipLaw.turned_back`), or None. The rate is constant
        over a state and changes only when the sets change, so a reversal is found at the
        start of a state, never inside one."""
        if self.u1x is None:
            return None
        # the rigid surface's tangential rate: zero when the depth is driven
        rigid = X_DRIVE if self.drive == "x" else np.zeros_like(X_DRIVE)
        return self.law.turned_back(self.slipping, self.sigma, self.u1x[..., None], rigid)

    def interval(self, D: float) -> tuple[float, float, str, int]:
        r"""The displacements at which this state is admissible, ``[lo, hi]``, and the event
        (kind, flat index) that ends it at ``hi``, for a state reached at pull displacement
        ``D``. A constraint is flat when its change over the displacement scale
        :math:`\max(D_{\rm scale}, |D|)` is below the tolerance; a violated flat constraint
        makes the state admissible nowhere (``lo = inf``, ``hi = -inf``).

        Every constraint is affine, :math:`a + bD \ge 0`: :math:`f_z \ge 0` on C,
        :math:`g \ge 0` off C, :math:`\lambda f_z \mp f_x \ge 0` on S
        (docs/theory/coupled.rst#coupled).
        Ties at ``hi`` go to the lowest flat index, then to the kinds in that order.
        """
        fz0, fz1 = self.f0[0], self.f1[0]
        lam = self.lam
        # the scale over which a rate matters: the first event's displacement, or how far the
        # pull has come (a rate negligible over the first event may not be over the pull)
        Dref = max(self.progress.scale, abs(D))
        fs = max(float(np.abs(fz0).max()), float(np.abs(fz1).max()) * Dref,
                 np.finfo(float).tiny)
        gs = max(self.scale_g, np.finfo(float).tiny)
        cons = (
            *self.law.stick_rows(lam, self.S, self.f0, self.f1, fs),
            (EventKind.LOST, self.C, fz0, fz1, fs),
            (EventKind.GAINED, ~self.C, self.g0, self.g1, gs),
        )
        return event_table(cons, D, Dref, self.progress.scale)

    def snapshot(self, D: float) -> Snapshot:
        """The totals and fields at ``D`` (copies)."""
        return Snapshot.of(self, D)

    def signature(self) -> bytes:
        """The contact and stick sets and the slip directions (bond offsets are continuous
        data: a site lost and bonded again at one drive is the same discrete state)."""
        return digest(self.C, self.S, self.sigma)

    def totals(self, D: float) -> tuple[float, float]:
        fz, fx, _ = self.at(D)
        return float(fx.sum()), float(fz.sum())

