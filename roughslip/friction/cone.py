r"""The Coulomb law with the traction vector at :math:`\nu > 0`: a faceted cone, exact events
(docs/theory/pull.rst#coulomb-cone).

Each bond carries :math:`\mathbf f_i = (f_x, f_y)` inside its friction set. The isotropic set
is the disc :math:`|\mathbf f_i| \le \lambda f_{z,i}`; here it is the regular polygon of
:math:`m` facets inscribed in it (:class:`Cone`), with a vertex on the drive
:math:`\hat{\mathbf e}`. A slipping bond's slip follows the normal of the set at its force
(associated flow): on facet :math:`k`, along its outward normal :math:`\mathbf n_k`; at a
vertex, in the cone of its two facets' normals. Every state is then affine in the drive
:math:`D`, and the events are exact:

* a bond that sticks holds :math:`\mathbf u_i = D\,\hat{\mathbf e} + \mathbf o_i` (two
  unknowns, :math:`f_x, f_y`) until its force reaches a facet line,
  :math:`\mathbf n_k\cdot\mathbf f_i = \rho\,\lambda f_{z,i}` with :math:`\rho = \cos(\pi/m)`;
* a bond on facet :math:`k` carries :math:`\rho\lambda f_{z,i}\mathbf n_k + \tau_i\mathbf t_k`
  (one unknown, :math:`\tau_i`, with :math:`\mathbf t_k\cdot(\mathbf u_i - D\hat{\mathbf e}
  - \mathbf o_i) = 0`) until :math:`|\tau_i|` reaches the facet's half-length
  :math:`\lambda f_{z,i}\sin(\pi/m)` (a vertex);
* a bond at a vertex carries the vertex (no unknown).

The slip :math:`\mathbf s_i = D\hat{\mathbf e} + \mathbf o_i - \mathbf u_i` (the rigid
surface relative to the half-space) must grow in the normal cone of the force's face: along
:math:`\mathbf n_k` on facet :math:`k`, as :math:`a\,\mathbf n_{k-1} + b\,\mathbf n_k` with
:math:`a, b \ge 0` at vertex :math:`k`. The rates are constant between events, so a bond
whose rate leaves the cone changes at the drive where the last event left it: a bond on a
facet whose slip rate turns back sticks again; at a vertex, a negative :math:`a` (or
:math:`b`) moves it onto facet :math:`k` (or :math:`k - 1`), both negative make it stick.

:math:`\mathbf o_i = \mathbf u_i - D\hat{\mathbf e}` at the bond's last change of state
(the slip accumulated up to it, negated). The unknowns are the
components of the sticking bonds and the :math:`\tau_i` of the bonds on facets; their matrix is
:math:`G_{tt}` on them, projected on each unknown's direction, and its inverse is updated as
bonds change state (:class:`~roughslip.linalg.inverse.UpdatableInverse`: a removal, or a
bordering, :math:`O(m^2)`). After every event both solutions that make the state affine,
:math:`G\varphi = \hat{\mathbf e}` and the part fixed by the slip, are checked against the FFT
operator and refined. Between two events every condition above is an affine function of
:math:`D`; the next event is the least root.

The inscribed polygon is the disc scaled by at most :math:`\cos(\pi/m)` in any direction, so
its strength differs from the disc's by at most :math:`1 - \cos(\pi/m)` (1.2e-3 at
:math:`m = 64`); the study of docs/results.md measures how the pull curve converges in
:math:`m`. Along the vertex on the drive the polygon is the disc: at full sliding every bond
carries :math:`\lambda f_{z,i}\hat{\mathbf e}`, and the friction force is
:math:`\lambda F_n` exactly.
"""

from __future__ import annotations

import math

import numpy as np

from roughslip.errors import InputError, MemoryLimitError, NumericalError
from roughslip.friction.bonds import Bonds, PullOptions, decoupled_result
from roughslip.friction.events import RATE_TIE, TIE, Curve, EventKind, plane_direction
from roughslip.friction.result import PullResult
from roughslip.linalg.inverse import UpdatableInverse
from roughslip.linalg.memory import available_bytes

#: the states of a bond
STICK, FACET, VERTEX = 0, 1, 2
#: the facets of the cone unless ``pull.facets`` says otherwise
FACETS = PullOptions.facets
#: the fewest and the most facets a pull takes (``pull.facets``)
MIN_FACETS, MAX_FACETS = 4, 4096
#: refinements per certification of a solution against the FFT operator
REFINEMENTS = 3
#: visits of one discrete state at one drive before the path is declared to cycle
VISITS = 3


