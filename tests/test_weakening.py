"""The slip-weakening law (roughslip.friction.weakening): its limits, every state of its path
against a dense equilibrium of the law, its bursts, and its inputs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from roughslip import couple, pull
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.elastic.operators import Grid, Material
from roughslip.errors import InputError
from roughslip.friction import weakening
from roughslip.friction.events import X
from roughslip.friction.response import DenseResponse
from roughslip.surfaces import sphere

LAM = 0.2


def _hertz(ratio: int, nu: float = 0.3):
    """A sphere (R = 1) pressed to d = 0.01 (contact radius a = 0.1) with pixels h = a/ratio
    on an open grid of 4a."""
    a = 0.1
    n = 4 * ratio
    problem = Problem(sphere((n, n), radius=1.0, a=a / ratio), Grid((n, n), a / ratio),
                      Material(1.0, nu), threads=1)
    return NormalSolver(problem, tol=1e-12).solve(depth=0.01)


@pytest.fixture(scope="module")
def hertz8():
    return _hertz(8)


def _weak(normal, lam_dynamic: float, slip_distance: float, **kw):
    return pull(normal, lam=LAM, slip_law="slip-weakening", lam_dynamic=lam_dynamic,
                slip_distance=slip_distance, **kw)


def test_no_weakening_is_the_coulomb_pull(hertz8):
    """lam_dynamic = lam: a failed bond slides at lam f_z, the Coulomb pull, event for
    event (to 1e-10 of the largest force)."""
    c = pull(hertz8, lam=LAM, slip_law="coulomb")
    w = _weak(hertz8, LAM, 5e-4)
    assert w.converged and w.curve.kind[1:] == c.curve.kind[1:]
    np.testing.assert_array_equal(w.curve.site[1:], c.curve.site[1:])
    scale = np.abs(c.curve.fx[1:]).max()
    assert np.abs(w.curve.fx[1:] - c.curve.fx[1:]).max() <= 1e-10 * scale
    assert np.abs(w.curve.dx[1:] - c.curve.dx[1:]).max() <= 1e-10 * np.abs(c.curve.dx[1:]).max()
    assert w.friction_force == pytest.approx(c.friction_force, rel=1e-10)


@pytest.mark.parametrize("dc", [1e-6, 1e-9])
def test_a_vanishing_slip_distance_to_zero_is_the_break_law(hertz8, dc):
    """lam_dynamic = 0 and d_c far below the pixel's weakening scale: every failure is
    unstable and drops the bond to zero force, so each burst breaks the bonds of the break
    law's avalanche at the same drive (D_x,lim of its first break, to rounding), and the
    friction force is the break law's. Within a burst the bonds fail in the order of the
    relaxation, which ties on this symmetric scene leave open: sets are compared."""
    b = pull(hertz8, lam=LAM, early_stop=False, method="inverse")
    w = _weak(hertz8, 0.0, dc, early_stop=False)
    fail = np.array([k in ("slip+", "slip-") for k in w.curve.kind[1:]])
    assert set(w.curve.kind[1:]) <= {"slip+", "slip-", "jump"}

    def groups(dx, site):
        """The failures grouped by the drive they happen at (the break law records an
        avalanche's later breaks below the drive)."""
        top = np.maximum.accumulate(dx)
        keys = np.unique(top)
        return keys, [set(site[top == k].tolist()) for k in keys]

    dw, sw = groups(w.curve.dx[1:][fail], w.curve.site[1:][fail])
    db, sb = groups(b.curve.dx[1:], b.curve.site[1:])
    assert len(sw) == len(sb) > 10
    assert sw == sb
    assert np.abs(dw - db).max() <= 1e-12 * db.max()
    assert w.friction_force == pytest.approx(b.friction_force, rel=1e-12)


def test_a_slip_distance_to_infinity_gives_lam_f_n(hertz8):
    """d_c -> infinity: the bonds keep their static strength through the slide, F_f -> lam
    F_n. Each bond has slipped at most the drive, so the deficit is at most
    (lam_s - lam_d) / lam_s times D / d_c at full sliding, D about the Cattaneo-Mindlin
    full-slip displacement (taken twice, for the pixels)."""
    from roughslip.contact.analytic import cattaneo_mindlin

    full = cattaneo_mindlin(hertz8.normal_force, 0.1, LAM, nu=0.3).delta_s
    for dc in (1.0, 1e3):
        w = _weak(hertz8, 0.1, dc)
        assert w.converged
        ratio = w.friction_force / (LAM * hertz8.normal_force)
        assert 1 - (LAM - 0.1) / LAM * 2 * full / dc < ratio <= 1 + 1e-12


def _check_state(st: weakening.WeakeningState, D: float, G: np.ndarray) -> None:
    """Every bond obeys its phase of the law at D, by a dense G_xx (its bounds too when the
    state is admissible at D, not inside a burst); the stability the state tracks is that of
    the dense Hessian of the weakening bonds."""
    f = st.forces(D)
    s = D - G @ f  # slip of the rigid surface over the half-space at each bond
    fz, sig, ph = st.fz, st.sigma[:, X], st.phase
    fs = fz.max()
    scale = max(st.progress.scale, D)
    stick, weak, res = ph == weakening.STICK, ph == weakening.WEAK, ph == weakening.RESIDUAL
    assert np.all(np.abs(s[stick] - st.s0[stick]) <= 1e-7 * scale)
    delta = st.delta[weak] + sig[weak] * (s[weak] - st.s0[weak])
    if st.violation(D) is None:
        assert np.all(np.abs(f[stick]) <= st.lam_cur[stick] * fz[stick] + 1e-8 * fs)
        assert np.all(delta <= st.dc * (1 + 1e-6))
    lam = LAM - (LAM - st.lam_d) * np.minimum(st.delta[weak] / st.dc, 1)
    strength = (lam * fz[weak] - st.k[weak] * sig[weak] * (s[weak] - st.s0[weak]))
    assert np.all(np.abs(sig[weak] * f[weak] - strength) <= 1e-8 * fs)
    assert np.all(np.abs(sig[res] * f[res] - st.lam_d * fz[res]) <= 1e-12 * fs)
    A = np.flatnonzero(~res)
    W = np.flatnonzero(weak)
    if W.size:
        K = np.linalg.inv(G[np.ix_(A, A)])
        wi = np.searchsorted(A, W)
        hess = K[np.ix_(wi, wi)] - np.diag(st.k[W])
        assert st.stable() == (np.linalg.eigvalsh(hess).min() > 0)


@pytest.mark.parametrize("lam_dynamic, dc", [(0.1, 5e-4), (0.0, 3e-4), (0.05, 2e-4)])
def test_every_state_of_the_path_obeys_the_law_against_a_dense_solve(monkeypatch,
                                                                   lam_dynamic, dc):
    """After every event, at its drive: stick bonds hold their slip within their strength,
    weakening bonds carry lambda(delta) f_z with delta in [0, d_c], residual ones
    lam_dynamic f_z, and every state is stable (dense Hessian): all against dense G_xx."""
    normal = _hertz(6)
    seen = []
    apply = weakening.WeakeningState.apply

    def checked(self, kind, j, D=0.0):
        apply(self, kind, j, D)
        if not hasattr(self, "_G"):
            self._G = self.b.dense()
        _check_state(self, D, self._G)
        seen.append(kind)

    monkeypatch.setattr(weakening.WeakeningState, "apply", checked)
    w = _weak(normal, lam_dynamic, dc)
    assert w.converged
    assert {"slip+", "residual"} <= set(seen)


def test_a_burst_holds_the_drive_and_its_states_never_set_the_friction(hertz8):
    """With lam_dynamic = 0 and a short d_c the failures run away: every failure inside a
    burst and its landing (a "jump" event) are recorded at the drive that set it off, and the
    friction force is the largest force of the stable path and the landings, never of a
    failure inside a burst (the relaxation there never brings the force above where it
    started, on this scene)."""
    w = _weak(hertz8, 0.0, 1e-4, early_stop=False)
    dx, fx, kinds = w.curve.dx[1:], w.curve.fx[1:], w.curve.kind[1:]
    assert np.all(np.diff(dx) >= 0)
    jumps = [i for i, k in enumerate(kinds) if k == "jump"]
    assert len(jumps) >= 3
    inside = np.zeros(dx.size, bool)
    last = -1
    for j in jumps:
        r = next(i for i in range(last + 1, j + 1) if dx[i] == dx[j])  # set it off
        assert r < j and kinds[r] in ("slip+", "slip-")
        inside[r + 1:j] = True
        last = j
    assert inside.any()
    assert set(kinds[i] for i in np.flatnonzero(inside)) <= {"slip+", "slip-"}
    assert w.friction_force == fx[~inside].max() == fx[w.peak_event - 1]


@pytest.mark.parametrize("lam_dynamic, dc", [(0.1, 5e-4), (0.0, 1e-4), (0.2, 5e-4)])
def test_the_early_stop_gives_the_friction_force_of_the_whole_path(hertz8, lam_dynamic, dc):
    """pull.early_stop stops once the bonds' strengths sum to no more than the best force
    (at a stable state, or inside a burst): the friction force is the whole path's, bit for
    bit, and the curve is the whole path's up to where it stopped."""
    full = _weak(hertz8, lam_dynamic, dc, early_stop=False)
    short = _weak(hertz8, lam_dynamic, dc)
    assert not full.details.early_stopped
    assert short.friction_force == full.friction_force
    n = len(short.curve.dx)
    assert short.details.early_stopped == (n < len(full.curve.dx))
    np.testing.assert_array_equal(short.curve.dx[:n - 1], full.curve.dx[:n - 1])
    np.testing.assert_array_equal(short.curve.fx[:n - 1], full.curve.fx[:n - 1])


def test_the_friction_force_converges_with_the_pixel_size():
    """The Hertz scene at a/h = 8 and 16 (lam_s = 0.2, lam_d = 0.1, d_c = 5e-4): under 2 %
    apart, where the break law's falls by about 30 %."""
    lo, hi = _hertz(8), _hertz(16)
    w = [_weak(n, 0.1, 5e-4).friction_force / (LAM * n.normal_force) for n in (lo, hi)]
    b = [pull(n, lam=LAM).friction_force / (LAM * n.normal_force) for n in (lo, hi)]
    assert abs(w[1] / w[0] - 1) < 0.02
    assert b[1] / b[0] < 0.75


def test_the_same_pull_gives_the_same_bits(hertz8):
    a = _weak(hertz8, 0.05, 2e-4)
    b = _weak(hertz8, 0.05, 2e-4)
    for x, y in ((a.curve.dx, b.curve.dx), (a.curve.fx, b.curve.fx),
                 (a.curve.site, b.curve.site), (a.peak.fx, b.peak.fx)):
        assert x.tobytes() == y.tobytes()


def test_bad_parameters_get_one_line_errors(hertz8):
    with pytest.raises(InputError, match="slip_distance: slip_law = 'slip-weakening' needs"):
        pull(hertz8, slip_law="slip-weakening", lam_dynamic=0.1)
    with pytest.raises(InputError, match=r"lam_dynamic = 0.3: must satisfy 0 <= lam_dynamic"):
        _weak(hertz8, 0.3, 1e-3)
    with pytest.raises(InputError, match=r"slip_distance = 0\.0: must be a finite number > 0"):
        _weak(hertz8, 0.1, 0.0)
    with pytest.raises(InputError, match=r"lam_dynamic = 0\.1: slip_law = 'break' has no such"):
        pull(hertz8, lam=LAM, lam_dynamic=0.1)
    with pytest.raises(InputError, match="lam_dynamic: slip_law = 'slip-weakening' needs"):
        couple(hertz8.problem, depth=0.01, lam=LAM, slip_law="slip-weakening")


def test_the_landing_curve_is_the_break_laws_sawtooth_in_the_limit(hertz8):
    """landing_curve (the curve of a pull that records where its bursts land) in the break
    limit: the bursts of the break law's sequence, each at the same drive, with the same
    number of breaks and the same force drop; the same peak."""
    from roughslip.analysis.bursts import landing_curve, pull_curve

    b = pull(hertz8, lam=LAM, early_stop=False, method="inverse")
    w = _weak(hertz8, 0.0, 1e-9, early_stop=False)
    cb = pull_curve(b.curve.dx[1:], b.curve.fx[1:], exhausted=True)
    cw = landing_curve(w.curve.dx[1:], w.curve.fx[1:], w.curve.site[1:])
    assert cw.peak == pytest.approx(cb.peak, rel=1e-12) == w.friction_force
    np.testing.assert_allclose(cw.burst_dx, cb.burst_dx, rtol=1e-12)
    np.testing.assert_array_equal(cw.burst_size, cb.burst_size)
    np.testing.assert_allclose(cw.burst_drop, cb.burst_drop, rtol=1e-9,
                               atol=1e-12 * cb.peak)


def _viscous_limit():
    """scripts/viscous_limit.py: the overdamped pull, integrated by a stiff solver."""
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).parents[1] / "scripts" / "viscous_limit.py"
    spec = importlib.util.spec_from_file_location("viscous_limit", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, mod)  # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return sys.modules[spec.name]


