"""The coupled normal-tangential model: exact events, dense reference, nu = 1/2 limit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import squeeze
from roughslip.coupling.coupled import squeeze_pull_coupled
from roughslip.coupling.histories import HISTORIES
from roughslip.errors import InputError
from roughslip.friction.events import VISITS, Progress, Snapshot, digest, follow_events
from roughslip.friction.pull import pull
from roughslip.surfaces.synthetic import sample_rng, self_affine, sphere


def _assert_same_path(other, ref):
    """The same events as the reference, and the same pull curve to 1e-8 (the solvers'
    agreement criterion throughout)."""
    assert [(e.kind, e.site) for e in other.events] == [(e.kind, e.site) for e in ref.events]
    assert np.allclose(other.curve.dx, ref.curve.dx, rtol=1e-8, atol=1e-12)
    assert np.allclose(other.curve.fx, ref.curve.fx, rtol=1e-8,
                       atol=1e-10 * np.abs(ref.curve.fx).max())
    assert np.allclose(other.curve.fz, ref.curve.fz, rtol=1e-8)
    assert np.allclose(other.curve.dz, ref.curve.dz, rtol=1e-8)
    assert other.friction_force == pytest.approx(ref.friction_force, rel=1e-8)


def rough(n=14, seed=3):
    return self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0),
                       oversample=2)


@pytest.mark.parametrize("history", HISTORIES.names())
@pytest.mark.parametrize("heights", ["rough", "sphere"])
def test_half_poisson_ratio_reproduces_the_decoupled_model(heights, history):
    """At nu = 1/2 (G_zx = 0) every squeeze history ends in the frictionless contact with
    every contact bonded and no tangential force, and the pull is the decoupled one."""
    h = rough(16) if heights == "rough" else sphere((14, 14), radius=12.0)
    depth = 1.2 if heights == "rough" else 0.8
    c = squeeze_pull_coupled(h, depth=depth, lam=0.2, nu=0.5, history=history)
    assert c.details.history == history
    normal = squeeze(h, depth=depth, nu=0.5, tol=1e-13)
    d = pull(normal, lam=0.2, method="inverse", early_stop=False, block=8)
    assert c.details.released == 0 and np.array_equal(c.start.contact, normal.contact)
    assert np.allclose(c.start.fz, normal.fz, rtol=0, atol=1e-11 * normal.fz.max())
    assert np.allclose(c.start.fx, 0.0, atol=1e-13)
    ev = c.events[1:]
    assert all(e.kind == "slip+" for e in ev) and len(ev) == d.steps
    assert [e.site for e in ev] == d.curve.site[1:].tolist()
    assert np.allclose([e.dx for e in ev], d.curve.dx[1:], rtol=1e-9)
    assert np.allclose([e.fx for e in ev], d.curve.fx[1:], rtol=1e-9)
    assert c.friction_force == pytest.approx(d.friction_force, rel=1e-9)
    assert c.normal_force_at_peak == pytest.approx(normal.normal_force, rel=1e-12)


@pytest.mark.parametrize("nu", [0.0, 0.3])
@pytest.mark.parametrize("history", HISTORIES.names())
def test_dense_reference_agrees_with_the_fft_solver(nu, history):
    h = rough(14, seed=5)
    kw = dict(depth=2.5, lam=0.25, nu=nu, history=history)
    ref = squeeze_pull_coupled(h, method="dense", reference=True, **kw)
    fft = squeeze_pull_coupled(h, method="cg", tol=1e-13, **kw)
    inc = squeeze_pull_coupled(h, method="dense", **kw)  # updated inverse
    assert [(e.kind, e.site) for e in inc.events] == [(e.kind, e.site) for e in ref.events]
    assert np.allclose(inc.curve.fx, ref.curve.fx, rtol=1e-9,
                       atol=1e-12 * np.abs(ref.curve.fx).max())
    assert fft.converged and ref.converged
    assert len(ref.events) == len(fft.events)
    # the squeeze's states are decisions too
    assert len(ref.events) + ref.details.squeeze_states > 20
    assert ref.details.squeeze_states == fft.details.squeeze_states == inc.details.squeeze_states
    assert [(e.kind, e.site) for e in ref.events] == [(e.kind, e.site) for e in fft.events]
    assert np.allclose(ref.curve.dx, fft.curve.dx, rtol=1e-8, atol=1e-12)
    assert np.allclose(ref.curve.fx, fft.curve.fx, rtol=1e-8,
                       atol=1e-10 * np.abs(ref.curve.fx).max())
    assert np.allclose(ref.curve.fz, fft.curve.fz, rtol=1e-8)
    assert ref.friction_force == pytest.approx(fft.friction_force, rel=1e-8)
    assert ref.details.released == fft.details.released


@pytest.mark.parametrize("history", HISTORIES.names())
@pytest.mark.parametrize("nu", [0.0, 0.25, 0.45])
def test_every_recorded_state_is_admissible(nu, history):
    h = rough(14, seed=7) + sphere((14, 14), radius=25.0)
    res = squeeze_pull_coupled(h, depth=1.4, lam=0.3, nu=nu, record_states=True,
                               history=history)
    assert res.details.states and len(res.details.states) == len(res.events)
    fscale = max(float(np.abs(s[1]).max()) for s in res.details.states)
    for _D, fz, fx, g, C, S in res.details.states:
        tol = 1e-8 * fscale
        assert np.all(fz[C] >= -tol), "f_z >= 0 in contact"
        assert np.all(fz[~C] == 0) and np.all(fx[~S] == 0), "no force off contact / slip"
        assert np.all(g[~C] >= -1e-8 * 1.4), "no penetration"
        assert np.all(np.abs(g[C]) <= 1e-8 * 1.4), "gap closed in contact"
        assert np.all(np.abs(fx[S]) <= 0.3 * fz[S] + tol), "|f_x| <= lambda f_z on stick sites"
        assert np.all(S <= C)
    # the recorded totals are the sums of the recorded fields
    for e, (_, fz, fx, *_rest) in zip(res.events, res.details.states, strict=True):
        assert e.fx == pytest.approx(fx.sum(), abs=1e-12 * fscale)
        assert e.fz == pytest.approx(fz.sum(), rel=1e-12)
    # the friction force is the largest F_x on the path, with F_z at the same D_x
    i = int(np.argmax(res.curve.fx))
    assert res.friction_force == res.curve.fx[i] and res.normal_force_at_peak == res.curve.fz[i]


def test_coupling_is_felt_at_zero_pull():
    """Under coupling the bonded squeeze already needs tangential forces; bonds are
    released at D_x = 0 and F_x(0) != 0 for a non-symmetric surface
    (docs/theory/coupled.rst#coupled)."""
    h = rough(14, seed=9)
    res = squeeze_pull_coupled(h, depth=1.3, lam=0.2, nu=0.0)
    assert res.details.released > 0
    assert abs(res.events[0].fx) > 1e-6 * res.normal_force
    kinds = {e.kind for e in res.events}
    assert "slip+" in kinds
    assert 0 < res.details.squeeze_seconds < res.seconds  # the time until the pull starts, a part


def test_no_contact_and_bad_input():
    res = squeeze_pull_coupled(np.zeros((4, 4)), depth=0.0)
    assert res.friction_force == 0 and not res.start.contact.any()
    with pytest.raises(InputError, match="lam"):
        squeeze_pull_coupled(np.zeros((4, 4)), depth=1.0, lam=0)
    with pytest.raises(InputError, match="method"):
        squeeze_pull_coupled(np.zeros((4, 4)), depth=1.0, method="lu")


def test_reciprocity_of_the_coupled_block():
    """Maxwell-Betti: u_z at i from a unit f_x at j equals u_x at j from a unit f_z at i, and
    the reduced block the solver factorises is symmetric."""
    from roughslip.contact.problem import Problem
    from roughslip.coupling.blocksolvers import DenseBlockSolver as _Dense
    from roughslip.elastic.operators import Grid, Material

    grid, mat = Grid((9, 11)), Material(1.0, 0.1)
    problem = Problem(np.zeros(grid.shape), grid, mat)
    op = problem.operator("zz", "zx", "xx")
    rng = np.random.default_rng(4)
    for _ in range(5):
        i, j = rng.integers(0, 99, 2)
        fx = np.zeros(grid.shape)
        fx.flat[j] = 1.0
        uz = op.apply_block(np.zeros(grid.shape), fx)[0].flat[i]
        fz = np.zeros(grid.shape)
        fz.flat[i] = 1.0
        ux = op.apply_block(fz, np.zeros(grid.shape))[1].flat[j]
        assert uz == pytest.approx(ux, rel=1e-12, abs=1e-15)
    d = _Dense(problem, reference=True)
    ids = np.concatenate([2 * rng.choice(99, 20, replace=False),
                          2 * rng.choice(99, 15, replace=False) + 1])
    A = d.entries(ids, ids)
    assert np.array_equal(A, A.T)
    assert np.linalg.eigvalsh(A).min() > 0


def test_dense_solver_checks_its_memory_first():
    """The dense path estimates its memory before it allocates: explicit ``dense`` refuses with
    the need, the budget and the alternatives; ``auto`` falls back to the matrix-free solver
    and says so (same events)."""
    from roughslip.coupling.coupled import dense_memory_bytes
    from roughslip.errors import MemoryLimitError
    from roughslip.linalg import memory

    h = rough(14, seed=5)
    sites = int(((2.5 - (h.max() - h)) > 0).sum())
    need = dense_memory_bytes(sites)
    free = squeeze_pull_coupled(h, depth=2.5, lam=0.25, nu=0.25)
    assert free.method == "dense" and "auto chose" not in free.message
    with memory.limited(0.5 * need / 2**30):
        with pytest.raises(MemoryLimitError, match=r"method 'dense'.*GiB.*method 'cg'"):
            squeeze_pull_coupled(h, depth=2.5, lam=0.25, nu=0.25, method="dense")
        tight = squeeze_pull_coupled(h, depth=2.5, lam=0.25, nu=0.25, tol=1e-13)
    assert tight.method == "cg" and tight.message.startswith("auto chose cg")
    assert tight.details.fallback.startswith("auto chose cg") and "GiB" in tight.details.fallback
    assert free.details.fallback == ""
    assert [(e.kind, e.site) for e in tight.events] == [(e.kind, e.site) for e in free.events]
    assert tight.friction_force == pytest.approx(free.friction_force, rel=1e-8)
    # the same under the Coulomb law: the matrix-free path solves the slip forces by GMRES on
    # the whole system, and the indentation falls back in the same way
    kw = dict(depth=2.5, lam=0.25, nu=0.25, slip_law="coulomb")
    free = squeeze_pull_coupled(h, **kw)
    with memory.limited(0.5 * need / 2**30):
        tight = squeeze_pull_coupled(h, tol=1e-13, **kw)
    from roughslip.contact.problem import Problem
    from roughslip.coupling.coupled import indent

    pb = Problem.from_arrays(h, nu=0.25)
    with memory.limited(0.02 * need / 2**30):  # the indentation grows its inverse from one site
        ind_tight = indent(pb, depth=2.5, lam=0.25, tol=1e-13)
    ind_free = indent(pb, depth=2.5, lam=0.25)
    assert tight.method == "cg" and free.method == "dense" and ind_tight.method == "cg"
    assert [(e.kind, e.site) for e in tight.events] == [(e.kind, e.site) for e in free.events]
    assert tight.friction_force == pytest.approx(free.friction_force, rel=1e-8)
    assert [(e.kind, e.site) for e in ind_tight.events] == \
        [(e.kind, e.site) for e in ind_free.events]
    assert np.allclose(ind_tight.fx, ind_free.fx, rtol=0, atol=1e-8 * ind_free.fz.max())


@pytest.mark.parametrize(("seed", "depth_rms"), [(1, 2.0), (6, 3.0), (39, 4.0)])
def test_matrix_free_solver_takes_states_admissible_within_tolerance(seed, depth_rms):
    """These scenes stopped the CG path with "inconsistent state (no violation but no
    admissible displacement)": a gap closing slowly with D_x put its root far from D for a
    violation far below the CG residual. The state is admissible within the value tolerances;
    the CG path now reproduces the dense reference event for event."""
    from roughslip.surfaces.synthetic import rms_height_of

    h = self_affine((24, 24), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0), oversample=2)
    depth = depth_rms * rms_height_of(h)
    cg = squeeze_pull_coupled(h, depth=depth, lam=0.2, nu=0.25, method="cg", tol=1e-10)
    ref = squeeze_pull_coupled(h, depth=depth, lam=0.2, nu=0.25, method="dense")
    assert cg.converged and ref.converged
    assert [(e.kind, e.site) for e in cg.events] == [(e.kind, e.site) for e in ref.events]
    assert cg.friction_force == pytest.approx(ref.friction_force, rel=1e-8)


