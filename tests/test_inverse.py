"""The updatable inverse of roughslip.linalg.inverse against dense inverses of the same matrix."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.errors import NumericalError
from roughslip.linalg.inverse import Tracked, UpdatableInverse, inverse_bytes


def _matrix(n: int, definite: bool, seed: int) -> np.ndarray:
    """A symmetric matrix: positive definite, or with about a third negative eigenvalues
    (kept away from zero, so that every principal submatrix met here is nonsingular)."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    w = rng.uniform(1.0, 4.0, n)
    if not definite:
        w[rng.random(n) < 0.35] *= -1
    A = (Q * w) @ Q.T
    return 0.5 * (A + A.T)


def _inverse(A: np.ndarray, **kw) -> UpdatableInverse:
    def entries(i, j, order):
        return np.array(A[np.ix_(i, j)], order=order)
    return UpdatableInverse(entries, A.shape[0], room=lambda m: True, **kw)


def _check(inv: UpdatableInverse, A: np.ndarray, rtol: float = 1e-9) -> None:
    """The held inverse, restricted to the live rows, is the inverse of A on the set."""
    ids = inv.unknowns()
    rows = inv.row[ids]
    E = np.eye(inv.m)[:, rows]
    got = inv.apply(E)[rows]
    want = np.linalg.inv(A[np.ix_(ids, ids)])
    assert np.abs(got - want).max() <= rtol * np.abs(want).max()


@pytest.mark.parametrize("definite", [True, False])
@pytest.mark.parametrize("block", [3, 512])
def test_removals_additions_and_compaction_match_the_dense_inverse(definite, block):
    """A random sequence of removals, bordered additions (sometimes past the spare capacity,
    which grows the buffer) and compactions, from one factorisation: the held inverse and the
    tracked solutions agree with dense solves throughout; indefinite matrices included. The
    tracked solutions are a vector and two blocks of columns, one Fortran-ordered (updated by
    BLAS in place, and kept in that order) and one C-ordered."""
    n = 60
    A = _matrix(n, definite, seed=3)
    rng = np.random.default_rng(5)
    rhs = rng.normal(size=n)
    blocks = {"F": np.asfortranarray(rng.normal(size=(n, 3))), "C": rng.normal(size=(n, 2))}
    inv = _inverse(A, block=block, definite=definite)
    start = np.sort(rng.choice(n, 30, replace=False))
    assert inv.factor(start)
    x0 = inv.apply(rhs[inv.ids])
    inv.tracked["r"] = Tracked(rhs[inv.ids].copy(), x0, lambda ids: rhs[ids])
    for key, R in blocks.items():
        b = np.array(R[inv.ids], order=key)
        inv.tracked[key] = Tracked(b, np.array(inv.apply(b), order=key),
                                   lambda ids, R=R: R[ids])
    for step in range(40):
        members = inv.unknowns()
        for u in rng.choice(members, rng.integers(1, 3), replace=False):
            assert inv.remove(int(u))
        outside = np.setdiff1d(np.arange(n), inv.unknowns())
        new = rng.choice(outside, rng.integers(0, 4), replace=False)
        if new.size:
            assert inv.add(np.sort(new)) is True
        if step % 7 == 6:
            assert inv.compact(0)
        _check(inv, A)
        ids = inv.unknowns()
        t = inv.tracked["r"]
        want = np.linalg.solve(A[np.ix_(ids, ids)], rhs[ids])
        assert np.abs(t.x[inv.row[ids]] - want).max() <= 1e-9 * np.abs(want).max()
        for key, R in blocks.items():
            t = inv.tracked[key]
            want = np.linalg.solve(A[np.ix_(ids, ids)], R[ids])
            assert np.abs(t.x[inv.row[ids]] - want).max() <= 1e-9 * np.abs(want).max()
        assert inv.tracked["F"].x.flags.f_contiguous
    assert inv.factorisations == 1