def test_a_piece_of_a_burst_is_the_linear_flow_in_closed_form():
    """On one piece of a burst (roughslip.friction.relax) the excess, the slip and the forces
    of the stuck bonds in closed form are those of the linear system integrated by a stiff
    solver, with an unstable and stable modes and the drive; the first event it finds is a
    root, and no event function is negative before it on a fine grid."""
    from scipy.integrate import solve_ivp

    from roughslip.friction import relax

    rng = np.random.default_rng(7)
    n, m = 9, 5
    A = rng.standard_normal((n, n))
    K = A @ A.T / n + np.eye(n)  # a stiffness: symmetric positive definite
    fz = rng.uniform(0.5, 1.5, n)
    rx = relax.Relaxation(DenseResponse(K), fz, 0.2, 0.1, 0.05)
    moving = np.arange(n) < m
    sigma = np.where(moving, rng.choice([-1.0, 1.0], n), 0.0)
    delta = np.where(moving, rng.uniform(0, 0.01, n), 0.0)
    delta[0] = 0.2  # residual: no softening
    f = rng.uniform(-0.05, 0.05, n)
    st = relax.Landing(f, np.zeros(n), delta, sigma, moving)
    e = np.where(moving, rng.uniform(0.0, 1e-3, n), 0.0)
    pc = relax._Piece(rx, st, e)
    pc.decompose()
    assert pc.mu[0] < 0 < pc.mu[-1]

    P = np.flatnonzero(moving)
    s = sigma[P]

    def rhs(t, y):
        ep = y[:m]
        return np.r_[pc.r - pc.B @ ep, ep]

    taus = np.array([0.01, 0.1, 0.5, 1.0])
    sol = solve_ivp(rhs, (0, taus[-1]), np.r_[e[P], np.zeros(m)], method="Radau",
                    rtol=1e-12, atol=1e-15, t_eval=taus)
    ep, dy = pc.at(taus)
    np.testing.assert_allclose(ep, sol.y[:m].T, rtol=1e-8, atol=1e-13)
    np.testing.assert_allclose(dy, sol.y[m:].T, rtol=1e-8, atol=1e-13)
    Q = np.flatnonzero(~moving)
    fq = f[Q] + rx.eta * taus[:, None] * K[Q].sum(axis=1) - (sol.y[m:].T * s) @ K[np.ix_(Q, P)].T
    np.testing.assert_allclose(pc.stuck_forces(taus, dy), fq, rtol=1e-8, atol=1e-13)

    end = 50.0
    grid = pc.grid(end)
    vals = pc.values(grid)
    k = int(np.flatnonzero((vals[1:] <= 0).any(axis=1))[0]) + 1
    tau, which = pc.first(grid, k, vals[k - 1:k + 1])
    assert abs(pc.values(tau)[0, which]) <= 1e-9 * max(1.0, float(np.abs(vals[0, which])))
    fine = np.linspace(0, tau, 20001)[1:-1]
    assert pc.values(fine).min() > 0