# -- load control --------------------------------------------------------------------------------
@pytest.mark.parametrize("nu", [0.1, 0.3])
def test_force_held_pull_agrees_between_solvers_and_holds_the_force(nu):
    """Squeeze to a normal force and pull at that force: the dense reference (no FFT), the
    updated inverse and matrix-free CG give the same events; F_z is the target at every event
    and D_z follows."""
    h = rough(14, seed=5)
    F = 15.0
    kw = dict(force=F, lam=0.25, nu=nu, pull_control="force")
    ref = squeeze_pull_coupled(h, method="dense", reference=True, **kw)
    inc = squeeze_pull_coupled(h, method="dense", **kw)
    fft = squeeze_pull_coupled(h, method="cg", tol=1e-13, **kw)
    assert ref.converged and inc.converged and fft.converged
    # the squeeze's states are decisions too
    assert len(ref.events) + ref.details.squeeze_states > 20
    assert ref.details.squeeze_states == fft.details.squeeze_states == inc.details.squeeze_states
    for other in (inc, fft):
        _assert_same_path(other, ref)
    assert np.allclose(ref.curve.fz, F, rtol=1e-10)  # the force is held
    assert ref.normal_force == pytest.approx(F, rel=1e-12)
    assert np.ptp(ref.curve.dz) > 1e-6 * ref.details.depth  # ... and the depth moves


