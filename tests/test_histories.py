"""Squeeze histories of the coupled model: each rule against an independent dense
implementation or the state it must reproduce, load control, and bad input."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import squeeze
from roughslip.coupling.coupled import couple, indent
from roughslip.coupling.histories import HISTORIES
from roughslip.errors import InputError
from roughslip.surfaces.synthetic import sample_rng, self_affine

TIE = 1e-9


def rough(n: int = 12, seed: int = 3) -> np.ndarray:
    return self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0),
                       oversample=2)


def _dense_block(problem: Problem) -> np.ndarray:
    """The full (z, x) block operator as a dense matrix, column by column from FFT products of
    unit forces (not from the kernel tables the solvers assemble from). Unknowns: f_z at
    site i is row i, f_x at site i is row n + i."""
    op = problem.operator("zz", "zx", "xx")
    n = problem.base.size
    A = np.empty((2 * n, 2 * n))
    for j in range(2 * n):
        f = np.zeros(2 * n)
        f[j] = 1.0
        uz, ux = op.apply_block(f[:n].reshape(problem.shape), f[n:].reshape(problem.shape))
        A[:, j] = np.concatenate([uz.ravel(), ux.ravel()])
    return 0.5 * (A + A.T)


def _simultaneous_by_hand(problem: Problem, depth: float, lam: float):
    """The simultaneous rule written out on the dense matrix: from the overlap, all bonded
    (u_x = 0), change every violation of the first kind found at once (tensile contacts
    leave; else penetrating sites enter, unbonded; else overloaded bonds break), solve
    again, until none is left."""
    A = _dense_block(problem)
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
    assert np.array_equal(r.contact0.ravel(), C) and np.array_equal(r.stick0.ravel(), S)
    assert np.allclose(r.fz0.ravel(), fz, rtol=0, atol=1e-10 * fz.max())
    assert np.allclose(r.fx0.ravel(), fx, rtol=0, atol=1e-10 * fz.max())
    assert r.released == int((C & ~S).sum()) > 0
    # a different rule from one bond at a time: here it releases a different set
    one = couple(pb, depth=1.6, lam=0.2, history="bonded", method="dense")
    assert one.squeeze_states > r.squeeze_states


@pytest.mark.parametrize("nu", [0.0, 0.25, 0.45])
def test_frictionless_history_starts_from_the_frictionless_squeeze_with_no_tangential_force(nu):
    h = rough(14, seed=6)
    pb = Problem.from_arrays(h, nu=nu)
    r = couple(pb, depth=1.5, lam=0.2, history="frictionless")
    normal = squeeze(h, depth=1.5, nu=nu, tol=1e-13)
    assert r.released == 0
    assert np.array_equal(r.contact0, normal.contact) and np.array_equal(r.stick0, r.contact0)
    assert np.allclose(r.fz0, normal.fz, rtol=0, atol=1e-10 * normal.fz.max())
    assert np.abs(r.fx0).max() <= 1e-10 * normal.fz.max()
    assert r.events[0].fx == pytest.approx(0.0, abs=1e-10 * normal.normal_force)


@pytest.mark.parametrize("law", ["break", "coulomb"])
def test_indent_history_starts_from_the_frictional_indentation(law):
    pb = Problem.from_arrays(rough(14, seed=8), nu=0.2)
    r = couple(pb, depth=1.4, lam=0.25, history="indent", slip_law=law)
    ind = indent(pb, depth=1.4, lam=0.25, slip_law=law)
    assert np.array_equal(r.contact0, ind.contact) and np.array_equal(r.stick0, ind.stick)
    scale = ind.fz.max()
    assert np.allclose(r.fz0, ind.fz, rtol=0, atol=1e-10 * scale)
    assert np.allclose(r.fx0, ind.fx, rtol=0, atol=1e-10 * scale)
    assert r.released == int((ind.contact & ~ind.stick).sum())
    assert r.released > 0 or law == "coulomb"  # a slipping site may stick again
    assert r.squeeze_states >= len(ind.events)


@pytest.mark.parametrize("history", HISTORIES.names())
def test_every_history_holds_the_normal_force_under_load_control(history):
    pb = Problem.from_arrays(rough(14, seed=2), nu=0.25)
    r = couple(pb, force=3.0, lam=0.2, history=history, pull_control="force")
    assert r.converged
    assert r.normal_force == pytest.approx(3.0, rel=1e-10)
    assert np.allclose(r.fz, 3.0, rtol=1e-9)
    by_depth = couple(pb, depth=r.depth, lam=0.2, history=history)
    # the same squeeze reached through its depth: the same state at D_x = 0
    assert np.array_equal(by_depth.stick0, r.stick0)
    assert by_depth.normal_force == pytest.approx(3.0, rel=1e-9)


def test_the_histories_differ_where_the_coupling_acts():
    """At nu = 0.25 the rules leave different starts: the frictionless one releases nothing
    and holds the most, the others release bonds."""
    pb = Problem.from_arrays(rough(16, seed=5), nu=0.25)
    out = {h: couple(pb, depth=1.6, lam=0.2, history=h) for h in HISTORIES.names()}
    assert out["frictionless"].released == 0
    assert all(out[h].released > 0 for h in ("bonded", "simultaneous", "indent"))
    assert out["frictionless"].friction_force > max(
        out[h].friction_force for h in ("bonded", "simultaneous", "indent"))


def test_an_unknown_history_is_refused_in_one_line():
    pb = Problem.from_arrays(rough(8), nu=0.25)
    with pytest.raises(InputError, match=r"history = 'gradual': unknown squeeze history; "
                       r"choose one of bonded, simultaneous, frictionless, indent"):
        couple(pb, depth=1.0, history="gradual")


def test_the_coulomb_friction_at_full_sliding_does_not_depend_on_the_history():
    """Under the Coulomb law, with contacts gained during the pull bonded, every contact ends
    slipping forwards, carrying lam f_z: that state is the same whatever the start, and so is
    the friction force when the peak is there. (With unbonded gains the contacts gained carry
    nothing, and which are gained depends on the path.)"""
    pb = Problem.from_arrays(rough(16, seed=5), nu=0.25)
    out = {h: couple(pb, depth=1.6, lam=0.2, history=h, slip_law="coulomb", gained="bonded")
           for h in HISTORIES.names()}
    ref = out["bonded"]
    assert ref.peak_dx == ref.events[-1].dx  # the peak is at full sliding
    for r in out.values():
        assert r.friction_force == pytest.approx(ref.friction_force, rel=1e-10)
        assert r.friction_force == pytest.approx(0.2 * r.normal_force_at_peak, rel=1e-10)
