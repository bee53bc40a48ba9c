"""Where slip-weakening bursts land: the least equilibrium on straight steps against the flow.

    python scripts/burst_landings.py [--sizes 32 48 64] [--seeds 1 2 3] [--depths 1.0 2.5]
                                     [--laws 0:0.05 0.1:0.01] [--threads 2]

``pull()`` lands each burst of the decoupled slip-weakening law on the least equilibrium above
the fold, followed on straight steps (roughslip.friction.least), and falls back on the
overdamped flow itself, integrated piece by piece (roughslip.friction.relax), where no step
keeps every slip from going back. This script pulls each scene twice, once as ``pull()`` does
and once with the flow on every burst, and compares every landing. Columns:

* ``bursts``: landings compared; ``flow``: those where the steps fell back on the flow;
* ``moving``: landings with the flow's moving bonds; ``fail``: those whose failures inside
  the burst are the flow's too, as sets (the flow can let a moving bond stop and fail again,
  which counts once more);
* ``slip``: the largest difference of the slips, relative to the largest slip of the pull;
* ``exc steps`` / ``exc flow``: the largest excess of a moving bond over its strength at a
  landing (0 at an exact equilibrium), relative to the largest normal force;
* ``F diff``: the relative difference of the friction forces;
* ``s steps`` / ``s flow``: seconds of each pull.

Scenes: a self-affine surface (H = 0.8, rms height 1, seed ``seed``, oversampled twice) on an
N x N open grid, pressed to ``depth`` (rms heights) with nu = 0.3, lam_s = 0.2 and each
``lam_d:d_c`` of ``--laws``; the pulls run to full sliding (no early stop).
"""

from __future__ import annotations

import argparse
import time
from unittest import mock

import numpy as np

from roughslip import pull
from roughslip.contact.squeeze import squeeze
from roughslip.friction import least, weakening
from roughslip.surfaces.synthetic import sample_rng, self_affine


def _pull(normal, lam_d: float, dc: float, threads: int, flow: bool) -> tuple:
    """One pull and every landing: (moving, slips, failures, excess), the friction force,
    the bursts that fell back on the flow, the seconds."""
    landings, fell = [], []
    steps = least.land
    keep = weakening.WeakeningState._land

    def land(*args, **kw):
        out = None if flow else steps(*args, **kw)
        fell.append(out is None)
        return out

    def record_landing(self, landing):
        rx = self._relax
        w0 = self._burst_slips
        force = self._burst_forces - rx.response.times(landing.w - w0)
        cap = rx.strength(landing.delta) * rx.fz
        P = landing.moving & ~((rx.lam_d == 0) & (landing.delta >= rx.dc))
        exc = float(np.abs(landing.sigma * force - cap)[P].max(initial=0.0)) / rx.fs
        landings.append((landing.moving.copy(), landing.w.copy(),
                         sorted(i for i, _, _ in landing.failures), exc))
        return keep(self, landing)

    burst = weakening.WeakeningState._burst

    def capture(self, D, p, s):
        b = self.b
        self._burst_forces = self.forces(D)
        u = b.apply(b.field(self._burst_forces), np.empty(b.shape)).ravel()[b.sites]
        self._burst_slips = np.where(self.phase == weakening.STICK, self.s0, D - u)
        return burst(self, D, p, s)

    with mock.patch.object(weakening.least, "land", land), \
            mock.patch.object(weakening.WeakeningState, "_land", record_landing), \
            mock.patch.object(weakening.WeakeningState, "_burst", capture):
        t0 = time.perf_counter()
        r = pull(normal, lam=0.2, slip_law="slip-weakening", lam_dynamic=lam_d,
                 slip_distance=dc, early_stop=False, threads=threads)
        secs = time.perf_counter() - t0
    return landings, r.friction_force, sum(fell), secs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 48, 64])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--depths", type=float, nargs="+", default=[1.0, 2.5])
    ap.add_argument("--laws", nargs="+", default=["0:0.05", "0.1:0.01"])
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    print(f"{'N':>3} {'seed':>4} {'depth':>5} {'lam_d':>5} {'d_c':>5} {'bonds':>5} "
          f"{'bursts':>6} {'flow':>4} {'moving':>6} {'fail':>4} {'slip':>8} {'exc steps':>9} "
          f"{'exc flow':>9} {'F diff':>8} {'s steps':>7} {'s flow':>7}")
    total = same_moving = same_fail = 0
    for n in args.sizes:
        for seed in args.seeds:
            h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0),
                            oversample=2)
            for depth in args.depths:
                normal = squeeze(h, depth=depth, nu=0.3, tol=1e-12)
                for law in args.laws:
                    lam_d, dc = map(float, law.split(":"))
                    a, fa, fell, ta = _pull(normal, lam_d, dc, args.threads, flow=False)
                    b, fb, _, tb = _pull(normal, lam_d, dc, args.threads, flow=True)
                    if len(a) != len(b):
                        raise SystemExit(f"N={n} seed {seed} depth {depth} {law}: "
                                         f"{len(a)} landings against the flow's {len(b)}")
                    moving = sum(np.array_equal(x[0], y[0]) for x, y in zip(a, b, strict=True))
                    fail = sum(x[2] == y[2] for x, y in zip(a, b, strict=True))
                    scale = max((float(np.abs(y[1]).max()) for y in b), default=1.0)
                    slip = max((float(np.abs(x[1] - y[1]).max()) / scale
                                for x, y in zip(a, b, strict=True)), default=0.0)
                    total += len(a)
                    same_moving, same_fail = same_moving + moving, same_fail + fail
                    print(f"{n:>3} {seed:>4} {depth:>5g} {lam_d:>5g} {dc:>5g} "
                          f"{int(normal.contact.sum()):>5} {len(a):>6} {fell:>4} "
                          f"{moving:>6} {fail:>4} "
                          f"{slip:>8.1e} {max((x[3] for x in a), default=0):>9.1e} "
                          f"{max((y[3] for y in b), default=0):>9.1e} "
                          f"{abs(fa - fb) / abs(fb):>8.1e} {ta:>7.2f} {tb:>7.2f}", flush=True)
    print(f"# of {total} landings, {same_moving} with the flow's moving bonds and {same_fail} "
          "with its failures")


if __name__ == "__main__":
    main()