def test_squeeze_to_a_force_then_hold_the_depth_equals_the_depth_controlled_model():
    h = rough(14, seed=9)
    by_force = squeeze_pull_coupled(h, force=5.0, lam=0.2, nu=0.25, pull_control="depth")
    by_depth = squeeze_pull_coupled(h, depth=by_force.details.depth, lam=0.2, nu=0.25)
    assert by_force.normal_force == pytest.approx(5.0, rel=1e-12)
    assert [(e.kind, e.site) for e in by_force.events] == \
        [(e.kind, e.site) for e in by_depth.events]
    assert np.allclose(by_force.curve.fx, by_depth.curve.fx, rtol=1e-8, atol=1e-12)
    assert np.allclose(by_force.curve.dz, by_force.details.depth)
    assert by_force.details.pull_control == "depth"
    # a depth-controlled squeeze with a force-held pull holds the squeezed force
    held = squeeze_pull_coupled(h, depth=by_force.details.depth, lam=0.2, nu=0.25,
                                pull_control="force")
    assert np.allclose(held.curve.fz, held.normal_force, rtol=1e-10)
    assert held.details.depth == pytest.approx(by_force.details.depth, rel=1e-12)


@pytest.mark.parametrize("history", HISTORIES.names())
def test_force_held_pull_at_half_poisson_ratio_is_the_decoupled_pull_at_that_load(history):
    """At nu = 1/2 the pull does not change the normal forces, so holding the force and holding
    the depth are the same pull, and equal to the decoupled model at the same load, after
    every squeeze history."""
    h = sphere((14, 14), radius=12.0)
    c = squeeze_pull_coupled(h, force=2.0, lam=0.2, nu=0.5, pull_control="force",
                             history=history)
    normal = squeeze(h, force=2.0, nu=0.5, tol=1e-13)
    d = pull(normal, lam=0.2, method="inverse", early_stop=False, block=8)
    assert c.details.depth == pytest.approx(normal.depth, rel=1e-10)
    assert np.allclose(c.curve.dz, normal.depth, rtol=1e-10)
    assert [e.site for e in c.events[1:]] == d.curve.site[1:].tolist()
    assert c.friction_force == pytest.approx(d.friction_force, rel=1e-9)


def test_load_control_rejects_bad_input():
    h = rough(8)
    with pytest.raises(InputError, match="exactly one of depth and force"):
        squeeze_pull_coupled(h, depth=1.0, force=1.0)
    with pytest.raises(InputError, match="pull_control"):
        squeeze_pull_coupled(h, depth=1.0, pull_control="speed")
    with pytest.raises(InputError, match="force = -1"):
        squeeze_pull_coupled(h, force=-1.0)
    assert squeeze_pull_coupled(h, force=0.0).friction_force == 0.0


# -- contacts gained during the pull -------------------------------------------------------------
def test_contacts_gained_while_pulling_enter_by_the_chosen_rule():
    """Unbonded (the default): a gained site carries f_z and no f_x. Bonded: it forms a bond
    that holds the elastic point where it met the rigid surface; it starts with no force, so
    it survives only while lambda f_z grows faster than |f_x|. Every recorded state is
    admissible, and the dense reference and matrix-free CG agree on the events."""
    h = rough(14, seed=7) + sphere((14, 14), radius=25.0)
    kw = dict(depth=1.4, lam=0.3, nu=0.25, record_states=True)
    unb = squeeze_pull_coupled(h, **kw)
    bon = squeeze_pull_coupled(h, gained="bonded", **kw)
    gained = [e.site for e in unb.events if e.kind == "gained"]
    assert gained and gained == [e.site for e in bon.events if e.kind == "gained"]
    for res, bonded in ((unb, False), (bon, True)):
        fscale = max(float(np.abs(s[1]).max()) for s in res.details.states)
        for k, (e, (_D, fz, fx, g, C, S)) in enumerate(zip(res.events, res.details.states,
                                                            strict=True)):
            assert np.all(fz[C] >= -1e-8 * fscale) and np.all(g[~C] >= -1e-8)
            assert np.all(np.abs(fx[S]) <= 0.3 * fz[S] + 1e-8 * fscale)
            if e.kind == "gained":  # the state after it is the next one recorded
                after = res.details.states[k + 1]
                assert after[4].flat[e.site] and after[5].flat[e.site] == bonded
    # a new bond starts with no force: it never jumps the totals
    for e, s in zip(bon.events, bon.details.states, strict=True):
        if e.kind == "gained":
            assert s[2].flat[e.site] == 0.0
    ref = squeeze_pull_coupled(h, gained="bonded", method="dense", reference=True, depth=1.4,
                               lam=0.3, nu=0.25)
    cg = squeeze_pull_coupled(h, gained="bonded", method="cg", tol=1e-13, depth=1.4, lam=0.3,
                              nu=0.25)
    assert [(e.kind, e.site) for e in cg.events] == [(e.kind, e.site) for e in ref.events]
    assert np.allclose(cg.curve.dx, ref.curve.dx, rtol=1e-8, atol=1e-12)
    assert np.allclose(cg.curve.fx, ref.curve.fx, rtol=1e-8,
                       atol=1e-10 * np.abs(ref.curve.fx).max())
    assert [(e.kind, e.site) for e in bon.events] == [(e.kind, e.site) for e in ref.events]
    with pytest.raises(InputError, match="gained"):
        squeeze_pull_coupled(h, depth=1.4, gained="sticky")


