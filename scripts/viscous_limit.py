"""The decoupled slip-weakening pull against the viscous limit of its own law, on rough scenes.

    python scripts/viscous_limit.py [--sizes 32] [--seeds 1 2 3] [--depths 1.0 2.5]
                                    [--laws 0:0.01 0:0.05 0.1:0.01 0.1:0.05]
                                    [--etas 1e-6 1e-7 1e-8] [--bursts-only] [--json FILE]

``pull()`` resolves a burst (a failure that the held drive cannot keep stable) as the limit of
a dynamics, without integrating the dynamics over the pull: the least equilibrium above the
fold (roughslip.friction.least), or the relaxation at the held drive in closed form, piece by
piece (roughslip.friction.relax). This script checks that against
the dynamics itself, an overdamped slip rate, integrated over the whole pull. With the drive
:math:`D = t` and :math:`f = G_{xx}^{-1}(D - w)` on the bonds (:math:`w` their slips),

.. math:: \\dot w_i = \\mathrm{sign}(f_i)\\,\\max(|f_i| - \\lambda(\\delta_i) f_{z,i},\\,0)/\\eta,
          \\qquad \\dot\\delta_i = |\\dot w_i|,

with :math:`\\lambda(\\delta) = \\lambda_s - (\\lambda_s - \\lambda_d)\\min(\\delta/d_c, 1)`, the
law of ``pull(..., slip_law="slip-weakening")``. Between bursts the quasi-static path is its
:math:`\\eta \\to 0` limit; inside a burst, the limit is whatever the dynamics does at the held
drive.

For each scene the script integrates this system with a stiff solver (SciPy's BDF with the
exact Jacobian, relative tolerance ``--rtol``; Radau gives the same forces to the tolerance at
four times the cost) for each viscosity in ``--etas`` until every bond slips at its residual
strength. The friction force is the largest :math:`F_x = \\sum f_i`: taken at every step,
each maximum near the largest refined on the solver's dense output. The forces are
extrapolated linearly in :math:`\\eta` to :math:`\\eta = 0` from the two smallest
viscosities. They must be small: a burst that starts from a weakly unstable state (growth
rate :math:`|\\mu|` in the fast time :math:`t/\\eta`) lets the viscous pull overshoot the
state that sets it off by a drive of about :math:`\\eta \\log(C/\\eta)/|\\mu|`, and the force
with it. That is linear in :math:`\\eta` only for :math:`\\eta \\ll C`, which on these scenes
can be as small as :math:`10^{-4}`: from :math:`\\eta = 10^{-5}` and :math:`3\\cdot10^{-5}` the
extrapolation overshoots by up to 0.05 %. Columns:

* ``err``: the spread of that extrapolation against the one from the two largest viscosities
  (the extrapolation's error);
* ``solver``: the solver's error, the change of the force at the smallest viscosity when the
  tolerance is divided by ten, times what the extrapolation multiplies it by;
* ``diff``: ``pull()``'s friction force against the extrapolated one, relative; ``ok`` says
  whether it is within ``err + solver``;
* ``bursts``: the bursts of ``pull()``'s path (its ``"jump"`` events).

Scenes: a self-affine surface (H = 0.8, rms height 1, seed ``seed``, oversampled twice) on an
N x N open grid, pressed to ``depth`` (rms heights) with nu = 0.3, lam_s = 0.2 and each
``lam_d:d_c`` of ``--laws``. The viscosity is in units of the force over the slip rate (E = 1,
pixel side 1, so a bond's relaxation time is about eta).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from dataclasses import asdict, dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from roughslip import pull
from roughslip.contact.squeeze import squeeze
from roughslip.friction.bonds import Bonds
from roughslip.friction.events import EventKind
from roughslip.surfaces.synthetic import sample_rng, self_affine


@dataclass
class Scene:
    """One rough scene and its slip-weakening law."""

    n: int
    seed: int
    depth: float
    lam_d: float
    dc: float
    lam_s: float = 0.2
    nu: float = 0.3


class Viscous:
    """The overdamped pull of the bonds ``b`` (module docstring), state ``y = [w, delta]``."""

    def __init__(self, b: Bonds, lam_s: float, lam_d: float, dc: float, eta: float) -> None:
        self.K = np.linalg.inv(b.dense())
        self.K1 = self.K.sum(axis=1)
        self.fz = b.fz.astype(float)
        self.lam_s, self.lam_d, self.dc, self.eta = lam_s, lam_d, dc, eta
        self.n = b.n

    def forces(self, t: float, w: np.ndarray) -> np.ndarray:
        return self.K1 * t - self.K @ w

    def _parts(self, t: float, y: np.ndarray):
        n = self.n
        w, delta = y[:n], y[n:]
        f = self.forces(t, w)
        weak = delta < self.dc
        lam = np.where(weak, self.lam_s - (self.lam_s - self.lam_d) * delta / self.dc,
                       self.lam_d)
        excess = np.abs(f) - lam * self.fz
        active = excess > 0
        s = np.sign(f)
        return f, s, weak, excess, active

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        _, s, _, excess, active = self._parts(t, y)
        rate = np.where(active, excess, 0.0) / self.eta
        return np.concatenate([s * rate, rate])

    def jac(self, t: float, y: np.ndarray) -> np.ndarray:
        n = self.n
        _, s, weak, _, active = self._parts(t, y)
        J = np.zeros((2 * n, 2 * n))
        a = np.flatnonzero(active)
        if a.size:
            soft = (self.lam_s - self.lam_d) * self.fz[a] / self.dc * weak[a]
            # d|f_i|/dw_j = -s_i K_ij
            J[np.ix_(a, np.arange(n))] = -self.K[a, :] / self.eta  # s_i * (-s_i K_ij)
            J[np.ix_(n + a, np.arange(n))] = -(s[a, None] * self.K[a, :]) / self.eta
            J[a, n + a] = s[a] * soft / self.eta
            J[n + a, n + a] = soft / self.eta
        return J

    def friction(self, t_end: float, rtol: float) -> tuple[float, int]:
        """The largest F_x on [0, t_end] and the number of steps. F_x is taken at every step
        and each maximum among them within 1e-3 of the largest is refined on the solver's
        dense output (its interpolation error is of the order of ``rtol``)."""
        n = self.n
        sol = solve_ivp(self.rhs, (0.0, t_end), np.zeros(2 * n), method="BDF", jac=self.jac,
                        rtol=rtol, atol=rtol * 1e-3, dense_output=True)
        if sol.status < 0:
            raise RuntimeError(f"the viscous pull failed: {sol.message}")
        F = self.K1.sum() * sol.t - self.K1 @ sol.y[:n]
        best = float(F.max())
        k = np.flatnonzero((F >= best - 1e-3 * abs(best))
                           & (F >= np.r_[-np.inf, F[:-1]]) & (F >= np.r_[F[1:], -np.inf]))
        for i in k:
            lo, hi = sol.t[max(i - 1, 0)], sol.t[min(i + 1, F.size - 1)]
            if hi <= lo:
                continue
            r = minimize_scalar(lambda t: -float(self.K1.sum() * t - self.K1 @ sol.sol(t)[:n]),
                                bounds=(lo, hi), method="bounded",
                                options={"xatol": 1e-14 * max(1.0, hi)})
            best = max(best, -float(r.fun))
        return best, int(sol.t.size)


def contact(sc: Scene):
    h = self_affine((sc.n, sc.n), hurst=0.8, rms_height=1.0, rng=sample_rng(sc.seed, 0),
                    oversample=2)
    return squeeze(h, depth=sc.depth, nu=sc.nu, tol=1e-12)


def study(sc: Scene, etas: list[float], rtol: float) -> dict:
    normal = contact(sc)
    res = pull(normal, lam=sc.lam_s, slip_law="slip-weakening", lam_dynamic=sc.lam_d,
               slip_distance=sc.dc, tol=1e-12)
    bursts = res.curve.kind.count(EventKind.JUMP)
    b = Bonds(normal, sc.lam_s)
    t_end = 1.2 * float(res.curve.drive.max()) + 10 * sc.dc + 10 * max(etas)
    forces, steps, secs = [], [], []
    for eta in etas:
        t0 = time.perf_counter()
        F, k = Viscous(b, sc.lam_s, sc.lam_d, sc.dc, eta).friction(t_end, rtol)
        forces.append(F)
        steps.append(k)
        secs.append(time.perf_counter() - t0)
    e = np.array(etas)
    order = np.argsort(e)
    e, F = e[order], np.array(forces)[order]
    # the solver's error: the smallest viscosity again at a tenth of the tolerance
    t0 = time.perf_counter()
    finer, _ = Viscous(b, sc.lam_s, sc.lam_d, sc.dc, float(e[0])).friction(t_end, rtol / 10)
    secs.append(time.perf_counter() - t0)
    solver = abs(finer - F[0]) / abs(finer)

    def linear(i: int, j: int) -> float:
        return float(F[i] - e[i] * (F[j] - F[i]) / (e[j] - e[i]))

    limit = linear(0, 1)
    err = abs(limit - linear(len(e) - 2, len(e) - 1)) / abs(limit) if len(e) > 2 else math.nan
    # the extrapolation multiplies the solver's errors by at most e1/(e1-e0) + e0/(e1-e0)
    amp = (e[1] + e[0]) / (e[1] - e[0])
    diff = (res.friction_force - limit) / limit
    return dict(**asdict(sc), bonds=b.n, bursts=bursts, pull=res.friction_force,
                etas=list(map(float, e)), forces=list(map(float, F)), steps=steps,
                seconds=secs, limit=limit, err=err, solver=amp * solver, diff=diff,
                ok=bool(abs(diff) <= err + amp * solver))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--depths", type=float, nargs="+", default=[1.0, 2.5])
    ap.add_argument("--laws", nargs="+", default=["0:0.01", "0:0.05", "0.1:0.01", "0.1:0.05"],
                    help="lam_dynamic:slip_distance")
    ap.add_argument("--etas", type=float, nargs="+", default=[1e-6, 1e-7, 1e-8])
    ap.add_argument("--rtol", type=float, default=1e-8)
    ap.add_argument("--bursts-only", action="store_true",
                    help="only the scenes whose pull() path has a burst")
    ap.add_argument("--json", help="write every row to this file")
    args = ap.parse_args()
    if len(args.etas) < 2:
        ap.error("--etas: at least two viscosities")
    print(f"# cores: {os.cpu_count()}; nu 0.3, lam_s 0.2; etas {args.etas}; rtol {args.rtol}")
    print(f"{'N':>3} {'seed':>4} {'depth':>5} {'lam_d':>5} {'d_c':>5} {'bonds':>5} "
          f"{'bursts':>6} {'pull()':>11} {'eta->0':>11} {'err':>8} {'solver':>8} {'diff':>9} "
          f"{'ok':>3} {'sec':>6}")
    rows = []
    for n in args.sizes:
        for seed in args.seeds:
            for depth in args.depths:
                for law in args.laws:
                    ld, dc = (float(v) for v in law.split(":"))
                    sc = Scene(n, seed, depth, ld, dc)
                    if args.bursts_only:
                        r = pull(contact(sc), lam=sc.lam_s, slip_law="slip-weakening",
                                 lam_dynamic=ld, slip_distance=dc, tol=1e-12)
                        if EventKind.JUMP not in r.curve.kind:
                            continue
                    row = study(sc, args.etas, args.rtol)
                    rows.append(row)
                    print(f"{n:>3} {seed:>4} {depth:>5.2g} {ld:>5.2g} {dc:>5.2g} "
                          f"{row['bonds']:>5} {row['bursts']:>6} {row['pull']:>11.7g} "
                          f"{row['limit']:>11.7g} {row['err']:>8.1e} {row['solver']:>8.1e} "
                          f"{row['diff']:>9.1e} "
                          f"{'yes' if row['ok'] else 'no':>3} {sum(row['seconds']):>6.1f}",
                          flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    bad = [r for r in rows if not r["ok"]]
    print(f"# {len(rows) - len(bad)} of {len(rows)} scenes: pull() within the extrapolation "
          f"error of the viscous limit; largest |diff| "
          f"{max((abs(r['diff']) for r in rows), default=0):.2e}")


if __name__ == "__main__":
    main()
