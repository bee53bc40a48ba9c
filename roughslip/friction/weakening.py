r"""The decoupled pull under linear slip-weakening friction: exact events, and bursts at
constant drive (docs/theory/pull.rst#slip-weakening).

A bond that fails slips, and its strength falls with the slip :math:`\delta` it has
accumulated since it first failed (Ida 1972; Palmer & Rice 1973; Andrews 1976):

.. math:: \lambda(\delta) = \lambda_s - (\lambda_s - \lambda_d)\,\min(\delta/d_c, 1).

With the slip :math:`s_i = D - u_i` of the rigid surface over the half-space, each bond is in
one of three phases, with one linear equation each:

* **stick**: :math:`s_i = s^0_i` (0 until it first slips), while
  :math:`|f_i| \le \lambda(\delta_i) f_{z,i}`;
* **weakening**: :math:`f_i + k_i s_i = c_i`, :math:`k_i = (\lambda_s - \lambda_d) f_{z,i}/d_c`,
  while :math:`\sigma_i f_i > \lambda_d f_{z,i}` (its slip below :math:`d_c`);
* **residual**: :math:`f_i = \sigma_i\lambda_d f_{z,i}`.

The forces of the stick and weakening bonds :math:`A` solve

.. math:: M f_A = D\,1 - b - G_{AR} f_R, \qquad M = G_{AA} - \mathrm{diag}(1/k_W),

(:math:`b_i = s^0_i` on stick bonds, :math:`c_i/k_i` on weakening ones), so
:math:`f_A = D\varphi - \psi` is affine in :math:`D` between events. :math:`M` is symmetric but
indefinite; its inverse is updated, not recomputed, by
:class:`~roughslip.linalg.inverse.UpdatableInverse`: a bond that starts or stops weakening
shifts a diagonal entry, a bond that reaches its residual strength leaves the set.

Stability. The state is stable under a held drive when the stiffness of the weakening bonds,
:math:`(G_{AA}^{-1})_{WW} - \mathrm{diag}(k_W)`, is positive definite; by Haynsworth's inertia
theorem that is when :math:`M` has exactly :math:`|W|` negative eigenvalues. Every update
changes that count by the sign of its pivot, so it is tracked exactly. A stick bond can start
weakening without losing stability only while :math:`(M^{-1})_{ii} > k_i`.

Bursts. A failure that would leave the state unstable (a stick bond whose weakening would,
or one at its residual strength whose release softens the weakening bonds,
:math:`(M^{-1})_{ii} \le 0`) sets off a burst at the held drive. It lands where an overdamped
slip rate takes it as its viscosity vanishes: the least equilibrium above the fold, followed
on straight steps (:func:`~roughslip.friction.least.land`), or, where the kernel's few
non-cooperative couplings would take a slip back, that flow itself in closed form between
its events (:class:`~roughslip.friction.relax.Relaxation`). Bonds slip, weaken, reach their
residual strength or join until the moving bonds settle in a stable state, which replaces
this one. The event loop
(:func:`~roughslip.friction.events.follow_events`) records the failures inside the burst and
the state it lands in (event ``"jump"``) at the drive. The friction force is the largest force
of the stable path and the landings. Every state the loop accepts is stable.

Reversal: a slipping bond (weakening, or residual with a residual strength above 0) whose slip
the pull would turn back sticks again where it is, keeping the strength it has reached.

On an inexact inverse (a compressed one, ``method="hierarchical"``,
:mod:`roughslip.linalg.hierarchical`), the same decisions are taken on refined numbers:
:math:`\varphi` and :math:`\psi` are certified against the FFT operator after every event,
not only after a fold, and every column whose entries decide something (the stability test
:math:`(M^{-1})_{pp} > k_p`, the pivot whose sign counts the negative eigenvalues) is refined
against it too; where the set grows, the compressed inverse counts the negative eigenvalues of
its new factorisation. Every number a decision reads then has a relative residual within the
pull's tolerance, as on the dense inverse after a fold.

Limits. :math:`\lambda_d = \lambda_s` is the Coulomb law (a failed bond goes straight to its
residual strength). :math:`\lambda_d = 0` with :math:`d_c` below the pixel's weakening scale
is the break law: every failure is unstable and the failed bond relaxes to zero force, so each
burst breaks the bonds of the break law's avalanche at its drive.
"""

