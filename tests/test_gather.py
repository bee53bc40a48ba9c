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