def test_a_lost_positive_pivot_is_reported_and_an_indefinite_one_is_taken():
    """With ``definite`` an update whose pivot is not positive fails (the caller factorises
    afresh); without it the same update goes through and stays exact."""
    A = np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.5], [0.0, 0.5, 3.0]])  # indefinite
    with pytest.raises(NumericalError, match="not positive definite"):
        _inverse(A).factor(np.arange(3))
    ind = _inverse(A, definite=False)
    assert ind.factor(np.array([0, 2]))
    assert ind.add(np.array([1])) is True  # Schur complement 1 - 2^2/1 - 0.5^2/3 < 0
    _check(ind, A)
    assert ind.remove(0)
    _check(ind, A)
    # the definite object refuses the same bordering
    d = _inverse(A)
    assert d.factor(np.array([0, 2]))
    assert d.add(np.array([1])) is False


def test_refine_certifies_one_or_several_columns_against_the_exact_operator():
    """One refinement step x + A^-1 (b - A_exact x) for a 1-D right-hand side (a crash
    before: products assumed two dimensions), counted and returned with the residual."""
    A = _matrix(20, True, seed=1)
    inv = _inverse(A)
    assert inv.factor(np.arange(20))
    b = np.arange(20.0)
    x = inv.apply(b) * (1 + 1e-6)  # a perturbed solution

    def residual(x):
        r = b - A @ x
        return r, float(np.linalg.norm(r) / np.linalg.norm(b))

    x, res, done = inv.refine(x, residual, 1e-13, 3)
    assert 1 <= done <= 3 and res <= 1e-13
    assert np.allclose(A @ x, b, rtol=0, atol=1e-12 * np.abs(b).max())


def test_room_is_asked_before_every_allocation():
    """No factorisation or growth without ``room``; a refused growth leaves the inverse as it
    was and says so (None)."""
    A = _matrix(12, True, seed=2)
    asked = []
    allow = {"ok": False}

    def room(m):
        asked.append(m)
        return allow["ok"]

    inv = UpdatableInverse(lambda i, j, o: np.array(A[np.ix_(i, j)], order=o), 12, room=room)
    assert not inv.factor(np.arange(4)) and not inv.ready and asked == [4]
    allow["ok"] = True
    assert inv.factor(np.arange(4))
    allow["ok"] = False
    assert inv.add(np.arange(4, 12)) is None  # needs a larger buffer
    assert asked[-1] == 12 and inv.m == 4
    _check(inv, A)
    assert inverse_bytes(1000) == 28 * 1000**2


def test_a_numerically_singular_indefinite_update_is_refused():
    """Without definiteness only a singular update fails: a zero pivot on removal (the rest
    would be singular) and a zero Schur complement on addition."""
    A = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 2.0]])  # eigenvalues -1, 1, 2
    inv = _inverse(A, definite=False)
    assert inv.factor(np.arange(3))
    assert not inv.remove(0)  # leaves [[0, 0], [0, 2]]: singular
    _check(inv, A)  # nothing changed
    inv = _inverse(A, definite=False)
    assert inv.factor(np.array([2]))
    assert inv.add(np.array([0])) is False  # Schur complement A_00 = 0
    _check(inv, A)


@pytest.mark.parametrize("block", [3, 512])
def test_the_lower_layout_shrinks_in_place_and_matches_the_dense_inverse(block):
    """The lower-triangle layout: removals one at a time, blocked folding and compaction in
    place; the held inverse and a tracked solution agree with dense solves throughout, the
    buffer is never reallocated, and growing the set or an indefinite matrix is refused."""
    n = 60
    A = _matrix(n, True, seed=4)
    rng = np.random.default_rng(6)
    rhs = rng.normal(size=n)
    inv = _inverse(A, block=block, lower=True)
    assert inv.factor(np.arange(n))
    base = inv.buf
    inv.tracked["r"] = Tracked(rhs.copy(), inv.apply(rhs), lambda ids: rhs[ids])
    for u in rng.permutation(n)[:45]:
        assert inv.remove(int(u))
        if inv.k == block:
            inv.flush()
        if (~inv.live).sum() > 0.25 * inv.m:
            assert inv.compact()
            assert np.shares_memory(inv.buf, base)
        _check(inv, A)
        ids = inv.unknowns()
        want = np.linalg.solve(A[np.ix_(ids, ids)], rhs[ids])
        got = inv.tracked["r"].x[inv.row[ids]]
        assert np.abs(got - want).max() <= 1e-9 * np.abs(want).max()
    assert inv.m < n  # it compacted
    with pytest.raises(ValueError, match="only shrinks"):
        inv.add(np.array([int(np.setdiff1d(np.arange(n), inv.unknowns())[0])]))
    with pytest.raises(ValueError, match="positive definite"):
        _inverse(A, lower=True, definite=False)