@pytest.mark.parametrize("symv_min", [0, 10**9])
def test_updated_inverse_tracks_solutions_through_set_changes(symv_min):
    """The dense solver's updated inverse (downdates, bordered additions, growth, compaction,
    pending terms folded in) and its tracked solutions agree with a direct solve of the block
    to 1e-10 through a random sequence of set changes, from one factorisation; with the
    products by the symmetric kernel (lower triangle) or the general one."""
    from roughslip.contact.problem import Problem
    from roughslip.coupling.blocksolvers import DenseBlockSolver as _Dense
    from roughslip.elastic.operators import Grid, Material

    grid = Grid((12, 12))
    problem = Problem(np.zeros(grid.shape), grid, Material(1.0, 0.25))
    d = _Dense(problem, tol=1e-13)
    d.inverse.block = 8  # fold pending terms in often
    d.refinements = 0  # the updates alone, without the certification's refinement
    d.inverse.symv_min = symv_min
    rng = np.random.default_rng(11)
    C = rng.random(grid.shape) < 0.6
    S = C & (rng.random(grid.shape) < 0.7)
    rz, rx = rng.normal(size=grid.shape), rng.normal(size=grid.shape)
    compactions = 0
    for _ in range(60):
        d.prepare(C, S)
        fz, fx, _ = d.solve(rz, rx, "a")
        ids = np.concatenate([2 * np.flatnonzero(C), 2 * np.flatnonzero(S) + 1])
        b = np.concatenate([rz[C], rx[S]])
        x = np.linalg.solve(d.entries(ids, ids), b)
        got = np.concatenate([fz[C], fx[S]])
        assert np.abs(got - x).max() <= 1e-10 * np.abs(x).max()
        assert not fz[~C].any() and not fx[~S].any()
        m = d.inverse.m
        # one to three removals (a contact takes its bond along), up to two additions
        for j in rng.choice(np.flatnonzero(C), rng.integers(1, 4), replace=False):
            if rng.random() < 0.5:
                C.flat[j] = S.flat[j] = False
            else:
                S.flat[j] = False
        free = np.flatnonzero(~C)
        for j in rng.choice(free, min(free.size, rng.integers(0, 3)), replace=False):
            C.flat[j] = True
            S.flat[j] = rng.random() < 0.5
        d.prepare(C, S)
        compactions += d.inverse.m < m
    assert d.inverse.factorisations == 1 and compactions > 0


def test_kept_displacements_follow_the_removals():
    """The displacements the dense solver returns for its kept solutions, moved along the
    removed columns (one block product per removal for all right-hand sides), are those of
    their forces to round-off, on and off the contact set (the gaps), through removals,
    additions, compactions and the periodic fresh products."""
    from roughslip.contact.problem import Problem
    from roughslip.coupling.blocksolvers import DenseBlockSolver as _Dense
    from roughslip.elastic.operators import Grid, Material

    grid = Grid((12, 12))
    problem = Problem(np.zeros(grid.shape), grid, Material(1.0, 0.25))
    d = _Dense(problem, tol=1e-13)
    d.inverse.block = 8
    d.refresh_every = 5
    rng = np.random.default_rng(4)
    C = rng.random(grid.shape) < 0.7
    S = C.copy()
    rhs = [(rng.normal(size=grid.shape), rng.normal(size=grid.shape), k) for k in "01"]
    ages = set()
    for step in range(45):
        d.prepare(C, S)
        for (fz, fx, uz), (_, _, key) in zip(d.solve_many(rhs), rhs, strict=True):
            want = d.displacements(fz, fx)
            kept = d._fields[key]
            ages.add(kept.age)
            scale = np.abs(want[0]).max() + np.abs(want[1]).max()
            assert np.abs(uz - want[0]).max() <= 1e-13 * scale
            assert np.abs(kept.ux - want[1]).max() <= 1e-13 * scale
        j = rng.choice(np.flatnonzero(S if S.any() else C))
        S.flat[j] = False
        if step % 9 == 8:  # a contact leaves, another enters
            C.flat[j] = False
            C.flat[rng.choice(np.flatnonzero(~C))] = True
    assert {0, 1, 5} <= ages and max(ages) <= 5  # moved, and computed afresh after 5
    assert d.inverse.factorisations == 1


def test_the_slip_block_follows_the_events_and_matches_a_dense_solve():
    """The dense solver's block of slip responses K^-1 H_P (one column per slip site, kept
    through removals, additions and compactions, columns added and dropped as sites start
    and stop slipping) is that of a dense solve with the assembled block K of the current
    sets and the columns H of the slip sites, to round-off, on and off its memoised state;
    a column is computed, by a product with the inverse, only when its site starts to slip."""
    from roughslip.contact.problem import Problem
    from roughslip.coupling.blocksolvers import DenseBlockSolver as _Dense
    from roughslip.elastic.operators import Grid, Material

    grid = Grid((12, 12))
    problem = Problem(np.zeros(grid.shape), grid, Material(1.0, 0.25))
    d = _Dense(problem, tol=1e-13)
    d.inverse.block = 8
    rng = np.random.default_rng(11)
    C = rng.random(grid.shape) < 0.7
    S = C.copy()
    compactions, applied, prev_P = 0, [], np.zeros(grid.shape, dtype=bool)
    apply = d.inverse.apply
    d.inverse.apply = lambda B: applied.append(B.shape[1] if B.ndim == 2 else 1) or apply(B)
    for step in range(40):
        m = d.inverse.m if d.inverse.ready else 0
        d.prepare(C, S)
        compactions += 0 < d.inverse.m < m
        P = C & ~S
        if P.any():
            applied.clear()
            E, fields = d.slip_response(np.flatnonzero(P))
            assert d.slip_response(np.flatnonzero(P))[0] is E  # the same state: memoised
            # one product with the inverse for each site new to P, none for the others
            assert sum(applied) == (P & ~prev_P).sum()
            ids = np.concatenate([2 * np.flatnonzero(C), 2 * np.flatnonzero(S) + 1])
            K = d.entries(ids, ids)
            Z = np.linalg.solve(K, d.entries(ids, 2 * np.flatnonzero(P) + 1))
            zrows = np.arange(int(C.sum()))[P[C]]  # the f_z rows of the slip sites
            # round-off of at most one update per step, each about cond(K) eps relative
            bound = 40 * np.linalg.cond(K) * np.finfo(float).eps
            assert np.abs(E - Z[zrows]).max() <= bound * np.abs(Z).max()
            v = rng.normal(size=int(P.sum()))
            fz, fx = fields(v)
            want = Z @ v
            assert np.abs(fz[C] - want[: int(C.sum())]).max() <= bound * np.abs(want).max()
            assert np.abs(fx[S] - want[int(C.sum()):]).max() <= bound * np.abs(want).max()
            assert not fz[~C].any() and not fx[~S].any()
        prev_P = P
        j = rng.choice(np.flatnonzero(S))  # a bond starts to slip
        S.flat[j] = False
        if step % 6 == 5:  # a slip site sticks again, a contact leaves, another enters
            S.flat[rng.choice(np.flatnonzero(C & ~S))] = True
            k = rng.choice(np.flatnonzero(C & ~S))
            C.flat[k] = False
            C.flat[rng.choice(np.flatnonzero(~C))] = True
    assert d.inverse.factorisations == 1 and compactions > 0