class Cone:
    r"""The regular polygon of ``m`` facets inscribed in the unit circle, with vertex 0 at the
    angle ``direction`` (degrees; :func:`~roughslip.friction.events.plane_direction`, exact
    on the axes). Vertex :math:`j` is at :math:`\theta + 2\pi j/m`; facet :math:`k` runs from
    vertex :math:`k` to vertex :math:`k + 1`, its outward normal :math:`\mathbf n_k` at
    :math:`\theta + 2\pi(k + 1/2)/m` and its tangent :math:`\mathbf t_k` the normal turned
    by +90 degrees: facet :math:`k` is :math:`\rho\,\mathbf n_k + \tau\,\mathbf t_k`,
    :math:`|\tau| \le h`, with :math:`\rho = \cos(\pi/m)` and :math:`h = \sin(\pi/m)`."""

    def __init__(self, m: int, direction: float) -> None:
        self.m = int(m)
        theta = math.radians(float(direction))
        j = np.arange(self.m)
        a = theta + 2 * np.pi * j / self.m
        self.vertices = np.column_stack([np.cos(a), np.sin(a)])
        self.vertices[0] = plane_direction(direction)
        b = a + np.pi / self.m
        self.normals = np.column_stack([np.cos(b), np.sin(b)])
        self.tangents = np.column_stack([-self.normals[:, 1], self.normals[:, 0]])
        self.rho = math.cos(math.pi / self.m)
        self.h = math.sin(math.pi / self.m)
        # the coefficients (a, b) of a slip a n_{j-1} + b n_j at vertex j
        N = np.stack([np.roll(self.normals, 1, axis=0), self.normals], axis=2)  # (m, 2, 2)
        self.cone_inverse = np.linalg.inv(N)


