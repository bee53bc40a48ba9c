"""A burst's landing as the least equilibrium above its start (roughslip.friction.least):
against the overdamped flow with any mobilities on a cooperative system, against the flow of
roughslip.friction.relax on every burst of rough pulls, and as an equilibrium."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip import pull
from roughslip.contact.squeeze import squeeze
from roughslip.friction import least, relax
from roughslip.friction.response import DenseResponse
from roughslip.surfaces.synthetic import sample_rng, self_affine

LAM_S, LAM_D, DC = 0.2, 0.1, 0.05


def _cooperative(seed: int, n: int = 24):
    """A stiffness whose off-diagonal entries are all negative (a slip anywhere raises the
    force on every other bond), positive definite, and a fold: one bond at its strength
    whose softening exceeds its own stiffness, the rest stuck below theirs."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 6 * np.sqrt(n / 24), (n, 2))  # the same density at any n
    r = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    C = np.where(r > 0, 0.6 / (1 + r ** 3), 0.0)
    K = np.diag(C.sum(axis=1) + rng.uniform(0.3, 0.6, n)) - C
    fz = rng.uniform(0.5, 1.5, n)
    cap = LAM_S * fz
    f = cap * rng.uniform(0.6, 0.995, n)
    p = int(np.argmin(np.diag(K) / fz))
    f[p] = cap[p]
    moving = np.arange(n) == p
    sigma = np.where(moving, 1.0, 0.0)
    kap = (LAM_S - LAM_D) * fz[p] / DC
    assert kap > K[p, p]  # the failing bond alone is unstable
    return K, fz, f, sigma, moving, p


def _flow(K, fz, f, mobility, y0):
    """The overdamped slip rate dy/dt = m max(F(y), 0) with the excess F over the strength,
    integrated by a stiff solver until it rests (time in units of the viscosity)."""
    from scipy.integrate import solve_ivp

    def excess(y):
        lam = LAM_S - (LAM_S - LAM_D) * np.minimum(y / DC, 1.0)
        return f - K @ y - lam * fz

    sol = solve_ivp(lambda t, y: mobility * np.maximum(excess(y), 0.0), (0, 2e3), y0,
                    method="LSODA", rtol=1e-11, atol=1e-14)
    assert sol.success
    return sol.y[:, -1]


@pytest.mark.parametrize("seed", [2, 3, 5])
def test_on_a_cooperative_system_every_mobility_lands_on_the_least_equilibrium(seed):
    """The no-passing property: with nonpositive couplings the overdamped flow from the fold
    rests on the least equilibrium above it whatever the bonds' mobilities, and the straight
    steps of the module land exactly there (to the flows' resting tolerance)."""
    K, fz, f, sigma, moving, p = _cooperative(seed)
    n = f.size
    rx = relax.Relaxation(DenseResponse(K), fz, LAM_S, LAM_D, DC)
    land = least.land(rx, f, np.zeros(n), np.zeros(n), sigma, moving, p)
    assert land is not None and not land.stopped
    assert land.moving.sum() > 1 and land.failures  # a cascade, not one bond
    y0 = np.zeros(n)
    y0[p] = 1e-9 * DC  # off the fold
    rng = np.random.default_rng(seed)
    for mobility in (np.ones(n), rng.uniform(0.1, 10.0, n)):
        y = _flow(K, fz, f, mobility, y0)
        np.testing.assert_allclose(land.w, y, rtol=0, atol=1e-7 * DC)
        assert np.array_equal(land.moving, y > 1e-6 * DC)


@pytest.mark.parametrize("seed", [2, 3, 5])
def test_the_landing_is_a_stable_equilibrium(seed):
    """At the landing every bond carries at most its strength, the moving ones exactly it
    (to rounding), and the moving set is stable: B positive definite."""
    K, fz, f, sigma, moving, p = _cooperative(seed)
    n = f.size
    rx = relax.Relaxation(DenseResponse(K), fz, LAM_S, LAM_D, DC)
    land = least.land(rx, f, np.zeros(n), np.zeros(n), sigma, moving, p)
    force = f - K @ land.w
    cap = rx.strength(land.delta) * fz
    scale = float(cap.max())
    assert np.all(force <= cap + 1e-13 * scale)
    assert np.abs(force - cap)[land.moving].max() <= 1e-13 * scale
    P = np.flatnonzero(land.moving)
    kap = np.where(land.delta[P] < DC, (LAM_S - LAM_D) * fz[P] / DC, 0.0)
    assert np.linalg.eigvalsh(K[np.ix_(P, P)] - np.diag(kap))[0] > 0


