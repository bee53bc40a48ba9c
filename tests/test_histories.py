"""Squeeze histories of the coupled model: each rule against an independent dense
implementation or the state it must reproduce, load control, and bad input."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import squeeze
from roughslip.coupling.coupled import couple, indent
from roughslip.coupling.histories import HISTORIES
from roughslip.errors import InputError
from roughslip.surfaces.synthetic import sample_rng, self_affine
from roughslip.testing import dense_block

TIE = 1e-9


def rough(n: int = 12, seed: int = 3) -> np.ndarray:
    return self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0),
                       oversample=2)


def _simultaneous_by_hand(problem: Problem, depth: float, lam: float):
    """The simultaneous rule written out on the dense matrix: from the overlap, all bonded
    (u_x = 0), change every violation of the first kind found at once (tensile contacts
    leave; else penetrating sites enter, unbonded; else overloaded bonds break), solve
    again, until none is left."""
    A = dense_block(problem)
    n = problem.base.size
    ubar = problem.base.ravel() + depth
    C = problem.overlap(depth).ravel() > 0
    S = C.copy()
    rounds = 0
    while True:
        rows = np.concatenate([np.flatnonzero(C), n + np.flatnonzero(S)])
        rhs = np.concatenate([ubar[C], np.zeros(int(S.sum()))])
        f = np.zeros(2 * n)
        f[rows] = np.linalg.solve(A[np.ix_(rows, rows)], rhs)
        fz, fx = f[:n], f[n:]
        gap = (A[:n] @ f) - ubar
        rounds += 1
        neg = C & (fz < -TIE * np.abs(fz).max())
        pen = ~C & (gap < -TIE * float(np.max(ubar)))
        over = S & (np.abs(fx) > lam * fz * (1 + TIE))
        if neg.any():
            C &= ~neg
            S &= ~neg
        elif pen.any():
            C |= pen
        elif over.any():
            S &= ~over
        else:
            return fz, fx, C, S


@pytest.mark.parametrize("nu", [0.0, 0.25])
def test_simultaneous_is_the_step_seven_rule_on_the_dense_matrix(nu):
    pb = Problem.from_arrays(rough(10, seed=4), nu=nu)
    fz, fx, C, S = _simultaneous_by_hand(pb, 1.6, 0.2)
    r = couple(pb, depth=1.6, lam=0.2, history="simultaneous", method="dense")
    assert np.array_equal(r.start.contact.ravel(), C) and np.array_equal(r.start.stick.ravel(), S)
    assert np.allclose(r.start.fz.ravel(), fz, rtol=0, atol=1e-10 * fz.max())
    assert np.allclose(r.start.fx.ravel(), fx, rtol=0, atol=1e-10 * fz.max())
    assert r.details.released == int((C & ~S).sum()) > 0
    # a different rule from one bond at a time: here it releases a different set
    one = couple(pb, depth=1.6, lam=0.2, history="bonded", method="dense")
    assert one.details.squeeze_states > r.details.squeeze_states


@pytest.mark.parametrize("nu", [0.0, 0.25, 0.45])
def test_frictionless_history_starts_from_the_frictionless_squeeze_with_no_tangential_force(nu):
    h = rough(14, seed=6)
    pb = Problem.from_arrays(h, nu=nu)
    r = couple(pb, depth=1.5, lam=0.2, history="frictionless")
    normal = squeeze(h, depth=1.5, nu=nu, tol=1e-13)
    assert r.details.released == 0
    assert np.array_equal(r.start.contact, normal.contact)
    assert np.array_equal(r.start.stick, r.start.contact)
    assert np.allclose(r.start.fz, normal.fz, rtol=0, atol=1e-10 * normal.fz.max())
    assert np.abs(r.start.fx).max() <= 1e-10 * normal.fz.max()
    assert r.events[0].fx == pytest.approx(0.0, abs=1e-10 * normal.normal_force)


@pytest.mark.parametrize("law", ["break", "coulomb"])
def test_indent_history_starts_from_the_frictional_indentation(law):
    pb = Problem.from_arrays(rough(14, seed=8), nu=0.2)
    r = couple(pb, depth=1.4, lam=0.25, history="indent", slip_law=law)
    ind = indent(pb, depth=1.4, lam=0.25, slip_law=law)
    assert np.array_equal(r.start.contact, ind.contact) and np.array_equal(r.start.stick, ind.stick)
    scale = ind.fz.max()
    assert np.allclose(r.start.fz, ind.fz, rtol=0, atol=1e-10 * scale)
    assert np.allclose(r.start.fx, ind.fx, rtol=0, atol=1e-10 * scale)
    assert r.details.released == int((ind.contact & ~ind.stick).sum())
    assert r.details.released > 0 or law == "coulomb"  # a slipping site may stick again
    assert r.details.squeeze_states >= len(ind.events)


@pytest.mark.parametrize("history", HISTORIES.names())
def test_every_history_holds_the_normal_force_under_load_control(history):
    pb = Problem.from_arrays(rough(14, seed=2), nu=0.25)
    r = couple(pb, force=3.0, lam=0.2, history=history, pull_control="force")
    assert r.converged
    assert r.normal_force == pytest.approx(3.0, rel=1e-10)
    assert np.allclose(r.curve.fz, 3.0, rtol=1e-9)
    by_depth = couple(pb, depth=r.details.depth, lam=0.2, history=history)
    # the same squeeze reached through its depth: the same state at D_x = 0
    assert np.array_equal(by_depth.start.stick, r.start.stick)
    assert by_depth.normal_force == pytest.approx(3.0, rel=1e-9)


def test_the_histories_differ_where_the_coupling_acts():
    """At nu = 0.25 the rules leave different starts: the frictionless one releases nothing
    and holds the most, the others release bonds."""
    pb = Problem.from_arrays(rough(16, seed=5), nu=0.25)
    out = {h: couple(pb, depth=1.6, lam=0.2, history=h) for h in HISTORIES.names()}
    assert out["frictionless"].details.released == 0
    assert all(out[h].details.released > 0 for h in ("bonded", "simultaneous", "indent"))
    assert out["frictionless"].friction_force > max(
        out[h].friction_force for h in ("bonded", "simultaneous", "indent"))


def test_an_unknown_history_is_refused_in_one_line():
    pb = Problem.from_arrays(rough(8), nu=0.25)
    with pytest.raises(InputError, match=r"history = 'gradual': unknown squeeze history; "
                       r"choose one of bonded, simultaneous, frictionless, indent"):
        couple(pb, depth=1.0, history="gradual")


def _murty(M: np.ndarray, q: np.ndarray) -> np.ndarray:
    """z >= 0 with w = q + M z >= 0 and z w = 0, by Murty's least-index principal pivoting
    (finite for a P-matrix: K. G. Murty, Math. Programming 6 (1974) 326): flip the lowest
    index whose z or w is negative, solve again."""
    n = q.size
    basis = np.zeros(n, bool)
    for _ in range(n * n):
        z = np.zeros(n)
        if basis.any():
            z[basis] = np.linalg.solve(M[np.ix_(basis, basis)], -q[basis])
        w = q + M @ z
        bad = (basis & (z < -1e-13 * np.abs(z).max())) | (~basis & (w < -1e-13 * np.abs(q).max()))
        if not bad.any():
            return z
        i = int(np.flatnonzero(bad)[0])
        basis[i] = not basis[i]
    raise AssertionError("principal pivoting did not end")


@pytest.mark.parametrize("seed", [3, 5])
def test_a_coulomb_pull_ends_in_the_one_full_sliding_state_of_its_bonds(seed):
    """Under the Coulomb law with bonded gains a pull ends with no bond sticking and every
    bond slipping forwards, carrying lam f_z; its normal forces solve the complementarity
    problem f_z >= 0, g = (G_zz + lam G_zx D_B) f_z - ubar >= 0, f_z g = 0, with D_B marking
    the contacts that carry a bond. G_zx is antisymmetric (its kernel is odd in x), so with
    every contact bonded the matrix has the symmetric part G_zz, is a P-matrix, and the end
    state is unique: the same for every history that bonds all its contacts. The bonded
    histories gain contacts at D_x = 0 unbonded (seed 3: one), which carry nothing, so they
    end lower there. Each end state is checked against principal pivoting on the dense
    matrix, to the certified solves' tolerance times the condition number."""
    pb = Problem.from_arrays(rough(16, seed=seed), nu=0.25)
    n, lam, tol = pb.base.size, 0.2, 1e-12
    A = dense_block(pb)
    Gzz, Gzx = A[:n, :n], A[:n, n:]
    assert np.abs(Gzx + Gzx.T).max() <= 1e-13 * np.abs(Gzx).max()  # antisymmetric
    ubar = pb.base.ravel() + 1.6
    ends, kappa = {}, 1.0
    for h in HISTORIES.names():
        r = couple(pb, depth=1.6, lam=lam, history=h, slip_law="coulomb", gained="bonded",
                   tol=tol)
        assert r.converged, r.message
        # contacts without a bond at D_x = 0 carry exactly nothing (no slip force is set)
        bond = ~(r.start.contact & ~r.start.stick & (r.start.fx == 0)).ravel()
        M = Gzz + lam * Gzx * bond[None, :]
        fz = _murty(M, -ubar)
        C = fz > 0
        kappa = max(kappa, float(np.linalg.cond(M[np.ix_(C, C)])))
        end = r.events[-1].fx  # the last bond's failure: the forces are continuous there
        assert end == pytest.approx(lam * fz[bond].sum(), rel=10 * kappa * tol)
        ends[h] = (bool(bond.all()), end)
    unbonded = sorted(h for h, (every, _) in ends.items() if not every)
    assert unbonded == (["bonded", "simultaneous"] if seed == 3 else [])
    every = [end for every, end in ends.values() if every]
    assert max(every) - min(every) <= 20 * kappa * tol * max(every)


