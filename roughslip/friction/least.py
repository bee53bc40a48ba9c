r"""A burst's landing as the least equilibrium above its start, followed on straight steps
(docs/theory/pull.rst#slip-weakening).

With the slip :math:`y_i \ge 0` of each bond since the fold, along its direction
:math:`\sigma_i`, the excess of every bond over its strength is

.. math:: F_i(y) = \sigma_i f_i - \lambda(\delta_i + y_i) f_{z,i}, \qquad
          f = f^0 - K \Sigma y,

with :math:`K = G_{xx}^{-1}` on all bonds. The overdamped slip rate of module
:mod:`~roughslip.friction.relax` is :math:`\dot y = \max(F(y), 0)/\eta`: every bond's slip only
grows, and a bond moves while its excess is positive. When :math:`-\Sigma K \Sigma` is
nonnegative off its diagonal (a *cooperative* system: a slip anywhere only raises the force on
the other bonds), the comparison theorem for such flows gives, for any positive mobilities,
the least equilibrium above the start: the least :math:`y \ge 0` with :math:`F(y) \le 0`
(Middleton's no-passing rule of driven elastic media). Every path that grows :math:`y` only
where the excess is not negative stays below it, and one that ends at an equilibrium ends
there. This module follows such a path on straight steps, each to its first event:

* **stable** (:math:`B = \Sigma K_{PP}\Sigma - \mathrm{diag}(\kappa_P f_{z,P})` positive
  definite on the moving set :math:`P`): the Newton step :math:`d = B^{-1} F_P`, along which
  every moving excess falls linearly to zero: the landing, unless an event comes first;
* **one bond alone**, when it softens faster than its own stiffness (:math:`B_{qq} < 0`) and
  its slip lowers no moving bond's excess that is at 0: :math:`d = e_q`, no solve;
* **unstable** otherwise, any :math:`d \ge 0` with :math:`B d \le 0`, so that no moving
  excess falls: the bond :math:`p` with :math:`(B^{-1})_{pp} < 0` driven while the others hold
  their excess, :math:`d = B^{-1} e_p / (B^{-1})_{pp}`; else :math:`d = -B^{-1} x` from the
  last step :math:`x \ge 0` (a step of inverse iteration towards the unstable eigenvector);
  else that eigenvector itself (Lanczos). In a cooperative system the last is nonnegative.

Events: a weakening bond reaches :math:`d_c` (a positive shift of :math:`B`'s diagonal), a
stuck bond reaches its strength (it joins :math:`P`: :math:`B` is bordered), and, on a step of
one bond, a moving bond's excess falls to 0. :math:`B^{-1}` is updated, not recomputed
(:class:`~roughslip.linalg.inverse.UpdatableInverse`), and the pivot of each update says how
its inertia changed. A step of one bond changes neither the moving set nor the softening, so it
leaves the inverse current, and its events update it like any other's. A burst starts from the
inverse the last burst of the pull left (``Carry``), updated to its moving set when few
bonds changed; else the inverse is factorised when a collective step first needs it, from the
part known to be definite, bordered by the bonds that joined since.

The pixel kernel's inverse is not exactly cooperative: bonds two pixels apart along a row or a
column, with a bond in contact between them, couple with the wrong sign, by up to a few
thousandths of the diagonal. The flow can then differ from the least equilibrium only if those
couplings stop a moving bond or set off a transient failure. :func:`land` returns None, and the
caller follows the flow, whenever no step keeps every slip from going back; the tests compare
both on every burst of rough scenes.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import linalg
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigsh

from roughslip.errors import NumericalError
from roughslip.friction.relax import Landing, Relaxation
from roughslip.linalg.inverse import UpdatableInverse

#: the order from which the unstable eigenvector is found by Lanczos iteration
LANCZOS_MIN = 200
#: the self-unstable bonds tried, in order, for a step of one bond alone
SOLO_TRIES = 8
#: a burst updates the last burst's inverse of B when the bonds to remove, shift or border
#: number at most this share of its moving set, and the updates since that inverse's
#: factorisation, these included, at most its order; else it factorises afresh
CARRY_SHARE = 0.125


class _Owner:
    """The assembler of an inverse of B, bound to the burst that holds the inverse now (a
    carried inverse passes from burst to burst, each with its own directions and
    softening)."""

    def __init__(self, a: _Ascent) -> None:
        self.a = a

    def entries(self, i: np.ndarray, j: np.ndarray, order: str) -> np.ndarray:
        return self.a._entries(i, j, order)


class Carry:
    """The inverse of B as the last burst of a pull left it, with the moving set, the
    directions and the softening it describes and its count of negative eigenvalues, for the
    next burst to update (``_Ascent.adopt``). Empty (``inv`` None) until a burst leaves
    one."""

    def __init__(self) -> None:
        self.inv: UpdatableInverse | None = None
        self.owner: _Owner | None = None  # its assembler
        self.P = self.sg = self.kt = np.empty(0)
        self.neg = 0
        self.updates = 0  # updates since its factorisation


class _Ascent:
    """The state of the path: slips, forces, the moving set, its softening, and the inverse
    of B on it (refreshed only when a step needs it)."""

    def __init__(self, rx: Relaxation, f: np.ndarray, delta: np.ndarray, sigma: np.ndarray,
                 moving: np.ndarray) -> None:
        self.rx = rx
        n = f.size
        sg = np.where(moving, sigma, np.sign(f))
        self.sg = np.where(sg == 0, 1.0, sg)
        self.f, self.d0 = f.copy(), delta
        self.y = np.zeros(n)
        self.P = moving.copy()
        self.free = (rx.lam_d == 0) & (delta >= rx.dc)  # zero strength: slips either way
        self.kap = (rx.lam_s - rx.lam_d) / rx.dc * rx.fz
        self.kt = np.where(moving & (delta < rx.dc), self.kap, 0.0)  # softening on P
        self.owner = _Owner(self)
        self.inv = UpdatableInverse(self.owner.entries, n, room=rx.response.room,
                                    definite=False)
        self.fresh = False  # whether the inverse and neg describe the current B
        #: bonds joined since B was last known positive definite on the rest of the moving
        #: set (ok), in order: a factorisation bordered by them gives the inertia cheaply
        self.pending: list[int] = []
        self.ok = True
        self.neg = 0  # negative eigenvalues of B
        self.driver = -1
        self.updates = 0  # updates of the inverse since its factorisation
        self.last: np.ndarray | None = None  # the last collective step (per bond)
        #: excess below which a moving bond counts as at its strength
        self.tiny = 1e-12 * rx.lam_s * rx.fs

    def _entries(self, i: np.ndarray, j: np.ndarray, order: str) -> np.ndarray:
        sg = self.sg
        A = sg[i][:, None] * self.rx.response.block(i, j) * sg[j][None, :]
        if np.array_equal(i, j):
            A[np.diag_indices(i.size)] -= self.kt[i]
        return np.asarray(A, order=order)

    def delta(self) -> np.ndarray:
        return self.d0 + np.where(self.free, 0.0, self.y)

    def excess(self) -> np.ndarray:
        rx = self.rx
        return self.sg * self.f - rx.strength(self.delta()) * rx.fz

    # -- the inverse of B ---------------------------------------------------------------------
    def refresh(self) -> bool:
        """The inverse of B on the moving set afresh, and its inertia: a Cholesky
        factorisation of the part known to be positive definite, bordered by the bonds
        joined since (each pivot's sign counts); else an LU inverse and the inertia of an
        LDL^T factorisation."""
        base = self.P.copy()
        base[self.pending] = False
        self.neg, self.driver = 0, -1
        try:
            if not self.ok or not base.any():
                raise NumericalError("no positive definite part")
            self.inv.factor(np.flatnonzero(base), positive=True)
            for q in self.pending:
                if not self.inv.add(np.array([q])):
                    raise NumericalError("a singular bordering")
                if self.inv.pivot < 0:
                    self.neg, self.driver = self.neg + 1, q
        except NumericalError:
            ids = np.flatnonzero(self.P)
            _, D, _ = linalg.ldl(self._entries(ids, ids, "C"), check_finite=False)
            self.neg = _negative(D)
            try:
                self.inv.factor(ids, positive=False)
            except NumericalError:
                return False
            self.ok = False
        self.fresh, self.updates = True, 0
        self._definite()
        return True

    def adopt(self, c: Carry) -> bool:
        """Take the last burst's inverse of B (``c``) and update it to this moving set: a
        removal for each bond that left it or turned (the pivot :math:`(B^{-1})_{ii}` is the
        Schur complement's reciprocal, so its sign is the inertia lost), a shift for each
        softening that changed, a bordering for each bond that joined (the failing one among
        them). False, and ``c`` emptied, when that costs more than a factorisation
        (:data:`CARRY_SHARE`) or an update is singular: the burst factorises afresh."""
        inv, P = c.inv, self.P
        if inv is None or c.P.size != P.size:
            return False
        turned = c.P & P & (c.sg != self.sg)
        out = np.flatnonzero(c.P & (~P | turned))
        soft = np.flatnonzero(c.P & P & ~turned & (c.kt != self.kt))
        new = np.flatnonzero(P & (~c.P | turned))
        m, changes = int(np.count_nonzero(P)), out.size + soft.size + new.size
        c.inv = None  # taken (or dropped)
        if changes > CARRY_SHARE * m or c.updates + changes > m:
            return False
        c.owner.a = self  # the carried inverse's entries are this burst's B
        neg, driver = c.neg, -1
        for i in out.tolist():
            if not inv.remove(i):
                return False
            neg -= inv.pivot < 0
            self._fold(inv)
        for i in soft.tolist():  # the diagonal of B moves by the change of softening
            k = float(c.kt[i] - self.kt[i])
            if inv.shift(i, k) is None:
                return False
            neg += (1 if k < 0 else -1) * (inv.pivot < 0)
            self._fold(inv)
        for i in new.tolist():
            if not inv.add(np.array([i])):
                return False
            if inv.pivot < 0:
                neg, driver = neg + 1, i
            self._fold(inv)
        if not inv.live.all() and not inv.compact():  # the steps read every row: none removed
            return False
        self.inv, self.owner, self.neg, self.driver = inv, c.owner, int(neg), driver
        self.fresh, self.updates = True, c.updates + changes
        self._definite()
        return True

    def keep(self, c: Carry) -> None:
        """Leave the inverse to the next burst (``c``), when it describes B."""
        c.inv, c.owner = (self.inv, self.owner) if self.fresh else (None, None)
        c.P, c.sg, c.kt = self.P.copy(), self.sg.copy(), self.kt.copy()
        c.neg, c.updates = self.neg, self.updates

    @staticmethod
    def _fold(inv: UpdatableInverse) -> None:
        if inv.k >= inv.block:
            inv.flush()

    def _definite(self) -> None:
        if self.neg == 0:  # positive definite on all of the moving set
            self.ok, self.pending = True, []

    def follow(self, kind: str, i: int, k: float) -> bool:
        """Update a fresh inverse for an event of bond ``i``: its softening ``k`` ends
        (``"dc"``), or it joins (``"join"``); the pivot says how the inertia changed."""
        if kind == "join":  # a rise of the diagonal keeps a definite part definite
            self.pending.append(i)
        if not self.fresh:
            return True
        inv = self.inv
        if kind == "dc":
            if inv.shift(i, k) is None:
                return False
            self.neg -= inv.pivot < 0
        else:
            if not inv.add(np.array([i])):
                return False
            if inv.pivot < 0:
                self.neg += 1
                self.driver = i
        self.updates += 1
        self._fold(inv)
        self._definite()
        return True

    # -- directions ---------------------------------------------------------------------------
    def solo(self, F: np.ndarray) -> int:
        """A bond that can slip alone (module docstring): it softens faster than its own
        stiffness, so its excess grows, and its slip lowers no moving bond's excess that is at
        0. -1: none (of the first SOLO_TRIES)."""
        K, tries = self.rx.response, 0
        for q in np.flatnonzero(self.P & ~self.free & (self.kt > 0)):
            q = int(q)
            if not self.kt[q] > K.diagonal(np.array([q]))[0]:
                continue
            tries += 1
            if tries > SOLO_TRIES:
                break
            rate = -self.sg * K.column(q) * self.sg[q]  # of the excess, per unit slip of q
            held = self.P & ~self.free & (F <= self.tiny)
            held[q] = False
            if not np.any(held & (rate < 0)):
                return q
        return -1

    def direction(self, F: np.ndarray) -> np.ndarray | None:
        """A collective step on the rows of the inverse (module docstring), or None when no
        candidate keeps every slip from going back."""
        inv = self.inv
        if self.neg == 0:
            return self._forward(inv.apply(F[inv.ids]))
        # unstable: drive one bond, the others held at their excess (the last to lose
        # stability, then the most negative diagonal entry of the inverse), else the
        # unstable eigenvector
        diag = np.where(inv.live, inv.diagonal(), math.inf)
        first = int(inv.row[self.driver]) if self.driver >= 0 else -1
        for r in dict.fromkeys((first, int(np.argmin(diag)))):
            if r >= 0 and diag[r] < 0:
                d = self._forward(inv.column(r) / diag[r])
                if d is not None:
                    self.driver = int(inv.ids[r])
                    return d
        # the last step's direction x: d = -B^-1 x has B d = -x <= 0, as wanted if d >= 0
        # (one step of inverse iteration towards the unstable eigenvector)
        if self.last is not None:
            x = np.where(inv.live, self.last[inv.ids], 0.0)
            d = self._forward(-inv.apply(x))
            if d is not None and np.any(d > 0):
                return d
        rows = np.flatnonzero(inv.live)
        ways = (True, False) if self.neg == 1 and rows.size > LANCZOS_MIN else (False,)
        for on_inverse in ways:
            mu, v = self._lowest(rows, on_inverse)
            if mu < 0:
                d = np.zeros(inv.m)
                d[rows] = v * np.sign(v.sum())
                d = self._forward(d)
                if d is not None or not on_inverse:
                    return d
        return None

    def _lowest(self, rows: np.ndarray, on_inverse: bool) -> tuple[float, np.ndarray]:
        r"""The lowest eigenpair of B on the live ``rows``: a dense eigensolver on small
        sets, else Lanczos from the last collective step, on B, or (``on_inverse``, when B has
        one negative eigenvalue :math:`\mu`) on its inverse, whose only negative eigenvalue is
        :math:`1/\mu` and, near a fold, far the largest: no B to assemble, and few
        iterations."""
        inv, m = self.inv, rows.size
        v0 = np.full(m, 1e-3)
        if self.last is not None:
            v0 += self.last[inv.ids[rows]]
        if on_inverse:
            x = np.zeros(inv.m)

            def times(v: np.ndarray) -> np.ndarray:
                x[rows] = np.ravel(v)
                return inv.apply(x)[rows]

            op = LinearOperator((m, m), matvec=times, dtype=float)
            try:
                nu, v = eigsh(op, k=1, which="SA", v0=v0, tol=1e-14)
            except ArpackNoConvergence:
                return 0.0, v0  # Lanczos on B decides
            return (1.0 / float(nu[0]) if nu[0] < 0 else 0.0), v[:, 0]
        B = self._entries(inv.ids[rows], inv.ids[rows], "C")
        if m <= LANCZOS_MIN:
            mu, v = linalg.eigh(B, subset_by_index=[0, 0], check_finite=False)
            return float(mu[0]), v[:, 0]
        mu, v = eigsh(B, k=1, which="SA", v0=v0, tol=1e-14)
        return float(mu[0]), v[:, 0]

    def _forward(self, d: np.ndarray) -> np.ndarray | None:
        """``d`` with rounding-level negative entries cleared, or None when a bond of nonzero
        strength would slip back."""
        free = self.free[self.inv.ids]
        back = (d < 0) & ~free
        if back.any() and float(-d[back].min()) > 1e-12 * float(np.abs(d).max()):
            return None
        return np.where(free, d, np.maximum(d, 0.0))


def _negative(D: np.ndarray) -> int:
    """Negative eigenvalues of the block diagonal D of an LDL^T factorisation."""
    n, i, neg = D.shape[0], 0, 0
    while i < n:
        if i + 1 < n and D[i + 1, i] != 0.0:
            a, b, c = D[i, i], D[i + 1, i], D[i + 1, i + 1]
            det = a * c - b * b
            neg += 1 if det < 0 else (2 if a + c < 0 else 0)
            i += 2
        else:
            neg += D[i, i] < 0
            i += 1
    return neg


def land(rx: Relaxation, f: np.ndarray, w: np.ndarray, delta: np.ndarray, sigma: np.ndarray,
         moving: np.ndarray, failing: int, best: float | None = None,
         carry: Carry | None = None) -> Landing | None:
    r"""The least equilibrium above the fold (module docstring): ``f`` the forces, ``w`` the
    slips, ``delta`` the accumulated slips, ``sigma`` the directions (nonzero on ``moving``),
    ``moving`` the bonds that slip at the fold, ``failing`` the one among them whose failure
    set the burst off (the others are stable: B is positive definite on them).

    ``best``: as in :meth:`Relaxation.run`, stop at the start of a step where the sum of the
    strengths is at most ``best``. Returns None when the path cannot be followed on monotone
    steps (module docstring): the caller follows the flow instead.

    ``carry``: the inverse of B the last burst of the same pull left (``Carry``), updated
    when few bonds changed; this burst leaves its own there."""
    a = _Ascent(rx, f, delta, sigma, moving)
    a.pending = [int(failing)]
    if carry is not None:
        a.adopt(carry)
    st = Landing(f.copy(), w.copy(), delta.copy(), np.where(moving, sigma, 0.0), moving.copy())
    K, n = rx.response, f.size
    st.peak = float(f.sum())
    for step in range(8 * n + 8):
        st.pieces = step + 1
        dl = a.delta()
        if best is not None and float((rx.strength(dl) * rx.fz).sum()) <= best:
            st.stopped = True
            return st
        F = a.excess()
        q = a.solo(F)
        if q >= 0:  # one bond alone: B is unchanged, its events update the inverse
            ids, d_rows, stable = np.array([q]), np.ones(1), False
        else:
            if not a.fresh and not a.refresh():
                return None
            d_rows = a.direction(F)
            if d_rows is None:
                return None
            ids, stable = a.inv.ids, a.neg == 0
            a.last = np.zeros(n)
            a.last[ids] = d_rows / max(float(np.abs(d_rows).max()), np.finfo(float).tiny)
        d = np.zeros(n)
        d[ids] = d_rows
        if ids.size == 1:  # forces per unit step
            df = -K.column(ids[0]) * (a.sg[ids[0]] * d_rows[0])
        else:
            df = -K.times(a.sg * d)
        rate = a.sg * df + np.where(a.P & ~a.free, a.kt * d, 0.0)  # of the excess
        t, kind, which = (1.0 if stable else math.inf), "land", -1
        weak = a.P & (a.kt > 0) & (d > 0)
        if weak.any():
            tw = np.full(n, math.inf)
            tw[weak] = (rx.dc - dl[weak]) / d[weak]
            j = int(np.argmin(tw))
            if tw[j] < t:
                t, kind, which = max(float(tw[j]), 0.0), "dc", j
        up = ~a.P & (rate > 0)
        if up.any():
            tj = np.full(n, math.inf)
            tj[up] = -F[up] / rate[up]
            j = int(np.argmin(tj))
            if tj[j] < t:
                t, kind, which = max(float(tj[j]), 0.0), "join", j
        if q >= 0:  # a moving bond's excess falling to 0 ends a step of one bond
            down = a.P & ~a.free & (rate < 0) & (F > a.tiny)
            if down.any():
                td = np.full(n, math.inf)
                td[down] = F[down] / -rate[down]
                j = int(np.argmin(td))
                if td[j] < t:
                    t, kind, which = float(td[j]), "held", j
        if not math.isfinite(t):
            return None
        a.y += t * d
        a.f += t * df
        st.peak = max(st.peak, float(a.f.sum()))
        Q = ~a.P
        if np.any(-a.sg[Q] * a.f[Q] > rx.strength(a.d0[Q]) * rx.fz[Q]):
            return None  # a stuck bond would fail backwards
        if kind == "land":
            break
        if kind == "dc":
            a.y[which] = rx.dc - a.d0[which]  # exactly at d_c
            k = a.kt[which]
            a.kt[which] = 0.0
            if not a.follow("dc", which, k):
                return None
        elif kind == "join":
            a.P[which] = True
            a.kt[which] = a.kap[which] if a.d0[which] < rx.dc else 0.0
            st.failures.append((which, float(a.sg[which]), float(a.f.sum())))
            if not a.follow("join", which, 0.0):
                return None
    else:
        return None
    if carry is not None:
        a.keep(carry)
    st.moving = a.P.copy()
    st.sigma = np.where(a.P, a.sg, 0.0)
    st.w = w + a.sg * a.y
    st.delta = a.delta()
    st.f = a.f
    return st