def test_a_slow_rate_is_flat_only_on_the_scale_of_the_pull_so_far():
    """Found at N = 128 (nu = 0.45, sample 13 of the study): off contact, g = g0 + D g1 with
    g0 = -1.6e-5 and g1 = 1.6e-4, at D = 0.5, long after a first event at 8.6e-6. Judged flat
    on the first event's scale, the gap counted as violated at every D and the admissible
    interval came out empty, [inf, -inf]; the loop then evaluated the state at D = -inf
    (a NaN from 0 x inf). Over the pull so far the gap is not flat: it has been open since
    D = 0.1. A non-finite displacement is an error, never a NaN."""
    from roughslip.coupling.state import ContactState as _State
    from roughslip.errors import NumericalError
    from roughslip.friction.laws import LAWS

    st = object.__new__(_State)
    st.C = np.array([[True, True, False]])
    st.S = np.array([[True, False, False]])
    st.lam, st.scale_g, st.slope = 0.2, 2.0, True
    st.progress = Progress(scale=8.6e-6)
    st.law = LAWS.get("break")
    st.f0 = (np.array([[0.4, 0.3, 0.0]]), np.array([[0.01, 0.0, 0.0]]))
    st.f1 = (np.array([[0.0, 0.01, 0.0]]), np.array([[0.1, 0.0, 0.0]]))
    st.g0 = np.array([[0.0, 0.0, -1.6e-5]])
    st.g1 = np.array([[0.0, 0.0, 1.6e-4]])
    lo, hi, kind, site = st.interval(0.5)
    assert lo == pytest.approx(0.1) and hi == pytest.approx((0.08 - 0.01) / (0.1 - 0.0))
    assert (kind, site) == ("slip+", 0)
    # on the first event's scale the rate is negligible: then the constraint is flat
    assert st.interval(0.0)[:2] == (math.inf, -math.inf)
    with pytest.raises(NumericalError, match="non-finite displacement"):
        st.at(-math.inf)
    assert np.all(np.isfinite(st.at(0.5)[2]))


@pytest.mark.parametrize(("seed", "load"), [(3, {"depth": 2.5}), (5, {"depth": 3.0}),
                                            (5, {"force": 40.0, "pull_control": "force"})])
def test_bulk_passes_by_cg_then_the_updated_inverse_match_the_reference(monkeypatch, seed,
                                                                        load):
    """The squeeze's bulk passes from the geometric overlap run matrix-free above
    ``bulk_min`` unknowns; the inverse is built for the set they leave. Forced on a small
    grid, the path is the reference's (every state factorised afresh, dense sums), event for
    event, to 1e-8."""
    from roughslip.coupling import blocksolvers

    h = rough(16, seed=seed)
    ref = squeeze_pull_coupled(h, **load, lam=0.2, nu=0.25, method="dense", reference=True)
    monkeypatch.setattr(blocksolvers.DenseBlockSolver, "bulk_min", 10)
    bulk_solves = []
    solve_many = blocksolvers.MatrixFreeBlockSolver.solve_many
    monkeypatch.setattr(blocksolvers.MatrixFreeBlockSolver, "solve_many",
                        lambda self, rhs: bulk_solves.append(len(rhs)) or solve_many(self, rhs))
    fast = squeeze_pull_coupled(h, **load, lam=0.2, nu=0.25, method="dense")
    # the bulk passes ran matrix-free: the overlap always has tensile sites, so a pass that
    # removes them is followed by at least one more
    assert len(bulk_solves) >= 2
    assert fast.converged and ref.converged and fast.details.released == ref.details.released
    assert [(e.kind, e.site) for e in fast.events] == [(e.kind, e.site) for e in ref.events]
    assert fast.friction_force == pytest.approx(ref.friction_force, rel=1e-8)
    np.testing.assert_allclose(fast.start.fz, ref.start.fz, rtol=0,
                               atol=1e-8 * np.abs(ref.start.fz).max())
    assert fast.residual <= 1e-11


# -- the Coulomb law -----------------------------------------------------------------------------
def _coulomb_admissible(res, lam):
    """Every recorded state: the constraints of the break law on contact and stick sites, and
    on the other contact sites either no tangential force (never bonded) or exactly
    f_x = +-lam f_z (a slipping bond). Forces to 1e-8 of the largest, gaps to 1e-8 of the
    depth (the gaps' scale: the highest point is at -depth). ``res``: a pull's result or an
    indentation's."""
    out = getattr(res, "details", res)  # a pull's states are in its details
    fscale = max(float(np.abs(s[1]).max()) for s in out.states)
    gtol = 1e-8 * out.depth
    slipping = 0
    for _D, fz, fx, g, C, S in out.states:
        tol = 1e-8 * fscale
        assert np.all(fz[C] >= -tol) and np.all(fz[~C] == 0) and np.all(fx[~C] == 0)
        assert np.all(g[~C] >= -gtol) and np.all(np.abs(g[C]) <= gtol)
        assert np.all(np.abs(fx[S]) <= lam * fz[S] + tol)
        P = C & ~S & (fx != 0)
        assert np.allclose(np.abs(fx[P]), lam * fz[P], rtol=1e-12, atol=1e-12 * fscale)
        slipping = max(slipping, int(P.sum()))
    return slipping


