"""The gathers of dense blocks from the kernels' pair tables: the compiled kernel against its
numpy twin (the same entries bit for bit), and the blocks against the closed-form dense
matrices."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.contact.problem import Problem
from roughslip.coupling.blocksolvers import DenseBlockSolver
from roughslip.elastic.operators import Grid, Material
from roughslip.elastic.tables import gather_pairs
from roughslip.linalg import jit


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba is not installed")
@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_compiled_gather_copies_the_same_entries_as_numpy(order, dtype):
    rng = np.random.default_rng(11)
    T = rng.standard_normal(500).astype(dtype)
    off = 250
    li, lj = rng.integers(-120, 120, 37), rng.integers(-120, 120, 23)
    rows, cols = rng.permutation(50)[:37], rng.permutation(30)[:23]
    blocks = []
    for compiled in (True, False):
        out = np.full((50, 30), -7.0, order=order, dtype=dtype)  # unwritten entries stay
        gather_pairs(T, li, lj, off, out, rows, cols, compiled=compiled)
        blocks.append(out)
    a, b = blocks
    assert a.tobytes(order="A") == b.tobytes(order="A")
    assert np.array_equal(a[np.ix_(rows, cols)], T[li[:, None] - lj[None, :] + off])
    assert np.count_nonzero(a == -7.0) == 50 * 30 - 37 * 23


@pytest.mark.parametrize("compiled", [True, False])
def test_coupled_block_is_the_closed_form_dense_block(compiled, monkeypatch):
    """The coupled solver's entries, z and x unknowns mixed in any order, are those of the
    dense matrices of the closed-form pixel kernels (G_xz(i - j) = G_zx(j - i) included)."""
    if compiled and not jit.HAVE_NUMBA:
        pytest.skip("numba is not installed")
    monkeypatch.setattr(jit, "ENABLED", compiled)
    rng = np.random.default_rng(5)
    shape = (7, 9)
    problem = Problem(np.zeros(shape), Grid(shape, 0.5), Material(2.0, 0.2))
    d = problem.operator("zz", "zx", "xx").tables.dense
    n = shape[0] * shape[1]
    full = np.block([[d("zz"), d("zx")], [d("xz"), d("xx")]])  # unknowns: z sites, x sites
    ids_i = rng.permutation(2 * n)[:40]
    ids_j = rng.permutation(2 * n)[:25]
    where = lambda ids: np.where(ids & 1, n + (ids >> 1), ids >> 1)  # noqa: E731
    s = DenseBlockSolver(problem)
    for order in ("C", "F"):
        A = s.entries(ids_i, ids_j, order)
        np.testing.assert_allclose(A, full[np.ix_(where(ids_i), where(ids_j))], rtol=1e-12,
                                   atol=1e-14 * np.abs(full).max())


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba is not installed")
def test_compiled_event_table_equals_numpy():
    """The event table's compiled scan against numpy: the same interval, kind and site on
    random rows with flat entries, ties within the tolerance, zeros of both signs and violated
    flat rows."""
    from roughslip.friction.events import TIE, event_table
    rng = np.random.default_rng(3)
    for trial in range(300):
        n = int(rng.integers(1, 60))
        cons = []
        for kind in ("lost", "gained", "slip"):
            m = rng.random(n) < 0.7
            a = rng.choice([0.0, -0.0, 1.0, 2.0, 1e-12, -1e-12]) + rng.random(n) * (trial % 3)
            b = rng.standard_normal(n)
            b[rng.random(n) < 0.2] = 0.0
            b[rng.random(n) < 0.1] = -1e-14  # flat at this scale
            if trial % 5 == 0:  # ties: equal roots at several entries
                a[::3], b[::3] = 1.0, -2.0
                a[1::3] *= 1 + TIE / 10
            if trial % 7 == 0:
                a[rng.integers(n)] = -1.0  # a violated entry (flat where b is)
            cons.append((kind, m, a, b, float(rng.choice([1.0, 1e-3]))))
        D, Dref, Dscale = 0.0, float(rng.choice([1.0, 0.1])), float(rng.choice([1.0, 1e-6]))
        got = event_table(cons, D, Dref, Dscale, compiled=True)
        want = event_table(cons, D, Dref, Dscale, compiled=False)
        assert got[2:] == want[2:] and np.array(got[:2]).tobytes() == np.array(want[:2]).tobytes()


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba is not installed")
@pytest.mark.parametrize("in_place", [True, False])
def test_compiled_compaction_equals_numpy(in_place, monkeypatch):
    """The compactions of an updated inverse, compiled and numpy, in place (the source columns
    overwritten as the sweep goes) and into a larger buffer: the same matrices bit for bit,
    the kept rows and columns of the source."""
    from roughslip.linalg import inverse

    rng = np.random.default_rng(8)
    m, cap = 57, 64
    keep = np.flatnonzero(rng.random(m) < 0.6)
    k = keep.size
    A = np.asfortranarray(rng.standard_normal((cap, cap)))
    want = A[:m, :m][np.ix_(keep, keep)]
    out = []
    for compiled in (True, False):
        monkeypatch.setattr(jit, "ENABLED", compiled)
        src = A.copy(order="F")
        dst = src if in_place else np.zeros((cap + 8, cap + 8), order="F")
        inverse._compact_full(src, dst, keep)
        assert np.array_equal(dst[:k, :k], want)
        flat = A[:m, :m].copy(order="F").reshape(-1, order="F")
        low = inverse._compact_lower(flat, m, keep)
        assert np.array_equal(np.tril(low), np.tril(want))
        out.append((dst[:k, :k].copy(), np.tril(low)))
    assert out[0][0].tobytes() == out[1][0].tobytes()
    assert out[0][1].tobytes() == out[1][1].tobytes()


def test_compiled_submatrix_equals_numpy(monkeypatch):
    """The gather of a submatrix (rows and columns in any order, repeated, from a Fortran
    block with more columns than it gathers), compiled and numpy: the same entries."""
    from roughslip.linalg import inverse

    rng = np.random.default_rng(9)
    A = np.asfortranarray(rng.standard_normal((41, 30)))
    rows, cols = rng.integers(0, 41, 17), rng.permutation(30)[:12]
    got = []
    for compiled in (True, False):
        monkeypatch.setattr(jit, "ENABLED", compiled)
        got.append(inverse.submatrix(A, rows, cols))
        assert np.array_equal(got[-1], A[np.ix_(rows, cols)])
    assert got[0].tobytes() == got[1].tobytes()


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba is not installed")
def test_compiled_break_candidates_equal_numpy():
    """The single-precision pull's candidate scan, compiled and numpy: the same leading row,
    ratio, bound and candidates on random rows with exact ties, ties within TIE, dead rows
    (infinite cap), zero forces and bounds wide enough to admit every row."""
    from roughslip.friction.breaking_single import _candidates
    from roughslip.friction.events import TIE
    rng = np.random.default_rng(11)
    seen_many = seen_tie = 0
    for trial in range(400):
        n = int(rng.integers(1, 80))
        phi = rng.standard_normal(n) * rng.choice([1.0, 1e-3])
        cap = rng.random(n) + 0.1
        cap[rng.random(n) < 0.2] = np.inf  # dead rows
        phi[rng.random(n) < 0.1] = 0.0
        if trial % 4 == 0 and n > 3:  # exact ties and ties inside the band
            lead = int(np.argmax(np.abs(phi) / cap))
            for k in rng.choice(n, 3, replace=False):
                if np.isfinite(cap[k]):
                    phi[k] = abs(phi[lead]) * cap[k] / cap[lead] * (1 + rng.choice(
                        [0.0, TIE / 3, -TIE / 3, 3 * TIE]))
        d = rng.random(n) * 2
        nu = float(rng.random() + 0.5)
        Rb = float(rng.choice([0.0, 1e-12, 1e-6, 1e-2, 10.0]))
        spread = float(np.sqrt(nu * d.max()) * Rb / cap[np.isfinite(cap)].min()
                       if np.isfinite(cap).any() else 0.0)
        got = _candidates(phi, cap, d, nu, Rb, spread, compiled=True)
        want = _candidates(phi, cap, d, nu, Rb, spread, compiled=False)
        if want is None:
            assert got is None
            continue
        assert got[0] == want[0]
        assert np.array([got[1], got[2]]).tobytes() == np.array([want[1], want[2]]).tobytes()
        assert np.array_equal(got[3], want[3]) and got[3].dtype == np.int64
        seen_many += want[3].size > 1
        seen_tie += int(np.sum(np.abs(np.abs(phi) / cap - want[1]) <= TIE * want[1])) > 1
    # the cases that matter were exercised: several candidates in at least a quarter of the
    # 400 trials, and a tie kept in at least a quarter of the 100 trials that build ties
    assert seen_many >= 400 // 4 and seen_tie >= 100 // 4
    # a non-finite ratio (an infinite or NaN force) is refused by both
    for v in (np.inf, np.nan):
        for compiled in (True, False):
            assert _candidates(np.array([1.0, v, 1.0]), np.ones(3), np.ones(3), 1.0, 0.0, 0.0,
                               compiled=compiled) is None
