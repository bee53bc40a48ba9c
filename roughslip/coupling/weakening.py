r"""Linear slip-weakening under coupling: a certified path-follower
(docs/theory/coupled.rst#coupled-weakening).

Every bond (a contact site that carries a tangential law) holds its elastic point at
:math:`u_x = D_x + o_i - \sigma_i s_i`, with :math:`s_i \ge 0` its slip in the direction
:math:`\sigma_i` of its force. A stick bond has its slip fixed; a moving bond (weakening or
residual) has it free, and carries its strength,

.. math:: \sigma_i f_{x,i} = \lambda(\delta_i) f_{z,i}, \qquad
          \lambda(\delta) = \lambda_s - (\lambda_s - \lambda_d)\min(\delta/d_c, 1),

with :math:`\delta_i` the slip since it first failed. With the contact set :math:`C` and the
bonds :math:`Q` fixed, the block of the coupled model on :math:`f_z(C), f_x(Q)` is the SPD
block of the stick solve, and every force, gap and the depth are affine in the drive
:math:`D` and the slips :math:`s` of the moving bonds :math:`P`:
:math:`f = f^0 + D f^1 + \sum_{j \in P} s_j c_j`, with :math:`c_j` the response to a unit slip
of bond :math:`j`. The law on :math:`P`, :math:`R_i(s, D) = \sigma_i f_{x,i} - \lambda_i f_{z,i}
= 0`, is then a system of quadratics: :math:`\lambda_i` is affine in :math:`s_i` on a weakening
bond and :math:`f_{z,i}` affine in :math:`(s, D)`. Between events the state is the curve
:math:`R = 0` in :math:`(s, D)`.

The curve is followed by pseudo-arclength continuation: a tangent :math:`t_0` at a point
:math:`x_0` of it, the predictor :math:`p(\tau) = x_0 + \tau t_0` and Newton's corrections on
:math:`F(x) = (R(x), t_0\cdot(x - x_0) - \tau)`. A step :math:`[0, h]` is accepted only with its
certificate:

* :math:`F` is quadratic, so :math:`\|F(p(\tau))\| \le \|R(x_0)\| + \tau^2\|q\|` exactly, with
  :math:`q_i = k_i t_{0,i}\,\mathrm{d}f_{z,i}(t_0)` (:math:`k_i = (\lambda_s-\lambda_d)/d_c` on
  weakening bonds); the Jacobian :math:`A` is Lipschitz with the constant
  :math:`L = \max_i 2 k_i \|\nabla f_{z,i}\|_1`; with :math:`\beta \ge \|A^{-1}\|` along the
  predictor (a Neumann bound from one at :math:`x_0`, itself a Neumann bound from the
  inverse of a nearby reference matrix, :mod:`roughslip.linalg.near`: the last fresh inverse,
  bordered, cut and changed by rank-one updates as bonds start and stop moving, so that a
  step costs :math:`O(P^2)`, not :math:`O(P^3)`), Kantorovich's theorem puts
  the one curve point with :math:`t_0\cdot(x-x_0) = \tau` within :math:`\rho = 2\beta\eta` of
  :math:`p(\tau)` for every :math:`\tau \le h`, when :math:`\beta L \eta \le 1/2`;
* every constraint that ends a state is affine in :math:`x` (a stick bond's
  :math:`\lambda f_z \mp f_x \ge 0`, :math:`f_z \ge 0` on :math:`C`, :math:`\delta \le d_c` on a
  weakening bond, a gap, through the kernel's decay), so on the tube it is at least its
  value on the predictor, affine in :math:`\tau`, less :math:`\|\gamma\|_1\rho`: positive at both
  ends means no root in the step, so no event is missed;
* the tangent's components move by at most :math:`\beta L (h\|t_0\|_\infty + \rho)` on the
  tube, so the signs that end a state (the drive's, at a fold; a slip rate's, at a reversal)
  and that of the rate of :math:`F_x` (an interior peak) are certified the same way.

An event of an affine constraint is located exactly, by Newton on :math:`R = 0` and the
constraint :math:`= 0`, once the tube shows it is the step's only root; a sign change of the
tangent is approached by certified steps until the component is below ``TIE`` of the
tangent's norm. A fold (the drive's component vanishing) or a state that is not stable (an
eigenvalue of :math:`\partial R/\partial s` with a real part :math:`\ge 0`) sets off a burst at
the held drive: the overdamped law :math:`\dot s_i = \max(e_i, 0)` (the excess over the
strength, on every bond) integrated to rest from the fold's unstable direction, the landing
polished by Newton and certified. Every state the path accepts is certified against the FFT
operator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import linalg
from scipy.integrate import solve_ivp

from roughslip.errors import NumericalError
from roughslip.friction.events import TIE, VISITS, Event, EventKind, EventPath, Snapshot, digest
from roughslip.linalg.near import Near, NearInverse

STICK, WEAK, RESID = 0, 1, 2


class EventCycle(NumericalError):
    """The sets came back to a state they left at the same drive (no quasi-static
    continuation): the pull ends there, not converged; anywhere else, an error."""


#: Newton's iterations on a curve point before a step is refused
NEWTON = 30
#: the excess, relative to the largest normal force, beyond which a stick bond fails, and
#: below which one arrested in a burst sticks
REST = 1e-10
#: the excess, relative to the largest normal force, at which a bond stops or moves again
#: inside a burst's flow, and above which no state is at rest
FLOW_EPS = 1e-9
#: a burst's push along its unstable mode, in d_c: the first that makes the mode grow at
#: :data:`ESCAPE` (a fold's mode is neutral until pushed)
PUSHES = (1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)
#: the excess, in FLOW_EPS, that a push past the last of PUSHES gives a mode in a flat valley
FLAT = 2.0
#: the least growth rate of a burst's mode, relative to the stiffest bond's rate
ESCAPE = 1e-6
#: the rate evaluations a burst's flow may take to its next event or rest before it is
#: refused as stalled (a flow at the residual's rounding floor takes bounded steps for ever)
FLOW_EVALS = 100_000
#: the horizons of a burst's flow, in units of the stiffest bond's relaxation time: the next
#: is tried when BDF overflows on the one before (its huge steps at rest). A shorter horizon
#: ends the flow early, and the burst's loop goes on from there: the same path, more calls
FLOW_SPANS = (1e12, 1e6, 1e3)
#: a violation that comes back inside a burst at less than this fraction of its last size
#: is an approach to a tie (a site tending to a contact with no force), not a cycle
APPROACH = 0.1
#: the returns of one violation inside a burst at which it is a cycle whatever its sizes
RETURNS = 30
#: the largest :math:`\theta = \|X\|\|E\|` at which a step is served from the reference
#: inverse (:mod:`roughslip.linalg.near`): its bound of the inverse's norm is then at most
#: (1 + THETA)/(1 - THETA) times the norm, so the certified steps shrink by at most that
THETA = 0.1
#: the updates of the reference (bonds added or taken out, rows replaced: about three per
#: event) after which it is inverted afresh, so that their rounding stays that of a few
#: fresh inverses
UPDATES = 100
#: the rows of the Jacobian that may be made the reference's own exactly at one point: those
#: whose change times the reference's inverse norm is THETA / 4 or more (the augmented row,
#: a bond turned residual); more, and the reference is inverted afresh
ROWS = 8


@dataclass(frozen=True)
class Weakening:
    r"""The law's numbers: :math:`\lambda_s, \lambda_d, d_c`."""

    lam_s: float
    lam_d: float
    dc: float

    @property
    def k(self) -> float:
        return (self.lam_s - self.lam_d) / self.dc

    def lam(self, delta: np.ndarray) -> np.ndarray:
        return self.lam_s - self.k * np.minimum(delta, self.dc)


class _Linear:
    """The affine response of the current sets: :math:`f = f^0 + D f^1 + s N` (rows of N: the
    moving bonds), the depth :math:`d^0 + d^1 D + s\\cdot d_N`. Forces vanish off the
    contact set, so N keeps only its columns ``idx`` (the contact sites); the affine parts
    are flat grids."""

    def __init__(self, fz0, fx0, fz1, fx1, dep0, dep1, fzd, idx):
        self.fz0, self.fx0, self.fz1, self.fx1 = fz0, fx0, fz1, fx1
        self.dep0, self.dep1, self.fzd = dep0, dep1, fzd
        self.idx = idx
        self.sites = np.empty(0, dtype=np.int64)
        self.Nz = np.zeros((0, idx.size))
        self.Nx = np.zeros((0, idx.size))
        self.dN = np.zeros(0)
        self.ref: NearInverse | None = None  # the augmented Jacobian's reference inverse
        self.blk = None  # the moving bonds' own rows (_Core._block)
        self.memo = None  # the fields at the last point asked (_Core.fields)

    def spread(self, a0: np.ndarray, s: np.ndarray, N: np.ndarray) -> np.ndarray:
        """The flat grid :math:`a^0 + s N` (a new array)."""
        out = a0.copy()
        if s.size:
            out[self.idx] += s @ N
        return out

    def cols(self, sites: np.ndarray) -> np.ndarray:
        """The positions of contact ``sites`` among the columns of N."""
        return np.searchsorted(self.idx, sites)