@pytest.mark.parametrize("nu", [0.0, 0.3])
def test_coulomb_law_agrees_between_the_solvers_and_the_direct_reference(nu):
    """Slipping bonds carry f_x = +-lam f_z, which makes the block system non-symmetric: the
    updated inverse solves it by GMRES on the slip forces (with the block of slip responses
    it keeps current), matrix-free CG's solver by GMRES on the whole system, the reference
    directly (LU of the assembled system, dense sums).
    Same events, forces to 1e-8; every state admissible; when the last bond slips, every
    bonded site carries lam f_z."""
    h = rough(14, seed=5)
    kw = dict(depth=2.5, lam=0.25, nu=nu, slip_law="coulomb")
    ref = squeeze_pull_coupled(h, method="dense", reference=True, record_states=True, **kw)
    inc = squeeze_pull_coupled(h, method="dense", **kw)
    fft = squeeze_pull_coupled(h, method="cg", tol=1e-13, **kw)
    assert ref.converged and inc.converged and fft.converged and ref.slip_law == "coulomb"
    assert len(ref.events) + ref.details.released > 20
    for other in (inc, fft):
        _assert_same_path(other, ref)
        assert other.residual <= 10 * 1e-12
    assert inc.details.slip_iterations > 0 and ref.details.slip_iterations == 0
    assert _coulomb_admissible(ref, 0.25) > 10
    _D, fz, fx, _g, C, S = ref.details.states[-1]  # as the last bond reaches its bound
    bonded = C & (fx != 0)
    assert S.sum() == 1 and np.allclose(fx[bonded], 0.25 * fz[bonded], rtol=1e-10)
    assert ref.curve.fx[-1] == pytest.approx(fx.sum(), rel=1e-12)
    # bonds released backwards by the squeeze stick again when the pull turns their slip
    # around, and slip forwards at last: at full sliding every bond pulls with +lam f_z
    kinds = [e.kind for e in ref.events]
    assert "stick" in kinds and kinds[-1] == "slip+" and ref.details.released > 0
    # a slipping bond keeps its friction: the Coulomb pull force exceeds the break law's
    brk = squeeze_pull_coupled(h, depth=2.5, lam=0.25, nu=nu)
    assert ref.friction_force > brk.friction_force


def test_coulomb_law_without_room_for_the_slip_block(monkeypatch):
    """When the block of slip responses does not fit in memory (with two copies of it), the
    dense solver goes without it from then on, and the Coulomb pull takes an FFT product and a
    product with the inverse per iteration instead: the same events, the forces to round-off."""
    from roughslip.coupling import blocksolvers

    h = rough(14, seed=5)
    kw = dict(depth=2.5, lam=0.25, nu=0.25, slip_law="coulomb", method="dense")
    with_block = squeeze_pull_coupled(h, **kw)
    d = blocksolvers.DenseBlockSolver(Problem.from_arrays(h, nu=0.25))
    monkeypatch.setattr(blocksolvers, "available_bytes", lambda: 1000)
    assert d._slip_columns(np.zeros((10, 0), order="F"), 5) is None  # 3 x 8 x 10 x 64 bytes
    monkeypatch.setattr(blocksolvers, "available_bytes", lambda: 1 << 40)
    monkeypatch.setattr(blocksolvers.DenseBlockSolver, "slip_response", lambda self, sites: None)
    without = squeeze_pull_coupled(h, **kw)
    assert without.converged and with_block.converged
    _assert_same_path(without, with_block)
    # both certified to the residual tol = 1e-12; every contact and stick set's block is a
    # principal submatrix of the whole grid's, so its condition number bounds theirs
    ids = np.arange(2 * h.size)
    kappa = np.linalg.cond(d.entries(ids, ids))
    rel = kappa * 2 * 1e-12
    assert without.friction_force == pytest.approx(with_block.friction_force, rel=rel)


def test_coulomb_law_under_load_control_and_with_bonded_gains():
    """The force-held pull and new bonds for gained contacts under the Coulomb law: the
    updated inverse follows the direct reference event for event, and the force is held."""
    h = rough(14, seed=7) + sphere((14, 14), radius=25.0)
    kw = dict(force=12.0, lam=0.3, nu=0.25, pull_control="force", gained="bonded",
              slip_law="coulomb")
    ref = squeeze_pull_coupled(h, method="dense", reference=True, record_states=True, **kw)
    inc = squeeze_pull_coupled(h, method="dense", **kw)
    assert ref.converged and inc.converged
    assert [(e.kind, e.site) for e in inc.events] == [(e.kind, e.site) for e in ref.events]
    assert np.allclose(inc.curve.fx, ref.curve.fx, rtol=1e-8,
                       atol=1e-10 * np.abs(ref.curve.fx).max())
    assert np.allclose(inc.curve.dz, ref.curve.dz, rtol=1e-8)
    _assert_same_path(inc, ref)
    assert np.allclose(ref.curve.fz, 12.0, rtol=1e-10)
    assert _coulomb_admissible(ref, 0.3) > 0


@pytest.mark.parametrize("history", HISTORIES.names())
@pytest.mark.parametrize("heights", ["rough", "sphere"])
def test_coulomb_law_at_half_poisson_ratio_is_the_decoupled_coulomb_pull(heights, history):
    """At nu = 1/2 nothing couples: the slipping bonds carry lam f_z of the frictionless
    squeeze, and the coupled Coulomb pull is the decoupled one, slip for slip, after every
    squeeze history."""
    h = rough(16) if heights == "rough" else sphere((14, 14), radius=12.0)
    depth = 1.2 if heights == "rough" else 0.8
    c = squeeze_pull_coupled(h, depth=depth, lam=0.2, nu=0.5, slip_law="coulomb",
                             history=history)
    normal = squeeze(h, depth=depth, nu=0.5, tol=1e-13)
    d = pull(normal, lam=0.2, method="inverse", slip_law="coulomb")
    ev = c.events[1:]
    assert c.details.released == 0 and len(ev) == d.steps
    if heights == "rough":  # on the sphere, symmetric sites tie: the order among them is free
        assert [e.site for e in ev] == d.curve.site[1:].tolist()
    assert sorted(e.site for e in ev) == sorted(d.curve.site[1:].tolist())
    assert np.allclose([e.dx for e in ev], d.curve.dx[1:], rtol=1e-9)
    assert np.allclose([e.fx for e in ev], d.curve.fx[1:], rtol=1e-9)
    assert c.friction_force == pytest.approx(d.friction_force, rel=1e-9)
    assert c.friction_force == pytest.approx(0.2 * normal.normal_force, rel=1e-9)
    with pytest.raises(InputError, match="slip_law"):
        squeeze_pull_coupled(h, depth=depth, slip_law="viscous")


# -- frictional indentation ----------------------------------------------------------------------
def _cylinder(n=64, radius=None):
    """A parabolic cylinder along y on one row: with a grid periodic in y the fields do not
    depend on y (plane strain)."""
    x = np.arange(n) - (n - 1) / 2
    return (-x**2 / (2 * (radius or n * n / 256)))[None, :]


