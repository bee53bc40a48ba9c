r"""A burst of slip-weakening at a held drive, as the limit of an overdamped slip rate
(docs/theory/pull.rst#slip-weakening), integrated piece by piece: where the straight steps
of :mod:`~roughslip.friction.least` would take a slip back, and as their reference.

Give each bond the slip rate :math:`\dot w_i = \sigma_i \max(e_i, 0)/\eta` with the excess
:math:`e_i = \sigma_i f_i - \lambda(\delta_i) f_{z,i}` over its strength, :math:`\dot\delta_i =
|\dot w_i|`, and drive :math:`D = t`. Between bursts the limit :math:`\eta \to 0` is the
quasi-static path. A burst starts where that path folds: a failure the held drive cannot keep
stable. In the fast time :math:`\tau = (t - t^*)/\eta` the drive is held, and the bonds with a
positive excess, the moving set :math:`P`, follow a linear system on each piece,

.. math:: \frac{de_P}{d\tau} = -B\,e_P + \eta\,\Sigma (K1)_P, \qquad
          B = \Sigma K_{PP} \Sigma - \mathrm{diag}(\kappa_P f_{z,P}),

with :math:`K = G_{xx}^{-1}` over all bonds (every bond holds its displacement, so this is the
stiffness between moving bonds), :math:`\Sigma = \mathrm{diag}(\sigma_P)` and the softening
rate :math:`\kappa_i = (\lambda_s - \lambda_d)/d_c` while :math:`\delta_i < d_c`, else 0.
:math:`B` is symmetric, so :math:`e_P(\tau) = V e^{-\Lambda\tau} V^T e_P(0)` plus the
drive's term from its eigenpairs, and the slip :math:`\int e_P` and the forces of the other
bonds follow in closed form. A piece ends at the first event:

* *arrest*: a moving bond's excess falls to 0 (it sticks, keeping the strength it reached; a
  bond of zero residual strength carries nothing and never arrests);
* *residual*: a weakening bond's slip reaches :math:`d_c` (its :math:`\kappa` drops to 0);
* *join*: a stuck bond's force reaches its strength (it moves, in the direction of its force).

The burst ends when :math:`B` is positive definite and no event is left: the moving bonds then
relax to the quasi-static state at the drive, weakening (below :math:`d_c`) or residual, and
the state is stable (module :mod:`~roughslip.friction.weakening`).

The start is the limit's, not zero: at the fold every moving bond's excess is of order
:math:`\eta` (:math:`\eta` times its quasi-static slip rate, the failing bond's 0), and the
drive goes on at rate :math:`\eta` in fast time. Which bonds grow and which arrest is decided
in that regime (an eigen-complementarity problem in the limit), so it is integrated as it is,
at :math:`\eta = \epsilon \max f_z` with :data:`EPS`: the landing depends on :math:`\eta`
through terms of order :math:`\eta\log\eta`, far below the tolerance of every event.

Events are roots of sums of exponentials. Each is bracketed on a grid of the fast time whose
steps grow by :data:`GROWTH` from :math:`10^{-3}/\max|\mu|` (:math:`\mu` the eigenvalues of
:math:`B`) and refined by Brent's method to
:data:`XTOL` relative; two roots of one function closer than a step are not resolved (a
near-tangency of an excess, where the two landings differ by the excess at the tangency).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from roughslip.errors import NumericalError
from roughslip.friction.response import Response

#: the viscosity of the start, relative to the largest normal force (module docstring)
EPS = 1e-12
#: the growth of the bracketing grid's steps in the fast time
GROWTH = 1.1
#: the relative tolerance of an event's fast time
XTOL = 1e-13
#: the transients a landing leaves, relative to the start's excess (e^-40)
SETTLED = 40.0


@dataclass
class Landing:
    """Where a burst ends: per bond, its force (stuck bonds), slip, accumulated slip, direction
    and whether it moves (relaxes to the quasi-static state at the drive); the pieces it
    took."""

    f: np.ndarray
    w: np.ndarray
    delta: np.ndarray
    sigma: np.ndarray
    moving: np.ndarray
    pieces: int = 0
    #: the largest sum of the forces inside the burst
    peak: float = -math.inf
    #: it stopped before landing: no state after it can exceed ``best`` (:meth:`Relaxation.run`)
    stopped: bool = False
    #: the bonds that failed (joined) inside the burst, in order: (bond, direction, sum of the
    #: forces then)
    failures: list[tuple[int, float, float]] = field(default_factory=list)


class _Piece:
    """One piece of the flow: the moving set fixed, closed-form in the fast time."""

    def __init__(self, rx: Relaxation, st: Landing, e: np.ndarray) -> None:
        self.P, self.Q = np.flatnonzero(st.moving), np.flatnonzero(~st.moving)
        P, Q, fz, delta = self.P, self.Q, rx.fz, st.delta
        self.eta, self.K1Q = rx.eta, rx.K1[Q]
        #: zero strength: the bond carries nothing, never arrests and may slip back
        self.free = (rx.lam_d == 0) & (delta[P] >= rx.dc)
        self.kap = np.where(delta[P] < rx.dc, (rx.lam_s - rx.lam_d) / rx.dc, 0.0) * fz[P]
        self.s = s = st.sigma[P]
        rx.response.room(P.size, 8 * Q.size * P.size)  # B's eigenvectors and K_QP
        self.B = s[:, None] * rx.response.block(P, P) * s[None, :] - np.diag(self.kap)
        self.r = rx.eta * s * rx.K1[P]  # the drive, in fast time
        self.e0 = e[P]
        self.KQ = rx.response.block(Q, P) * s[None, :]
        self.fQ = st.f[Q]
        self.capQ = rx.strength(delta[Q]) * fz[Q]
        #: stuck bonds at their strength (one that arrested, say): their room is taken from
        #: the change of the force, not against the force itself (:meth:`_room`)
        self.atcap = self.capQ - np.abs(self.fQ) <= 0
        self.left = np.where(delta[P] < rx.dc, rx.dc - delta[P], np.inf)  # slip to d_c
        self.lam0 = rx.strength(delta[P]) * fz[P]

    def decompose(self) -> None:
        """The eigenpairs of B and the start and the drive in their basis."""
        self.mu, self.V = np.linalg.eigh(self.B)
        self.c0, self.g = self.V.T @ self.e0, self.V.T @ self.r

    def at(self, tau: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        r"""The excess of the moving bonds and their slip since the piece began (a row per
        time): :math:`e = V(c_0 E + g\Phi)`, :math:`\int e = V(c_0\Phi + g\Psi)` with
        :math:`E = e^{-\mu\tau}`, :math:`\Phi = (1 - E)/\mu`, :math:`\Psi = (\tau - \Phi)/\mu`
        (:math:`c_0 = V^T e(0)`, :math:`g = V^T r` the drive)."""
        mu = self.mu
        t = np.atleast_1d(np.asarray(tau, float))[:, None]
        x = mu[None, :] * t
        small = np.abs(x) < 1e-6
        safe = np.where(mu == 0, 1.0, mu)
        Phi = np.where(small, t * (1 - x / 2 + x * x / 6), -np.expm1(-x) / safe)
        Psi = np.where(small, t * t * (0.5 - x / 6 + x * x / 24), (t - Phi) / safe)
        E = np.exp(-x)
        return (self.c0 * E + self.g * Phi) @ self.V.T, (self.c0 * Phi + self.g * Psi) @ self.V.T

    def _room(self, df: np.ndarray, cols: np.ndarray) -> np.ndarray:
        r"""The room to their strength of stuck bonds ``cols`` (indices or a mask into
        :attr:`Q`) that start at it, after the change ``df`` of their forces:
        :math:`(c - |f_0|) - (2f_0\Delta f + \Delta f^2)/(|f_0 + \Delta f| + |f_0|)`, which
        is :math:`c - |f_0 + \Delta f|` without its cancellation: a room of order
        :math:`\eta` is not lost to the rounding of the force, whose sign would decide a join
        at the start (and an arrest would undo it, over and over)."""
        cap, f0 = self.capQ[cols], self.fQ[cols]
        den = np.abs(f0 + df) + np.abs(f0)
        grow = np.divide(df * (2 * f0 + df), den, out=np.abs(df), where=den > 0)
        return (cap - np.abs(f0)) - grow

    def _change(self, tau: np.ndarray | float, dy: np.ndarray, cols: np.ndarray
                ) -> np.ndarray:
        """The change of the forces of stuck bonds ``cols`` since the piece began (a row per
        time)."""
        t = np.atleast_1d(np.asarray(tau, float))[:, None]
        return self.eta * t * self.K1Q[None, cols] - dy @ self.KQ[cols].T

    def stuck_forces(self, tau: np.ndarray | float, dy: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(tau, float))[:, None]
        return self.fQ[None, :] + self.eta * t * self.K1Q[None, :] - dy @ self.KQ.T

    def moving_forces(self, ep: np.ndarray, dy: np.ndarray) -> np.ndarray:
        return self.s * (self.lam0 - self.kap * dy + ep)

    def values(self, tau: np.ndarray | float) -> np.ndarray:
        """Every event function at ``tau`` (columns; positive: no event yet): the excess of
        the moving bonds that can arrest, the slip left to d_c, the room of the stuck bonds
        to their strength."""
        ep, dy = self.at(tau)
        arrest = np.where(self.free[None, :], np.inf, ep)
        weak = np.where(self.kap[None, :] > 0, self.left[None, :] - dy, np.inf)
        room = self.capQ[None, :] - np.abs(self.stuck_forces(tau, dy))
        if self.atcap.any():
            a = self.atcap
            room[:, a] = self._room(self._change(tau, dy, a), a)
        return np.concatenate([arrest, weak, room], axis=1)

    def total(self, tau: np.ndarray | float) -> np.ndarray:
        """The sum of all forces at ``tau``."""
        ep, dy = self.at(tau)
        return self.stuck_forces(tau, dy).sum(axis=1) + self.moving_forces(ep, dy).sum(axis=1)

    def horizon(self, rx: Relaxation) -> float:
        """How far in the fast time to look for the next event: on a stable piece until its
        transients have died (then it lands), on an unstable one until its excess would be
        far above any force (an event comes before)."""
        mu, c0, g = self.mu, self.c0, self.g
        if mu[0] > 0:
            amp = float(np.abs(c0 - g / mu).max())
            end = (math.log(max(amp, rx.eta) / (1e-3 * rx.eta)) + SETTLED) / mu[0]
        else:
            grow = float(np.abs(c0[mu < 0]).max() + np.abs(g[mu < 0]).max() / -mu[0])
            end = math.log(1e6 * rx.fs / max(grow, rx.eta * 1e-6)) / -mu[0]
        if end * rx.eta > 1e-3 * rx.fs / max(float(np.abs(rx.K1).max()), 1e-300):
            raise NumericalError("slip-weakening: a burst lands on a state at the edge of "
                                 "stability (its relaxation outlasts the held drive)")
        return end

    def grid(self, end: float) -> np.ndarray:
        """Brackets for the events: 0, then steps growing by GROWTH from 1e-3/max|mu|."""
        t = 1e-3 / max(float(np.abs(self.mu).max()), 1e-300)
        n = max(math.ceil(math.log(max(end / t, 1.0)) / math.log(GROWTH)), 0)
        pts = t * GROWTH ** np.arange(n + 1)
        return np.concatenate([[0.0], pts[pts < end], [end]])

    def value(self, tau: float, c: int) -> float:
        """Event function ``c`` of :meth:`values` alone at ``tau``."""
        mu, nP = self.mu, self.P.size
        x = mu * tau
        small = np.abs(x) < 1e-6
        safe = np.where(mu == 0, 1.0, mu)
        Phi = np.where(small, tau * (1 - x / 2 + x * x / 6), -np.expm1(-x) / safe)
        if c < nP:
            return float(self.V[c] @ (self.c0 * np.exp(-x) + self.g * Phi))
        Psi = np.where(small, tau * tau * (0.5 - x / 6 + x * x / 24), (tau - Phi) / safe)
        if c < 2 * nP:
            return float(self.left[c - nP] - self.V[c - nP] @ (self.c0 * Phi + self.g * Psi))
        q = c - 2 * nP
        dy = self.V @ (self.c0 * Phi + self.g * Psi)
        if self.atcap[q]:
            dq = self.eta * tau * self.K1Q[q] - float(self.KQ[q] @ dy)
            return float(self._room(np.array([dq]), np.array([q]))[0])
        fq = self.fQ[q] + self.eta * tau * self.K1Q[q] - float(self.KQ[q] @ dy)
        return float(self.capQ[q] - abs(fq))

    def scan(self, grid: np.ndarray, chunk: int = 16) -> tuple[int, np.ndarray | None]:
        """The first point of ``grid`` after 0 where an event function is at or below 0 and
        the values there and at the point before (-1, None: none)."""
        prev = self.values(grid[:1])
        for a in range(1, grid.size, chunk):
            vals = np.vstack([prev, self.values(grid[a:a + chunk])])
            hit = np.flatnonzero((vals[1:] <= 0).any(axis=1))
            if hit.size:
                k = int(hit[0]) + 1
                return a + k - 1, vals[k - 1:k + 1]
            prev = vals[-1:]
        return -1, None

    def first(self, grid: np.ndarray, k: int, vals: np.ndarray) -> tuple[float, int]:
        """The first root in (grid[k-1], grid[k]] among the functions that cross there
        (Brent's method, to XTOL; ``vals``: the values at both points): its time and
        column."""
        lo, hi = float(grid[k - 1]), float(grid[k])
        cols = np.flatnonzero((vals[1] <= 0) & (vals[0] > 0))
        if cols.size == 0:
            cols = np.flatnonzero(vals[1] <= 0)
        best, which = hi, int(cols[0])
        for c in cols:
            def fn(t: float, c: int = int(c)) -> float:
                return self.value(t, c)

            tc = brentq(fn, lo, hi, xtol=XTOL * hi, rtol=4 * np.finfo(float).eps) \
                if fn(lo) > 0 else lo
            if tc < best:
                best, which = tc, int(c)
        return best, which


class Relaxation:
    r"""The fast-time flow of a burst (module docstring) over :math:`K = G_{xx}^{-1}` on all
    bonds (``response``, :mod:`~roughslip.friction.response`), with the normal forces ``fz``
    and the law :math:`\lambda_s, \lambda_d, d_c`."""

    def __init__(self, response: Response, fz: np.ndarray, lam_s: float, lam_d: float,
                 dc: float) -> None:
        self.response, self.fz = response, np.asarray(fz, float)
        self.K1 = response.row_sums
        self.lam_s, self.lam_d, self.dc = lam_s, lam_d, dc
        self.fs = max(float(np.abs(self.fz).max()), np.finfo(float).tiny)
        self.eta = EPS * self.fs

    def strength(self, delta: np.ndarray) -> np.ndarray:
        r""":math:`\lambda(\delta)`."""
        return self.lam_s - (self.lam_s - self.lam_d) * np.minimum(delta / self.dc, 1.0)

    def run(self, f: np.ndarray, w: np.ndarray, delta: np.ndarray, sigma: np.ndarray,
            moving: np.ndarray, rate: np.ndarray, limit: int, best: float | None = None
            ) -> Landing:
        r"""Relax from the fold: ``f`` the forces, ``w`` the slips, ``delta`` the accumulated
        slips, ``sigma`` the directions (nonzero on ``moving``), ``moving`` the bonds that
        slip at the fold (the failing one included), ``rate`` their quasi-static slip rates
        :math:`dw/dD` (0 for the failing bond). At most ``limit`` pieces.

        ``best``: stop (:attr:`Landing.stopped`) at the start of a piece where the sum of the
        bonds' strengths, :math:`\sum_i \lambda(\delta_i) f_{z,i}`, is at most ``best``:
        strengths only fall, so no equilibrium after it, the landing included, can carry
        more."""
        st = Landing(f.copy(), w.copy(), delta.copy(), sigma.copy(), moving.copy())
        m = st.moving
        # each moving bond carries its strength plus eta times its slip rate
        e = np.zeros(f.size)
        e[m] = self.eta * st.sigma[m] * rate[m]
        st.f[m] = st.sigma[m] * self.strength(st.delta[m]) * self.fz[m] + self.eta * rate[m]
        while True:
            st.pieces += 1
            if st.pieces > limit:
                raise NumericalError(f"slip-weakening: a burst did not land in {limit} pieces")
            if best is not None and float((self.strength(st.delta) * self.fz).sum()) <= best:
                st.stopped = True
                return st
            pc = _Piece(self, st, e)
            if self._at_start(pc, st, e):
                continue
            pc.decompose()
            end = pc.horizon(self)
            grid = pc.grid(end)
            k, vals = pc.scan(grid)
            self._peak(pc, grid if k < 0 else grid[:k + 1], st)
            if k < 0:
                if pc.mu[0] <= 0:
                    raise NumericalError("slip-weakening: a burst grows without an event")
                self._advance(pc, st, e, end)
                return st
            tau, which = pc.first(grid, k, vals)
            self._advance(pc, st, e, tau)
            nP = pc.P.size
            if which < nP:  # arrest: it sticks with the strength it reached
                self._arrest(int(pc.P[which]), st, e)
            elif which < 2 * nP:  # weakening -> residual
                i = pc.P[which - nP]
                st.delta[i] = max(st.delta[i], self.dc)
            else:  # a stuck bond reaches its strength
                self._join(int(pc.Q[which - 2 * nP]), st, e)

    def _arrest(self, i: int, st: Landing, e: np.ndarray) -> None:
        st.f[i] = st.sigma[i] * self.strength(st.delta[i:i + 1])[0] * self.fz[i]
        st.moving[i], st.sigma[i], e[i] = False, 0.0, 0.0

    def _join(self, i: int, st: Landing, e: np.ndarray) -> None:
        st.moving[i], e[i] = True, 0.0
        st.sigma[i] = math.copysign(1.0, st.f[i])
        st.f[i] = st.sigma[i] * self.strength(st.delta[i:i + 1])[0] * self.fz[i]
        st.failures.append((i, float(st.sigma[i]), float(st.f.sum())))

    def _at_start(self, pc: _Piece, st: Landing, e: np.ndarray) -> bool:
        """Events due at the start of a piece, all at once: a moving bond at zero excess whose
        excess falls arrests, a stuck bond at its strength whose force rises joins."""
        de = pc.r - pc.B @ pc.e0
        now = pc.P[~pc.free & (pc.e0 <= 0) & (de <= 0)]
        for i in now:
            self._arrest(int(i), st, e)
        if now.size:
            return True
        dfq = pc.eta * pc.K1Q - pc.KQ @ pc.e0
        over = pc.Q[(np.abs(pc.fQ) >= pc.capQ) & (np.sign(pc.fQ) * dfq > 0)]
        for i in over:
            self._join(int(i), st, e)
        return bool(over.size)

    def _peak(self, pc: _Piece, grid: np.ndarray, st: Landing) -> None:
        """Keep the largest sum of the forces on ``grid`` (refined between its neighbours)."""
        F = pc.total(grid)
        j = int(np.argmax(F))
        if not F[j] > st.peak:
            return
        st.peak = float(F[j])
        lo, hi = float(grid[max(j - 1, 0)]), float(grid[min(j + 1, grid.size - 1)])
        if hi > lo:
            res = minimize_scalar(lambda t: -float(pc.total(t)[0]), bounds=(lo, hi),
                                  method="bounded", options={"xatol": XTOL * hi})
            st.peak = max(st.peak, float(-res.fun))

    def _advance(self, pc: _Piece, st: Landing, e: np.ndarray, tau: float) -> None:
        """Move the state along the piece to ``tau``."""
        ep, dy = pc.at(tau)
        ep, dy = ep[0], dy[0]
        P = pc.P
        st.f[pc.Q] = pc.stuck_forces(tau, dy)[0]
        st.f[P] = pc.moving_forces(ep, dy)
        st.w[P] += pc.s * dy
        st.delta[P] += np.where(pc.free, 0.0, dy)  # a free bond's slip may turn back
        e[P] = ep
