r"""The frictional indentation of the coupled model under the faceted Coulomb cone, with the
traction vector (docs/theory/coupled.rst#coupled-cone).

A rigid surface is pressed into the half-space from first touch (:math:`D_z = 0`) to a depth.
Every contact site carries :math:`(f_z, f_x, f_y)`, coupled through all nine pixel kernels
(:math:`G_{zx}, G_{zy}` move the surface tangentially under a normal load when
:math:`\nu < 1/2`). A site that touches sticks where it is; its tangential force stays in the
regular polygon of :math:`m` facets inscribed in the disc :math:`|\mathbf f_t| \le \lambda f_z`
(:class:`~roughslip.friction.cone.Cone`, a vertex on x), and when it slips, its slip follows
the normal of the polygon at its force (associated flow). The polygon is homogeneous in
:math:`f_z`, so every condition stays linear in the forces and every state is affine in the
depth: the path is a sequence of exact events, as in the decoupled cone
(:mod:`roughslip.friction.cone`). A contact site

* sticks: :math:`\mathbf u_t = \mathbf o` (its position when it last changed state) and
  :math:`u_z = \bar u_z`; unknowns :math:`f_z, f_x, f_y`;
* slides on facet :math:`k`: :math:`\mathbf f_t = \rho\lambda f_z\mathbf n_k + \tau\mathbf t_k`,
  :math:`\mathbf t_k\cdot(\mathbf u_t - \mathbf o) = 0` and :math:`u_z = \bar u_z`; unknowns
  :math:`f_z, \tau`;
* sits at vertex :math:`j`: :math:`\mathbf f_t = \lambda f_z\mathbf v_j` and
  :math:`u_z = \bar u_z`; unknown :math:`f_z`.

The slip :math:`\mathbf s = \mathbf o - \mathbf u_t` (the rigid surface relative to the
half-space) grows in the normal cone of the force's face; its rate is constant between events.
The events: a gap closes (the site sticks), a normal force reaches zero (the site leaves
contact), a sticking force reaches a facet's line, a force on a facet reaches its end, and a
slip rate that leaves its normal cone (the site sticks again, or moves to a facet).

The system is not symmetric (the polygon ties :math:`\mathbf f_t` to :math:`f_z`). Each site
holds three rows and three columns, :math:`A_{pq} = Q_p G_{pq} P_q + \delta_{pq} E_p`, where
:math:`P_p` maps the site's unknowns to its forces, :math:`Q_p` picks its equations, and
:math:`E_p` is the identity on the unknowns its state does not use. A change of state changes
one site's rows and columns, a rank-6 change of :math:`A`, and the explicit inverse follows it
by the Sherman–Morrison–Woodbury formula (:math:`O(n^2)`); a site enters with the identity
block, which leaves the inverse as it is. After every event the two solutions that make the
state affine are checked against the FFT operator and refined; when refinement does not reach
the tolerance, the inverse is computed afresh once.

The inscribed polygon's strength differs from the disc's by at most :math:`1 - \cos(\pi/m)`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from roughslip.contact.problem import Problem, finite
from roughslip.elastic.tables import gather_pairs
from roughslip.errors import InputError, MemoryLimitError, NumericalError
from roughslip.friction.cone import FACET, FACETS, MAX_FACETS, MIN_FACETS, STICK, VERTEX, Cone
from roughslip.friction.events import RATE_TIE, TIE, Curve, EventKind, plane_direction
from roughslip.friction.result import CoupledDetails, PullResult, PullState
from roughslip.linalg.memory import available_bytes
from roughslip.linalg.threads import blas_threads

#: a site out of contact
OUT = 3
#: a contact without a bond, carrying no tangential force (a contact gained during a pull with
#: ``gained = "unbonded"``)
FREE = 4
#: the displacement (rows) and force (columns) components, in the order of a site's unknowns
NAMES = ("z", "x", "y")
#: refinements of a solution before the inverse is computed afresh
REFINEMENTS = 3
#: visits of one discrete state at one depth before the path is declared to cycle
VISITS = 3
#: rows of the inverse per block of an update (a block and its products stay in cache)
ROWS = 256


@dataclass(frozen=True)
class ConeIndentation:
    r"""The state at the end of a frictional indentation under the faceted cone
    (:func:`indent_cone`), and its path.

    ``fz``, ``fx``, ``fy`` and ``mode`` are grids of the problem's shape; ``mode`` holds
    :data:`~roughslip.friction.cone.STICK`, ``FACET``, ``VERTEX`` (the decoupled cone's
    states) or :data:`OUT` per site. ``events`` counts the events, ``residual`` is the worst
    certified relative residual and ``refreshes`` the inverses computed afresh. The
    ``path_*`` arrays list, at the start and after every event, the depth, :math:`F_z`, and
    the sites in contact and sticking."""

    depth: float
    lam: float
    facets: int
    fz: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    mode: np.ndarray
    events: int
    residual: float
    refreshes: int
    path_depth: np.ndarray
    path_force: np.ndarray
    path_contact: np.ndarray
    path_stick: np.ndarray

    @property
    def contact(self) -> np.ndarray:
        """The sites in contact."""
        return self.mode != OUT

    @property
    def stick(self) -> np.ndarray:
        """The sites that stick."""
        return self.mode == STICK

    def loading_ratio(self, start: float) -> tuple[float, float, float]:
        r""":math:`c/a` over the loading from the depth ``start`` to the end:
        :math:`\sqrt{\langle A_{\rm stick}/A_{\rm contact}\rangle}`, the area fraction
        averaged over the depth (each state of the path weighted by the depth it holds),
        and the least and largest :math:`c/a` of those states. Under self-similar loading the
        continuum fraction is constant; the pixel rings of the two zones make the states'
        fraction a sawtooth about it, which the average smooths."""
        d = self.path_depth
        ends = np.append(d[1:], self.depth)
        w = np.clip(ends, start, None) - np.clip(d, start, None)
        if not (w > 0).any():
            raise InputError(f"start = {start!r}: no state of the path lies beyond it")
        frac = self.path_stick / np.maximum(self.path_contact, 1)
        each = np.sqrt(frac[w > 0])
        return (math.sqrt(float((w * frac).sum() / w.sum())), float(each.min()),
                float(each.max()))

    @property
    def stick_ratio(self) -> float:
        r""":math:`c/a = \sqrt{A_{\rm stick}/A_{\rm contact}}`, the ratio of the radii of
        the discs with the stick and the contact areas."""
        n = int(self.contact.sum())
        return math.sqrt(int(self.stick.sum()) / n) if n else math.nan


class _Sites:
    """Dense kernel blocks between sites, from the operator's pair tables (exact pixel
    kernels on open grids), for the three components."""

    def __init__(self, problem: Problem) -> None:
        comps = ("zz", "zx", "zy", "xx", "xy", "yy")
        self.op = problem.operator(*comps).with_threads(1)
        self.tables = {c: self.op.tables.pair(c) for c in comps}
        self.ny, self.nx = problem.shape

    def block(self, si: np.ndarray, sj: np.ndarray) -> np.ndarray:
        """:math:`G_{ab}` between sites ``si`` and ``sj`` (flat indices), shape
        ``(len(si), 3, len(sj), 3)``: displacement ``a`` at ``si`` per force ``b`` at ``sj``."""
        out = np.empty((si.size, 3, sj.size, 3))
        for a in range(3):
            for b in range(3):
                name = NAMES[a] + NAMES[b]
                flipped = name not in self.tables
                T, w, off = self.tables[name[::-1] if flipped else name]
                li = (si // self.nx) * w + si % self.nx
                lj = (sj // self.nx) * w + sj % self.nx
                if flipped:  # G_ab(i - j) = G_ba(j - i)
                    li, lj = -li, -lj
                tmp = np.empty((si.size, sj.size))
                gather_pairs(T, li, lj, off, tmp)
                out[:, a, :, b] = tmp
        return out

    def displacements(self, F: np.ndarray) -> np.ndarray:
        """:math:`\\mathbf u = G\\mathbf f` on the grid for force fields ``F`` (3, ny, nx), by
        FFT (:meth:`~roughslip.elastic.operators.ElasticOperator.apply_full`)."""
        return self.op.apply_full(F, np.empty_like(F))


class ConeIndent:
    """The state of a frictional indentation under the faceted cone (module docstring): the
    sites that have touched (slots), each one's state, and the inverse of the system on
    them."""

    def __init__(self, problem: Problem, depth: float, lam: float, facets: int,
                 tol: float, max_events: int | None, direction: float = 0.0) -> None:
        self.problem, self.lam, self.tol = problem, float(lam), float(tol)
        self.end = float(depth)
        self.cone = Cone(facets, direction)  # a vertex on the drive
        self.k = _Sites(problem)
        self.base = problem.base.ravel()
        # room for the sites that touch: at first the overlap at the end widened by two
        # pixels, grown when more touch (the coupling moves the gaps; on periodic grids the
        # surface may rise anywhere)
        first = ndimage.binary_dilation(problem.overlap(self.end) >= 0, iterations=2)
        self.cap = 0
        self.slot = np.full(self.base.size, -1, dtype=np.int64)
        self.used = 0
        self._grow(max(int(first.sum()), 4))
        self.D = 0.0  # the depth while indenting, the tangential drive while pulling
        #: the drive's unit vector while pulling (None while indenting)
        self.e: np.ndarray | None = None
        #: the state a contact gained while pulling enters: STICK (bonded where it touches)
        #: or FREE
        self.gained = STICK
        self.events, self.refreshes, self.worst = 0, 0, 0.0
        self.limit = (max_events if max_events is not None
                      else 40 * self.cap * (facets // 4 + 4) + 100)
        self._seen: dict[bytes, int] = {}
        #: a site's self-compliance, the scale of the displacements' ties
        self.g0 = float(self.k.block(np.array([0]), np.array([0]))[0, 0, 0, 0])
        for s in np.flatnonzero(self.base >= 0.0):
            self.apply(self._slot_of(int(s)), STICK)

    # -- the sites and their blocks ------------------------------------------------------------
    def _grow(self, cap: int) -> None:
        """Room for ``cap`` sites (at most the grid's), the inverse and every per-site array
        copied. The memory asked for counts what a fresh inverse needs at its peak (the
        kernels, the matrix and its inverse beside the stored one)."""
        cap = min(cap, self.base.size)
        need = 4 * 8 * (3 * cap) ** 2
        if need > available_bytes():
            raise MemoryLimitError(
                f"the Coulomb cone under coupling on up to {cap} contact sites needs "
                f"~{need / 2**30:.2f} GiB but {available_bytes() / 2**30:.2f} GiB are "
                "available; lower the depth or use pull.components = 'x'")
        old, m = self.cap, 3 * self.used

        def grown(name, shape, fill=0.0, dtype=float):
            arr = np.full(shape, fill, dtype=dtype)
            if old:
                arr[:old] = getattr(self, name)
            setattr(self, name, arr)

        inv = np.zeros((3 * cap, 3 * cap))
        if old:
            inv[:m, :m] = self.inv[:m, :m]
        self.inv = inv
        grown("sites", cap, 0, np.int64)  # the site of each slot
        grown("mode", cap, OUT, np.int8)
        grown("face", cap, 0, np.int64)
        grown("ref", (cap, 2))
        grown("P", (cap, 3, 3))
        grown("Q", (cap, 3, 3))
        grown("E", (cap, 3, 3))
        self.cap = cap

    def _slot_of(self, site: int) -> int:
        p = int(self.slot[site])
        if p < 0:
            if self.used == self.cap:
                self._grow(2 * self.cap)
            p = self.used
            self.used += 1
            self.sites[p], self.slot[site] = site, p
            self.E[p] = np.eye(3)  # out of contact: the identity block
            self.inv[3 * p:3 * p + 3, 3 * p:3 * p + 3] = np.eye(3)
        return p

    def _blocks(self, mode: int, face: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``P``, ``Q``, ``E`` of a site in ``mode`` on ``face`` (module docstring)."""
        P, Q, E = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
        c, lam = self.cone, self.lam
        if mode == OUT:
            E[:] = np.eye(3)
        elif mode == FREE:
            P[0, 0], Q[0, 0] = 1.0, 1.0
            E[1, 1] = E[2, 2] = 1.0
        elif mode == STICK:
            P[:], Q[:] = np.eye(3), np.eye(3)
        elif mode == FACET:
            n, t = c.normals[face], c.tangents[face]
            P[0, 0], P[1:, 0], P[1:, 1] = 1.0, c.rho * lam * n, t
            Q[0, 0], Q[1, 1:] = 1.0, t
            E[2, 2] = 1.0
        else:
            P[0, 0], P[1:, 0] = 1.0, lam * c.vertices[face]
            Q[0, 0] = 1.0
            E[1, 1] = E[2, 2] = 1.0
        return P, Q, E

    def apply(self, p: int, mode: int, face: int = 0) -> None:
        """Slot ``p`` changes to ``mode`` on ``face`` at the current depth: its rows and
        columns change, and the inverse follows (Woodbury, rank 6)."""
        m = 3 * self.used
        P1, Q1, E1 = self._blocks(mode, face)
        G = self.k.block(self.sites[p:p + 1], self.sites[:self.used])[0]  # (3, used, 3)
        P, Q = self.P[:self.used], self.Q[:self.used]
        # rows of slot p (3, m) and columns (m, 3), before and after
        GP = np.matmul(G.transpose(1, 0, 2), P)  # G_pq P_q
        rows0 = np.matmul(self.Q[p], GP).transpose(1, 0, 2).reshape(3, m)
        GP[p] = G[:, p, :] @ P1
        rows1 = np.matmul(Q1, GP).transpose(1, 0, 2).reshape(3, m)
        QG = np.matmul(Q, G.transpose(1, 2, 0))  # Q_q G_qp, with G_qp[a, b] = G_pq[b, a]
        cols0 = np.matmul(QG, self.P[p]).reshape(m, 3)
        cols1 = np.matmul(QG, P1)
        cols1[p] = Q1 @ G[:, p, :].T @ P1
        cols1 = cols1.reshape(m, 3)
        R = slice(3 * p, 3 * p + 3)
        rows0[:, R] += self.E[p]
        cols0[R] += self.E[p]
        rows1[:, R] += E1
        cols1[R] += E1
        dR = rows1 - rows0
        dR[:, R] = 0.0
        dC = cols1 - cols0
        inv = self.inv[:m, :m]
        with blas_threads(1):
            # one pass over the rows of the inverse for both products, one for the update
            AU = np.empty((m, 6))  # A^-1 U
            VA = np.zeros((6, m))  # V^T A^-1
            AU[:, :3] = inv[:, R]
            VA[3:] = inv[R, :]
            for i in range(0, m, ROWS):
                blk = inv[i:i + ROWS]
                AU[i:i + ROWS, 3:] = blk @ dC
                VA[:3] += dR[:, i:i + ROWS] @ blk
            S = np.eye(6)
            S[:3] += dR @ AU
            S[3:] += AU[R]
            try:
                W = np.linalg.solve(S, VA)
            except np.linalg.LinAlgError:
                W = None
            if W is None or not np.all(np.isfinite(W)):
                self._set(p, mode, face, P1, Q1, E1)
                self.refresh()
                return
            for i in range(0, m, ROWS):
                inv[i:i + ROWS] -= AU[i:i + ROWS] @ W
        self._set(p, mode, face, P1, Q1, E1)

    def _set(self, p, mode, face, P1, Q1, E1) -> None:
        if mode != self.mode[p] or face != self.face[p]:
            self.ref[p] = self._ut(p) - (0.0 if self.e is None else self.D * self.e)
        self.mode[p], self.face[p] = mode, face
        self.P[p], self.Q[p], self.E[p] = P1, Q1, E1

    def _ut(self, p: int) -> np.ndarray:
        """The tangential displacement of slot ``p`` at the current depth (zero before the
        first solve)."""
        if not hasattr(self, "U0"):
            return np.zeros(2)
        s = self.sites[p]
        return self.U0[1:, s] + self.D * self.U1[1:, s]

    def refresh(self) -> None:
        """The inverse computed afresh from the kernels."""
        u = self.used
        G = self.k.block(self.sites[:u], self.sites[:u])
        A = np.einsum("pab,pbqc,qcd->paqd", self.Q[:u], G, self.P[:u]).reshape(3 * u, 3 * u)
        A += _blockdiag(self.E[:u])
        with blas_threads(None):
            try:
                self.inv[:3 * u, :3 * u] = np.linalg.inv(A)
            except np.linalg.LinAlgError:
                raise NumericalError(
                    f"frictional indentation: the system of {u} sites is singular at depth "
                    f"{self.D!r}") from None
        self.refreshes += 1

    # -- the affine state ----------------------------------------------------------------------
    def _rhs(self) -> tuple[np.ndarray, np.ndarray]:
        """Right-hand sides per slot (used, 3): the part per unit depth and the rest."""
        u = self.used
        mode = self.mode[:u]
        inn = mode != OUT
        r1 = np.zeros((u, 3))
        r0 = np.zeros((u, 3))
        st, fa = mode == STICK, mode == FACET
        t = self.cone.tangents[self.face[:u][fa]]
        r0[st, 1:] = self.ref[:u][st]
        r0[fa, 1] = np.einsum("pa,pa->p", t, self.ref[:u][fa])
        if self.e is None:  # indenting: the overlap moves with the depth
            r1[inn, 0] = 1.0
            r0[inn, 0] = self.base[self.sites[:u][inn]]
        else:  # pulling: the bonds move with the drive
            r0[inn, 0] = self.base[self.sites[:u][inn]] + self.end
            r1[st, 1:] = self.e
            r1[fa, 1] = t @ self.e
        return r1, r0

    def _fields(self, y: np.ndarray) -> np.ndarray:
        u = self.used
        f = np.einsum("pab,pb->pa", self.P[:u], y.reshape(u, 3))
        F = np.zeros((3, self.base.size))
        F[:, self.sites[:u]] = f.T
        return F

    def solve(self) -> None:
        """Both parts of the state, each certified against the FFT operator (module
        docstring): forces ``F1, F0`` and displacements ``U1, U0`` on the grid, (3, n)."""
        u, m = self.used, 3 * self.used
        r1, r0 = self._rhs()
        scale1 = max(float(np.linalg.norm(r1)), np.finfo(float).tiny)
        scale0 = float(np.linalg.norm(r0)) + scale1 * max(abs(self.D), self.g0 * 1e-3)
        out = []
        for r, scale in ((r1, scale1), (r0, scale0)):
            for attempt in range(2):
                y = self.inv[:m, :m] @ r.ravel()
                for _ in range(REFINEMENTS + 1):
                    F = self._fields(y)
                    U = self.k.displacements(F.reshape(3, *self.problem.shape)).reshape(3, -1)
                    eq = (np.einsum("pab,bp->pa", self.Q[:u], U[:, self.sites[:u]])
                          + np.einsum("pab,pb->pa", self.E[:u], y.reshape(u, 3)))
                    res_v = (r - eq).ravel()
                    res = float(np.linalg.norm(res_v)) / scale
                    if res <= self.tol:
                        break
                    y = y + self.inv[:m, :m] @ res_v
                if res <= self.tol:
                    break
                if attempt == 0:
                    self.refresh()
            if res > self.tol:
                raise NumericalError(
                    f"frictional indentation: a solution's residual {res:.1e} stays above "
                    f"tol = {self.tol:g} at depth {self.D!r}")
            self.worst = max(self.worst, res)
            out.append((F, U))
        (self.F1, self.U1), (self.F0, self.U0) = out

    # -- events --------------------------------------------------------------------------------
    def next_event(self) -> tuple[float, int, int, int]:
        """The least depth increment to an event, its slot (or ``-1 - site`` for a gap that
        closes), the next state and its face; ``inf`` when none is ahead."""
        cone, lam, D = self.cone, self.lam, self.D
        u = self.used
        F = self.F0 + D * self.F1
        Fr = self.F1
        fscale = max(float(np.abs(F[0]).max()), np.finfo(float).tiny)
        ftie = TIE * fscale
        rtie = TIE * max(float(np.abs(Fr).max()), np.finfo(float).tiny)
        best, rank, who, to, where = math.inf, 3, 0, -1, 0

        def take(inc: np.ndarray, ids: np.ndarray, mode, face, kind: int = 0) -> None:
            # the least increment; at one driver value, a bound reached (kind 0) before a
            # normal force that reaches zero (kind 1, so that a new contact may slip first)
            # before a slip rate that turns (kind 2), then the lowest id
            nonlocal best, rank, who, to, where
            if not inc.size:
                return
            i = int(np.argmin(inc))
            if inc[i] > best * (1 + TIE):
                return
            key = (0 if inc[i] >= best * (1 - TIE) else -1, kind, int(ids[i]))
            if key < (0, rank, who):
                best, rank, who = float(inc[i]), kind, int(ids[i])
                to = mode if np.isscalar(mode) else int(mode[i])
                where = face if np.isscalar(face) else int(face[i])

        # gaps that close: every site out of contact
        inside = np.zeros(self.base.size, bool)
        inside[self.sites[:u][self.mode[:u] != OUT]] = True
        out_sites = np.flatnonzero(~inside)
        depth, moving = (D, 1.0) if self.e is None else (self.end, 0.0)
        g = self.U0[0, out_sites] + D * self.U1[0, out_sites] - (depth + self.base[out_sites])
        gr = self.U1[0, out_sites] - moving
        gtie = TIE * max(depth, self.g0 * fscale)
        with np.errstate(divide="ignore", invalid="ignore"):
            inc = np.where(gr < 0, np.maximum(g, 0.0) / -gr, np.inf)
        inc = np.where(g < -gtie, 0.0, inc)
        take(inc, -1 - out_sites, STICK if self.e is None else self.gained, 0)
        slots = np.arange(u)
        sites = self.sites[:u]
        fz, fr = F[0, sites], Fr[0, sites]
        ft, ftr = F[1:, sites].T, Fr[1:, sites].T
        sr = -self.U1[1:, sites].T  # slip rates
        if self.e is not None:
            sr += self.e
        mode = self.mode[:u]
        # normal forces that reach zero
        c = mode != OUT
        with np.errstate(divide="ignore", invalid="ignore"):
            inc = np.where(fr[c] < -rtie, np.maximum(fz[c], 0.0) / -fr[c], np.inf)
        inc = np.where(fz[c] < -ftie, 0.0, inc)
        take(inc, slots[c], OUT, 0, 1)
        # sticking forces that reach a facet's line
        s = mode == STICK
        if s.any():
            val = ft[s] @ cone.normals.T - cone.rho * lam * fz[s, None]
            rate = ftr[s] @ cone.normals.T - cone.rho * lam * fr[s, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                inc = np.where(rate > rtie, np.maximum(-val, 0.0) / rate, np.inf)
            inc = np.where(val > ftie, 0.0, inc)
            # the first line met; among lines met at once (a force at the cone's apex, a
            # new contact) the one the force's rate crosses fastest
            first = inc.min(axis=1)
            tied = inc <= first[:, None] * (1 + TIE)
            k = np.argmax(np.where(tied, rate, -np.inf), axis=1)
            Dk = D + np.where(np.isfinite(first), first, 0.0)
            p = Dk[:, None] * ftr[s] + ft[s] - D * ftr[s]
            half = cone.h * lam * (fz[s] + (Dk - D) * fr[s])
            # where the force is still at the apex, where it meets the line follows the rates
            apex = np.abs(half) <= cone.h * lam * ftie
            p[apex], half[apex] = ftr[s][apex], cone.h * lam * fr[s][apex]
            with np.errstate(divide="ignore", invalid="ignore"):
                tau = np.einsum("pa,pa->p", p, cone.tangents[k]) / half
            hi, lo = tau >= 1 - 1e-9, tau <= -1 + 1e-9
            nxt = np.where(hi | lo, VERTEX, FACET)
            face = np.where(hi, (k + 1) % cone.m, k)
            take(first, slots[s], nxt, face)
        # forces on a facet that reach its end, and slip rates that turn back
        f = mode == FACET
        if f.any():
            k = self.face[:u][f]
            t = cone.tangents[k]
            half, halfr = cone.h * lam * fz[f], cone.h * lam * fr[f]
            tau, taur = np.einsum("pa,pa->p", ft[f], t), np.einsum("pa,pa->p", ftr[f], t)
            with np.errstate(divide="ignore", invalid="ignore"):
                up = np.where(taur - halfr > rtie, np.maximum(half - tau, 0.0) / (taur - halfr),
                              np.inf)
                down = np.where(-taur - halfr > rtie,
                                np.maximum(half + tau, 0.0) / (-taur - halfr), np.inf)
            up = np.where(tau > half + ftie, 0.0, up)
            down = np.where(-tau > half + ftie, 0.0, down)
            sig = np.einsum("pa,pa->p", sr[f], cone.normals[k])
            stie = RATE_TIE * max(float(np.abs(sr[f]).max()), np.finfo(float).tiny)
            take(np.where(sig < -stie, 0.0, np.inf), slots[f], STICK, 0, 2)
            take(up, slots[f], VERTEX, (k + 1) % cone.m)
            take(down, slots[f], VERTEX, k)
        v = mode == VERTEX
        if v.any():
            j = self.face[:u][v]
            ab = np.einsum("pij,pj->pi", cone.cone_inverse[j], sr[v])
            stie = RATE_TIE * max(float(np.abs(sr[v]).max()), np.finfo(float).tiny)
            neg = ab < -stie
            both = neg.all(axis=1)
            take(np.where(both, 0.0, np.inf), slots[v], STICK, 0, 2)
            take(np.where(neg[:, 0] & ~both, 0.0, np.inf), slots[v], FACET, j, 2)
            take(np.where(neg[:, 1] & ~both, 0.0, np.inf), slots[v], FACET, (j - 1) % cone.m,
                 2)
        return best, who, to, where

    def run(self) -> None:
        """Follow the events to the end depth; the state is solved there."""
        self.path = [self._record()]
        while True:
            self.solve()
            inc, who, mode, face = self.next_event()
            if self.D + inc >= self.end:
                self.D = self.end
                return
            self.events += 1
            if self.events > self.limit:
                raise NumericalError(f"frictional indentation: more than {self.limit} events "
                                     f"before depth {self.end!r}")
            self._guard(inc, "depth")
            self.D += inc
            p = self._slot_of(-1 - who) if who < 0 else who
            self.apply(p, mode, face)
            self.path.append(self._record())

    def pull(self, direction: float, gained: str) -> tuple[list, str]:
        """Pull from the indented state along ``direction`` (degrees) at its depth until no
        event is ahead (full sliding). Returns the curve's rows (drive, force vector,
        :math:`F_z`, kind, site), each taken just before its event, and a message when the
        event limit stopped the pull. The state at the largest force along the drive is kept
        in :attr:`peak` (its row, forces and modes)."""
        self.e = np.array(plane_direction(direction))
        self.gained = STICK if gained == "bonded" else FREE
        self.D = 0.0
        self._seen.clear()
        self.solve()
        rows = [(0.0, self._force(), self._fz(), str(EventKind.START), -1)]
        self.peak = (0, self.fields(), _grid_modes(self))
        while True:
            inc, who, mode, face = self.next_event()
            if not math.isfinite(inc):
                return rows, ""
            self.events += 1
            if self.events > self.limit:
                return rows, f"stopped after {self.limit} events before full sliding"
            self._guard(inc, "drive")
            self.D += inc
            p = self._slot_of(-1 - who) if who < 0 else who
            rows.append((self.D, self._force(), self._fz(), _kind(int(self.mode[p]), mode),
                         int(self.sites[p])))
            if rows[-1][1] @ self.e > rows[self.peak[0]][1] @ self.e:  # the state there
                self.peak = (len(rows) - 1, self.fields(), _grid_modes(self))
            self.apply(p, mode, face)
            self.solve()

    def _guard(self, inc: float, what: str) -> None:
        """A discrete state met more than :data:`VISITS` times at one value of the driver
        (to the tie) is a cycle: an error."""
        if inc <= TIE * max(abs(self.D), 1e-300):
            sig = self.mode[:self.used].tobytes() + self.face[:self.used].tobytes()
            self._seen[sig] = self._seen.get(sig, 0) + 1
            if self._seen[sig] > VISITS:
                raise NumericalError(
                    f"Coulomb cone under coupling: the state at {what} {self.D!r} repeats (a "
                    f"cycle of events at constant {what})")
        else:
            self._seen.clear()

    def _force(self) -> np.ndarray:
        return (self.F0[1:] + self.D * self.F1[1:]).sum(axis=1)

    def _fz(self) -> float:
        return float(self.F0[0].sum() + self.D * self.F1[0].sum())

    def fields(self) -> np.ndarray:
        """The forces (3, ny, nx) at the current driver."""
        return (self.F0 + self.D * self.F1).reshape(3, *self.problem.shape)

    def _record(self) -> tuple[float, float, int, int]:
        Fz = self._fz() if hasattr(self, "F0") else 0.0
        m = self.mode[:self.used]
        return self.D, Fz, int((m != OUT).sum()), int((m == STICK).sum())


def _kind(old: int, new: int) -> str:
    """The curve's kind of event of a site that goes from ``old`` to ``new``."""
    if old == OUT:
        return str(EventKind.GAINED)
    if new == OUT:
        return str(EventKind.LOST)
    if old == STICK:
        return str(EventKind.SLIP_PLUS)
    return str(EventKind.STICK if new == STICK else EventKind.TURN)


def _blockdiag(E: np.ndarray) -> np.ndarray:
    n = E.shape[0]
    out = np.zeros((3 * n, 3 * n))
    for p in range(n):
        out[3 * p:3 * p + 3, 3 * p:3 * p + 3] = E[p]
    return out


def _checked(problem: Problem, depth: float, lam: float, facets: int
             ) -> tuple[float, float, int]:
    depth = finite(depth, "depth")
    if not depth > 0:
        raise InputError(f"depth = {depth!r}: the indentation needs depth > 0")
    lam = finite(lam, "lam")
    if not lam > 0:
        raise InputError(f"lam = {lam!r}: the cone needs a friction coefficient > 0")
    if isinstance(facets, bool) or not isinstance(facets, int | np.integer) or not (
            MIN_FACETS <= facets <= MAX_FACETS):
        raise InputError(f"facets = {facets!r}: must be an integer from {MIN_FACETS} to "
                         f"{MAX_FACETS}")
    problem.check_depth(depth)
    return depth, lam, int(facets)


def indent_cone(problem: Problem, depth: float, *, lam: float = 0.2, facets: int = FACETS,
                tol: float = 1e-10, max_events: int | None = None) -> ConeIndentation:
    r"""The frictional indentation of ``problem``'s rigid surface from first touch to
    ``depth`` under the faceted Coulomb cone with the traction vector, in the coupled model
    (module docstring): exact events, every state certified against the FFT operator.

    Parameters
    ----------
    problem : Problem
        The rigid surface, grid and material (all three components are coupled).
    depth : float
        The final depth :math:`D_z` from first touch (> 0).
    lam : float
        The friction coefficient :math:`\lambda` (> 0).
    facets : int
        The facets :math:`m` of the polygon inscribed in the cone (4 to 4096).
    tol : float
        The relative residual every solution is certified to.
    max_events : int, optional
        The most events before the path is stopped with an error.

    Returns
    -------
    ConeIndentation
        The forces, the state of every site and the path.

    Notes
    -----
    Spence's frictional indentation of a sphere (D. A. Spence, J. Elasticity 5 (1975) 297)
    checks it: under monotonic loading the stick radius is a fixed fraction :math:`c/a` of
    the contact radius, set by :math:`\lambda` and :math:`\beta = (1 - 2\nu)/(2 - 2\nu)`
    (docs/results.md).
    """
    depth, lam, facets = _checked(problem, depth, lam, facets)
    st = ConeIndent(problem, depth, lam, facets, tol, max_events)
    st.run()
    shape = problem.shape
    F = (st.F0 + st.D * st.F1).reshape(3, *shape)
    mode = np.full(problem.base.size, OUT, dtype=np.int8)
    mode[st.sites[:st.used]] = st.mode[:st.used]
    path = np.array(st.path, dtype=float).reshape(-1, 4)
    return ConeIndentation(
        depth=depth, lam=lam, facets=int(facets), fz=F[0], fx=F[1], fy=F[2],
        mode=mode.reshape(shape), events=st.events, residual=st.worst,
        refreshes=st.refreshes, path_depth=path[:, 0], path_force=path[:, 1],
        path_contact=path[:, 2].astype(np.int64), path_stick=path[:, 3].astype(np.int64))


def couple_cone(problem: Problem, depth: float, *, lam: float = 0.2, direction: float = 0.0,
                facets: int = FACETS, gained: str = "unbonded", tol: float = 1e-10,
                max_events: int | None = None) -> PullResult:
    r"""The coupled model with the traction vector under the faceted Coulomb cone: the
    frictional indentation from first touch to ``depth`` (:func:`indent_cone`), then the pull
    along ``direction`` (degrees from x) at that depth, by exact events, to full sliding.

    The friction force is the largest pull force along the drive on the path; with the depth
    held, :math:`F_z` changes as the contact changes. A contact gained during the pull enters
    bonded where it touches (``gained = "bonded"``) or without a bond, carrying a normal force
    alone (``"unbonded"``). The result is :func:`~roughslip.coupling.coupled.couple`'s, with
    the history ``"indent"`` and the y forces of both states.

    The polygon keeps a vertex on the drive from first touch, so the indentation differs from
    :func:`indent_cone`'s (a vertex on x) by the polygon's orientation when ``direction`` is
    not a multiple of the facets' angle (the two polygons' strengths in any direction differ
    by at most :math:`1 - \cos(\pi/m)`).
    One ``max_events`` budget covers both phases: spent during the indentation it raises
    :class:`~roughslip.errors.NumericalError`, during the pull it ends the curve unconverged.
    """
    t0 = time.perf_counter()
    direction = finite(direction, "direction")
    if gained not in ("bonded", "unbonded"):
        raise InputError(f"gained = {gained!r}: must be 'bonded' or 'unbonded'")
    st = _indented(problem, depth, lam, facets, tol, max_events, direction)
    start_F = st.fields()
    start_mode = _grid_modes(st)
    t_squeeze = time.perf_counter() - t0
    rows, message = st.pull(direction, gained)
    drive = np.array([r[0] for r in rows])
    force = np.array([r[1] for r in rows]).reshape(-1, 2)
    e = st.e
    along = force @ e
    peak, peak_F, peak_mode = st.peak
    curve = Curve(drive, force, np.array([r[2] for r in rows]), np.full(drive.size, depth),
                  tuple(r[3] for r in rows), np.array([r[4] for r in rows], dtype=np.int64),
                  direction=tuple(float(c) for c in e))
    start = PullState(start_F[0], start_F[1], start_mode != OUT, start_mode == STICK,
                      start_F[2])
    at_peak = PullState(peak_F[0], peak_F[1], peak_mode != OUT, peak_mode == STICK, peak_F[2])
    return PullResult(
        friction_force=float(along[peak]), normal_force_at_peak=float(curve.fz[peak]),
        normal_force=float(start_F[0].sum()), curve=curve, peak_event=peak, peak=at_peak,
        start=start, converged=not message, seconds=time.perf_counter() - t0, method="dense",
        slip_law="coulomb", residual=st.worst, solves=st.events, message=message or (
            f"exact event path of the Coulomb cone under coupling ({facets} facets): "
            f"{st.events} events, indentation and pull"),
        details=CoupledDetails(contact_area=float((start_mode != OUT).mean()),
                               released=int(((start_mode != OUT) & (start_mode != STICK)).sum()),
                               depth=float(depth), pull_control="depth", history="indent",
                               squeeze_seconds=t_squeeze))


def _indented(problem: Problem, depth: float, lam: float, facets: int, tol: float,
              max_events: int | None, direction: float) -> ConeIndent:
    depth, lam, facets = _checked(problem, depth, lam, facets)
    st = ConeIndent(problem, depth, lam, facets, tol, max_events, direction)
    st.run()
    return st


def _grid_modes(st: ConeIndent) -> np.ndarray:
    mode = np.full(st.base.size, OUT, dtype=np.int8)
    mode[st.sites[:st.used]] = st.mode[:st.used]
    return mode.reshape(st.problem.shape)