from __future__ import annotations

import math

import numpy as np

from roughslip.errors import MemoryLimitError, NumericalError
from roughslip.friction import least
from roughslip.friction.bonds import Bonds, PullOptions, decoupled_result
from roughslip.friction.events import (
    RATE_TIE,
    TIE,
    Curve,
    EventKind,
    EventPath,
    Snapshot,
    X,
    argext,
    digest,
    event_table,
)
from roughslip.friction.relax import Landing, Relaxation
from roughslip.friction.response import NO_BURSTS, burst_response
from roughslip.friction.result import PullResult
from roughslip.friction.sliding import FollowEvents, TangentialState
from roughslip.linalg.inverse import Tracked, inverse_bytes
from roughslip.linalg.memory import available_bytes

STICK, WEAK, RESIDUAL = 0, 1, 2


def _no_values(ids: np.ndarray) -> np.ndarray:
    """Right-hand sides of added unknowns: the state recomputes its solutions after an add."""
    return np.zeros(ids.size)


class WeakeningState(TangentialState):
    """The bonds of a squeeze under slip-weakening, affine in the pull (module docstring): the
    tangential state with the weakening phase, on an indefinite stick solver."""

    def __init__(self, b: Bonds, opt: PullOptions) -> None:
        self._common(b, opt)
        law = self.law
        self.lam_s, self.lam_d = float(b.lam), float(law.lam_dynamic)
        self.dc = float(law.slip_distance)
        n = b.n
        self.fz = b.fz
        self.k = (self.lam_s - self.lam_d) * self.fz / self.dc  # weakening stiffness
        self.phase = np.zeros(n, dtype=np.int8)
        # sigma (the slip directions, zero: sticks) is the tangential state's; the slip s, the
        # strength and the forces below are its x components
        self.lam_cur = np.full(n, self.lam_s)  # strength reached, lambda(delta)
        self.delta = np.zeros(n)  # slip accumulated up to the phase's start
        self.s0 = np.zeros(n)  # slip where the phase started
        self.bvec = np.zeros(n)  # b of M f = D 1 - b - G f_R, per bond (c/k when weakening)
        self.dshift = np.zeros(n)  # diagonal of M minus that of G (-1/k on weakening bonds)
        self.fR = np.zeros(n)  # forces of residual bonds
        self.neg = 0  # negative eigenvalues of M
        self.snaps = 0  # bonds that reached their residual strength inside bursts
        self.discontinuous = False  # the last event was a burst
        self._relax: Relaxation | None = None
        self._carry = least.Carry()  # the inverse of B one burst leaves the next
        self.failed_inside: list[tuple[str, int, float]] = []
        #: the largest force of the stable path so far, and whether the pull stopped early
        self.best, self.stopped, self._transient = -math.inf, False, False
        #: the largest sum of the forces inside a burst's relaxation, and its drive
        self.inside: tuple[float, float] = (-math.inf, 0.0)

        #: the stick solver's inverse is exact to rounding (dense), else every decision is
        #: taken on solutions and columns refined against the FFT operator (module docstring)
        self.exact = not (opt.method is not None and opt.method.inexact)
        factory = opt.solver()
        size = inverse_bytes if self.exact else factory.memory_bytes

        def room(m: int) -> bool:
            if size(m) > available_bytes():
                raise MemoryLimitError(
                    f"slip-weakening: the inverse on {m} bonds ({factory.kind}) needs "
                    f"~{size(m) / 2**30:.2f} GiB but "
                    f"{available_bytes() / 2**30:.2f} GiB are available")
            return True

        self.inv = factory(self._entries, n, room=room, threads=opt.threads, block=opt.block,
                           definite=False, points=b.points())
        try:
            self.inv.factor(np.arange(n), positive=True)  # G_xx on the bonds: all stick
        except NumericalError as exc:
            raise NumericalError(f"G_xx on the bonds: {exc}") from None
        self._retrack()

    # -- the matrix and its solutions ------------------------------------------------------
    def _entries(self, i: np.ndarray, j: np.ndarray, order: str) -> np.ndarray:
        """:math:`M` between the bonds ``i`` and ``j`` (G_xx, shifted on weakening bonds)."""
        A = self.b.entries(i, j, order)
        if np.array_equal(i, j):
            d = self.dshift[i]
            if d.any():
                A[np.diag_indices(i.size)] += d
        return A

    def _load(self) -> np.ndarray:
        return self.b.field(self.fR)

    def _rhs_psi(self, pos: np.ndarray) -> np.ndarray:
        """:math:`b + G_{AR} f_R` on the bonds ``pos`` (one FFT product when bonds are
        residual)."""
        out = self.bvec[pos].copy()
        if self.fR.any():
            u = self.b.apply(self._load(), np.empty(self.b.shape)).ravel()
            out += u[self.b.sites[pos]]
        return out

    def _retrack(self) -> None:
        """phi and psi afresh on the current rows (after a factorisation or an addition)."""
        inv = self.inv
        pos = inv.ids
        live = inv.live
        one = live.astype(float)
        rhs = np.zeros(inv.m)
        rhs[live] = self._rhs_psi(pos[live])
        for name, r in (("phi", one), ("psi", rhs)):
            x = inv.apply(r)
            x[~live] = 0.0
            inv.tracked[name] = Tracked(r.copy(), x, _no_values)
        self.recertify()

    def _rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """phi, psi, the bond of each row, and the live rows."""
        t = self.inv.tracked
        return t["phi"].x, t["psi"].x, self.inv.ids, self.inv.live

    def _certify(self, x: np.ndarray, rhs: np.ndarray, scale: float) -> np.ndarray:
        r"""``x`` (on the rows) refined until :math:`\|rhs - M x\|` is within the tolerance of
        ``scale`` (``rhs`` on the live rows; iterative refinement, module
        :mod:`roughslip.linalg.inverse`, with :math:`M` applied by the FFT operator)."""
        inv, b = self.inv, self.b
        live = inv.live
        pos = inv.ids[live]
        sites = b.sites[pos]
        shift = self.dshift[pos]

        def residual(x: np.ndarray) -> tuple[np.ndarray, float]:
            v = np.zeros(b.shape)
            v.ravel()[sites] = x[live]
            u = b.apply(v, np.empty(b.shape)).ravel()[sites] + shift * x[live]
            r = np.zeros(inv.m)
            r[live] = rhs - u
            return r, float(np.linalg.norm(r[live])) / scale

        x, res, nref = inv.refine(x, residual, self.opt.tol, 3)
        self.worst = max(self.worst, res)
        self.refinements += nref
        self.ok &= res <= self.opt.tol
        return x

    def recertify(self) -> None:
        """Check phi and psi against the FFT operator (iterative refinement, module
        :mod:`roughslip.linalg.inverse`)."""
        inv = self.inv
        pos = inv.ids[inv.live]
        for name, rhs in (("phi", np.ones(pos.size)), ("psi", self._rhs_psi(pos))):
            # psi's right-hand side is a displacement of the order of the drive's
            scale = max(float(np.linalg.norm(rhs)), self.progress.scale * math.sqrt(rhs.size),
                        1e-300)
            t = inv.tracked[name]
            t.x = self._certify(t.x, rhs, scale)

    def _column(self, p: int) -> np.ndarray:
        """Column ``p`` (a bond) of the current inverse on the rows; on an inexact inverse
        refined against the FFT operator, so that the stability tests and the pivots' signs
        read it to the tolerance."""
        inv = self.inv
        r = int(inv.row[p])
        col = inv.column(r)
        if self.exact:
            return col
        e = np.zeros(int(inv.live.sum()))
        e[int(np.count_nonzero(inv.live[:r]))] = 1.0
        return self._certify(col, e, 1.0)

    def _fold(self) -> None:
        """Fold the pending updates when the block is full, and certify phi and psi then;
        on an inexact inverse after every event (module docstring)."""
        inv = self.inv
        if inv.k < inv.block:
            if not self.exact:
                self.recertify()
            return
        inv.flush()
        if inv.live.sum() < 0.75 * inv.m:
            inv.compact()
        self.recertify()

    # -- the affine state (an EventState of the event loop) ---------------------------------
    @property
    def S(self) -> np.ndarray:
        """The stick sites (grid)."""
        return self.b.mask(np.flatnonzero(self.phase == STICK))

    def holds(self) -> bool:
        """Whether any bond sticks or weakens (the pull goes on while one does), and the
        pull has not stopped early (:meth:`_stop_early`)."""
        return not self.stopped and bool(np.any(self.phase != RESIDUAL))

    def _stop_early(self, D: float) -> None:
        r"""Stop the pull (``opt.early_stop``) once the sum of the bonds' strengths at ``D``
        is at most the largest force of the stable path so far, :attr:`best`: strengths only
        fall, and in an equilibrium no bond carries more than its strength, so no later state
        of the path or landing can exceed it (a weakening bond's strength is the force it
        carries, :math:`\sigma f`)."""
        if not self.opt.early_stop or self.stopped or np.all(self.phase == RESIDUAL):
            return
        cap = self.lam_cur * self.fz
        W = self.phase == WEAK
        if W.any():
            cap[W] = self.sigma[W, X] * self.forces(D)[W]
        if float(cap.sum()) <= self.best:
            self.stopped = True

    def forces(self, D: float) -> np.ndarray:
        """:math:`f_x` per bond at ``D``."""
        phi, psi, ids, live = self._rows()
        f = self.fR.copy()
        f[ids[live]] = D * phi[live] - psi[live]
        return f

    def at(self, D: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not math.isfinite(D):
            raise NumericalError(f"the pull reached a non-finite displacement D_x = {D!r}")
        return self.b.field(self.fz), self.b.field(self.forces(D)), np.zeros(self.b.shape)

    def totals(self, D: float) -> tuple[float, float]:
        phi, psi, _, live = self._rows()
        F = D * float(phi[live].sum()) - float(psi[live].sum()) + float(self.fR.sum())
        return F, float(self.b.normal.fz.sum())

    def signature(self) -> bytes:
        """The phases, the slip directions and the slip each phase started from (a burst at
        one drive meets the same phases again only with more slip)."""
        return digest(self.phase, self.sigma, self.delta, self.s0)

    def snapshot(self, D: float) -> Snapshot:
        return Snapshot.of(self, D)

    def stable(self) -> bool:
        """Whether M has one negative eigenvalue per weakening bond (module docstring)."""
        return self.neg == int(np.count_nonzero(self.phase == WEAK))

    def _check_stable(self) -> None:
        """Every event keeps the state stable: a failure that would not is a burst, which
        lands on a stable state (:meth:`_burst`)."""
        if not self.stable():
            raise NumericalError("slip-weakening: an unstable state outside a burst "
                                 "(internal error)")

    def _cons(self, D: float) -> tuple[list, np.ndarray, float]:
        """The constraint rows ``a + b D >= 0`` on the rows of the inverse."""
        phi, psi, ids, live = self._rows()
        ph = self.phase[ids]
        fz = self.fz[ids]
        fs = max(float(np.abs(self.fz).max()), np.finfo(float).tiny)
        S, W = live & (ph == STICK), live & (ph == WEAK)
        sg = self.sigma[ids, X]
        lam = self.lam_cur[ids]
        cons = [(EventKind.SLIP_PLUS, S, lam * fz + psi, -phi, fs),
                (EventKind.SLIP_MINUS, S, lam * fz - psi, phi, fs),
                (EventKind.RESIDUAL, W, -sg * psi - self.lam_d * fz, sg * phi, fs)]
        return cons, ids, fs

    def interval(self, D: float) -> tuple[float, float, str, int]:
        """The admissible interval of the drive and the event ending it
        (:func:`~roughslip.friction.events.event_table`)."""
        self._check_stable()
        cons, ids, _ = self._cons(D)
        scale = self.progress.scale
        lo, hi, kind, row = event_table(cons, D, max(scale, abs(D)), scale)
        return lo, hi, kind, (int(self.b.sites[ids[row]]) if row >= 0 else -1)

    def violation(self, D: float) -> tuple[str, int] | None:
        """The most violated constraint at ``D`` (in units of the bond's f_z; ties to the
        lowest row), or None. The event it names is a transient one (not on the stable
        path)."""
        self._check_stable()
        cons, ids, _ = self._cons(D)
        best, which = TIE, None
        for name, m, a, b, _ in cons:
            if not m.any():
                continue
            excess = np.where(m, -(a + b * D) / self.fz[ids], -np.inf)
            j = argext(excess, m, "max")
            if excess[j] > best * (1 + TIE):
                best, which = float(excess[j]), (name, int(self.b.sites[ids[j]]))
        self._transient = which is not None
        return which

    def _slip_rates(self) -> np.ndarray:
        r""":math:`\partial s/\partial D` of every bond on the current piece (0 on stick
        bonds; one FFT product when bonds are residual)."""
        if self._rate is None:
            phi, _, ids, live = self._rows()
            rate = np.zeros(self.b.n)
            W = live & (self.phase[ids] == WEAK)
            rate[ids[W]] = -phi[W] / self.k[ids[W]]
            R = self.phase == RESIDUAL
            if R.any() and self.lam_d > 0:
                v = np.zeros(self.b.shape)
                v.ravel()[self.b.sites[ids[live]]] = phi[live]
                u = self.b.apply(v, np.empty(self.b.shape)).ravel()[self.b.sites]
                rate[R] = 1.0 - u[R]
            self._rate = rate
        return self._rate

    def reversal(self) -> int | None:
        """A slipping bond whose slip the pull would turn back (the most, above
        ``RATE_TIE``; ties to the lowest bond): it sticks again where it is, keeping the
        strength it has reached. Residual bonds of zero strength carry nothing and never
        stick again. Returns its site."""
        can = (self.phase == WEAK) | ((self.phase == RESIDUAL) & (self.lam_d > 0))
        if self.stopped or not can.any():
            return None
        back = np.where(can, -self.sigma[:, X] * self._slip_rates(), -np.inf)
        top = float(back.max())
        if not top > RATE_TIE:
            return None
        return int(self.b.sites[np.flatnonzero(back >= top - TIE * max(1.0, top))[0]])

    # -- events ----------------------------------------------------------------------------
    def _set_b(self, p: int, value: float, col: np.ndarray) -> None:
        """Change :math:`b_p` of psi's right-hand side (``col``: column p of the inverse)."""
        self.inv.change_rhs("psi", p, value - self.bvec[p], col)
        self.bvec[p] = value

    def _leave(self, p: int, force: float, col: np.ndarray | None = None) -> None:
        """Bond ``p`` leaves the set with the fixed force ``force`` (residual); ``col``: its
        column of the inverse, when at hand."""
        inv = self.inv
        if not inv.remove(p, column=col, held={"psi": -force}):  # psi_r + F moves to the rhs
            raise NumericalError("slip-weakening: a singular update of the inverse")
        if inv.pivot < 0:
            self.neg -= 1
        self.fR[p] = force
        self.dshift[p] = 0.0
        self.bvec[p] = 0.0
        self.phase[p] = RESIDUAL
        self.lam_cur[p] = self.lam_d

    def _shift(self, p: int, delta: float, col: np.ndarray | None = None) -> np.ndarray:
        new = self.inv.shift(p, delta, column=col)
        if new is None:
            raise NumericalError("slip-weakening: a singular update of the inverse")
        if self.inv.pivot < 0:
            self.neg += 1 if delta < 0 else -1
        self.dshift[p] += delta
        return new

    def apply(self, kind: str, j: int, D: float = 0.0) -> None:
        """Apply the event ``kind`` of the bond at site ``j`` at ``D``: a stick bond that
        fails starts to weaken (or, at its residual strength, to slip) if the state stays
        stable, else it sets off a burst (:meth:`_burst`); a weakening bond reaches its
        residual strength; a slipping bond sticks again."""
        self._rate = None
        if not self._transient:  # a state of the stable path: it counts for the peak
            self.best = max(self.best, self.totals(D)[0])
        self._transient = False
        p = int(self.position[j])
        inv = self.inv
        self.discontinuous = False
        self.failed_inside = []
        if kind in (EventKind.SLIP_PLUS, EventKind.SLIP_MINUS):
            s = float(self.law.failed_direction(kind)[X])
            weakening = bool(np.any(self.phase == WEAK))
            col = self._column(p) if self.k[p] > 0 or weakening or not self.exact else None
            d = float(col[inv.row[p]]) if col is not None else math.inf
            if self.lam_cur[p] > self.lam_d:
                # stable iff (M^-1)_pp > k_p: stick -> weakening from the slip and strength
                # it has, on the line f + k s = c with c = s lam f_z + k s0 (b = c / k)
                if d > self.k[p] * (1 + TIE):
                    self.sigma[p] = self.law.failed_direction(kind)
                    col = self._shift(p, -1.0 / self.k[p], col)
                    self.phase[p] = WEAK
                    self._set_b(p, s * self.fz[p] * self.lam_cur[p] / self.k[p] + self.s0[p],
                                col)
                else:
                    self._burst(D, p, s)
            elif not weakening or d > 0:  # at its residual strength, and the rest stays stable
                self.sigma[p] = self.law.failed_direction(kind)
                self.delta[p] = max(self.delta[p], self.dc)
                self._leave(p, s * self.lam_d * self.fz[p], col)
            else:
                self._burst(D, p, s)
        elif kind == EventKind.RESIDUAL:
            s = self.sigma[p, X]
            self.delta[p] += s * (self._slip(p, D) - self.s0[p])
            self._leave(p, s * self.lam_d * self.fz[p], None if self.exact else self._column(p))
        elif kind == EventKind.STICK:
            s = self.sigma[p, X]
            slip = self._slip(p, D)
            if self.phase[p] == WEAK:
                f = float(self.forces(D)[p])
                self.delta[p] += s * (slip - self.s0[p])
                self.lam_cur[p] = s * f / self.fz[p]
                col = self._shift(p, 1.0 / self.k[p], None if self.exact else self._column(p))
                self.phase[p] = STICK
                self._set_b(p, slip, col)
            else:
                self._restick_residual(p, slip)
            self.s0[p] = slip
            self.sigma[p] = 0.0
        else:
            raise NumericalError(f"slip-weakening: no event {kind!r} (internal error)")
        self._fold()
        self._stop_early(D)

    # -- bursts ----------------------------------------------------------------------------
    def _relaxation(self) -> Relaxation:
        """The fast-time flow of a burst, on :math:`K = G_{xx}^{-1}` over all bonds (made at
        the first burst): dense when it and the inverse of B on the moving bonds, at most as
        large (:mod:`~roughslip.friction.least`), fit in memory and the stick solver is
        exact, else compressed and certified against the FFT operator
        (:func:`~roughslip.friction.response.burst_response`)."""
        if self._relax is None:
            response = burst_response(self.b, self.opt.tol, self.opt.threads,
                                      compressed=not self.exact)
            self._relax = Relaxation(response, self.fz, self.lam_s, self.lam_d, self.dc)
        return self._relax

    def _burst(self, D: float, p: int, s: float) -> None:
        r"""Bond ``p`` fails in the direction ``s`` at ``D`` and the state cannot stay stable:
        the burst relaxes at the held drive as the limit of an overdamped slip rate (module
        docstring) and the state it lands in replaces this one (:meth:`_land`)."""
        relax = self._relaxation()
        b = self.b
        f = self.forces(D)
        # slips, w = D - u (stick bonds: as they are)
        u = b.apply(b.field(f), np.empty(b.shape)).ravel()[b.sites]
        stick = self.phase == STICK
        w = np.where(stick, self.s0, D - u)
        delta = self.delta.copy()
        W = self.phase == WEAK
        delta[W] += self.sigma[W, X] * (w[W] - self.s0[W])
        R = self.phase == RESIDUAL  # at d_c, not a rounding below it
        delta[R] = np.maximum(delta[R], self.dc)
        moving = ~stick
        sigma = self.sigma[:, X].copy()
        moving[p], sigma[p] = True, s
        best = self.best if self.opt.early_stop else None
        land = least.land(relax, f, w, delta, sigma, moving, p, best=best, carry=self._carry)
        if land is None:  # not on monotone steps: the flow itself, from the slip rates
            phi, _, ids, live = self._rows()  # dw/dD = 1 - G df/dD
            dfdD = np.zeros(b.n)
            dfdD[ids[live]] = phi[live]
            du = b.apply(b.field(dfdD), np.empty(b.shape)).ravel()[b.sites]
            rate = np.where(stick, 0.0, 1.0 - du)
            rate[p] = 0.0
            land = relax.run(f, w, delta, sigma, moving, rate, limit=20 * b.n + 100, best=best)
        if land.stopped:  # no state after this point can exceed the best: stop here
            self.stopped = True
            return
        if land.peak > self.inside[0]:
            self.inside = (land.peak, D)
        self._land(land)

    def _land(self, land: Landing) -> None:
        """Take the state a burst lands in: moving bonds weaken (below d_c) or are residual,
        the others stick where they are, with the strength they reached. The inverse follows
        the bonds whose phase changed (:meth:`_rephase`)."""
        mv = land.moving
        weak = mv & (land.delta < self.dc)
        res = mv & ~weak
        stick = ~mv
        old = self.phase.copy()
        self.snaps += int(np.count_nonzero(res & (old != RESIDUAL)))
        self.phase[:] = STICK
        self.phase[weak], self.phase[res] = WEAK, RESIDUAL
        self.sigma[:] = 0.0
        self.sigma[mv, X] = land.sigma[mv]
        self.delta[:] = np.where(res, np.maximum(land.delta, self.dc), land.delta)
        self.lam_cur[:] = self._relax.strength(self.delta)
        self.s0[:] = land.w
        k = np.where(weak, self.k, 1.0)
        self.bvec[:] = np.where(stick, land.w, 0.0)
        self.bvec[weak] = (land.sigma * self.fz * self.lam_cur / k + land.w)[weak]
        self.fR[:] = np.where(res, land.sigma * self.lam_d * self.fz, 0.0)
        self._rephase(old, weak, res)
        self.discontinuous = True
        self.failed_inside = [(EventKind.slip(s), int(self.b.sites[i]), F)
                              for i, s, F in land.failures]
        self._retrack()

    def _rephase(self, old: np.ndarray, weak: np.ndarray, res: np.ndarray) -> None:
        r"""The inverse of :math:`M` after a landing: updated bond by bond (a shift of the
        diagonal for a bond that starts or stops weakening, a removal for one that becomes
        residual, a bordering for one that stops being residual) when few bonds changed, else
        factorised afresh. The landing is stable, so :math:`M` must have one negative
        eigenvalue per weakening bond: the updates' pivots must say so."""
        shift = np.where(weak, -1.0 / np.where(weak, self.k, 1.0), 0.0)
        changed = np.flatnonzero(self.phase != old)
        inv = self.inv
        # a compressed set that a bond joins is compressed afresh: factorise it once
        joins = not self.exact and bool(np.any(old[changed] == RESIDUAL))
        if changed.size <= max(8, int(inv.live.sum()) // 8) and not joins:
            for p in changed:
                a, b = old[p], self.phase[p]
                col = None if self.exact or a == RESIDUAL else self._column(p)
                if b == RESIDUAL:
                    if not inv.remove(p, column=col):
                        break
                    self.neg -= inv.pivot < 0
                elif a == RESIDUAL:
                    self.dshift[p] = shift[p]
                    if not inv.add(np.array([p])):
                        break
                    self.neg = self._joined_neg()
                else:
                    delta = shift[p] - self.dshift[p]
                    if inv.shift(p, delta, column=col) is None:
                        break
                    if inv.pivot < 0:
                        self.neg += 1 if delta < 0 else -1
                self.dshift[p] = shift[p]
            else:
                if self.stable():
                    return
        self.dshift[:] = shift
        if not self.exact:  # the dense guard counted a burst's inverse beside this one
            self._carry.inv = None
        if not inv.factor(np.flatnonzero(~res), positive=False):
            raise MemoryLimitError("slip-weakening: out of memory for the inverse after a "
                                   "burst")
        # the landing is stable; a compressed inverse counts it from its factorisation
        self.neg = int(np.count_nonzero(weak)) if self.exact else inv.negatives

    def _joined_neg(self) -> int:
        """The negative eigenvalues of :math:`M` after a bond joined the set: one more if its
        Schur complement (the pivot) is negative; a compressed inverse, which compresses the
        new set afresh, counts them from its factorisation."""
        return self.neg + (self.inv.pivot < 0) if self.exact else self.inv.negatives

    def _slip(self, p: int, D: float) -> float:
        """The slip :math:`s = D - u` of bond ``p`` at ``D``."""
        if self.phase[p] == WEAK:  # f + k s = c = k b
            return float(self.bvec[p] - self.forces(D)[p] / self.k[p])
        if self.phase[p] == STICK:
            return float(self.s0[p])
        f = self.b.field(self.forces(D))
        u = self.b.apply(f, np.empty(self.b.shape)).ravel()[self.b.sites[p]]
        return float(D - u)

    def _restick_residual(self, p: int, slip: float) -> None:
        """A residual bond sticks again: it joins the set (the inverse is bordered) and the
        solutions are recomputed on the new right-hand side."""
        inv = self.inv
        self.fR[p] = 0.0
        self.phase[p] = STICK
        self.bvec[p] = slip
        done = inv.add(np.array([p]))
        if not done:
            raise NumericalError("slip-weakening: a singular update of the inverse"
                                 if done is False else "slip-weakening: out of memory")
        self.neg = self._joined_neg()
        self._retrack()

    def result(self, path: EventPath, t0: float) -> PullResult:
        """The pull's result: ``friction_force`` is the largest force of the stable path and
        the landings (module docstring). The message says when the force inside a burst's
        relaxation rose above it (a transient at the held drive, not an equilibrium)."""
        b, opt = self.b, self.opt
        curve = Curve.of(path.events)
        peak = path.peak
        n_jumps = curve.kind.count(EventKind.JUMP)
        resp = self._relax.response if self._relax is not None else NO_BURSTS
        end = "stopped once no later state could exceed the peak" if self.stopped else \
            "exact event path to full sliding"
        note = (f"; inside a burst at D_x = {self.inside[1]:.6g} the force rose to "
                f"{self.inside[0]:.6g}, above the friction force (a relaxation, not an "
                "equilibrium)") if self.inside[0] > peak.fx_total + TIE * abs(peak.fx_total) \
            else ""
        return decoupled_result(
            b, friction_force=max(peak.fx_total, 0.0), curve=curve, peak_event=path.peak_event,
            peak_fx=peak.fx, peak_stick=peak.stick, t0=t0, method=opt.method_name,
            slip_law=opt.slip_law, converged=bool(self.ok) and not path.message,
            residual=max(self.worst, resp.worst), solves=self.refinements,
            early_stopped=self.stopped,
            message=path.message or (f"{end}, {n_jumps} burst(s), {self.snaps} bond(s) "
                                     f"reached their residual strength inside one{note}"
                                     f"{resp.describe()}{self._refined()}"))

    def _refined(self) -> str:
        """What the message adds on an inexact inverse ("" on a dense one)."""
        if self.exact:
            return ""
        return (f"; on the {self.inv.kind} inverse every solution and column decided on was "
                f"refined against the FFT operator ({self.refinements} corrections, relative "
                f"residuals within {self.worst:.1e})")


#: how the weakening state is followed: every burst's landing is recorded, and the states
#: inside a burst do not count for the peak
BURSTS = FollowEvents(landings=True, avalanche_peaks=False)


def weaken(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    r"""The decoupled pull under slip-weakening friction to full sliding, on the event loop
    (:func:`~roughslip.friction.events.follow_events`): the exact piecewise-linear path, its
    bursts at constant drive, and the state each lands in (module docstring;
    :meth:`WeakeningState.result`)."""
    return WeakeningState(b, opt).run(BURSTS, t0)