def _bursts(monkeypatch, flow: bool):
    """Every landing of two rough pulls (N = 32, lam_d = 0 and 0.1), through the module or
    through the flow of roughslip.friction.relax."""
    from roughslip.friction import weakening

    seen, used = [], []
    real = least.land

    def land(*args, **kw):
        out = None if flow else real(*args, **kw)
        used.append(out is not None)
        return out

    monkeypatch.setattr(weakening.least, "land", land)
    keep = weakening.WeakeningState._land

    def record(self, landing):
        seen.append((landing.moving.copy(), landing.w.copy(),
                     sorted(i for i, _, _ in landing.failures)))
        return keep(self, landing)

    monkeypatch.setattr(weakening.WeakeningState, "_land", record)
    forces = []
    for seed, depth, lam_d, dc in ((3, 2.5, 0.0, 0.05), (1, 2.5, 0.1, 0.01)):
        h = self_affine((32, 32), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0),
                        oversample=2)
        normal = squeeze(h, depth=depth, nu=0.3, tol=1e-12)
        forces.append(pull(normal, lam=LAM_S, slip_law="slip-weakening", lam_dynamic=lam_d,
                           slip_distance=dc, early_stop=False).friction_force)
    return seen, used, forces


def test_rough_bursts_land_where_the_flow_does(monkeypatch):
    """The pixel kernel is nearly cooperative: on every burst of two rough pulls the
    module's landing has the flow's moving set, every failure it records is one of the flow's
    (the flow may also let a moving bond stop and fail again, which it records once more),
    and slips within 1e-6 of the largest (measured: 2e-7). The flow rests at a drive later by
    its viscosity times the fast time it takes to settle, and leaves an excess of a few 1e-9
    of the largest normal force (the steps: 1e-14); each pull carries its own differences on.
    The friction forces agree to 1e-12."""
    fast, used, f_fast = _bursts(monkeypatch, flow=False)
    monkeypatch.undo()
    slow, _, f_slow = _bursts(monkeypatch, flow=True)
    assert len(fast) == len(slow) > 80
    assert sum(used) >= 0.9 * len(used)  # the steps, not the fallback, were tested
    worst = 0.0
    for (m1, w1, j1), (m2, w2, j2) in zip(fast, slow, strict=True):
        assert np.array_equal(m1, m2) and set(j1) <= set(j2)
        worst = max(worst, np.abs(w1 - w2).max() / np.abs(w2).max())
    assert worst <= 1e-6
    np.testing.assert_allclose(f_fast, f_slow, rtol=1e-12)


def test_a_burst_updates_the_last_bursts_inverse_as_if_factorised(monkeypatch):
    """Bursts of one pull carry the inverse of B from one to the next and update it
    (least.Carry): after each such update it is the inverse of B on the new moving set (to
    1e-9 of the identity, the updates' rounding against the conditioning) and its count of
    negative eigenvalues is B's, from a dense eigendecomposition. The two rough pulls of the
    flow comparison then have the landings and friction forces of bursts that factorise
    afresh: the same moving sets and failures, slips within 1e-10 of the largest, friction
    within 1e-12."""
    adopted, checked = [], []
    real = least._Ascent.adopt

    def adopt(self, c):
        ok = real(self, c)
        adopted.append(ok)
        if ok:
            ids = self.inv.ids[self.inv.live]
            B = self._entries(ids, ids, "C")
            inv = self.inv.apply(np.eye(self.inv.m)[:, self.inv.live])[self.inv.live]
            err = np.abs(inv @ B - np.eye(ids.size)).max()
            checked.append((err, self.neg, int(np.sum(np.linalg.eigvalsh(B) < 0))))
        return ok

    monkeypatch.setattr(least._Ascent, "adopt", adopt)
    carried, _, f_carried = _bursts(monkeypatch, flow=False)
    monkeypatch.undo()
    monkeypatch.setattr(least._Ascent, "adopt", lambda self, c: False)
    fresh, _, f_fresh = _bursts(monkeypatch, flow=False)
    assert sum(adopted) >= 0.3 * len(adopted) > 20  # the updates, not the factorisations
    assert all(err <= 1e-9 and neg == dense for err, neg, dense in checked)
    assert len(carried) == len(fresh)
    worst = 0.0
    for (m1, w1, j1), (m2, w2, j2) in zip(carried, fresh, strict=True):
        assert np.array_equal(m1, m2) and j1 == j2
        worst = max(worst, np.abs(w1 - w2).max() / np.abs(w2).max())
    assert worst <= 1e-10
    np.testing.assert_allclose(f_carried, f_fresh, rtol=1e-12)