def test_indentation_at_half_poisson_ratio_is_the_frictionless_squeeze():
    """At nu = 1/2 nothing couples: every site touches and stays stuck with no tangential
    force, and the normal forces are the frictionless squeeze's at the same depth."""
    from roughslip.contact.problem import Problem
    from roughslip.coupling.coupled import indent

    h = sphere((14, 14), radius=12.0)
    r = indent(Problem.from_arrays(h, nu=0.5), depth=0.8, lam=0.2)
    normal = squeeze(h, depth=0.8, nu=0.5, tol=1e-13)
    assert r.converged and r.depth == 0.8
    assert {e.kind for e in r.events} == {"start", "gained", "end"}
    assert np.array_equal(r.contact, normal.contact) and np.array_equal(r.stick, r.contact)
    assert np.allclose(r.fz, normal.fz, rtol=0, atol=1e-11 * normal.fz.max())
    assert np.all(r.fx == 0) and r.normal_force == pytest.approx(normal.normal_force, rel=1e-12)
    assert np.all(np.diff(r.contact_counts) >= 0) and r.contact_counts[-1] == r.contact.sum()


@pytest.mark.parametrize("case", ["sphere", "cylinder"])
def test_indentation_agrees_between_the_solvers_and_the_direct_reference(case):
    """Coulomb law during the approach: the updated inverse, matrix-free GMRES and the direct
    reference follow the same events to 1e-8, every state is admissible, and slip runs the
    way the theory says: for nu < 1/2 the surface is drawn towards the middle of the contact,
    so friction pushes it outwards (f_x < 0 on the left, > 0 on the right of a cylinder)."""
    from roughslip.contact.problem import Problem
    from roughslip.coupling.coupled import indent

    if case == "sphere":
        pb = Problem.from_arrays(sphere((12, 12), radius=10.0), nu=0.0)
        kw = dict(depth=0.6, lam=0.1)
    else:
        pb = Problem.from_arrays(_cylinder(128), nu=0.0, boundary="periodic")
        kw = dict(depth=1.0, lam=0.3)
    ref = indent(pb, method="dense", reference=True, record_states=True, **kw)
    inc = indent(pb, method="dense", **kw)
    fft = indent(pb, method="cg", tol=1e-13, **kw)
    assert ref.converged and inc.converged and fft.converged
    kinds = [e.kind for e in ref.events]
    assert kinds.count("gained") > 10 and "slip+" in kinds and "slip-" in kinds
    for other in (inc, fft):
        assert [(e.kind, e.site) for e in other.events] == [(e.kind, e.site) for e in ref.events]
        assert np.allclose(other.dz, ref.dz, rtol=1e-8, atol=1e-12)
        assert np.allclose(other.fz, ref.fz, rtol=0, atol=1e-8 * ref.fz.max())
        assert np.allclose(other.fx, ref.fx, rtol=0, atol=1e-8 * ref.fz.max())
    _coulomb_admissible(ref, kw["lam"])
    if case == "cylinder":
        idx = np.flatnonzero(ref.contact[0])
        mid = (pb.shape[1] - 1) / 2
        slip = ref.slip[0]
        assert np.all(slip[idx[idx < mid]] <= 0) and np.all(slip[idx[idx > mid]] >= 0)
        stuck = np.flatnonzero(ref.stick[0])
        assert stuck.size and np.all(np.diff(stuck) == 1)  # one central stick zone