def test_a_burst_lands_where_the_overdamped_pull_does_as_its_viscosity_vanishes():
    """The burst is the limit of the overdamped slip rate
    (docs/theory/pull.rst#slip-weakening): on a rough scene whose bursts involve a choice
    between bonds (N = 32, seed 2, depth 1 rms, lam_d = 0, d_c = 0.05: 56 bonds), the
    friction force is the viscous pull's, integrated
    over the whole path by a stiff solver at eta = 1e-6, 1e-7 and 1e-8 and extrapolated to
    eta = 0, within the extrapolation's spread and the solver's error, plus 1e-7 for the
    solver's relative tolerance of 1e-8 amplified by the extrapolation, whose estimate by one
    tenfold refinement can fall short on another BLAS kernel. (A rule that lands each
    failure at rest before the next, nearest its residual strength first, misses by 1.4 %
    here.)"""
    v = _viscous_limit()
    row = v.study(v.Scene(32, 2, 1.0, 0.0, 0.05), [1e-6, 1e-7, 1e-8], 1e-8)
    assert row["bursts"] >= 3
    assert row["err"] + row["solver"] < 1e-5
    assert abs(row["diff"]) <= row["err"] + row["solver"] + 1e-7, row


def test_the_room_of_a_bond_at_its_strength_does_not_cancel():
    """A stuck bond that starts a piece at its strength (one that just arrested): its room
    after a change of its force of order eta is exact to the last bits (against exact
    rational arithmetic), where c - |f_0 + df| is lost in the rounding of f_0 and its sign
    would join the bond at the start."""
    from fractions import Fraction

    from roughslip.friction import relax

    rng = np.random.default_rng(3)
    pc = relax._Piece.__new__(relax._Piece)
    f0 = rng.uniform(-1e-2, 1e-2, 64)
    pc.fQ, pc.capQ = f0, np.abs(f0) * (1 - rng.uniform(0, 1e-16, 64) * (np.arange(64) % 2))
    df = rng.uniform(-1, 1, 64) * 1e-18 * np.abs(f0) * 1e2
    room = pc._room(df, np.arange(64))
    exact = np.array([float(Fraction(c) - abs(Fraction(a) + Fraction(d)))
                      for c, a, d in zip(pc.capQ, f0, df, strict=True)])
    # each product and quotient rounds once (the growth is at most |df|), and c - |f_0| is
    # exact for such close numbers: a few eps of |df| + |c - |f_0||
    bound = 8 * np.finfo(float).eps * (np.abs(df) + np.abs(pc.capQ - np.abs(f0)))
    assert np.all(np.abs(room - exact) <= bound)
    naive = pc.capQ - np.abs(f0 + df)
    assert np.any(np.sign(naive) != np.sign(exact))


def test_a_rough_burst_with_a_bond_at_its_strength_lands():
    """A rough scene at nu = 0.45 (N = 64, rough_h08's sample 10, depth 2 rms, lam_d = 0.1,
    d_c = 0.01) whose burst, with the room of a bond at its residual strength taken against
    its force, arrested and joined that bond over and over at the start of a piece and never
    landed: it lands, and the pull runs to its end."""
    from roughslip.run.config import load_config
    from roughslip.run.sample import run_sample

    root = Path(__file__).resolve().parents[1]
    cfg = load_config(root / "configs" / "rough_h08.toml", [
        "grid.n=64", "squeeze.depths=[2.0]", "material.nu=0.45", "pull.slip_law='slip-weakening'",
        "pull.lam_dynamic=0.1", "pull.slip_distance=0.01", "execution.threads=1"])
    res = run_sample(cfg, 10)
    sc = res.scalars
    assert sc["pull_converged"].all()
    # between the residual strength's sliding force and the static strength's
    mu = sc["friction_force"] / sc["normal_force"]
    assert np.all((0.1 <= mu) & (mu <= 0.2)), mu
