r"""The Coulomb law's exact event path on an inexact inverse, with certified decisions: a
single-precision one (``pull(..., slip_law="coulomb", precision="single")``) or a compressed
one (``method="hierarchical"``); docs/theory/pull.rst#certified-slip-events.

The state is the decoupled pull's (:class:`~roughslip.friction.sliding.TangentialState`):
stick forces :math:`f_S = D\varphi - \psi` with :math:`G_{SS}\varphi = 1_S` and
:math:`G_{SS}\psi = G_{SL}f_L - o_S`, both tracked through the removals on the stored inverse.
Here neither is exact between certifications. With :math:`r_\varphi` and :math:`r_\psi` their
residuals against the FFT operator, every entry obeys (as for the break law,
:mod:`roughslip.friction.breaking_single`)

.. math:: |\tilde\varphi_i - \varphi_i| \le \sqrt{\nu d_i}\,\|r_\varphi\|_2 = e_{\varphi,i},
          \qquad |\tilde\psi_i - \psi_i| \le \sqrt{\nu d_i}\,\|r_\psi\|_2 = e_{\psi,i},

and both residual norms are bounded between certifications by the measured residual plus
:math:`\hat\gamma\sum|\alpha|\,\|\tilde c\|` over the removals, :math:`\alpha = \tilde\varphi_k
/ \tilde c_k` for :math:`\varphi` and :math:`(\tilde\psi_k + f_{L,k})/\tilde c_k` for
:math:`\psi` (the removed bond's force moves to the right-hand side), with
:math:`\hat\gamma` the break law's bound on a column's residual ratio
:math:`\|e_k - G\tilde c\|/\|\tilde c\|` (at least a compressed inverse's :math:`\delta`;
sampled, with a safety factor). Unlike the break law's path, which learns how far the
removals' errors cancel, this one assumes no cancellation: a first residual above its bound
is counted in the message. A bond that sticks
again takes the :math:`u_x` of the tracked forces as its offset, within
:math:`\|Ge_j\|_2\,\nu(|D|\,\|r_\varphi\| + \|r_\psi\|)` of the exact path's; that
error is added to :math:`\|r_\psi\|` from then on (:attr:`CertifiedSlide.offset_error`).

Each decision of the event loop (:func:`~roughslip.friction.events.follow_events`) is made on
the tracked values and kept only when every value inside these bounds makes the same one:

* the next event (:meth:`CertifiedSlide.interval`): a stick row's constraint
  :math:`a + bD \ge 0` has :math:`a = \lambda f_z \pm \psi` and :math:`b = \mp\varphi`, so its
  root lies in the interval that interval division gives, and the first root must stay
  below every other row's lower bound by more than the tie tolerance, fall for every value
  (not flat), and stay on one side of :math:`D \pm` the tie tolerance with :math:`\Delta D`
  added; the lower end of the admissible interval must stay at or below :math:`D -
  \Delta D` and the event;
* an overloaded bond (:meth:`CertifiedSlide.violation`): its overload
  :math:`|D\varphi_i - \psi_i|/(\lambda f_{z,i})` within :math:`(|D| e_{\varphi,i} +
  e_{\psi,i} + |\varphi_i|\,\Delta D)/(\lambda f_{z,i})` of it, :math:`\Delta D` the error
  of the drive;
* a slip that turns back (:meth:`CertifiedSlide.reversal`): the slipping bonds' rates
  :math:`G_{LS}\tilde\varphi` are within :math:`\|G e_j\|_2\,\nu\|r_\varphi\|_2` of the exact
  ones, :math:`\|G e_j\|_2 \le 2\|G e_0\|_2` for the corner column :math:`e_0` (the kernel is
  even in x and in y).

The drive's error :math:`\Delta D` is that of the root the loop's drive came from
(:meth:`CertifiedSlide.apply`).

When the next event is left open, the rows that can change it, at most
``MAX_SHARPEN`` (32), are sharpened
(:meth:`CertifiedSlide._sharpen`: one residual per solution, and a column of the inverse per
row) and the decision is asked again. When a decision is still open,
:math:`\tilde\varphi` and :math:`\tilde\psi` are refined against the FFT operator and the
decision is made on the refined values, as the double-precision path makes it. The friction
force under this law is the slipping forces' sum at full sliding, exact once the events are;
the other points of the curve carry the bound, reported in the message.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from roughslip.errors import InputError
from roughslip.friction.bonds import Bonds, PullOptions, stick_residual, tracked_rhs
from roughslip.friction.breaking_single import CERT_FRACTION, MAX_SHARPEN, _Bound
from roughslip.friction.events import (
    RATE_TIE,
    TIE,
    X_DRIVE,
    EventKind,
    EventPath,
    X,
    event_table,
)
from roughslip.friction.result import PullResult
from roughslip.friction.sliding import FollowEvents, TangentialState, slide

#: refinements of a tracked solution at a certification or an open decision
REFINEMENTS = 4
#: no interval's event pending (:meth:`CertifiedSlide.apply`)
_NO_EVENT = (math.nan, 0.0, False, "", -1, math.nan)


def _quotient(n_lo: np.ndarray, n_hi: np.ndarray, d_lo: np.ndarray, d_hi: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """The range of ``n / d`` for ``n`` in ``[n_lo, n_hi]`` and ``d`` in ``[d_lo, d_hi]``,
    ``0 <= d_lo <= d_hi`` (interval division; a denominator that may vanish leaves the range
    unbounded on the numerator's side)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        least = np.where(n_lo >= 0, n_lo / d_hi, np.where(d_lo > 0, n_lo / d_lo, -math.inf))
        most = np.where(n_hi <= 0, n_hi / d_hi, np.where(d_lo > 0, n_hi / d_lo, math.inf))
    least[np.isnan(least)] = -math.inf  # 0/0, inf/inf: unbounded
    most[np.isnan(most)] = math.inf
    return least, most


def _meet(x: np.ndarray, e: np.ndarray, y: np.ndarray, f: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, bool]:
    """The centre and half-width of the intersection of ``[x - e, x + e]`` and ``[y - f, y +
    f]``, and whether they meet everywhere; where they do not (which correct bounds rule
    out), the second interval."""
    lo, hi = np.maximum(x - e, y - f), np.minimum(x + e, y + f)
    empty = lo > hi
    return (np.where(empty, y, 0.5 * (lo + hi)), np.where(empty, f, 0.5 * (hi - lo)),
            not bool(empty.any()))


class CertifiedSlide(TangentialState):
    """The decoupled pull's state on an inexact inverse, whose every decision is certified
    (module docstring)."""

    def __init__(self, b: Bonds, opt: PullOptions) -> None:
        super().__init__(b, opt)
        self.track_slip()
        self.bound = _Bound(b, self.inv, opt.tol)
        self.R_psi, self.A_psi = 0.0, 0.0  # psi's measured residual and its removals' count
        #: the offsets' error: a bond that sticks again holds the u_x of the tracked forces
        self.offset_error = 0.0
        corner = np.zeros(b.shape)
        corner[0, 0] = 1.0
        #: a bound on the 2-norm of any column of G_xx on the grid
        self.column_norm = 2.0 * float(np.linalg.norm(b.apply(corner, np.empty(b.shape))))
        #: decisions made
        self.decisions = 0
        #: decisions the bounds left open (refined against the FFT operator)
        self.opened = 0
        #: first residuals of a refinement above their bound
        self.exceeded = 0
        #: the largest bound on a curve point's relative error so far
        self.curve_error = 0.0
        self._dD = 0.0  # the bound on the error of the last event's drive
        #: the last interval's event: its root, the root's error, and whether it lies beyond
        #: the drive for every value within the bounds
        self._event: tuple[float, float, bool, str, int, float] = _NO_EVENT
        #: |du_x/dD - 1| (with its error) of the bond that sticks again, for its offset's error
        self._stick_rate = math.nan
        #: open decisions sharpened (:meth:`_sharpen`), whether or not that settled them
        self.sharpened = 0
        #: a bound on the error of the drive the event loop sits at (:meth:`apply`)
        self._drive_error = 0.0
        self._fresh = False
        self.recertify()

    # -- the bounds -----------------------------------------------------------------------------
    def _phi_bound(self) -> float:
        r"""The bound on the norm of phi's residual: the last measured one plus
        :math:`\hat\gamma\sum|\alpha|\,\|\tilde c\|` over the removals since
        (:math:`\hat\gamma` bounds each column's residual ratio, so no cancellation between
        the removals' errors is assumed)."""
        return self.bound.R + self.bound.gamma_hat * self.bound.A

    def _psi_own(self) -> float:
        """The bound on the norm of psi's residual against its own right-hand side."""
        return self.R_psi + self.bound.gamma_hat * self.A_psi

    def _psi_bound(self) -> float:
        """... and against the exact path's, whose offsets differ by ``offset_error``."""
        return self._psi_own() + self.offset_error

    def _errors(self) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`e_\varphi` and :math:`e_\psi` on the rows now (module docstring)."""
        s = np.sqrt(self.bound.nu * self.bound.d)
        return s * self._phi_bound(), s * self._psi_bound()

    def _leaving(self, row: int, carried: float) -> np.ndarray:
        inv = self.inv
        c = inv.column(row)
        t = inv.tracked
        self.bound.removed(float(t["phi"].x[row] / c[row]), c)
        self.A_psi += abs(float((t["psi"].x[row] + carried) / c[row])) * float(
            np.linalg.norm(c[inv.live]))
        return c

    def _psi_residual(self, first: list[float]):
        """``residual(x)`` of psi's equation on the rows by the FFT operator (relative to the
        right-hand side's norm), and that norm."""
        b, inv = self.b, self.inv
        live = inv.live
        pos = inv.ids[live]
        rhs = tracked_rhs(b, pos, self._load(), self.offset)

        def residual(x: np.ndarray) -> tuple[np.ndarray, float]:
            r, res = stick_residual(b, pos, x[live], rhs)
            full = np.zeros(inv.m)
            full[live] = r
            if not first:
                first.append(res)
            return full, res

        return residual, max(float(np.linalg.norm(rhs)), 1e-300)

    def _refine(self, fold: bool) -> None:
        """Refine both tracked solutions against the FFT operator, count a first residual
        above its bound, and restart the bounds from the refined residuals; after a fold also
        take the inverse's diagonal afresh and sample two of its columns (the column ratio,
        :class:`_Bound`)."""
        bd, inv, tol = self.bound, self.inv, self.opt.tol
        steps = (("phi", bd._residual_on_rows, self._phi_bound(), bd.A),
                 ("psi", self._psi_residual, self._psi_own(), self.A_psi))
        for name, make, expected, count in steps:
            first: list[float] = []
            made = make(first)
            residual, scale = made if name == "psi" else (made, bd._rhs_norm())
            t = inv.tracked[name]
            t.x, res, n = inv.refine(t.x, residual, CERT_FRACTION * tol, REFINEMENTS)
            if count > 0 and first[0] * scale > (1 + 1e-6) * expected:
                self.exceeded += 1
            if name == "phi":
                bd.R, bd.A = res * scale, 0.0
            else:
                self.R_psi, self.A_psi = res * scale, 0.0
            self.refinements += n
            self.worst = max(self.worst, res)
        if fold:
            bd.refresh_and_sample(self.rows.cap)
        self.ok = self.worst <= tol
        self._rate = None

    def recertify(self) -> None:
        """After a fold: both tracked solutions certified, the bounds restarted."""
        if self._fresh:  # a bond stuck again: the inverse was factorised on a larger set
            self.bound = _Bound(self.b, self.inv, self.opt.tol)
            self._fresh = False
        self._refine(fold=True)

    def _stick_again(self, pos: int, j: int, D: float) -> None:
        # its offset is u_x of the tracked forces, within ||G e_j|| ||f~ - f|| of the exact
        self.offset_error += self.column_norm * self.bound.nu * (
            abs(D) * self._phi_bound() + self._psi_bound()) + self._stick_rate * (
            self._drive_error)
        self._fresh = True
        self.R_psi = self.A_psi = 0.0
        super()._stick_again(pos, j, D)

    def apply(self, kind: str, j: int, D: float = 0.0) -> None:
        r"""An event, applied as the tangential state applies it, and the bound on the error
        of the drive the loop goes on from (:attr:`_drive_error`). The loop's next drive is
        :math:`\max(D, h)` for an event at :math:`h`, whose error is at most the larger of
        the two errors; when :math:`h > D` for every value within the bounds it is :math:`h`
        alone, with the root's error. An avalanche's state (applied at its root below the
        drive), an overload and a stick hold the drive, and its error. A bond that sticks again
        takes its offset :math:`u_x - D` at a drive within that error of the exact path's,
        which moves it by :math:`|\dot u_x - 1|` times the error (:meth:`_stick_again`)."""
        hi, dD, beyond, e_kind, e_site, at = self._event
        if kind == EventKind.STICK:
            self._stick_rate = abs(float(self.rates()[j]) - float(X_DRIVE[X])) + (
                self.column_norm * self.bound.nu * self._phi_bound())
        # the interval's event, moving the loop's drive (not held: an avalanche's state, an
        # overload or a stick)
        if (kind, j) == (e_kind, e_site) and D >= at:
            self._drive_error = dD if beyond and D == hi else max(self._drive_error, dD)
        self._event = _NO_EVENT
        super().apply(kind, j, D)

    def _open(self) -> None:
        """A decision the bounds leave open: refine, then decide on the refined values."""
        self.opened += 1
        self._refine(fold=False)

    # -- the decisions --------------------------------------------------------------------------
    def interval(self, D: float) -> tuple[float, float, str, int]:
        """The admissible interval and the event ending it
        (:meth:`~roughslip.friction.sliding.TangentialState.interval`), certified: when the
        bounds leave the event or the interval's lower end open, sharpened on the rows that
        can change it (:meth:`_sharpen`; at most
        ``MAX_SHARPEN`` (32) of them), and refined
        when still open."""
        self.decisions += 1
        lo, hi, kind, row, sure, cand = self._interval(D, check=True)
        if not sure and cand is not None and cand.size <= MAX_SHARPEN:
            sharp = self._sharpen(cand)
            lo, hi, kind, row, sure, _ = self._interval(D, check=True, sharp=sharp)
        if not sure:
            self._open()
            lo, hi, kind, row, _, _ = self._interval(D, check=False)
        return lo, hi, kind, (self._site(row) if row >= 0 else -1)

    def _sharpen(self, rows: np.ndarray) -> tuple[np.ndarray, ...]:
        r"""phi and psi on ``rows``, sharpened by one residual each against the FFT operator,
        with their bounds: :math:`\varphi_i \approx \tilde\varphi_i + \tilde c_i^T r_\varphi`
        within :math:`\nu\hat\gamma\|\tilde c_i\|\,\|r_\varphi\|` (the error of the
        column :math:`\tilde c_i`, :meth:`_Bound._sharpen
        <roughslip.friction.breaking_single._Bound._sharpen>`), and psi alike, with the
        offsets' error added. The measured residuals also restart both running bounds."""
        self.sharpened += 1
        bd, inv = self.bound, self.inv
        live = inv.live
        residuals = []
        for name, make, expected, count in (
                ("phi", bd._residual_on_rows, self._phi_bound(), bd.A),
                ("psi", self._psi_residual, self._psi_own(), self.A_psi)):
            made = make([])
            residual, scale = made if name == "psi" else (made, bd._rhs_norm())
            x = inv.tracked[name].x
            r, res = residual(x)
            slack = bd.rounding(float(np.linalg.norm(x[live])), scale)
            rn = res * scale + slack
            if count > 0 and rn > (1 + 1e-6) * expected:
                self.exceeded += 1
            residuals.append((r, rn, slack))
        (r_phi, n_phi, s_phi), (r_psi, n_psi, s_psi) = residuals
        bd.R, bd.A = n_phi, 0.0
        self.R_psi, self.A_psi = n_psi, 0.0
        phi, psi = inv.tracked["phi"].x, inv.tracked["psi"].x
        out = np.empty((4, rows.size))
        eps = 4 * np.finfo(float).eps
        for k, i in enumerate(rows):
            c = inv.column(int(i))
            c[~live] = 0.0
            reach = bd.nu * bd.gamma_hat * float(np.linalg.norm(c))  # the column's error
            out[0, k] = phi[i] + float(c @ r_phi)
            out[1, k] = psi[i] + float(c @ r_psi)
            norm = float(np.linalg.norm(c))
            out[2, k] = reach * n_phi + norm * s_phi + eps * abs(phi[i])
            out[3, k] = (reach * n_psi + norm * s_psi + eps * abs(psi[i])
                         + math.sqrt(bd.nu * bd.d[i]) * self.offset_error)
        return (rows, *out)

    def _interval(self, D: float, check: bool, sharp: tuple[np.ndarray, ...] | None = None
                  ) -> tuple[float, float, str, int, bool, np.ndarray | None]:
        """The base state's interval on the tracked values (on ``sharp``'s values on its rows,
        :meth:`_sharpen`), the row of its event, whether every value within the bounds gives
        the same decision (module docstring), and the rows that may change it (None: any)."""
        phi, psi, fz, live = self._rows()
        e_phi, e_psi = self._errors()
        if sharp is not None:
            rows, s_phi, s_psi, s_ephi, s_epsi = sharp
            phi, psi = phi.copy(), psi.copy()
            phi[rows], e_phi[rows], met_phi = _meet(phi[rows], e_phi[rows], s_phi, s_ephi)
            psi[rows], e_psi[rows], met_psi = _meet(psi[rows], e_psi[rows], s_psi, s_epsi)
            self.exceeded += (not met_phi) + (not met_psi)  # a bound that failed
        scale = self.progress.scale
        Dref = max(scale, abs(D))
        fs = max(float(np.abs(fz).max()), np.finfo(float).tiny)
        zero = np.zeros(phi.shape)
        cons = self.law.stick_rows(self.b.lam, live, (fz, -psi), (zero, phi), fs)
        lo, hi, kind, row = event_table(cons, D, Dref, scale)
        tol_d = TIE * max(scale, abs(D))
        fall_lo = np.full(phi.shape, math.inf)  # the least root a falling row can have
        rise_hi = np.full(phi.shape, -math.inf)  # the largest root a rising row can have
        own_lo, own_hi, flat, nowhere = -math.inf, math.inf, True, False
        for name, mask, a, b_, sc in cons:
            ea, eb = e_psi, e_phi
            m = mask & np.isfinite(a)
            tiny = TIE * sc
            # a row that may be flat and violated makes the state admissible nowhere
            if np.any(m & (np.abs(b_) * Dref <= tiny + eb * Dref) & (a - ea < -tiny)):
                nowhere = True
            with np.errstate(divide="ignore", invalid="ignore"):
                # falling (b < 0): root a / |b|, |b| in [max(-b - eb, 0), -b + eb]
                least, _ = _quotient(a - ea, a + ea, np.maximum(-b_ - eb, 0.0), -b_ + eb)
                fall_lo = np.where(m & (b_ < eb), np.minimum(fall_lo, least), fall_lo)
                # rising (b > 0): root -a / b, b in [max(b - eb, 0), b + eb]
                _, most = _quotient(-a - ea, -a + ea, np.maximum(b_ - eb, 0.0), b_ + eb)
                rise_hi = np.where(m & (b_ > -eb), np.maximum(rise_hi, most), rise_hi)
            if name == kind and row >= 0:
                lo_r, hi_r = _quotient(a[row:row + 1] - ea[row], a[row:row + 1] + ea[row],
                                       np.maximum(-b_[row:row + 1] - eb[row], 0.0),
                                       -b_[row:row + 1] + eb[row])
                own_lo, own_hi = float(lo_r[0]), float(hi_r[0])
                # the row must fall for every value within the bounds, and not be flat
                flat = bool((-b_[row] - eb[row]) * Dref <= tiny)
        self._dD = max(own_hi - hi, hi - own_lo) if row >= 0 else 0.0
        # the event loop compares hi - D with -tol_d and tol_d: neither may lie in its range
        gap_lo, gap_hi = own_lo - D - self._drive_error, own_hi - D + self._drive_error
        # an event beyond D + tol_d for every value: the loop's next drive is its root alone
        self._event = (hi, self._dD, row >= 0 and gap_lo > 0, kind,
                       self._site(row) if row >= 0 else -1, D)
        if not check:  # decided on refined values
            return lo, hi, kind, row, True, None
        if nowhere:
            return lo, hi, kind, row, False, None
        lo_hi = float(rise_hi.max(initial=-math.inf))
        Dlo = D - self._drive_error  # the exact path's drive is within this of D
        if row < 0:  # no falling row: none may be one
            sure = bool(not (fall_lo < math.inf).any() and lo_hi <= Dlo + tol_d)
            return lo, hi, kind, row, sure, np.flatnonzero((fall_lo < math.inf)
                                                           | (rise_hi > Dlo + tol_d))
        others = fall_lo.copy()
        others[row] = math.inf
        tie = 2 * TIE * max(abs(own_hi), scale)
        sure = (not flat and math.isfinite(own_hi) and float(others.min()) > own_hi + tie
                and lo_hi <= min(Dlo, own_lo) + tol_d
                and not any(gap_lo <= t <= gap_hi for t in (-tol_d, tol_d)))
        cand = (fall_lo <= own_hi + tie) | (rise_hi > min(Dlo, own_lo) + tol_d)
        cand[row] = True
        return lo, hi, kind, row, sure, np.flatnonzero(cand)

    def violation(self, D: float) -> tuple[str, int] | None:
        """The overloaded bond, certified: refined first unless the bounds leave no row
        or exactly one row beyond its strength."""
        phi, psi, fz, live = self._rows()
        e_phi, e_psi = self._errors()
        over = self.law.overload(self.b.lam, live, fz, D * phi - psi)
        err = np.zeros(phi.shape)
        # the exact path's drive is within _drive_error of D
        np.divide(abs(D) * e_phi + e_psi + np.abs(phi) * self._drive_error, self.b.lam * fz,
                  out=err, where=live & (fz > 0))
        self.decisions += 1
        high, low = over + err > 1 + TIE, over - err > 1 + TIE
        if high.any() and not (int(high.sum()) == 1 and int(low.sum()) == 1):
            self._open()
        return super().violation(D)

    def reversal(self) -> int | None:
        """The slipping bond that sticks again, certified against the rates' bound:
        refined first when it leaves the answer open."""
        slipping = self.sigma.any(axis=-1)
        if not (self.law.reverses and slipping.any()):
            return None
        fresh = self._rate is None
        j = super().reversal()
        if not fresh:
            return j
        self.decisions += 1
        err = self.column_norm * self.bound.nu * self._phi_bound()
        back = np.where(slipping, (self.sigma * (self._rate[self.b.sites, None] - X_DRIVE))
                        .sum(axis=-1), -math.inf)
        if j is None:
            sure = float(back.max()) + err <= RATE_TIE
        else:
            k = int(self.position[j])
            top = float(back[k])
            rest = back.copy()
            rest[k] = -math.inf
            sure = (top - err > RATE_TIE and float(rest.max(initial=-math.inf)) + err
                    < top - err - 2 * TIE * max(1.0, top))
        if sure:
            return j
        self._open()
        return super().reversal()

    # -- the curve and the result ---------------------------------------------------------------
    def totals(self, D: float) -> tuple[float, float]:
        """F_x and F_z at ``D``, summed over the live rows (a compressed inverse leaves its
        removed rows' entries at its own error, not zero); the bound on F_x's error joins
        :attr:`curve_error`."""
        phi, psi, _, live = self._rows()
        F_x = D * float(phi[live].sum()) - float(psi[live].sum()) + self.slip_sum
        F_z = self.fz_total
        m = int(live.sum())
        err = (math.sqrt(m) * self.bound.nu * (abs(D) * self._phi_bound()
                                               + self._psi_bound())
               + abs(float(phi[live].sum())) * max(self._dD, self._drive_error))
        self.curve_error = max(self.curve_error, err / max(abs(F_x), 1e-300))
        return F_x, F_z

    def result(self, path: EventPath, t0: float) -> PullResult:
        """The pull's result, its message with the certification's counts and the curve's
        bound."""
        res = super().result(path, t0)
        what = ("single precision" if self.opt.precision == "single"
                else f"{self.inv.kind} inverse")
        msg = (f"{res.message}; {self.b.n} bonds, {what}: {self.refinements} refinements, "
               f"{self.sharpened} of {self.decisions} decisions sharpened, "
               f"{self.opened} refined in full, bound exceeded "
               f"{self.exceeded} times; curve points within {self.curve_error:.1e} relative, "
               "the friction force exact")
        return replace(res, message=msg, details=replace(res.details,
                                                         precision=self.opt.precision))


def slide_certified(b: Bonds, opt: PullOptions, t0: float) -> PullResult:
    r"""The decoupled pull by the event loop (:func:`~roughslip.friction.sliding.slide`); on an
    inexact inverse (``precision = "single"`` or a compressed one) with certified decisions
    (:class:`CertifiedSlide`, the x-only model)."""
    inexact = opt.precision == "single" or (opt.method is not None and opt.method.inexact)
    if not inexact:
        return slide(b, opt, t0)
    if b.k > 1:
        raise InputError("the Coulomb cone of the traction vector has no certified decisions: "
                         "it needs the dense inverse in double precision (method 'inverse', "
                         "precision 'double')")
    return CertifiedSlide(b, opt).run(FollowEvents(), t0)


__all__ = ["CertifiedSlide", "slide_certified"]