@pytest.mark.parametrize("ratio", [0.6, 1.2])
def test_the_stick_zone_of_a_loaded_cylinder_is_the_continuum_one(ratio):
    """Monotonic loading of a parabolic cylinder is self-similar in the continuum: the stick
    zone keeps a constant fraction c/a of the contact, which in the limit beta lam -> 0
    depends on lam / beta only and is computed independently by
    :func:`plane_indentation_stick_ratio` (singular integral equation, Gauss-Chebyshev).
    At nu = 0.49 (beta lam < 5e-4) and a period of about 900 contact half-widths (the period
    biases c/a by about 1.7 a/L), the discrete model holds c/a to a pixel at each end of the
    stick zone over the second half of a loading to a = 37 pixels, its median within a pixel
    of the continuum value, and each new contact costs a couple of events (not the 24 of a
    slip zone sticking and slipping again at every new contact)."""
    from roughslip.contact.analytic import plane_indentation_stick_ratio
    from roughslip.contact.problem import Problem
    from roughslip.coupling.coupled import indent

    nu = 0.49
    beta = (1 - 2 * nu) / (2 * (1 - nu))
    r = indent(Problem.from_arrays(_cylinder(32768, radius=4096.0), nu=nu,
                                   boundary="periodic"), depth=1.0, lam=ratio * beta)
    c, s = r.contact_counts, r.stick_counts
    kinds = np.array([e.kind for e in r.events])
    late = (kinds == "gained") & (c >= c[-1] // 2)
    frac = s[late] / c[late]
    pixel = 2 / c[-1]  # one site at each end of the stick zone, at the end of the loading
    assert c[-1] >= 70 and late.sum() >= 15
    # each end of the stick zone within a site of its place: a spread of two such steps, at
    # the smallest contact of the window
    assert np.ptp(frac) <= 2 * (2 / c[late].min())
    assert abs(np.median(frac) - plane_indentation_stick_ratio(ratio)) <= pixel
    assert len(r.events) <= 4 * (kinds == "gained").sum()


def test_indentation_rejects_bad_input():
    from roughslip.contact.problem import Problem
    from roughslip.coupling.coupled import indent

    pb = Problem.from_arrays(sphere((8, 8), radius=5.0), nu=0.3)
    for kw, match in (({"depth": -1.0}, "depth"), ({"depth": float("nan")}, "depth"),
                      ({"depth": 1.0, "lam": 0.0}, "lam"),
                      ({"depth": 1.0, "slip_law": "glue"}, "slip_law")):
        with pytest.raises(InputError, match=match):
            indent(pb, **kw)
    r = indent(pb, depth=0.0)
    assert r.normal_force == 0 and r.converged
    # on a periodic grid the depth is measured from the mean plane: it has a limit
    per = Problem.from_arrays(_cylinder(32), nu=0.3, boundary="periodic")
    too_deep = per.depth_limit() + 0.1
    for call in (indent, squeeze_pull_coupled):
        with pytest.raises(InputError, match="max\\(h\\) - mean\\(h\\)"):
            call(per, depth=too_deep)


def test_the_dense_solver_refines_when_its_residual_is_above_tol():
    """A tolerance below what the inverse reaches makes every solve refine (a crash before:
    the refinement step passed a vector where the product expected columns); the friction
    force is that of the default tolerance, and the run says it missed tol."""
    from roughslip import couple
    from roughslip.contact.problem import Problem
    from roughslip.elastic.operators import Grid, Material

    n, h = 24, 0.1 / 6
    p = Problem(sphere((n, n), radius=1.0, a=h), Grid((n, n), h), Material(1.0, 0.3))
    ref = couple(p, depth=0.0036, lam=0.3, method="dense")
    tight = couple(p, depth=0.0036, lam=0.3, method="dense", tol=1e-17)
    assert ref.converged and not tight.converged
    assert tight.friction_force == pytest.approx(ref.friction_force, rel=1e-12)
    assert tight.residual < 1e-15


def test_the_coupled_squeeze_under_load_honours_the_squeeze_method():
    """Under load control the starting contact set comes from the frictionless squeeze by
    the chosen method; the coupled squeeze corrects it exactly, so both methods give the same
    answer to the solver's tolerance, and an unknown method is an error that names it."""
    from roughslip.contact.problem import Problem
    from roughslip.coupling.coupled import couple
    from roughslip.elastic.operators import Grid, Material

    h = self_affine((20, 20), hurst=0.8, rms_height=1.0, rng=sample_rng(2, 0))
    p = Problem(h, Grid((20, 20), 1.0), Material(1.0, 0.25))
    pk = couple(p, force=6.0, lam=0.2, squeeze_method="pk")
    act = couple(p, force=6.0, lam=0.2, squeeze_method="active-set")
    assert act.friction_force == pytest.approx(pk.friction_force, rel=1e-9)
    assert act.normal_force == pytest.approx(6.0, rel=1e-10)
    assert np.array_equal(act.start.contact, pk.start.contact)
    with pytest.raises(InputError, match="method = 'nope': unknown squeeze method"):
        couple(p, force=6.0, lam=0.2, squeeze_method="nope")


class _Flipper:
    """An event state that a rule sends back and forth between two discrete states at one
    drive: lost at D, gained again at D, as a degenerate site was before its rule."""

    def __init__(self) -> None:
        self.C = np.ones((2, 2), bool)
        self.S = self.C.copy()
        self.progress, self.discontinuous = Progress(), False
        self.failed_inside = ()

    def interval(self, D):
        kind = "lost" if self.C[0, 0] else "gained"
        return D, D, kind, 0  # due at once, whatever the state

    def violation(self, D):
        return None

    def reversal(self):
        return None

    def holds(self):
        return True

    def apply(self, kind, j, D=0.0):
        self.C.ravel()[j] = self.S.ravel()[j] = kind == "gained"

    def solve(self):
        pass

    def at(self, D):
        z = np.zeros((2, 2))
        return z, z, z

    def totals(self, D):
        return 0.0, 0.0

    def snapshot(self, D):
        return Snapshot.of(self, D)

    def dx_at(self, D):
        return D

    def depth_at(self, D):
        return 0.0

    def signature(self):
        return digest(self.C, self.S)


def test_the_event_loop_stops_when_a_state_comes_back_at_one_drive():
    """A state that comes back at one drive ends the path as a cycle on its VISITS-th visit
    (a second visit may differ by continuous data), naming the event and the site, instead
    of running to the event limit."""
    path = follow_events(_Flipper(), limit=1000, record_states=False)
    kinds = [e.kind for e in path.events]
    assert kinds == ["start"] + ["lost", "gained"] * (VISITS - 1)
    assert path.message.startswith("the events cycle") and "'gained' event at site 0" in (
        path.message)


def _block_solver_uses() -> dict[str, set[str]]:
    """Attributes read on a block solver by the coupled model's states, histories and
    driver: on ``solver``, ``s`` and ``self.solver``."""
    import ast
    from pathlib import Path

    import roughslip

    pkg = Path(roughslip.__file__).parent / "coupling"
    out = {}
    for name in ("state.py", "histories.py", "coupled.py"):
        used = set()
        for node in ast.walk(ast.parse((pkg / name).read_text())):
            if isinstance(node, ast.Attribute):
                v = node.value
                if (isinstance(v, ast.Name) and v.id in ("solver", "s")) or (
                        isinstance(v, ast.Attribute) and v.attr == "solver"):
                    used.add(node.attr)
        out[name] = used
    return out


def test_the_block_solver_protocol_is_what_the_coupled_model_uses():
    """The protocol lists every member its callers read, and every registered solver has every
    member of it (by introspection): a new solver that implements the protocol runs."""
    import inspect

    from roughslip.coupling.blocksolvers import SOLVERS, BlockSolver

    members = {n for n in dir(BlockSolver) if not n.startswith("_")}
    members |= set(BlockSolver.__annotations__)
    for name, used in _block_solver_uses().items():
        assert used <= members, f"{name}: {sorted(used - members)}"
    pb = Problem.from_arrays(np.zeros((4, 4)), nu=0.25)
    for method in SOLVERS.names():
        solver = SOLVERS.get(method)(pb)
        for m in members:
            assert hasattr(solver, m), f"{method}: {m}"
        for n, f in inspect.getmembers(BlockSolver, inspect.isfunction):
            if not n.startswith("_"):
                want = list(inspect.signature(f).parameters)
                have = list(inspect.signature(getattr(type(solver), n)).parameters)
                assert have[: len(want)] == want, f"{method}: {n}"


@pytest.mark.parametrize("law", ["break", "coulomb"])
@pytest.mark.parametrize("method", [m for m in __import__(
    "roughslip.coupling.blocksolvers", fromlist=["SOLVERS"]).SOLVERS.names()])
def test_every_block_solver_follows_the_dense_reference(method, law):
    """The shared suite of the block solvers, over the registry: every registered solver, on
    a rough scene under both laws, from the bonded and the frictionless histories, gives the
    events of the dense reference (every state factorised afresh, displacements by dense
    sums) and its forces within 4 cond(K) tol, cond(K) bounded by the whole grid's block."""
    from roughslip.coupling.coupled import couple
    from roughslip.testing import dense_block

    h = self_affine((12, 12), hurst=0.8, rms_height=1.0, rng=sample_rng(9, 0), oversample=2)
    pb = Problem.from_arrays(h, nu=0.25)
    w = np.linalg.eigvalsh(dense_block(pb))
    tol = 1e-12
    bound = 4 * (w[-1] / w[0]) * tol
    for history in ("bonded", "frictionless"):
        kw = dict(depth=1.4, lam=0.3, slip_law=law, history=history, tol=tol)
        ref = couple(pb, method="dense", reference=True, **kw)
        res = couple(pb, method=method, **kw)
        assert res.converged and res.method == method, res.message
        assert [(e.kind, e.site) for e in res.events] == [(e.kind, e.site) for e in ref.events]
        scale = float(np.abs(ref.start.fz).max())
        assert np.allclose(res.curve.fx, ref.curve.fx, rtol=bound, atol=bound * scale)
        assert res.friction_force == pytest.approx(ref.friction_force, rel=bound)