def test_a_diagonal_shift_matches_the_dense_inverse_and_reports_its_pivot():
    """shift(u, delta) adds delta to A[u, u]: the held inverse, a tracked solution of an
    unchanged right-hand side and the pivot 1 + delta (A^-1)_uu follow the dense ones, with
    removals in between; an update that makes the matrix singular is refused and changes
    nothing."""
    A = _matrix(30, True, 7)
    inv = _inverse(A, definite=False, block=4)
    inv.factor(np.arange(30))
    b = np.linspace(-1.0, 2.0, 30)
    inv.tracked["x"] = Tracked(b.copy(), inv.apply(b), lambda ids: np.zeros(ids.size))
    B = A.copy()
    for u, delta in [(3, -2.0), (11, -5.0), (3, 2.0), ("remove", 5), (20, -0.3), (7, -9.0),
                     (11, 1.5)]:
        live = inv.unknowns()
        if u == "remove":
            assert inv.remove(delta)
            continue
        want_pivot = 1.0 + delta * np.linalg.inv(B[np.ix_(live, live)])[live == u][0][live == u]
        col = inv.shift(u, delta)
        B[u, u] += delta
        assert inv.pivot == pytest.approx(float(want_pivot[0]), rel=1e-10)
        Binv = np.linalg.inv(B[np.ix_(live, live)])
        rows = inv.row[live]
        assert np.abs(col[rows] - Binv[:, live == u][:, 0]).max() <= 1e-9 * np.abs(Binv).max()
        _check(inv, B)
        np.testing.assert_allclose(inv.diagonal()[rows], np.diag(Binv), rtol=1e-9,
                                   atol=1e-12 * np.abs(Binv).max())
        x = Binv @ b[live]
        assert np.abs(inv.tracked["x"].x[rows] - x).max() <= 1e-9 * np.abs(x).max()
    live = inv.unknowns()
    rows = inv.row[live]
    before = inv.apply(np.eye(inv.m)[:, rows]).copy()
    c00 = np.linalg.inv(B[np.ix_(live, live)])[0, 0]
    assert inv.shift(int(live[0]), -1.0 / c00) is None  # singular
    assert np.array_equal(inv.apply(np.eye(inv.m)[:, rows]), before)


def test_adding_one_unknown_reports_its_schur_complement_as_the_pivot():
    """add([u]) of an indefinite matrix: the pivot is A_uu - A_uS A_SS^-1 A_Su, whose sign
    says whether a negative eigenvalue came with it."""
    A = _matrix(24, False, 11)
    inv = _inverse(A, definite=False, block=4)
    inv.factor(np.arange(20))
    for u in (20, 21, 22, 23):
        S = inv.unknowns()
        want = A[u, u] - A[u, S] @ np.linalg.solve(A[np.ix_(S, S)], A[S, u])
        neg = int((np.linalg.eigvalsh(A[np.ix_(S, S)]) < 0).sum())
        assert inv.add(np.array([u]))
        assert inv.pivot == pytest.approx(want, rel=1e-9)
        T = inv.unknowns()
        assert int((np.linalg.eigvalsh(A[np.ix_(T, T)]) < 0).sum()) == neg + (want < 0)