def _rates(A: np.ndarray, C: np.ndarray, S: np.ndarray, sigma: np.ndarray, lam: float):
    """The rates in D_x of (f_z, f_x, u_z, u_x) on the dense block for the sets C and S and
    the slip directions sigma (slipping sites carry f_x = sigma lam f_z), the depth held."""
    n = C.size
    cz, cx = np.flatnonzero(C), np.flatnonzero(S)
    E = np.zeros((2 * n, cz.size + cx.size))  # unknowns -> forces
    E[cz, np.arange(cz.size)] = 1.0
    E[n + cx, cz.size + np.arange(cx.size)] = 1.0
    slip = C & ~S & (sigma != 0)
    E[n + np.flatnonzero(slip), np.searchsorted(cz, np.flatnonzero(slip))] = (
        lam * sigma[slip])
    rows = np.concatenate([cz, n + cx])
    y = np.linalg.solve((A @ E)[rows], np.concatenate([np.zeros(cz.size), np.ones(cx.size)]))
    f = E @ y
    u = A @ f
    return f[:n], f[n:], u[:n], u[n:]


def test_a_bond_gained_with_no_force_fails_before_its_contact_is_lost():
    """A contact gained bonded starts with f_z = f_x = 0, so its strength is zero too. Where
    its normal force would fall while it sticks, its loss and its failure are due at the same
    drive (exact data, not a near-tie), and the bond fails first. On this scene the rate
    problem of such a site, its four states (out of contact, stuck, slipping either way)
    solved on the dense matrix, has exactly one admissible state, slipping forwards, and the
    pull takes it at once; no site is lost and gained again at one drive."""
    pb = Problem.from_arrays(rough(16, seed=5), nu=0.25)
    lam = 0.2
    r = couple(pb, depth=1.6, lam=lam, history="frictionless", slip_law="coulomb",
               gained="bonded", record_states=True)
    assert r.converged, r.message
    A = dense_block(pb)
    ev = r.events
    pairs = list(itertools.pairwise(ev))
    assert not any(a.kind in ("lost", "gained") and b.kind in ("lost", "gained")
                   and a.site == b.site for a, b in pairs)
    degenerate = [k for k, (a, b) in enumerate(pairs)
                  if a.kind == "gained" and b.kind.startswith("slip") and a.site == b.site]
    assert degenerate  # the scene has one (site 67)
    for k in degenerate:
        j = ev[k].site
        _, _, fx, _, C, S = r.details.states[k]  # the state the gain ends
        C, S = C.ravel().copy(), S.ravel().copy()
        sigma = np.where(C & ~S, np.sign(fx.ravel()), 0.0)
        ok = {}
        for state in ("out", "stick", "slip+", "slip-"):
            C[j], S[j] = state != "out", state == "stick"
            sigma[j] = {"slip+": 1.0, "slip-": -1.0}.get(state, 0.0)
            dfz, dfx, duz, dux = _rates(A, C, S, sigma, lam)
            scale = np.abs(dfz).max()
            if state == "out":
                ok[state] = duz[j] >= 0  # the gap must not close
            elif state == "stick":
                ok[state] = dfz[j] >= 0 and abs(dfx[j]) <= lam * dfz[j]
            else:  # pressed, and slipping the way its force points
                ok[state] = dfz[j] >= 0 and sigma[j] * (dux[j] - 1.0) <= 1e-9 * scale
        assert [s for s, good in ok.items() if good] == [ev[k + 1].kind]