class ConeState:
    """The bonds of a squeeze under the faceted Coulomb cone (module docstring): the state of
    each bond, the inverse on the unknowns, and the event path to full sliding."""

    def __init__(self, b: Bonds, opt: PullOptions, facets: int) -> None:
        if b.k != 2:
            raise ValueError("the Coulomb cone needs both tangential components")
        self.b, self.opt = b, opt
        n = b.n
        self.cone = Cone(facets, b.direction)
        self.e = np.asarray(b.drive, dtype=float)
        self.mode = np.zeros(n, dtype=np.int8)
        self.face = np.zeros(n, dtype=np.int64)
        self.ref = np.zeros((n, 2))  # o_i: u_i - D e at the bond's last change of state
        self.known = np.zeros((n, 2))  # the forces the law fixes (facets and vertices)
        self.uk = np.zeros((n, 2))  # their displacements at the bonds
        self._layout: tuple | None = None
        self.cap = b.cap
        self.D = 0.0
        self.worst, self.refinements = 0.0, 0
        #: events so far, and the most a pull may take before it is stopped unconverged
        self.events, self.limit = 0, 40 * n * (facets // 4 + 4) + 100
        self._seen: dict[bytes, int] = {}
        # a displacement scale: a bond's self-compliance times the largest strength
        g0 = float(b.entries(np.array([0]), np.array([0]))[0, 0])
        self.dscale = g0 * float(self.cap.max())
        # the inverse on at most 2n unknowns (a bond leaves before it joins again: compacted
        # in place), its pending columns, and the row of every unknown the ids can name
        need = 8 * (2 * n) ** 2 + 8 * opt.block * 2 * n + 8 * n * (2 + facets) + 8 * 64 * n

        def room(m: int) -> bool:
            if need > available_bytes():
                raise MemoryLimitError(
                    f"the Coulomb cone's inverse of G_tt on {n} bonds (dense, double "
                    f"precision) needs ~{need / 2**30:.2f} GiB but "
                    f"{available_bytes() / 2**30:.2f} GiB are available; use "
                    "pull.components = 'x' (an eighth of the memory)")
            return True

        self.size = 2 * n + n * self.cone.m
        self.inv = UpdatableInverse(self._entries, self.size, room=room, threads=opt.threads,
                                    block=opt.block, definite=True)
        try:
            self.inv.factor(np.arange(2 * n))
        except NumericalError as exc:
            raise NumericalError(f"G_tt on the bonds: {exc}") from None

    # -- the unknowns --------------------------------------------------------------------------
    def _owner(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The bond of each unknown and its direction: unknown ``2i`` and ``2i + 1`` are the x
        and y components of bond ``i``, unknown ``2n + i m + k`` its force along the tangent
        of facet ``k``."""
        ids = np.asarray(ids, dtype=np.int64)
        n, m = self.b.n, self.cone.m
        xy = ids < 2 * n
        bond = np.where(xy, ids // 2, (ids - 2 * n) // m)
        d = np.empty((ids.size, 2))
        c = ids[xy] % 2
        d[xy, 0], d[xy, 1] = c == 0, c == 1
        d[~xy] = self.cone.tangents[(ids[~xy] - 2 * n) % m]
        return bond, d

    def _entries(self, i: np.ndarray, j: np.ndarray, order: str = "F") -> np.ndarray:
        r""":math:`\mathbf d_p^T G(\mathbf x_p, \mathbf x_q)\,\mathbf d_q` between the unknowns
        ``i`` and ``j`` (:meth:`_owner`), from the closed-form pixel kernels."""
        i, j = np.asarray(i, dtype=np.int64), np.asarray(j, dtype=np.int64)
        n = self.b.n
        if (i < 2 * n).all() and (j < 2 * n).all():
            return self.b.entries(i, j, order=order)
        bi, di = self._owner(i)
        bj, dj = self._owner(j)
        xi = (2 * bi[:, None] + np.arange(2)).ravel()
        xj = (2 * bj[:, None] + np.arange(2)).ravel()
        E = self.b.entries(xi, xj, order="C").reshape(i.size, 2, j.size, 2)
        out = np.einsum("pa,paqb,qb->pq", di, E, dj)
        return np.asfortranarray(out) if order == "F" else np.ascontiguousarray(out)

    def _tau_id(self, bond: int, k: int) -> int:
        return 2 * self.b.n + bond * self.cone.m + k

    # -- the affine state ----------------------------------------------------------------------
    def _grid(self, F: np.ndarray) -> np.ndarray:
        """The displacements :math:`\\mathbf u` at the bonds of bond forces ``F`` (n, 2)."""
        b = self.b
        field = np.zeros((2, *b.shape))
        field.reshape(2, -1)[:, b.sites] = F.T
        u = b.apply(field, np.empty((2, *b.shape)))
        return u.reshape(2, -1)[:, b.sites].T

    def _forces(self, x: np.ndarray) -> np.ndarray:
        """Bond forces (n, 2) of the values ``x`` on the rows of the inverse (its live rows)."""
        live, bond, d = self._rows()
        F = np.zeros((self.b.n, 2))
        np.add.at(F, bond, x[live, None] * d)
        return F

    def _rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The live rows of the inverse, the bond of each and its direction (kept until the
        rows change)."""
        if self._layout is None or self._layout[0] != self.inv.version:
            live = np.flatnonzero(self.inv.live)
            self._layout = (self.inv.version, live, *self._owner(self.inv.ids[live]))
        return self._layout[1:]

    def solve(self) -> None:
        r"""The state as affine functions of :math:`D`: bond forces
        :math:`\mathbf F = D\,\mathbf F_a + \mathbf F_b` and displacements
        :math:`\mathbf U = D\,\mathbf U_a + \mathbf U_b`, from :math:`\varphi` (right-hand side
        :math:`\mathbf d_p\cdot\hat{\mathbf e}`) and :math:`\chi` (right-hand side
        :math:`\mathbf d_p\cdot(\mathbf o_i - G\mathbf f_{\rm fixed})_i`), each certified
        against the FFT operator: the residual of :math:`\chi` is that of the whole state,
        :math:`\mathbf d_p\cdot(\mathbf o_i - \mathbf U_{b,i})`, so the fixed forces'
        displacements (updated bond by bond from the kernel's columns) only start it."""
        inv = self.inv
        live, bond, d = self._rows()
        r1 = np.zeros(inv.m)
        r0 = np.zeros(inv.m)
        r1[live] = d @ self.e
        held = np.einsum("pa,pa->p", d, self.ref[bond])  # d . o: what the state must hold
        r0[live] = np.einsum("pa,pa->p", d, self.ref[bond] - self.uk[bond])
        X = inv.apply(np.column_stack([r1, r0]))
        X[~inv.live] = 0.0
        scale1 = max(float(np.linalg.norm(r1)), np.finfo(float).tiny)
        scale0 = float(np.linalg.norm(held)) + scale1 * max(abs(self.D), self.dscale)
        U = []
        for c, scale in enumerate((scale1, scale0)):
            x = X[:, c]
            for it in range(REFINEMENTS + 1):
                F = self._forces(x) + (self.known if c else 0.0)
                u = self._grid(F)
                r = np.zeros(inv.m)
                r[live] = (r1[live] if c == 0 else held) - np.einsum("pa,pa->p", d, u[bond])
                res = float(np.linalg.norm(r)) / scale
                if res <= self.opt.tol or it == REFINEMENTS:
                    break
                step = inv.apply(r)
                step[~inv.live] = 0.0
                x = x + step
                self.refinements += 1
            self.worst = max(self.worst, res)
            if res > self.opt.tol:
                raise NumericalError(
                    f"Coulomb cone: a solution's residual {res:.1e} stays above tol = "
                    f"{self.opt.tol:g} after {REFINEMENTS} refinements at D = {self.D!r}")
            X[:, c] = x
            U.append(u)
        self.Fa = self._forces(X[:, 0])
        self.Fb = self._forces(X[:, 1]) + self.known
        self.Ua, self.Ub = U

    def force(self, D: float) -> np.ndarray:
        """The bond forces (n, 2) at the drive ``D`` in the current state."""
        return D * self.Fa + self.Fb

    # -- events --------------------------------------------------------------------------------
    def next_event(self) -> tuple[float, int, int, int]:
        """The least drive increment to an event, its bond, the bond's next state and its
        facet or vertex (``inf``, -1 when none is ahead). A condition already violated
        beyond the tie gives an increment 0 (the avalanche at constant drive)."""
        cone, D = self.cone, self.D
        F0, Fa = self.force(D), self.Fa
        Sa = self.e - self.Ua  # the slip rates
        ftie = TIE * self.cap
        rtie = TIE * max(float(np.abs(Fa).max(initial=0.0)), np.finfo(float).tiny)
        n = self.b.n
        best = np.full(n, np.inf)
        to = np.full(n, -1, dtype=np.int8)
        where = np.zeros(n, dtype=np.int64)

        def take(idx, inc, mode, face):
            better = inc < best[idx]
            k = idx[better]
            best[k], to[k], where[k] = inc[better], mode, np.broadcast_to(face, inc.shape)[better]

        s = np.flatnonzero(self.mode == STICK)
        if s.size:
            cap = self.cap[s, None]
            val = F0[s] @ cone.normals.T - cone.rho * cap
            rate = Fa[s] @ cone.normals.T
            with np.errstate(divide="ignore", invalid="ignore"):
                inc = np.where(rate > rtie, np.maximum(-val, 0.0) / rate, np.inf)
            inc = np.where(val > ftie[s, None], 0.0, inc)
            k = np.argmin(inc, axis=1)
            first = inc[np.arange(s.size), k]
            # the facet's line is met at a vertex when the point is at its end
            Dk = D + np.where(np.isfinite(first), first, 0.0)
            p = Dk[:, None] * Fa[s] + self.Fb[s]
            tau = np.einsum("pa,pa->p", p, cone.tangents[k]) / (cone.h * self.cap[s])
            hi, lo = tau >= 1 - 1e-9, tau <= -1 + 1e-9
            mode = np.where(hi | lo, VERTEX, FACET)
            face = np.where(hi, (k + 1) % cone.m, k)
            for mval in (FACET, VERTEX):
                sel = mode == mval
                take(s[sel], first[sel], mval, face[sel])
        # slipping bonds: the slip rate must stay in the normal cone of the force's face; the
        # rates are constant between events, so a bond whose rate leaves it changes at once
        f = np.flatnonzero(self.mode == FACET)
        if f.size:
            k = self.face[f]
            t = cone.tangents[k]
            half = cone.h * self.cap[f]
            tau0 = np.einsum("pa,pa->p", F0[f], t)
            taua = np.einsum("pa,pa->p", Fa[f], t)
            siga = np.einsum("pa,pa->p", Sa[f], cone.normals[k])
            with np.errstate(divide="ignore", invalid="ignore"):
                up = np.where(taua > rtie, np.maximum(half - tau0, 0.0) / taua, np.inf)
                down = np.where(taua < -rtie, np.maximum(half + tau0, 0.0) / -taua, np.inf)
            up = np.where(tau0 > half + ftie[f], 0.0, up)
            down = np.where(-tau0 > half + ftie[f], 0.0, down)
            take(f, np.where(siga < -RATE_TIE, 0.0, np.inf), STICK, 0)  # first: ties stick
            take(f, up, VERTEX, (k + 1) % cone.m)
            take(f, down, VERTEX, k)
        v = np.flatnonzero(self.mode == VERTEX)
        if v.size:
            j = self.face[v]
            ab = np.einsum("pij,pj->pi", cone.cone_inverse[j], Sa[v])  # a n_{j-1} + b n_j
            neg = ab < -RATE_TIE
            both = neg.all(axis=1)
            take(v, np.where(neg[:, 0] & ~both, 0.0, np.inf), FACET, j)  # along n_j alone
            take(v, np.where(neg[:, 1] & ~both, 0.0, np.inf), FACET, (j - 1) % cone.m)
            for p in np.flatnonzero(both):  # the slip turns back: the bond's own problem
                mode, face = self._leave_vertex(int(v[p]), int(j[p]), Sa[v[p]])
                take(v[p:p + 1], np.zeros(1), mode, face)
        if not np.isfinite(best).any():
            return math.inf, -1, -1, -1
        low = float(best.min())
        i = int(np.flatnonzero(best <= low + TIE * max(low, 1e-300))[0])  # ties: lowest
        return low, i, int(to[i]), int(where[i])

    def _leave_vertex(self, i: int, j: int, rate: np.ndarray) -> tuple[int, int]:
        r"""Where bond ``i`` at vertex ``j`` goes when its slip rate ``rate`` points along
        neither facet: the one state of its own 2-by-2 problem, the others held as they are.
        With :math:`C` the bond's compliance given the others (the Schur complement of
        :math:`G_{tt}` on the live unknowns), sticking makes the force rate
        :math:`\dot{\mathbf f} = C^{-1}\dot{\mathbf s}`, which must not leave through either
        facet; on facet :math:`k` the force moves along :math:`\mathbf t_k` at
        :math:`\dot\tau` and slips along :math:`\mathbf n_k` at :math:`\dot\sigma \ge 0`,
        :math:`\dot{\mathbf s} - C\mathbf t_k\dot\tau = \dot\sigma\mathbf n_k`, with
        :math:`\dot\tau` away from the vertex. :math:`C` is positive definite, so one of the
        three holds."""
        inv, cone = self.inv, self.cone
        live, _, _ = self._rows()
        xy = np.array([2 * i, 2 * i + 1])
        B = np.zeros((inv.m, 2))
        B[live] = self._entries(inv.ids[live], xy, "C")
        HB = inv.apply(B)
        HB[~inv.live] = 0.0
        C = self._entries(xy, xy, "C") - B.T @ HB
        tie = RATE_TIE * max(float(np.abs(rate).max()), np.finfo(float).tiny)
        fdot = np.linalg.solve(C, rate)
        if (cone.normals[[j - 1, j]] @ fdot <= tie / float(np.abs(C).max())).all():
            return STICK, 0
        for k, away in ((j % cone.m, 1.0), ((j - 1) % cone.m, -1.0)):
            tau, sig = np.linalg.solve(np.column_stack([C @ cone.tangents[k], cone.normals[k]]),
                                       rate)
            if away * tau >= -tie and sig >= -tie:
                return FACET, k
        return STICK, 0

    def apply(self, i: int, mode: int, face: int) -> None:
        """Bond ``i`` changes to ``mode`` on ``face`` at the current drive: its unknowns leave
        or join the inverse, and what the law fixes of its force changes."""
        inv, cone, D = self.inv, self.cone, self.D
        cap = float(self.cap[i])
        self.ref[i] = self.Ua[i] * D + self.Ub[i] - D * self.e
        old = int(self.mode[i])
        if old == STICK:
            for u in (2 * i, 2 * i + 1):
                self._remove(u)
        elif old == FACET:
            self._remove(self._tau_id(i, int(self.face[i])))
        before = self.known[i].copy()
        self.known[i] = 0.0
        if mode == STICK:
            self._add(np.array([2 * i, 2 * i + 1]))
        elif mode == FACET:
            self.known[i] = cone.rho * cap * cone.normals[face]
            self._add(np.array([self._tau_id(i, face)]))
        else:
            self.known[i] = cap * cone.vertices[face]
        self.mode[i], self.face[i] = mode, face
        change = self.known[i] - before
        if change.any():
            col = self.b.entries(np.arange(2 * self.b.n), np.array([2 * i, 2 * i + 1]),
                                 order="C")
            self.uk += (col @ change).reshape(-1, 2)
        if inv.m > 64 and np.count_nonzero(~inv.live) > inv.m // 4:
            inv.compact()

    def _remove(self, unknown: int) -> None:
        if not self.inv.remove(unknown):
            raise NumericalError(f"Coulomb cone: the pivot of unknown {unknown} is not positive")

    def _add(self, new: np.ndarray) -> None:
        ok = self.inv.add(new)
        if ok is None:
            raise MemoryLimitError("Coulomb cone: no room to border the inverse")
        if not ok:
            raise NumericalError("Coulomb cone: a bordered Schur complement is not positive "
                                 "definite")

    def step(self) -> tuple[float, int, int, int]:
        """Solve the state and find its next event (:meth:`next_event`), counting it and
        guarding against a cycle: a discrete state met more than :data:`VISITS` times at one
        drive (to the tie) raises :class:`~roughslip.errors.NumericalError`."""
        self.solve()
        inc, i, mode, face = self.next_event()
        if i < 0:
            return inc, i, mode, face
        self.events += 1
        if inc <= TIE * max(abs(self.D), self.dscale):  # at one drive, to the tie
            sig = self.signature()
            self._seen[sig] = self._seen.get(sig, 0) + 1
            if self._seen[sig] > VISITS:
                raise NumericalError(
                    f"Coulomb cone: the state at D = {self.D + inc!r} repeats (a cycle of "
                    f"events at constant drive on bond {int(self.b.sites[i])})")
        else:
            self._seen.clear()
        return inc, i, mode, face

    def run_to(self, force: float) -> float:
        """Follow the events until the pull force along the drive reaches ``force`` (the
        partial-slip state under a tangential load), and stop there: the state is affine in
        the drive inside its last interval. Returns that drive (``D``); the bond forces
        are :meth:`force` at it and the stick bonds those in :data:`STICK`. Raises
        :class:`~roughslip.errors.InputError` when the load is not below the force at full
        sliding."""
        while True:
            inc, i, mode, face = self.step()
            if self.events > self.limit:
                raise NumericalError(f"Coulomb cone: no load of {force!r} after {self.limit} "
                                     "events")
            F0 = float(self.force(self.D).sum(axis=0) @ self.e)
            rate = float(self.Fa.sum(axis=0) @ self.e)
            if i < 0 and F0 < force:  # full sliding: no event ahead
                raise InputError(f"a tangential load of {force!r} is not below the force at "
                                 f"full sliding, {F0!r}")
            if i < 0 or F0 + rate * inc >= force:
                self.D += (force - F0) / rate if force > F0 else 0.0
                return self.D
            self.D += inc
            self.apply(i, mode, face)

    def signature(self) -> bytes:
        return self.mode.tobytes() + self.face.tobytes()


def cone_slide(b: Bonds, opt: PullOptions, t0: float, facets: int = FACETS) -> PullResult:
    r"""The decoupled pull under the faceted Coulomb cone with ``facets`` facets, from rest to
    full sliding: the exact event path of :class:`ConeState` (module docstring). The curve
    holds every event; the friction force is the force along the drive at full sliding,
    :math:`\lambda F_n`."""
    st = ConeState(b, opt, facets)
    drives, forces, kinds, sites = [0.0], [np.zeros(2)], [str(EventKind.START)], [-1]
    message = ""
    while True:
        inc, i, mode, face = st.step()
        if i < 0:
            break
        if st.events > st.limit:
            message = f"stopped after {st.limit} events without reaching full sliding"
            break
        D = st.D = st.D + inc
        kind = (EventKind.SLIP_PLUS if st.mode[i] == STICK
                else EventKind.STICK if mode == STICK else EventKind.TURN)
        drives.append(D)
        forces.append(st.force(D).sum(axis=0))
        kinds.append(str(kind))
        sites.append(int(b.sites[i]))
        st.apply(i, mode, face)
    F = st.force(st.D)
    fz = float(b.normal.fz.sum())
    curve = Curve(np.array(drives), np.array(forces), np.full(len(drives), fz),
                  np.full(len(drives), np.nan), tuple(kinds), np.array(sites, dtype=np.int64),
                  direction=tuple(float(c) for c in st.e))
    along = F @ st.e
    return decoupled_result(
        b, friction_force=float(along.sum()), curve=curve, peak_event=len(drives) - 1,
        peak_fx=b.field(F[:, 0]), peak_stick=b.mask(np.flatnonzero(st.mode == STICK)),
        t0=t0, method=opt.method_name, slip_law=opt.slip_law,
        converged=not message, residual=st.worst, solves=st.refinements,
        message=message or (f"exact event path of the Coulomb cone ({facets} facets) to "
                            f"full sliding, {st.events} events"),
        precision="double", peak_fy=b.field(F[:, 1]))