@pytest.mark.parametrize("seed", [2, 3])
def test_the_unstable_eigenvector_from_the_inverse_is_b_s(seed):
    """With one negative eigenvalue mu, Lanczos on the inverse of B (its only negative
    eigenvalue is 1/mu) gives the lowest eigenpair of B that Lanczos on B itself and a dense
    eigendecomposition give: mu to 1e-10 relative, the eigenvector to 1e-8."""
    n = least.LANCZOS_MIN + 100
    K, fz, f, sigma, _, p = _cooperative(seed, n)
    rx = relax.Relaxation(DenseResponse(K), fz, LAM_S, LAM_D, DC)
    a = least._Ascent(rx, f, np.zeros(n), sigma, np.ones(n, dtype=bool))
    a.kt[:] = np.where(np.arange(n) == p, a.kap, 0.0)  # only the failing bond softens
    a.ok, a.pending = False, []
    assert a.refresh() and a.neg == 1
    rows = np.flatnonzero(a.inv.live)
    B = a._entries(a.inv.ids[rows], a.inv.ids[rows], "C")
    w, V = np.linalg.eigh(B)
    for on_inverse in (True, False):
        mu, v = a._lowest(rows, on_inverse)
        assert mu == pytest.approx(w[0], rel=1e-10)
        assert np.abs(v * np.sign(v @ V[:, 0]) - V[:, 0]).max() <= 1e-8


@pytest.mark.parametrize("seed", [4, 7, 11])
def test_a_carried_inverse_counts_the_inertia_through_every_kind_of_update(monkeypatch,
                                                                          seed):
    """On an indefinite B (several negative eigenvalues), a carried inverse brought to a new
    moving set by removals, sign turns, softenings that start and that end, and borderings:
    the count of negative eigenvalues from the pivots is B's (dense eigenvalues), and the
    inverse is B's to 1e-9 of the identity."""
    monkeypatch.setattr(least, "CARRY_SHARE", 1.0)
    rng = np.random.default_rng(seed)
    n = 40
    K, fz, f, _, _, _ = _cooperative(seed, n)
    rx = relax.Relaxation(DenseResponse(K), fz, LAM_S, LAM_D, DC)
    soft = 1.5 * np.diag(K)  # a softening above the bond's own stiffness
    P1 = rng.random(n) < 0.7
    sg1 = np.where(rng.random(n) < 0.8, 1.0, -1.0)
    a1 = least._Ascent(rx, f, np.zeros(n), np.where(P1, sg1, 0.0), P1)
    a1.kt[:] = np.where(P1 & (rng.random(n) < 0.3), soft, 0.0)
    a1.ok, a1.pending = False, []  # the inertia from an LDL^T factorisation
    assert a1.refresh() and a1.neg >= 2
    carry = least.Carry()
    a1.keep(carry)
    P2, sg2, kt2 = P1.copy(), sg1.copy(), a1.kt.copy()
    on, off = np.flatnonzero(P1), np.flatnonzero(~P1)
    P2[rng.choice(on, 3, replace=False)] = False  # leave
    P2[rng.choice(off, 3, replace=False)] = True  # join
    both = np.flatnonzero(P1 & P2)
    sg2[rng.choice(both, 2, replace=False)] *= -1  # turn
    kt2[both[kt2[both] > 0][:3]] = 0.0  # the softening ends (the diagonal rises)
    kt2[both[kt2[both] == 0][-1:]] = soft[both[kt2[both] == 0][-1:]]  # starts (falls)
    a2 = least._Ascent(rx, f, np.zeros(n), np.where(P2, sg2, 0.0), P2)
    a2.kt[:] = np.where(P2, kt2, 0.0)
    assert a2.adopt(carry)
    inv = a2.inv
    ids = inv.ids[inv.live]
    assert np.array_equal(np.sort(ids), np.flatnonzero(P2)) and inv.live.all()
    B = a2._entries(ids, ids, "C")
    assert a2.neg == int(np.sum(np.linalg.eigvalsh(B) < 0))
    assert np.abs(inv.apply(np.eye(ids.size)) @ B - np.eye(ids.size)).max() <= 1e-9