class _Core:
    r"""The coupled model's sets under slip-weakening, and the path that follows them
    (module docstring). Fields are flat grids; ``C`` the contact sites, ``Q`` the bonds.

    ``drive`` ``"x"``: the pull :math:`D_x` at the depth ``depth`` or the normal force
    ``force``; ``"z"``: the depth :math:`D_z` itself (the frictional indentation, contacts
    gained bonded).
    """

    def __init__(self, solver, problem, law: Weakening, C: np.ndarray, offset: np.ndarray, *,
                 depth: float | None = None, force: float | None = None, drive: str = "x",
                 gained: str = "unbonded", tol: float = 1e-12) -> None:
        self.solver, self.law = solver, law
        self.shape = problem.shape
        self.base = problem.base.ravel().copy()
        n = self.base.size
        self.C = C.ravel().copy()
        self.Q = self.C.copy()
        self.offset = offset.ravel().copy()
        self.phase = np.zeros(n, dtype=np.int8)
        self.sigma = np.zeros(n)
        self.delta = np.zeros(n)  # slip since the first failure, at the state's start
        self.depth, self.force = depth, force
        self.drive, self.gained = drive, gained
        self.tol = tol
        self.lin: _Linear | None = None
        self.D = 0.0
        self.s = np.zeros(0)
        self.scale = 1.0  # the drive's scale: the first event's drive
        self.scaled = False
        self.gmax = self._kernel_max()
        self.zx = self._zx_ratio()
        self.worst = 0.0
        self.steps = 0
        self.bursts = 0
        #: bursts whose weak mode landed by Newton's method (:meth:`_Events._weak_landing`)
        self.weak_landings = 0
        self.changes = 0  # set changes (events), to tell a flow that came back from one that moved
        self._origin: tuple[int, np.ndarray, int] | None = None  # the last push: changes, s, level
        self._approach: tuple[np.ndarray, np.ndarray] | None = None  # the path's last tangent
        self.stopped = ""

    # -- the linear response --------------------------------------------------------------------
    def _kernel_max(self) -> float:
        """The largest displacement of a unit force, either component: bounds a gap's change
        by the 1-norm of the force change."""
        ny, nx = self.shape
        e = np.zeros(self.shape)
        e[ny // 2, nx // 2] = 1.0
        z = np.zeros(self.shape)
        out = 0.0
        for f in ((e, z), (z, e)):
            uz, ux = self.solver.displacements(*f)
            out = max(out, float(np.abs(uz).max()), float(np.abs(ux).max()))
        return out

    def _zx_ratio(self) -> float | None:
        r"""The bound :math:`|G_{zx}| \le r\,G_{zz}` over every offset of the grid (unit
        forces at a corner reach them all, the kernels being even or odd in each axis), or
        None when :math:`G_{zz}` is not positive everywhere."""
        e = np.zeros(self.shape)
        e[0, 0] = 1.0
        z = np.zeros(self.shape)
        gzz = self.solver.displacements(e, z)[0]
        gzx = self.solver.displacements(z, e)[0]
        if not float(gzz.min()) > 0:
            return None
        return float((np.abs(gzx) / gzz).max())

    @property
    def moving(self) -> np.ndarray:
        return self.Q & (self.phase != STICK)

    def _grid(self, a: np.ndarray) -> np.ndarray:
        return a.reshape(self.shape)

    def linearize(self) -> None:
        """Solve the current sets at :math:`s = 0` (the slips folded into the offsets) and the
        responses of the moving bonds."""
        sv, sh = self.solver, self.shape
        C, Q = self._grid(self.C), self._grid(self.Q)
        sv.prepare(C, Q)
        zero, ones = np.zeros(sh), np.ones(sh)
        base, off = self._grid(self.base), self._grid(self.offset)
        idx = np.flatnonzero(self.C)
        if self.drive == "z":
            (a, b) = sv.solve_many([(base, off, "w0"), (ones, zero, "w1")])
            lin = _Linear(a[0].ravel(), a[1].ravel(), b[0].ravel(), b[1].ravel(), 0.0, 1.0,
                          None, idx)
        elif self.force is None:
            a, b = sv.solve_many([(base + self.depth, off, "w0"), (zero, ones, "w1")])
            lin = _Linear(a[0].ravel(), a[1].ravel(), b[0].ravel(), b[1].ravel(),
                          float(self.depth), 0.0, None, idx)
        else:
            fb, fd, f1 = sv.solve_many([(base, off, "wb"), (ones, zero, "wd"),
                                        (zero, ones, "w1")])
            sd = float(fd[0].sum())
            if not sd > 0:
                raise NumericalError("load control: the contact set carries no force under a "
                                     "uniform approach (no contact left)")
            d0 = (self.force - float(fb[0].sum())) / sd
            d1 = -float(f1[0].sum()) / sd
            lin = _Linear((fb[0] + d0 * fd[0]).ravel(), (fb[1] + d0 * fd[1]).ravel(),
                          (f1[0] + d1 * fd[0]).ravel(), (f1[1] + d1 * fd[1]).ravel(), d0, d1,
                          (fd[0].ravel()[idx], fd[1].ravel()[idx], sd), idx)
        self.lin = lin
        self._columns(np.flatnonzero(self.moving))
        self.s = np.zeros(lin.sites.size)

    def _columns(self, sites: np.ndarray) -> None:
        """The responses of the moving bonds ``sites`` to a unit slip each (rows of N)."""
        lin = self.lin
        k = sites.size
        Nz, Nx, dN = np.zeros((k, lin.idx.size)), np.zeros((k, lin.idx.size)), np.zeros(k)
        if k:
            fz, fx = self.solver.unit_responses(sites)
            sg = -self.sigma[sites]
            Nz, Nx = fz[:, lin.idx] * sg[:, None], fx[:, lin.idx] * sg[:, None]
            if lin.fzd is not None:
                fdz, fdx, sd = lin.fzd
                dN = -Nz.sum(axis=1) / sd
                Nz = Nz + dN[:, None] * fdz
                Nx = Nx + dN[:, None] * fdx
        lin.sites, lin.Nz, lin.Nx, lin.dN = sites, Nz, Nx, dN
        lin.blk = lin.memo = None

    def _add_column(self, j: int) -> None:
        lin = self.lin
        old = (lin.sites, lin.Nz, lin.Nx, lin.dN)
        self._columns(np.array([j]))
        lin.sites = np.concatenate([old[0], lin.sites])
        lin.Nz = np.vstack([old[1], lin.Nz])
        lin.Nx = np.vstack([old[2], lin.Nx])
        lin.dN = np.concatenate([old[3], lin.dN])
        lin.blk = lin.memo = None
        self.s = np.concatenate([self.s, [0.0]])
        if lin.ref is not None:
            # border the reference with the new bond's row and column at the current point
            # (the augmented row, a tangent that had no component for it, gets 0)
            if not lin.ref.border(lin.sites.size - 1,
                                  *self._border_entries(lin.sites.size - 1)):
                lin.ref = None

    def _drop_column(self, j: int) -> None:
        lin = self.lin
        keep = lin.sites != j
        if lin.ref is not None and not lin.ref.remove(int(np.flatnonzero(~keep)[0])):
            lin.ref = None
        lin.sites, lin.Nz, lin.Nx, lin.dN = (lin.sites[keep], lin.Nz[keep], lin.Nx[keep],
                                             lin.dN[keep])
        lin.blk = lin.memo = None
        self.s = self.s[keep]

    # -- fields at a point ----------------------------------------------------------------------
    def fields(self, s: np.ndarray, D: float) -> tuple[np.ndarray, np.ndarray, float]:
        """Normal and tangential forces (flat grids, not to be written to) and the depth at
        ``(s, D)``; the last point's are kept until the affine parts change."""
        lin = self.lin
        key = (s.tobytes(), D)
        if lin.memo is not None and lin.memo[0] == key:
            return lin.memo[1]
        fz = lin.spread(lin.fz0 + D * lin.fz1, s, lin.Nz)
        fx = lin.spread(lin.fx0 + D * lin.fx1, s, lin.Nx)
        out = fz, fx, lin.dep0 + lin.dep1 * D + float(s @ lin.dN)
        lin.memo = (key, out)
        return out

    def _lam(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Strength and its slope in s of the moving bonds."""
        P = self.lin.sites
        d = self.delta[P] + s
        weak = self.phase[P] == WEAK
        lam = np.where(weak, self.law.lam_s - self.law.k * d, self.law.lam_d)
        return lam, np.where(weak, self.law.k, 0.0)

    def _block(self):
        """The moving bonds' own rows: (A_z, A_x) with :math:`A[i, j]` the change of
        :math:`f(P_i)` per unit slip of :math:`P_j`, and the affine parts on P; kept until
        the columns or the base point change."""
        lin = self.lin
        if getattr(lin, "blk", None) is None:
            P = lin.sites
            cP = lin.cols(P)
            lin.blk = (np.ascontiguousarray(lin.Nz[:, cP].T),
                       np.ascontiguousarray(lin.Nx[:, cP].T),
                       lin.fz0[P], lin.fx0[P], lin.fz1[P], lin.fx1[P])
        return lin.blk

    def residual(self, s: np.ndarray, D: float, *_: object) -> np.ndarray:
        r""":math:`R_i = \sigma_i f_{x,i} - \lambda_i f_{z,i}` on the moving bonds."""
        Az, Ax, fz0, fx0, fz1, fx1 = self._block()
        P = self.lin.sites
        lam, _ = self._lam(s)
        return self.sigma[P] * (fx0 + D * fx1 + Ax @ s) - lam * (fz0 + D * fz1 + Az @ s)

    def jacobian(self, s: np.ndarray, D: float, *_: object, rows: int = 0) -> np.ndarray:
        r""":math:`[\partial R/\partial s,\ \partial R/\partial D]`, with ``rows`` more
        rows left for the caller (uninitialised)."""
        Az, Ax, fz0, _, fz1, fx1 = self._block()
        P = self.lin.sites
        p = P.size
        lam, k = self._lam(s)
        sg = self.sigma[P]
        J = np.empty((p + rows, p + 1))
        Js = J[:p, :p]
        np.multiply(sg[:, None], Ax, out=Js)
        Js -= lam[:, None] * Az
        Js[np.diag_indices(p)] += k * (fz0 + D * fz1 + Az @ s)
        J[:p, p] = sg * fx1 - lam * fz1
        return J

    def jacobian_times(self, s: np.ndarray, D: float, v: np.ndarray) -> np.ndarray:
        """:meth:`jacobian` times ``v``, without forming it."""
        Az, Ax, fz0, _, fz1, fx1 = self._block()
        P = self.lin.sites
        lam, k = self._lam(s)
        sg = self.sigma[P]
        vs, vD = v[:-1], float(v[-1])
        return (sg * (Ax @ vs) - lam * (Az @ vs) + k * (fz0 + D * fz1 + Az @ s) * vs
                + vD * (sg * fx1 - lam * fz1))

    def _border_entries(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Row and column ``k`` of the augmented Jacobian at the current point (the
        augmented row's entry in the column, a tangent that had no component for bond
        ``k``, is 0)."""
        Az, Ax, fz0, _, fz1, fx1 = self._block()
        P = self.lin.sites
        lam, kk = self._lam(self.s)
        sg = self.sigma[P]
        row = np.append(sg[k] * Ax[k] - lam[k] * Az[k], sg[k] * fx1[k] - lam[k] * fz1[k])
        col = np.append(sg * Ax[:, k] - lam * Az[:, k], 0.0)
        d = kk[k] * (fz0[k] + self.D * fz1[k] + float(Az[k] @ self.s))
        row[k] += d
        col[k] = row[k]
        return row, col

    def fscale(self) -> float:
        """The force unit of the ties: the largest normal force, or what the drive adds over
        its scale where there is none yet (first touch), as in the affine models."""
        if not self.C.any():
            return np.finfo(float).tiny
        lin = self.lin
        fz = np.abs(lin.fz0 + self.D * lin.fz1)[self.C].max()
        rate = np.abs(lin.fz1[self.C]).max() * max(self.scale, abs(self.D))
        return max(float(fz), float(rate), np.finfo(float).tiny)

    # -- the constraints ------------------------------------------------------------------------
    def _norms(self) -> None:
        r"""Per site, the 1-norms of the gradients of f_z and f_x in (s, D); the bound of
        each gap's gradient, :math:`\|\nabla g_j\|_1 \le \sum_k G_{zz,jk}(\|\nabla
        f_{z,k}\|_1 + r\|\nabla f_{x,k}\|_1)` with :math:`|G_{zx}| \le r G_{zz}`, else through
        the kernel's largest entry; the gradient of the total F_x."""
        lin = self.lin
        lin.nz1 = lin.spread(np.abs(lin.fz1), np.ones(lin.sites.size), np.abs(lin.Nz))
        lin.nx1 = lin.spread(np.abs(lin.fx1), np.ones(lin.sites.size), np.abs(lin.Nx))
        rest = float(np.abs(lin.dN).sum()) + abs(lin.dep1)
        lin.g1 = (self.gmax * (float(np.abs(lin.Nz).sum() + np.abs(lin.Nx).sum())
                               + float(np.abs(lin.fz1).sum() + np.abs(lin.fx1).sum())) + rest)
        lin.gn = np.full(int((~self.C).sum()), lin.g1)
        if self.zx is not None:
            # |dg_j| <= sum_k G_zz,jk (|df_z,k| + r |df_x,k|): one product with the
            # positive kernel, with a margin for its rounding
            w = lin.nz1 + self.zx * lin.nx1
            uz = self.solver.displacements(self._grid(w), np.zeros(self.shape))[0].ravel()
            tight = uz[~self.C] * (1 + 1e-9) + 1e-12 * lin.g1 + rest
            lin.gn = np.minimum(lin.gn, tight)
        lin.gF = np.append(lin.Nx.sum(axis=1), lin.fx1.sum())
        lin.gz = np.append(lin.Nz.sum(axis=1), lin.fz1.sum())

    def gaps(self, fz: np.ndarray, fx: np.ndarray, dep: float) -> np.ndarray:
        uz, _ = self.solver.displacements(self._grid(fz), self._grid(fx))
        return uz.ravel() - self.base - dep

    def constraints(self, s: np.ndarray, D: float, v: np.ndarray | None = None,
                    end: tuple[str, float] | None = None):
        """Every constraint that ends the state, ``c >= 0``, at ``(s, D)``: (kind codes,
        sites, values, rates along ``v``, gradient 1-norms)."""
        lin, law = self.lin, self.law
        fz, fx, dep = self.fields(s, D)
        B = np.flatnonzero(self.Q & (self.phase == STICK))
        Cs = np.flatnonzero(self.C)
        P = lin.sites
        Wr = np.flatnonzero(self.phase[P] == WEAK)
        off = np.flatnonzero(~self.C)
        lamB = law.lam(self.delta[B])
        g = self.gaps(fz, fx, dep)[off]
        kinds = [np.full(B.size, 0), np.full(B.size, 1), np.full(Cs.size, 2),
                 np.full(Wr.size, 3), np.full(off.size, 4)]
        sites = [B, B, Cs, P[Wr], off]
        vals = [lamB * fz[B] - fx[B], lamB * fz[B] + fx[B], fz[Cs],
                law.dc - self.delta[P[Wr]] - s[Wr], g]
        norms = [lamB * lin.nz1[B] + lin.nx1[B]] * 2 + [lin.nz1[Cs], np.ones(Wr.size),
                                                        lin.gn]
        if end is not None:
            kinds.append(np.array([5]))
            sites.append(np.array([-1]))
            if end[0] == "depth":
                vals.append(np.array([end[1] - D]))
                norms.append(np.array([1.0]))
            else:
                vals.append(np.array([end[1] - float(fz.sum())]))
                norms.append(np.array([float(np.abs(lin.gz).sum())]))
        out = [np.concatenate(kinds), np.concatenate(sites), np.concatenate(vals), None,
               np.concatenate(norms)]
        if v is not None:
            vs, vD = v[:-1], v[-1]
            dz = lin.spread(vD * lin.fz1, vs, lin.Nz)
            dx = lin.spread(vD * lin.fx1, vs, lin.Nx)
            ddep = vD * lin.dep1 + float(vs @ lin.dN)
            dg = self.gaps(dz, dx, ddep + 0.0)[off] + self.base[off]  # gaps() subtracts base
            rates = [lamB * dz[B] - dx[B], lamB * dz[B] + dx[B], dz[Cs], -vs[Wr], dg]
            if end is not None:
                rates.append(np.array([-vD if end[0] == "depth" else -float(dz.sum())]))
            out[3] = np.concatenate(rates)
        return out, (fz, fx, dep)

    # -- the path-follower ----------------------------------------------------------------------
    def _tangent(self, s: np.ndarray, D: float, prev: np.ndarray | None, fz=None
                 ) -> tuple[np.ndarray, Near]:
        r"""The unit tangent of R = 0 at (s, D), oriented along ``prev`` (else D growing), and
        the augmented Jacobian [J; t] served from the reference inverse
        (:class:`roughslip.linalg.near.Near`: solves and the bounds the certificate needs).

        The reference is the last fresh inverse, bordered and cut down as bonds start and
        stop moving. A fresh one is taken when there is none, after :data:`UPDATES` updates,
        or when :func:`_serve` cannot serve the Jacobian (more than :data:`ROWS` rows moved
        far, an update refused, or :math:`\theta \ge` :data:`THETA`)."""
        p = s.size
        row = np.zeros(p + 1)
        if prev is None:
            row[-1] = 1.0
        else:
            row[:] = prev
        A = self.jacobian(s, D, fz, rows=1)
        A[-1] = row
        ref = self.lin.ref
        if ref is not None and ref.size == p + 1 and ref.updates < UPDATES:
            near = _serve(ref, A)
            if near is not None:
                e = np.zeros(p + 1)
                e[-1] = 1.0
                t = self._orient(near.solve(e), prev)
                A[-1] = t
                near = _serve(ref, A)
                if near is not None:
                    return t, near
                A[-1] = row
        try:
            X = linalg.inv(A, check_finite=False)
        except linalg.LinAlgError:
            raise NumericalError("coupled slip-weakening: a singular augmented Jacobian "
                                 f"at D = {D!r}") from None
        # [J; row]^-1 = [X_J, z] with J z = 0, row.z = 1: the tangent is z / |z|, and
        # [J; t]^-1 = [X_J - t (t.X_J), t] (J t = 0, t.t = 1)
        t = self._orient(X[:, -1], prev)
        X[:, :-1] -= np.outer(t, t @ X[:, :-1])
        X[:, -1] = t
        A[-1] = t
        self.lin.ref = NearInverse.of(A, X)
        return t, self.lin.ref.near(A)

    @staticmethod
    def _orient(z: np.ndarray, prev: np.ndarray | None) -> np.ndarray:
        t = z / np.linalg.norm(z)
        if prev is not None and float(t @ prev) < 0:
            t = -t
        return t

    def _newton(self, x: np.ndarray, t0: np.ndarray, x0: np.ndarray, h: float,
                near: Near | None = None) -> np.ndarray | None:
        """The curve point with t0.(x - x0) = h, from ``x`` (None: no convergence): chord
        iterations on ``near`` (the augmented Jacobian at x0, :meth:`_tangent`) while they
        contract fast, then Newton's."""
        fs = self.fscale()
        if near is not None:
            last = math.inf
            for _ in range(8):
                s, D = x[:-1], float(x[-1])
                R = self.residual(s, D)
                dx = near.solve(np.append(R, float(t0 @ (x - x0)) - h))
                x = x - dx
                step = float(np.abs(dx).max())
                if (np.abs(R).max(initial=0.0) <= 1e-14 * fs
                        and step <= 1e-15 * max(np.abs(x).max(), self.scale)):
                    return x
                if step > 0.25 * last:
                    break
                last = step
        for _ in range(NEWTON):
            s, D = x[:-1], float(x[-1])
            R = self.residual(s, D)
            F = np.append(R, float(t0 @ (x - x0)) - h)
            A = np.vstack([self.jacobian(s, D), t0])
            try:
                dx = linalg.solve(A, F)
            except linalg.LinAlgError:
                return None
            x = x - dx
            if (np.abs(R).max(initial=0.0) <= 1e-14 * fs
                    and np.abs(dx).max() <= 1e-15 * max(np.abs(x).max(), self.scale)):
                return x
        s, D = x[:-1], float(x[-1])
        R = self.residual(s, D)
        return x if np.abs(R).max(initial=0.0) <= 1e-12 * fs else None

    def _kantorovich(self, t0, near, R0, h):
        """The tube around p(tau), tau <= h (module docstring): (beta, rho, L, beta on the
        whole tube), or None when the theorem's conditions fail."""
        lin = self.lin
        P = lin.sites
        _, k = self._lam(self.s)
        beta0 = near.beta
        L = float((2 * k * lin.nz1[P]).max(initial=0.0))
        tn = float(np.abs(t0).max())
        r0 = float(np.abs(R0).max(initial=0.0))
        if L == 0.0:
            return beta0, beta0 * r0, 0.0, beta0
        if beta0 * L * h * tn >= 0.5:
            return None
        beta = beta0 / (1 - beta0 * L * h * tn)
        ts, tD = t0[:-1], t0[-1]
        dfz = self._block()[0] @ ts + tD * lin.fz1[P] if P.size else np.zeros(0)
        q = float(np.abs(k * ts * dfz).max(initial=0.0))
        eta = r0 + h * h * q
        if beta * beta * L * eta > 0.5:  # Kantorovich: beta L |A^-1 F| <= 1/2
            return None
        rho = 2 * beta * eta
        grow = beta0 * L * (h * tn + rho)
        if grow >= 1:
            return None
        return beta, rho, L, beta0 / (1 - grow)

    def _scales(self, kinds: np.ndarray, end: tuple[str, float] | None) -> np.ndarray:
        """The unit of each constraint's tie tolerance: the largest normal force, d_c, the
        largest height, the end's own."""
        fs = self.fscale()
        gs = max(float(np.abs(self.base).max()), abs(self.lin.dep0), 1e-300)
        es = 1.0 if end is None else max(abs(end[1]), 1e-300)
        table = np.array([fs, fs, fs, self.law.dc, gs, es])
        return table[kinds]

    def _reversible(self) -> np.ndarray:
        """The moving bonds whose slip direction matters: all but residual bonds of zero
        residual strength."""
        P = self.lin.sites
        return ~((self.phase[P] == RESID) & (self.law.lam_d == 0.0))

    def _value(self, kind: int, site: int, s: np.ndarray, D: float,
               end: tuple[str, float] | None) -> float:
        fz, fx, dep = self.fields(s, D)
        if kind in (0, 1):
            lam = float(self.law.lam(self.delta[site]))
            return lam * fz[site] - (fx[site] if kind == 0 else -fx[site])
        if kind == 2:
            return float(fz[site])
        if kind == 3:
            r = int(np.flatnonzero(self.lin.sites == site)[0])
            return self.law.dc - self.delta[site] - float(s[r])
        if kind == 4:
            return float(self.gaps(fz, fx, dep)[site])
        return end[1] - D if end[0] == "depth" else end[1] - float(fz.sum())

    def advance(self, end: tuple[str, float] | None, on_point) -> tuple[str, int]:
        """Follow the curve from the current point to the next event and stop there: the event
        (``"slip+"``, ``"slip-"``, ``"lost"``, ``"residual"``, ``"gained"``, ``"end"``,
        ``"stick"``, ``"fold"``) and its site. ``on_point(s, D)`` sees every accepted point."""
        names = (EventKind.SLIP_PLUS, EventKind.SLIP_MINUS, EventKind.LOST, EventKind.RESIDUAL,
                 EventKind.GAINED, EventKind.END)
        prev, h = None, None
        for _ in range(200_000):
            s, D = self.s, self.D
            x0 = np.append(s, D)
            R0 = self.residual(s, D)
            t0, near = self._tangent(s, D, prev)
            self._approach = (self.lin.sites.copy(), t0)
            tn = float(np.abs(t0).max())
            if t0[-1] <= TIE * tn:
                return "fold", -1
            (kinds, sites, c0, c1, g1), _ = self.constraints(s, D, t0, end)
            tie = TIE * self._scales(kinds, end)
            bad = c0 < -tie
            if bad.any():
                raise NumericalError("coupled slip-weakening: a violated constraint on the "
                                     f"path at D = {D!r} (internal error)")
            # an event due here goes before a reversal (as in the Coulomb law's loop: a bond
            # that touches and at once slips would otherwise turn the slip zone back)
            # due here: located to the secant's tolerance, at a rate rounding cannot decide
            now = (c0 <= 1e-3 * tie) & (c1 < -TIE * g1 * tn)
            if now.any():
                e = _first(now, sites)
                return names[kinds[e]], int(sites[e])
            ts = t0[:-1]
            rev = self._reversible() & (ts < 0)
            if rev.any():
                # the fastest reversal; rates within the path's ties of it (symmetric sites)
                # go by the lowest site
                rows = np.flatnonzero(rev)
                rows = rows[ts[rows] <= ts[rows].min() + TIE * tn]
                r = int(rows[np.argmin(self.lin.sites[rows])])
                return EventKind.STICK, int(self.lin.sites[r])
            fall = c1 < 0
            tau = np.full(c0.size, np.inf)
            tau[fall] = c0[fall] / -c1[fall]
            tau_ev = float(tau.min(initial=np.inf))
            gF = self.lin.gF
            F1 = float(gF @ t0)
            tieF = TIE * float(np.abs(gF).sum()) * tn
            peak_side = F1 > tieF  # F_x rising: its sign must hold over the step
            if h is None:
                h = tau_ev if math.isfinite(tau_ev) else self.scale
            h = min(h, tau_ev * (1 + 1e-12)) if math.isfinite(tau_ev) else h
            hmin = 1e-14 * max(float(np.abs(x0).max()), self.scale)
            while True:
                if not h > hmin:
                    raise NumericalError("coupled slip-weakening: the path-follower cannot "
                                         f"certify a step at D = {D!r} (step {h:.3g})")
                if tau_ev <= h:
                    e = _first(tau <= tau_ev * (1 + 1e-9) + hmin, sites, tau)
                    got = self._locate(e, kinds, sites, c0, x0, t0, tau_ev, end, near)
                    if got is not None:
                        te, xe = got
                        # the rows due at the landing too (ties): applied from there on
                        ce = self.constraints(xe[:-1], float(xe[-1]), None, end)[0][2]
                        ties = (ce <= tie) | (np.arange(c0.size) == e)
                        if np.all(ce >= -tie) and self._certified(
                                t0, near, R0, te, c0, c1, g1, tie, ties, gF, peak_side, x0,
                                xe, fall_row=e):
                            self._accept(xe)
                            on_point(xe[:-1], float(xe[-1]))
                            # the tangent at the landing, not the step's start (one chord
                            # correction: J(xe) z = 0 to second order in the step)
                            z = t0 - near.solve(np.append(
                                self.jacobian_times(xe[:-1], float(xe[-1]), t0), 0.0))
                            self._approach = (self.lin.sites.copy(), z / np.linalg.norm(z))
                            return names[kinds[e]], int(sites[e])
                        h = 0.5 * te
                    else:
                        h = 0.5 * tau_ev
                    continue
                x1 = self._newton(x0 + h * t0, t0, x0, h, near)
                if x1 is not None and self._certified(t0, near, R0, h, c0, c1, g1, tie,
                                                      np.zeros(c0.size, bool), gF,
                                                      peak_side, x0, x1):
                    self._accept(x1)
                    on_point(x1[:-1], float(x1[-1]))
                    prev, h = t0, 2 * h
                    break
                h *= 0.5
        raise NumericalError("coupled slip-weakening: no event after 200000 steps")

    def _accept(self, x: np.ndarray) -> None:
        self.s, self.D = x[:-1].copy(), float(x[-1])
        self.steps += 1

    def _locate(self, e, kinds, sites, c0, x0, t0, tau_ev, end, near=None):
        """The curve point where constraint ``e`` vanishes, by the secant method in tau
        from its predicted root: (tau, x) or None.

        A gap lands just past its root, closed by between 0 and 1e-3 of its tie, so that
        the contact the event makes starts without tension: landed on its open side, a
        128^2 Hertz indentation gained a site at a gap of 2.9e-14, which in contact pulled
        a tension of 2.6 TIE of the largest force; it was lost at once and the path cycled.
        Every other constraint lands on its root to 1e-3 of its tie."""
        k, j = int(kinds[e]), int(sites[e])
        scale = float(self._scales(np.array([k]), end)[0])
        aim = -0.5e-3 * TIE * scale if k == 4 else 0.0
        ta, ca = 0.0, float(c0[e]) - aim
        tb = tau_ev
        xb = None
        for _ in range(40):
            xb = self._newton(x0 + tb * t0, t0, x0, tb, near)
            if xb is None:
                return None
            cb = self._value(k, j, xb[:-1], float(xb[-1]), end) - aim
            if abs(cb) <= (0.5e-3 if k == 4 else 1e-3) * TIE * scale:
                return tb, xb
            if cb == ca:
                return None
            tn = tb - cb * (tb - ta) / (cb - ca)
            if not (0 < tn < 4 * max(tau_ev, tb)):
                return None
            ta, ca, tb = tb, cb, tn
            if abs(tb - ta) <= 1e-15 * max(abs(tb), self.scale):
                xb = self._newton(x0 + tb * t0, t0, x0, tb, near)
                return None if xb is None else (tb, xb)
        return None

    def _tangent_bound(self, t0, near, dx: float, L: float, beta_t: float) -> np.ndarray:
        r"""Per component, how far the tangent (scaled to :math:`t_0\cdot z = 1`) moves on
        the tube, whose points are within ``dx`` of :math:`x_0`: with
        :math:`\Delta A` the change of the augmented Jacobian,
        :math:`z - t_0 = -A_0^{-1}\Delta A\,t_0 + A_0^{-1}\Delta A\,A^{-1}\Delta A\,t_0`,
        and :math:`|(\Delta A\,t_0)_i| \le k_i\,dx\,(|\mathrm{d}f_{z,i}(t_0)| +
        |t_{0,i}|\,\|\nabla f_{z,i}\|_1)` (the law's quadratic terms only)."""
        lin = self.lin
        P = lin.sites
        _, k = self._lam(self.s)
        if L == 0.0 or not P.size:
            return np.zeros(t0.size)
        ts, tD = t0[:-1], t0[-1]
        dfz = self._block()[0] @ ts + tD * lin.fz1[P]
        u = np.append(k * dx * (np.abs(dfz) + np.abs(ts) * lin.nz1[P]), 0.0)
        second = L * dx * beta_t * float(u.max())
        return near.abs_bound(u + second)

    def _certified(self, t0, near, R0, h, c0, c1, g1, tie, skip, gF, rising, x0, x1,
                   fall_row: int | None = None) -> bool:
        """The step's certificate (module docstring): the curve on [0, h] stays in the tube,
        no constraint but ``skip`` has a root on it, the tangent keeps its signs, and the
        located event's own constraint falls monotonically."""
        kb = self._kantorovich(t0, near, R0, h)
        if kb is None:
            return False
        _, rho, L, beta_t = kb
        tn = float(np.abs(t0).max())
        # the point's own rounding: of its size, and of Newton's tolerance on R through beta
        # (a point of tiny slips under large forces is fixed no closer than that)
        slack = (1e-13 * max(float(np.abs(x1).max()), self.scale)
                 + 2e-14 * beta_t * self.fscale())
        if float(np.abs(x1 - (x0 + h * t0)).max()) > rho * (1 + 1e-9) + slack:
            return False  # Newton left the tube: not the branch the certificate is about
        dz = beta_t * L * (h * tn + rho) * tn
        dzv = self._tangent_bound(t0, near, h * tn + rho, L, beta_t)
        lbA = np.minimum(c0, c0 + h * c1) - g1 * (rho + slack)
        lbB = c0 + np.minimum(0.0, h * (c1 - g1 * dz))
        ok = np.maximum(lbA, lbB) > -tie
        if not ok[~skip].all():
            return False
        if fall_row is not None and not c1[fall_row] + g1[fall_row] * dz < 0:
            return False
        if t0[-1] - dzv[-1] <= 0:
            return False
        # a slip rate may come within the tie of zero: it then runs back by at most TIE d_c
        ts = t0[:-1]
        back = h * np.maximum(dzv[:-1] - ts, 0.0)
        if np.any(self._reversible() & (ts - dzv[:-1] <= 0) & (back > TIE * self.law.dc)):
            return False
        if self.drive == "x" and rising:
            if not float(gF @ t0) - float(np.abs(gF) @ dzv) > 0:
                return False
        return True


def _serve(ref: NearInverse, A: np.ndarray) -> Near | None:
    r"""``A`` served from the reference (:class:`roughslip.linalg.near.Near`), its rows that
    moved far from the reference's made the reference's own first (rank-one each); None when
    more than :data:`ROWS` rows moved far, an update is refused, or :math:`\theta \ge`
    :data:`THETA` remains."""
    moved = np.abs(A - ref.A).sum(axis=1)
    big = np.flatnonzero(moved * ref.norm() >= 0.25 * THETA)
    if big.size > ROWS:
        return None
    for i in big:
        if not ref.replace_row(int(i), A[i]):
            return None
        moved[i] = 0.0
    near = ref.near(A, float(moved.max(initial=0.0)))
    return near if near.theta < THETA else None


def _proved_stable(J: np.ndarray) -> bool:
    """Whether a Cholesky factor of the negated symmetric part of ``J`` exists (or ``J`` is
    empty): then every eigenvalue has a negative real part, an eigenvalue's real part being
    the Rayleigh quotient of the symmetric part at its eigenvector."""
    if not J.size:
        return True
    try:
        linalg.cholesky(-0.5 * (J + J.T), check_finite=False)
        return True
    except linalg.LinAlgError:
        return False


def _abscissa(J: np.ndarray) -> float:
    """The largest real part of the eigenvalues of ``J``, or -inf where
    :func:`_proved_stable` settles their sign."""
    return -np.inf if _proved_stable(J) else float(linalg.eigvals(J).real.max())


def _growth_bound(J: np.ndarray) -> float:
    """An upper bound of :func:`_abscissa`: the largest eigenvalue of the symmetric part
    (the numerical abscissa; the same Rayleigh quotient argument), or -inf where
    :func:`_proved_stable` holds. One symmetric eigenvalue costs a tridiagonal reduction,
    not the non-symmetric QR iteration."""
    if _proved_stable(J):
        return -np.inf
    k = J.shape[0] - 1
    return float(linalg.eigvalsh(0.5 * (J + J.T), subset_by_index=[k, k], driver="evr",
                                 check_finite=False)[0])


def _least_crossing(c0: np.ndarray, c1: np.ndarray, c2: np.ndarray) -> float | None:
    r"""The least :math:`x \ge 0` at which some :math:`c_{0,i} + c_{1,i} x + c_{2,i} x^2`
    reaches 1, or None. Per row, with :math:`c = c_0 - 1 < 0`: a rising row (:math:`c_1 > 0`)
    crosses at the smaller positive root, :math:`2c/(-c_1 - \sqrt{c_1^2 - 4c_2c})`, when the
    discriminant is not negative (this form does not cancel, and is the linear root when
    :math:`c_2 = 0`); a row that first falls crosses only if convex, at
    :math:`(-c_1 + \sqrt{\cdot})/(2c_2)`."""
    c = c0 - 1.0
    if (c >= 0).any():
        return 0.0
    disc = c1 * c1 - 4.0 * c2 * c
    root = np.full(c.shape, np.inf)
    rise = (c1 > 0) & (disc >= 0)
    root[rise] = 2.0 * c[rise] / (-c1[rise] - np.sqrt(disc[rise]))
    fall = (c1 <= 0) & (c2 > 0)
    root[fall] = (-c1[fall] + np.sqrt(disc[fall])) / (2.0 * c2[fall])
    best = float(root.min(initial=np.inf))
    return best if math.isfinite(best) else None


def _first(mask: np.ndarray, sites: np.ndarray, order: np.ndarray | None = None) -> int:
    """The row of ``mask`` with the lowest ``order`` then the lowest site (the package's tie
    rule)."""
    rows = np.flatnonzero(mask)
    if order is not None:
        best = order[rows].min()
        rows = rows[order[rows] <= best * (1 + 1e-9)]
    return int(rows[np.argmin(sites[rows])])


class _Events:
    """The operations that change the sets, the burst, and the driver (mixed into
    :class:`WeakeningContact`)."""

    # -- sets ----------------------------------------------------------------------------------
    def rebase(self) -> None:
        """Fold the moving bonds' slips into their offsets and accumulated slips (s = 0)."""
        lin = self.lin
        if lin is None:
            return
        P = lin.sites
        if P.size and self.s.any():
            s = self.s
            lin.fz0 = lin.spread(lin.fz0, s, lin.Nz)
            lin.fx0 = lin.spread(lin.fx0, s, lin.Nx)
            lin.dep0 = lin.dep0 + float(s @ lin.dN)
            lin.blk = lin.memo = None
            self.offset[P] -= self.sigma[P] * s
            self.delta[P] += s
        self.s = np.zeros(P.size)

    def relinearize(self) -> None:
        self.rebase()
        self.linearize()
        self._norms()

    def apply(self, kind: str, j: int) -> None:
        """Change the sets for the event ``kind`` at site ``j`` (at the current point)."""
        self.changes += 1
        self.rebase()
        if kind in (EventKind.SLIP_PLUS, EventKind.SLIP_MINUS):
            self.sigma[j] = 1.0 if kind == EventKind.SLIP_PLUS else -1.0
            weak = self.delta[j] < self.law.dc and self.law.k > 0
            self.phase[j] = WEAK if weak else RESID
            self._add_column(j)
            self._norms()
        elif kind == EventKind.STICK:
            self.phase[j] = STICK
            self.sigma[j] = 0.0
            self._drop_column(j)
            self._norms()
        elif kind == EventKind.RESIDUAL:
            self.phase[j] = RESID
        elif kind == EventKind.LOST:
            self.C[j] = self.Q[j] = False
            self.phase[j], self.sigma[j], self.delta[j] = STICK, 0.0, 0.0
            self.relinearize()
        elif kind == EventKind.GAINED:
            if self.drive == "z" or self.gained == "bonded":
                fz, fx, _ = self.fields(self.s, self.D)
                ux = self.solver.displacements(self._grid(fz), self._grid(fx))[1].ravel()
                self.offset[j] = ux[j] - (self.D if self.drive == "x" else 0.0)
                self.Q[j] = True
                self.phase[j], self.sigma[j], self.delta[j] = STICK, 0.0, 0.0
            self.C[j] = True
            self.relinearize()
        else:
            raise NumericalError(f"coupled slip-weakening: unknown event {kind!r}")

    def holds(self) -> bool:
        """Whether a bond sticks or weakens (the pull goes on while one does)."""
        return bool(np.any(self.Q & (self.phase != RESID)))

    def certify(self) -> None:
        """The forces at the current point against the FFT operator: u_z on C and u_x on the
        bonds are what they impose; refreshed once from fresh solves, else an error."""
        for attempt in range(2):
            res = self._check()
            self.worst = max(self.worst, res) if attempt else self.worst
            if res <= 100 * self.tol:
                self.worst = max(self.worst, res)
                return
            self.relinearize()
        raise NumericalError(f"coupled slip-weakening: residual {res:.2e} against the FFT "
                             "operator")

    def _check(self) -> float:
        s, D = self.s, self.D
        fz, fx, dep = self.fields(s, D)
        uz, ux = self.solver.displacements(self._grid(fz), self._grid(fx))
        uz, ux = uz.ravel(), ux.ravel()
        want_z = self.base + dep
        want_x = (D if self.drive == "x" else 0.0) + self.offset.copy()
        P = self.lin.sites
        want_x[P] -= self.sigma[P] * s
        rz, rx = (uz - want_z)[self.C], (ux - want_x)[self.Q]
        # relative to the displacements imposed, or to the heights' scale where the drive
        # imposes none (an indentation at first touch)
        m = int(self.C.sum() + self.Q.sum())
        scale = max(float(np.linalg.norm(np.concatenate([want_z[self.C], want_x[self.Q]]))),
                    float(np.abs(self.base).max()) * math.sqrt(m), np.finfo(float).tiny)
        return float(np.linalg.norm(np.concatenate([rz, rx]))) / scale

    # -- stability and bursts ------------------------------------------------------------------
    def stable(self) -> bool:
        """Every eigenvalue of dR/ds on the moving bonds has a negative real part
        (:func:`_abscissa`)."""
        return _abscissa(self.jacobian(self.s, self.D)[:, :-1]) < 0

    def _violation(self) -> tuple[str, int] | None:
        """At the current point: a weakening bond slipped past d_c (a burst's push can carry
        it there), a contact in tension, a gap closed, a stick bond beyond its strength (by
        more than the rest tolerance); the worst of the first kind found."""
        P = self.lin.sites
        if P.size:
            past = (self.law.dc - self.delta[P] - self.s) * (self.phase[P] == WEAK)
            if past.min() < -TIE * self.law.dc:
                return EventKind.RESIDUAL, int(P[np.argmin(past)])
        fz, fx, dep = self.fields(self.s, self.D)
        fs = self.fscale()
        C = np.flatnonzero(self.C)
        neg = fz[C] < -TIE * fs
        if neg.any():
            return EventKind.LOST, int(C[neg][np.argmin(fz[C][neg])])
        off = np.flatnonzero(~self.C)
        if off.size:
            g = self.gaps(fz, fx, dep)[off]
            gs = max(float(np.abs(self.base).max()), abs(dep), 1e-300)
            pen = g < -TIE * gs
            if pen.any():
                return EventKind.GAINED, int(off[pen][np.argmin(g[pen])])
        B = np.flatnonzero(self.Q & (self.phase == STICK))
        if B.size:
            ex = np.abs(fx[B]) - self.law.lam(self.delta[B]) * fz[B]
            over = ex > REST * fs
            if over.any():
                r = np.flatnonzero(over)
                r = r[ex[r] >= ex[r].max() * (1 - 1e-9)]
                j = int(B[r].min())
                return EventKind.slip(fx[j]), j
        return None

    def burst(self, push: tuple[np.ndarray, float] | None = None,
              forcing=None) -> list[tuple[str, int, float]]:
        r"""Relax at the held drive to the rest of the overdamped law
        :math:`\dot s_i = \max(e_i, 0)` (module docstring), from ``push`` (a mode of
        :meth:`unstable_mode`, at a fold) or from the unstable mode, signed by what
        ``forcing`` returns (:meth:`approach_forcing`, after an event; called only when the
        mode is needed); returns the failures on the way (kind, site, F_x)."""
        failed: list[tuple[str, int, float]] = []
        self.bursts += 1
        self._origin = None
        self._stopped: set[int] = set()
        self._pushed = False
        if push is not None:
            self._push(push)
        elif self._violation() is None and not self.stable():
            self._push(self.unstable_mode(None if forcing is None else forcing()))
        seen: dict[tuple, tuple[int, int, float]] = {}  # visits, returns, last size
        idle = 0  # flows in a row that changed nothing
        for _ in range(100_000):
            v = self._violation()
            if v is not None:
                key = (str(v[0]), v[1], self.signature())
                size = self._size(*v)
                if key in seen:
                    visits, returns, last = seen[key]
                    returns += 1
                    if not abs(size) < APPROACH * abs(last):
                        visits += 1
                else:
                    visits, returns = 1, 0
                seen[key] = (visits, returns, size)
                if visits >= VISITS or returns >= RETURNS:
                    raise self._cycle(*v, "inside a burst", returns)
                if v[0] in (EventKind.SLIP_PLUS, EventKind.SLIP_MINUS):
                    failed.append((v[0], v[1], self.totals()[0]))
                self.apply(*v)
                idle = 0
                continue
            if not self.lin.sites.size:
                return failed
            if self._rest():
                return failed
            if not self._pushed and self._violation() is not None:
                continue  # the polish at rest left a bond beyond its strength: that first
            before = (self.changes, self.s.copy(), frozenset(self._stopped))
            self._flow()
            if (before[0] == self.changes and np.array_equal(before[1], self.s)
                    and before[2] == self._stopped):
                idle += 1
                if idle >= VISITS:
                    raise NumericalError(
                        "coupled slip-weakening: a burst's flow makes no progress at "
                        f"{'D_x' if self.drive == 'x' else 'D_z'} = {self.D!r}, yet the state "
                        "is not at rest")
            else:
                idle = 0
        raise NumericalError("coupled slip-weakening: a burst did not come to rest")

    def _size(self, kind: str, j: int) -> float:
        """How far the violation ``kind`` at site ``j`` is past its tie: a contact's
        tangential force and its tension beyond the flow's loss threshold, a gap's
        penetration, a stick bond's excess over its strength, a weakening bond's slip past
        d_c. A violation that returns shrinking by :data:`APPROACH` each time converges on
        the tie (a Zeno sequence), so it is not counted as a cycle: in a 32^2 indentation a
        site's tangential force at its loss went 3e-4, 4e-6, 4e-8 before it stayed out."""
        fz, fx, dep = self.fields(self.s, self.D)
        if kind == EventKind.LOST:  # the flow finds a loss at a tension of 2 TIE fs
            return abs(float(fx[j])) + max(-float(fz[j]) - 2 * TIE * self.fscale(), 0.0)
        if kind == EventKind.GAINED:
            return -float(self.gaps(fz, fx, dep)[j])
        if kind == EventKind.RESIDUAL:
            r = int(np.flatnonzero(self.lin.sites == j)[0])
            return float(self.delta[j] + self.s[r] - self.law.dc)
        return abs(float(fx[j])) - float(self.law.lam(self.delta[j:j + 1])[0] * fz[j])

    def _cycle(self, kind: str, j: int, where: str, times: int = VISITS - 1) -> EventCycle:
        """The error of a state met again (:data:`VISITS`), naming the drive and the site."""
        return EventCycle(f"the events cycle {where} at "
                          f"{'D_x' if self.drive == 'x' else 'D_z'} = {self.D!r}: {str(kind)!r} at "
                          f"site {j} came back {times} times (no quasi-static continuation)")

    def unstable_mode(self, forcing: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """The direction a burst leaves in: the mode of dR/ds of the largest real part, with
        the sign in which it is forced (its left eigenvector against ``forcing``, the rate of
        R along the path that led here, :meth:`approach_forcing`; where that is None or
        within the path's ties of zero, as at a fold, against dR/dD), the bonds it would
        take back held (the decoupled law's rule at a fold); and that real part relative to
        the stiffest bond's (the diagonal of dR/ds), the mode's rate."""
        JA = self.jacobian(self.s, self.D)
        w, vl, vr = linalg.eig(JA[:, :-1], left=True, right=True)
        i = int(np.argmax(w.real))
        v, u = np.real(vr[:, i]), np.real(vl[:, i])
        if float(u @ v) < 0:
            u = -u
        f = JA[:, -1]
        if forcing is not None:
            # the tangent's components are decided to TIE of its norm (the path's ties): a
            # forcing within that of zero on u does not sign the mode
            tn = float(np.abs(self._approach[1]).max()) if self._approach else 1.0
            floor = TIE * tn * float(np.abs(JA).sum(axis=1).max(initial=0.0)) * float(
                np.abs(u).sum())
            if abs(float(u @ forcing)) > floor:
                f = forcing
        if float(u @ f) < 0:
            v = -v
        vp = np.maximum(v, 0.0)
        return vp if vp.any() else np.abs(v), float(w[i].real) * self._rate_scale(JA)

    def approach_forcing(self) -> np.ndarray | None:
        r"""The rate of R, in the current sets, along the tangent of the path that led to the
        current point (a bond that joined since moves at the rate 0): :math:`J_A t`, None
        when no path led here.

        It signs the unstable mode as the viscous law :math:`\eta\dot s = \max(e, 0)` does
        as :math:`\eta \to 0`. Linearised at the event, the bonds that moved before it lag
        behind the curve by :math:`\eta` times their rates :math:`\tau_s` (:math:`\tau =
        t/t_D`), and the drive adds :math:`\partial R/\partial D`; on the mode (rate
        :math:`\mu`, left eigenvector :math:`u`) the two give the amplitude
        :math:`(\eta/\mu^2)(\mu\,u\cdot\tau_s + u\cdot\partial R/\partial D) =
        (\eta/\mu^2)\,u\cdot J_A\tau`, for any event. After a failure, :math:`J_A t` is
        the failed bond's rate of loading on its own row and vanishes on the others."""
        if self._approach is None:
            return None
        sites, t = self._approach
        P = self.lin.sites
        rate = dict(zip(sites.tolist(), t[:-1].tolist(), strict=True))
        tt = np.array([rate.get(int(p), 0.0) for p in P] + [float(t[-1])])
        return self.jacobian_times(self.s, self.D, tt)

    @staticmethod
    def _rate_scale(JA: np.ndarray) -> float:
        """The unit of a mode's rate: one over the largest diagonal entry of dR/ds."""
        return 1.0 / max(float(np.abs(np.diag(JA[:, :-1])).max(initial=0.0)),
                         np.finfo(float).tiny)

    def _push(self, mode: tuple[np.ndarray, float]) -> None:
        r"""Move the slips along a burst's unstable direction by the first of :data:`PUSHES`
        (in d_c) at which the mode grows at least at :data:`ESCAPE` and that is larger than
        a push the flow brought back.

        A fold is located to a tolerance on its stable side: there the mode's rate is
        :math:`\approx 0` and grows with the push :math:`x` as :math:`2ax` (the path's
        quadratic term), so a tiny push leaves the flow at the residual's rounding floor,
        where the integrator's steps stay bounded and the escape takes unbounded time. A
        slowly growing mode pushed along its positive part (the bonds it would take back
        held) can decay below the rest tolerance before it grows; the polish then returns
        to the state pushed from, with no set changed. The landing does not depend on the
        push once the flow escapes (the polish finds the same rest); a state no push leaves
        is refused. Past the ladder, a mode that grows but leaves the excess below the flow's
        threshold is pushed by the root of its quadratic (:meth:`_flat_push`)."""
        v, rate = mode
        v = v / max(float(np.abs(v).max()), 1e-300)
        s0 = self.s.copy()
        first = 0
        if self._origin is not None:
            changes, s_prev, level = self._origin
            if (changes == self.changes and s_prev.size == s0.size
                    and float(np.abs(s0 - s_prev).max(initial=0.0))
                    <= 0.5 * PUSHES[level] * self.law.dc):
                first = level + 1
        for level in range(first, len(PUSHES)):
            self.s = s0 + PUSHES[level] * self.law.dc * v
            if level != 0 and rate < ESCAPE:
                rate = self._mode_rate()
            if rate >= ESCAPE and (float(np.abs(self.residual(self.s, self.D)).max())
                                   >= FLOW_EPS * self.fscale()):
                break
        else:
            level = len(PUSHES) - 1
            x = self._flat_push(s0, v) if first < len(PUSHES) and rate >= ESCAPE else None
            if x is None and rate >= ESCAPE:
                landing = self._weak_landing(s0, v)
                if landing is not None:  # the rest the flow reaches, found directly
                    self.s, self._origin, self._pushed = landing, None, False
                    self.weak_landings += 1
                    return
            if x is None:
                self.s = s0
                raise NumericalError(
                    f"coupled slip-weakening: a burst cannot leave the state at "
                    f"{'D_x' if self.drive == 'x' else 'D_z'} = {self.D!r}: its mode grows "
                    f"at {rate:.2e} of the stiffest bond's rate, or the flow came back, after "
                    f"a push of {PUSHES[-1]:g} d_c and the push its excess's quadratic gives")
            self.s = s0 + x * self.law.dc * v
        self._origin = (self.changes, s0, level)
        self._pushed = True

    def _mode_rate(self) -> float:
        """The largest real part of the eigenvalues of dR/ds at the current slips, in the
        stiffest bond's rate (:meth:`_rate_scale`)."""
        JA = self.jacobian(self.s, self.D)
        return float(linalg.eigvals(JA[:, :-1]).real.max()) * self._rate_scale(JA)

    def _flat_push(self, s0: np.ndarray, v: np.ndarray) -> float | None:
        r"""The push, in d_c, that takes a growing mode out of a flat valley, or None.

        Past the largest of :data:`PUSHES` the mode may still grow (its rate at least
        :data:`ESCAPE`) while the excess stays below the flow's threshold :data:`FLOW_EPS`:
        the residual's quadratic term along the mode is small. On the ray
        :math:`s_0 + x\,d_c v` the residual is exactly quadratic in :math:`x` (module
        docstring), :math:`R(x) = R_0 + x\,r_1 + x^2 r_2`, so the least :math:`x` at which
        :math:`\max_i R_i` reaches :data:`FLAT` times FLOW_EPS of the largest normal force is solved
        for, not searched (:func:`_least_crossing`). Every state on the ray before it has an
        excess below FLAT flow thresholds, within a small factor of the flow's own
        resolution, so the ray stands for the flow it cannot integrate; an event on the way
        (a constraint :meth:`_violation` finds) ends the push just past its root, located by
        bisection to ``TIE`` of the push, and the burst applies it there. None when no
        excess reaches the target along the ray, or the mode does not grow at the push."""
        dc = self.law.dc
        R0 = self.residual(s0, self.D)
        Rp = self.residual(s0 + dc * v, self.D)
        Rm = self.residual(s0 - dc * v, self.D)
        r1, r2 = 0.5 * (Rp - Rm), 0.5 * (Rp + Rm) - R0
        target = FLAT * FLOW_EPS * self.fscale()
        x = _least_crossing(R0 / target, r1 / target, r2 / target)
        if x is None:
            return None
        x *= 1 + 1e-9
        self.s = s0 + x * dc * v
        if self._violation() is not None:
            lo, hi = 0.0, x
            for _ in range(200):
                if hi - lo <= TIE * hi:
                    break
                mid = 0.5 * (lo + hi)
                self.s = s0 + mid * dc * v
                if self._violation() is None:
                    lo = mid
                else:
                    hi = mid
            x = hi
            self.s = s0 + x * dc * v
        rate = self._mode_rate()
        self.s = s0
        return x if rate >= ESCAPE else None

    def _weak_landing(self, s0: np.ndarray, v: np.ndarray) -> np.ndarray | None:
        r"""The stable rest that the flow from ``s0`` along a weakly growing mode ``v``
        reaches, found by Newton's method instead of the flow, or None.

        A mode that grows at little more than :data:`ESCAPE` can stop growing within a
        fraction of :math:`d_c`: the excess along it rises to a maximum below the flow's
        threshold :data:`FLOW_EPS` and falls to a second root, a stable rest. The flow cannot
        resolve that rise, and the rest polish returns to ``s0``. On the ray
        :math:`s_0 + x\,d_c v` the first push of :data:`PUSHES` at which the mode decays
        lies past the excess's maximum, where Newton's method on :math:`R = 0` goes to that
        second root (in the one-dimensional reduction :math:`R = ax - bx^2`, beyond
        :math:`a/2b` the iteration converges to :math:`a/b`). The root is the landing if the
        slips only grew on the way to it (the law's :math:`\dot s \ge 0`), it lies at least a
        quarter of that push from ``s0``, no constraint is violated and no excess falls below
        the flow's stop threshold on the segment to it (16 points: no bond stops on the way)
        and it is stable; None otherwise."""
        dc, fs = self.law.dc, self.fscale()
        for x in PUSHES:
            self.s = s0 + x * dc * v
            if self._violation() is not None:
                break
            if self._mode_rate() >= 0:
                continue
            if not self._polish(fs):
                break
            s1, ds = self.s.copy(), self.s - s0
            if (float(ds.min(initial=0.0)) < -TIE * x * dc
                    or float(np.abs(ds).max(initial=0.0)) < 0.25 * x * dc):
                break
            for t in np.linspace(0.0, 1.0, 17)[1:]:
                self.s = s0 + t * ds
                if (self._violation() is not None or float(
                        self.residual(self.s, self.D).min(initial=0.0)) < -FLOW_EPS * fs):
                    self.s = s0  # an event, or a bond the flow would stop, on the way
                    return None
            self.s = s1
            if self.stable():
                return s1
            break
        self.s = s0
        return None

    def _polish(self, fs: float) -> bool:
        """Newton's method on R = 0 from the current slips, to 1e-14 of the force unit ``fs``
        in :data:`NEWTON` iterations; whether it got there."""
        for _ in range(NEWTON):
            R = self.residual(self.s, self.D)
            if np.abs(R).max(initial=0.0) <= 1e-14 * fs:
                return True
            self.s = self.s - linalg.solve(self.jacobian(self.s, self.D)[:, :-1], R)
        return False

    def _rest(self) -> bool:
        """At rest: arrested bonds stick, the others are polished to R = 0 by Newton, and the
        state is stable (else pushed along its unstable mode)."""
        fs = self.fscale()
        R = self.residual(self.s, self.D)
        if self._pushed or R.max(initial=0.0) > FLOW_EPS * fs:
            return False
        arrested = (R < -REST * fs) & self._reversible()
        for j in self.lin.sites[arrested]:
            self.apply(EventKind.STICK, int(j))
        if not self._polish(fs):
            return False
        if self._violation() is not None:
            return False
        if self.stable():
            return True
        self._push(self.unstable_mode())
        return not self._pushed  # a weak mode's landing is a stable rest (_weak_landing)

    def _flow(self) -> None:
        r"""Integrate the overdamped law (BDF) to its next event or to rest. The rate is
        smooth on the mobile bonds (:math:`\dot s = e`); a bond whose excess falls below
        :data:`FLOW_EPS` of the largest normal force stops (an event), and one stopped comes
        back when its excess rises above it: the kink of :math:`\max(e, 0)` is an event,
        never a step."""
        D, fs, law = self.D, self.fscale(), self.law
        P = self.lin.sites
        held = np.isin(P, np.fromiter(self._stopped, dtype=np.int64, count=len(self._stopped)))
        # the thresholds are crossings inside a flow; a change of the sets between flows can
        # put a bond past one, and a stopped bond beyond it would never start again
        R0 = self.residual(self.s, D)
        self._stopped.difference_update(P[held & (R0 > FLOW_EPS * fs)].tolist())
        self._stopped.update(P[~held & (R0 < -FLOW_EPS * fs)].tolist())
        M = ~np.isin(P, np.fromiter(self._stopped, dtype=np.int64, count=len(self._stopped)))
        Js0 = self.jacobian(self.s, D)[:, :-1]
        c = 1.0 / max(float(np.abs(np.diag(Js0)).max(initial=0.0)), np.finfo(float).tiny)
        # an implicit step longer than 2/mu damps a mode growing at the rate mu: the flow
        # would settle on an unstable equilibrium. The steps stay below 1/omega <= 1/mu,
        # omega the mobile bonds' block's numerical abscissa at the flow's start.
        grow = _growth_bound(c * Js0[np.ix_(M, M)])
        max_step = 1.0 / grow if grow > 0 else np.inf
        B = np.flatnonzero(self.Q & (self.phase == STICK))
        Wr = np.flatnonzero((self.phase[P] == WEAK) & M)
        Cs = np.flatnonzero(self.C)

        memo: dict[str, tuple[np.ndarray, object]] = {}

        def at(name, y, fn):  # the events see one point at a time: each field once
            got = memo.get(name)
            if got is None or not np.array_equal(got[0], y):
                got = memo[name] = (y.copy(), fn(y, D))
            return got[1]

        def residual(y):
            return at("R", y, self.residual)

        def fields(y):
            return at("f", y, self.fields)

        evals, drive = 0, "D_x" if self.drive == "x" else "D_z"

        def rate(t, y):
            nonlocal evals
            evals += 1
            if evals > FLOW_EVALS:
                raise NumericalError(
                    f"coupled slip-weakening: a burst's flow at {drive} = {D!r} reached no "
                    f"event in {FLOW_EVALS} evaluations (it stalled near a rest it cannot "
                    "leave)")
            return c * np.where(M, residual(y), 0.0)

        def jac(t, y):
            return c * M[:, None] * self.jacobian(y, D)[:, :-1]

        def join(t, y):
            fz, fx, _ = fields(y)
            return float((np.abs(fx[B]) - law.lam(self.delta[B]) * fz[B]).max()) / fs - 2 * REST

        def resid(t, y):
            return float((law.dc - self.delta[P[Wr]] - y[Wr]).min()) / law.dc

        def lost(t, y):
            return float(fields(y)[0][Cs].min()) / fs + 2 * TIE

        def stop(t, y):
            return float(residual(y)[M].min()) / fs + FLOW_EPS

        def go(t, y):
            return float(residual(y)[~M].max()) / fs - FLOW_EPS

        def calm(t, y):  # at rest to the polish's reach
            return float(np.abs(residual(y)[M]).max()) / fs - 0.1 * REST

        events = []
        for fn, on, sign in ((join, B.size, 1), (resid, Wr.size, -1), (lost, Cs.size, -1),
                             (stop, M.any(), -1), (go, (~M).any(), 1), (calm, M.any(), -1)):
            if on:
                fn.terminal, fn.direction = True, sign
                events.append(fn)
        self._pushed = False
        # BDF's difference table can overflow on the huge steps it takes at rest: then the
        # same flow again over shorter horizons (the burst's loop goes on from its end)
        for span in FLOW_SPANS:
            evals = 0  # each horizon gets its own budget of evaluations
            try:
                with np.errstate(over="raise", invalid="raise"):
                    sol = solve_ivp(rate, (0.0, span), self.s, method="BDF", jac=jac,
                                    events=events, rtol=1e-9, atol=1e-12 * law.dc,
                                    max_step=max_step)
                break
            except FloatingPointError:
                continue
        else:
            raise NumericalError("coupled slip-weakening: the burst's flow overflowed")
        if sol.status < 0:
            raise NumericalError(f"coupled slip-weakening: the burst's flow failed: "
                                 f"{sol.message}")
        self.s = sol.y[:, -1].copy()
        if sol.status != 1:
            return
        R = self.residual(self.s, D)
        for fn, te in zip(events, sol.t_events, strict=True):
            if not te.size:
                continue
            if fn is resid:
                r = int(np.argmin(law.dc - self.delta[P[Wr]] - self.s[Wr]))
                self.apply(EventKind.RESIDUAL, int(P[Wr][r]))
            elif fn is stop:
                self._stopped.add(int(P[M][np.argmin(R[M])]))
            elif fn is go:
                self._stopped.discard(int(P[~M][np.argmax(R[~M])]))

    def totals(self) -> tuple[float, float]:
        fz, fx, _ = self.fields(self.s, self.D)
        return float(fx.sum()), float(fz.sum())


class WeakeningContact(_Events, _Core):
    __doc__ = _Core.__doc__

    def signature(self) -> bytes:
        """The discrete state: contact, bonds, phases and slip directions."""
        return digest(self.C, self.Q, self.phase, self.sigma)

    def snapshot(self) -> Snapshot:
        fz, fx, _ = self.fields(self.s, self.D)
        F_x, F_z = float(fx.sum()), float(fz.sum())
        return Snapshot(F_x, F_z, self.D if self.drive == "x" else 0.0, self._grid(fz).copy(),
                        self._grid(fx).copy(), self._grid(self.Q & (self.phase == STICK)).copy(),
                        self._grid(self.C).copy())

    def depth_now(self) -> float:
        return self.fields(self.s, self.D)[2]

    def run(self, limit: int, end: tuple[str, float] | None = None) -> EventPath:
        """Follow the path from the current point: a pull (``drive`` x) until no bond sticks
        or weakens, a driven depth until ``end`` (``("depth", D_z)`` or ``("force", F_z)``).
        Every burst is recorded by the failures inside it and its landing (``"jump"``); the
        peak is the largest F_x of the stable path (its interior maxima located) and the
        landings."""
        self.relinearize()
        self._approach = None  # a tangent of an earlier run or drive signs nothing here
        path = EventPath([], None, self.snapshot())

        def record(kind: str, site: int, F: float | None = None) -> None:
            F_x, F_z = self.totals()
            path.events.append(Event(self.D if self.drive == "x" else 0.0,
                                     F_x if F is None else F, F_z, kind, site,
                                     self.depth_now()))
            path.counts.append((int(self.C.sum()), int((self.Q & (self.phase == STICK)).sum())))

        def on_point(s: np.ndarray, D: float) -> None:
            if self.drive != "x":
                return
            lin = self.lin
            F = float(lin.spread(lin.fx0 + D * lin.fx1, s, lin.Nx).sum())
            if F > path.peak.fx_total:
                path.peak = self.snapshot()
                path.peak_event = len(path.events)

        def relax(push=None, forcing=None) -> None:
            if push is None and self._violation() is None and self.stable():
                return
            for k_in, j_in, F_in in self.burst(push, forcing):
                record(k_in, j_in, F_in)
            self.certify()
            record(EventKind.JUMP, -1)
            on_point(self.s, self.D)

        seen: dict[tuple, int] = {}
        seen_at = self.D
        record(EventKind.START, -1)
        try:
            relax()
            path.peak = self.snapshot() if self.drive == "x" else path.peak
            while True:
                if self.drive == "x" and not self.holds():
                    break
                if len(path.events) > limit:
                    path.message = f"stopped after {limit} events"
                    break
                kind, j = self.advance(end, on_point)
                if self.D != seen_at:
                    seen.clear()
                    seen_at = self.D
                key = (str(kind), j, self.signature())
                seen[key] = seen.get(key, 0) + 1
                if seen[key] >= VISITS:
                    raise self._cycle(kind, j, "on the path")
                if not self.scaled and self.D > 0:
                    self.scale, self.scaled = self.D, True
                if kind == EventKind.END:
                    self.certify()
                    record(kind, -1)
                    break
                if kind == "fold":
                    relax(self.unstable_mode())
                    continue
                record(kind, j)
                self.apply(kind, j)
                self.certify()
                relax(forcing=self.approach_forcing)
        except EventCycle as exc:
            if self.drive != "x":
                raise
            path.message = str(exc)  # the pull ends there, not converged
        return path


def settle(wc: WeakeningContact) -> int:
    """Relax the state at its drive when it is not admissible or not stable (a burst,
    module docstring); returns the bonds that failed on the way."""
    wc.relinearize()
    if wc._violation() is None and wc.stable():
        return 0
    failed = wc.burst()
    wc.certify()
    return len(failed)


@dataclass
class WeakeningSqueeze:
    """A history's outcome under slip-weakening: the state at :math:`D_x = 0` and what it
    took."""

    state: WeakeningContact
    released: int
    states: int


def squeeze_weakening(problem, solver, setup, law: Weakening, history: str
                      ) -> WeakeningSqueeze:
    """The squeeze histories under slip-weakening (docs/theory/coupled.rst#coupled-weakening):

    * ``"frictionless"``: the frictionless squeeze, every contact bonded where it is;
    * ``"bonded"`` and ``"simultaneous"``: every contact of the bonded squeeze bonded with
      :math:`u_x = 0`, then released by the law's own overdamped flow, which moves every
      overloaded bond at once and has no order: under this law the two coincide;
    * ``"indent"``: the frictional indentation from first touch, the depth driven, every
      site bonding where it touches and failing by the law.
    """
    from roughslip.coupling.histories import _bonded_overlap
    from roughslip.coupling.histories import frictionless as frictionless_history

    n = problem.base.size
    if history == "frictionless":
        sq = frictionless_history(problem, solver, setup)
        st = sq.state
        wc = WeakeningContact(solver, problem, law, st.C, st.offset, depth=setup.depth,
                              force=setup.force, tol=setup.tol)
        return WeakeningSqueeze(wc, settle(wc), sq.states)
    if history in ("bonded", "simultaneous"):
        st, k = _bonded_overlap(problem, solver, setup)
        wc = WeakeningContact(solver, problem, law, st.C, np.zeros(n), depth=setup.depth,
                              force=setup.force, tol=setup.tol)
        wc.relinearize()
        released = settle(wc)
        return WeakeningSqueeze(wc, released, k + wc.bursts)
    if history == "indent":
        if setup.depth is not None:
            end, scale_depth = ("depth", float(setup.depth)), float(setup.depth)
        else:
            end = ("force", float(setup.force))
            scale_depth = 0.0 if setup.force == 0 else setup.normal(problem).depth
        top = (problem.base >= 0.0).ravel()
        wc = WeakeningContact(solver, problem, law, top, np.zeros(n), depth=scale_depth,
                              drive="z", gained="bonded", tol=setup.tol)
        path = wc.run(setup.limit, end=end)
        if path.message:
            raise NumericalError(f"coupled indentation: {path.message}")
        wc.rebase()
        dz = wc.D
        wc.drive, wc.D, wc.gained = "x", 0.0, "unbonded"
        wc.scaled, wc.scale = False, 1.0
        wc.depth, wc.force = (dz, None) if setup.force is None else (None, setup.force)
        released = int((wc.Q & (wc.phase != STICK)).sum())
        settle(wc)
        return WeakeningSqueeze(wc, released, len(path.events))
    raise NumericalError(f"coupled slip-weakening: no history {history!r}")
