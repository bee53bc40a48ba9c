"""The compressed (HODLR) inverse against dense linear algebra: its cluster tree, its cross
approximation, its factorisation, its removals and folds, its error measure and its memory
estimate; and the pull method on it where no other test reaches."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.contact.squeeze import squeeze
from roughslip.errors import InputError, NumericalError
from roughslip.friction.bonds import Bonds
from roughslip.friction.breaking_single import _compression_error
from roughslip.friction.pull import pull
from roughslip.linalg.hierarchical import (
    HierarchicalInverse,
    aca,
    cluster_tree,
    hierarchical_bytes,
    recompress,
)
from roughslip.linalg.inverse import Tracked
from roughslip.surfaces.synthetic import sample_rng, self_affine

EPS = float(np.finfo(float).eps)


def _kernel(points: np.ndarray, shift: float = 1.0):
    """A smooth positive definite kernel (inverse multiquadric) plus ``shift`` on the
    diagonal: well conditioned, with off-diagonal blocks of low numerical rank."""
    def entries(i, j, order="F", dtype=float):
        d2 = ((points[i][:, None, :] - points[j][None, :, :]) ** 2).sum(-1)
        out = 1.0 / np.sqrt(d2 + 4.0) + shift * (np.asarray(i)[:, None] == np.asarray(j)[None])
        return np.asarray(out, order=order, dtype=dtype)
    return entries


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 40, (900, 2))
    entries = _kernel(pts)
    A = entries(np.arange(900), np.arange(900))
    return pts, entries, A


def _held(pts, entries, **kw) -> HierarchicalInverse:
    h = HierarchicalInverse(entries, pts.shape[0], room=lambda m: True, points=pts, **kw)
    h.factor(np.arange(pts.shape[0]))
    return h


def test_cluster_tree_halves_by_the_wider_coordinate():
    pts = np.random.default_rng(1).uniform(0, 1, (300, 2)) * [10.0, 1.0]
    perm, ranges, left, level = cluster_tree(pts, 20)
    assert np.array_equal(np.sort(perm), np.arange(300))
    leaves = [ranges[c] for c in np.flatnonzero(left < 0)]
    assert all(0 < b - a <= 20 for a, b in leaves)
    assert sum(b - a for a, b in leaves) == 300
    inner = np.flatnonzero(left >= 0)
    assert np.array_equal(level[left[inner]], level[inner] + 1)
    a, b = ranges[left[0]]  # the first split is along x, the wider extent
    assert pts[perm[a:b], 0].max() <= pts[perm[b:], 0].min()
    again = cluster_tree(pts, 20)
    assert np.array_equal(again[0], perm)  # deterministic


def test_cross_approximation_reaches_the_svd_rank(scene):
    pts, entries, _ = scene
    I, J = np.flatnonzero(pts[:, 0] < 15), np.flatnonzero(pts[:, 0] > 25)
    B = entries(I, J)
    U, V = aca(lambda i: entries(I[i:i + 1], J)[0], lambda j: entries(I, J[j:j + 1])[:, 0],
               B.shape, 1e-12, 200)
    U, V = recompress(U, V, 1e-10)
    s = np.linalg.svd(B, compute_uv=False)
    tail = np.sqrt(np.cumsum((s * s)[::-1]))[::-1]
    assert U.shape[1] <= int(np.count_nonzero(tail > 1e-10 * tail[0])) + 2
    assert np.linalg.norm(B - U @ V.T) <= 1e-9 * np.linalg.norm(B)


def test_columns_diagonal_and_products_match_the_dense_inverse(scene):
    pts, entries, A = scene
    h = _held(pts, entries, leaf=32, tol=1e-10)
    assert h.ranks().max() > 0  # really compressed
    Ai = np.linalg.inv(A)
    # the compressed matrix is within tol of A, so its inverse within about kappa tol
    bound = 10 * np.linalg.cond(A) * 1e-10 * np.abs(Ai).max()
    for r in (0, 17, 899):
        np.testing.assert_allclose(h.column(r), Ai[:, r], rtol=0, atol=bound)
    np.testing.assert_allclose(h.diagonal(), np.diag(Ai), rtol=0, atol=bound)
    B = np.random.default_rng(2).standard_normal((900, 3))
    np.testing.assert_allclose(h.apply(B), Ai @ B, rtol=0, atol=bound * np.abs(B).sum(0).max())
    # the compressed product inverts the held inverse to rounding
    x = B[:, 0]
    np.testing.assert_allclose(h.apply(h.compressed_product(x)), x, rtol=0,
                               atol=1e3 * EPS * np.abs(x).max() * np.linalg.cond(A))


def test_single_precision_storage_is_the_double_one_rounded(scene, monkeypatch):
    """In float32 the bases, leaves and solves are the double ones rounded: half the memory;
    columns, diagonal, products, removals and folds within the float32 rounding of the
    inverse (about kappa eps32), the compressed product within eps32 of the double one."""
    pts, entries, A = scene
    d = _held(pts, entries, leaf=32, tol=1e-10)
    h = _held(pts, entries, leaf=32, tol=1e-10, dtype=np.float32)
    assert h.V.dtype == np.float32 and h.clusters[0].YL.dtype == np.float32
    assert 0.45 < h.nbytes() / d.nbytes() < 0.55
    eps32 = float(np.finfo(np.float32).eps)
    Ai = np.linalg.inv(A)
    bound = 10 * np.linalg.cond(A) * (1e-10 + eps32) * np.abs(Ai).max()
    for r in (0, 17, 899):
        col = h.column(r)
        assert col.dtype == np.float64
        np.testing.assert_allclose(col, Ai[:, r], rtol=0, atol=bound)
    np.testing.assert_allclose(h.diagonal(), np.diag(Ai), rtol=0, atol=bound)
    B = np.random.default_rng(2).standard_normal((900, 2))
    np.testing.assert_allclose(h.apply(B), Ai @ B, rtol=0, atol=bound * np.abs(B).sum(0).max())
    x = B[:, 0]
    np.testing.assert_allclose(h.compressed_product(x), d.compressed_product(x), rtol=0,
                               atol=10 * eps32 * np.abs(A).sum(1).max() * np.abs(x).max())
    # widened a few rows at a time: the same product, for one vector and for several
    from roughslip.linalg import hierarchical
    whole = h.compressed_product(B)
    monkeypatch.setattr(hierarchical, "ROWS", 7)
    np.testing.assert_allclose(h.compressed_product(B), whole, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(h.compressed_product(x), whole[:, 0], rtol=1e-13, atol=1e-13)
    order = np.random.default_rng(3).permutation(900)[:80]
    for u in order:
        assert h.remove(int(u))
        if h.k == 16:
            h.flush()
    keep = np.setdiff1d(np.arange(900), order)
    Ak = np.linalg.inv(A[np.ix_(keep, keep)])
    live = np.flatnonzero(h.live)
    np.testing.assert_allclose(h.column(int(live[5]))[live], Ak[:, 5], rtol=0, atol=bound)
    # a leaf emptied by removals keeps every solve above it in float32
    leaf = next(c for c in h.clusters if c.left < 0 and c.stop > c.start)
    for p in range(leaf.start, leaf.stop):
        r = int(h.perm[p])
        if h.live[r]:
            assert h.remove(int(h.ids[r]))
    h.flush()
    assert leaf.stop == leaf.start
    for c in h.clusters:
        for a in (c.U, c.V, c.YL, c.YR, c.T, c.dense, c.inverse):
            assert a is None or a.dtype == np.float32
    single = HierarchicalInverse.memory_bytes(10_000, itemsize=4)
    assert 0.5 < single / HierarchicalInverse.memory_bytes(10_000, itemsize=8) < 0.6


def test_removals_folds_and_compaction_follow_the_dense_inverse(scene):
    pts, entries, A = scene
    h = _held(pts, entries, leaf=32, tol=1e-10, block=16)
    h.tracked["phi"] = Tracked(np.ones(900), h.apply(np.ones(900)), lambda ids: np.ones(ids.size))
    order = np.random.default_rng(3).permutation(900)[:120]
    for step, u in enumerate(order):
        assert h.remove(int(u))
        if h.k == h.block:
            h.flush()
        if step == 70:
            h.compact()
            assert h.live.all() and h.m == 900 - 71
    keep = np.setdiff1d(np.arange(900), order)
    Ai = np.linalg.inv(A[np.ix_(keep, keep)])
    live = np.flatnonzero(h.live)
    assert np.array_equal(h.ids[live], keep)  # the rows keep the unknowns' order
    bound = 10 * np.linalg.cond(A) * 1e-10 * np.abs(Ai).max()
    np.testing.assert_allclose(h.tracked["phi"].x[live], Ai.sum(1), rtol=0,
                               atol=bound * 900)
    np.testing.assert_allclose(h.column(int(live[5]))[live], Ai[:, 5], rtol=0, atol=bound)
    np.testing.assert_allclose(h.diagonal()[live], np.diag(Ai), rtol=0, atol=bound)


def test_solves_in_place_leave_inputs_and_bases_untouched(scene):
    """The solves overwrite a copy only: the right-hand side given to :meth:`apply` and the
    bases the solves start from are unchanged, so after a fold the compressed matrix (read
    from the bases) is still what the held inverse inverts."""
    pts, entries, A = scene
    h = _held(pts, entries, leaf=32, tol=1e-10, block=16)
    inner = [c for c in h.clusters if c.U is not None and c.U.shape[1]]
    assert all(not np.shares_memory(c.U, c.YL) and not np.shares_memory(c.V, c.YR)
               for c in inner)
    B = np.random.default_rng(4).standard_normal((900, 2))
    for rhs in (B, B[:, 0], np.asfortranarray(B)):
        before = rhs.copy()
        h.apply(rhs)
        assert np.array_equal(rhs, before)
    for u in np.random.default_rng(5).permutation(900)[:16]:
        assert h.remove(int(u))
    h.flush()
    x = np.where(h.live, B[:, 1], 0.0)
    np.testing.assert_allclose(h.apply(h.compressed_product(x)), x, rtol=0,
                               atol=1e3 * EPS * np.abs(x).max() * np.linalg.cond(A))


def test_what_it_does_not_hold_is_refused(scene):
    pts, entries, _ = scene
    with pytest.raises(ValueError, match="double or single precision"):
        HierarchicalInverse(entries, 900, room=lambda m: True, points=pts, dtype=np.float16)
    h = _held(pts, entries)
    for call in (lambda: h.shift(0, 1.0), lambda: h.compact(extra=3),
                 lambda: h.factor(np.arange(900), positive=False)):
        with pytest.raises(ValueError):
            call()
    assert not HierarchicalInverse(entries, 900, room=lambda m: False,
                                   points=pts).factor(np.arange(900))


def _shifted(pts: np.ndarray, dshift: np.ndarray):
    """The kernel of :func:`_kernel` with the diagonal shifts ``dshift`` (read when called)."""
    base = _kernel(pts)

    def entries(i, j, order="F", dtype=float):
        A = base(i, j, order, np.float64)
        A += dshift[np.asarray(i)][:, None] * (np.asarray(i)[:, None] == np.asarray(j)[None])
        return np.asarray(A, order=order, dtype=dtype)
    return entries


def test_indefinite_shifts_removals_and_additions_follow_the_dense_inverse(scene):
    """Diagonal shifts that make the matrix indefinite, removals, an addition, folds and a
    compaction: the tracked solution, a column and the diagonal follow the dense inverse of
    the matrix on the final set, and the count of negative eigenvalues follows its spectrum,
    both from the pivots and from the factorisation."""
    pts = scene[0]
    n = pts.shape[0]
    dshift = np.zeros(n)
    entries = _shifted(pts, dshift)
    h = HierarchicalInverse(entries, n, room=lambda m: True, points=pts, definite=False,
                            leaf=32, tol=1e-10, block=16)
    assert h.factor(np.arange(n), positive=True) and h.negatives == 0
    h.tracked["phi"] = Tracked(np.ones(n), h.apply(np.ones(n)), lambda ids: np.ones(ids.size))
    rng = np.random.default_rng(6)
    order = rng.permutation(n)
    weak, gone = order[:60], order[60:110]
    steps = [("shift", int(u), -3.0) for u in weak[:40]] + [("remove", int(u), 0.0)
                                                            for u in gone]
    steps += [("shift", int(u), -3.0) for u in weak[40:]] + [("shift", int(weak[3]), 3.0)]
    steps += [("remove", int(weak[7]), 0.0), ("add", int(gone[0]), 0.0),
              ("add", int(weak[7]), 0.0)]
    out = set()
    for step, (what, u, delta) in enumerate(steps):
        if what == "shift":
            assert h.shift(u, delta) is not None
            dshift[u] += delta
        elif what == "remove":
            assert h.remove(u)
            out.add(u)
        else:
            assert h.add(np.array([u])) is True
            out.discard(u)
        if step % 16 == 15:  # a fold with shifts and removals pending
            h.flush()
        if step == 70:
            h.compact()
        keep = np.setdiff1d(np.arange(n), sorted(out))
        if step % 25 == 0 or step == len(steps) - 1:
            w = np.linalg.eigvalsh(entries(keep, keep))
            assert np.abs(w).min() > 1e-3  # no eigenvalue near zero: the count is robust
            assert h.negatives == np.count_nonzero(w < 0)
    assert h.negatives > 0 and h.shifts == len(weak) + 1 and h.factorisations >= 9
    A = entries(keep, keep)
    Ai = np.linalg.inv(A)
    live = np.flatnonzero(h.live)
    assert np.array_equal(np.sort(h.ids[live]), keep)
    at = np.argsort(h.ids[live])  # the rows in the order of keep
    bound = 10 * np.linalg.cond(A) * 1e-10 * np.abs(Ai).max()
    np.testing.assert_allclose(h.tracked["phi"].x[live][at], Ai.sum(1), rtol=0,
                               atol=bound * n)
    r = int(live[at[5]])
    np.testing.assert_allclose(h.column(r)[live][at], Ai[:, 5], rtol=0, atol=bound)
    np.testing.assert_allclose(h.diagonal()[live][at], np.diag(Ai), rtol=0, atol=bound)
    h.flush()
    h.factor(keep)  # the inertia from the factorisation alone
    assert h.negatives == np.count_nonzero(np.linalg.eigvalsh(A) < 0)
    with pytest.raises(NumericalError, match="not positive definite"):
        h.factor(keep, positive=True)


@pytest.fixture(scope="module")
def rough():
    normal = squeeze(self_affine((96, 96), hurst=0.8, rms_height=1.0, rng=sample_rng(4, 0)),
                     depth=2.4, nu=0.3, tol=1e-13)
    b = Bonds(normal, 0.2)
    iy, ix = np.divmod(b.sites, b.shape[1])
    h = HierarchicalInverse(b.entries, b.n, room=lambda m: True,
                            points=np.column_stack([iy, ix]).astype(float))
    h.factor(np.arange(b.n))
    return normal, b, h


def test_error_measure_bounds_the_compression_on_the_bond_matrix(rough):
    """The measured delta (Lanczos on G - A~ by the FFT operator) bounds the dense norm of
    the difference, and bounds each column's residual: ||e_k - G c~|| <= delta ||c~||."""
    _, b, h = rough
    assert b.n > 500  # the Lanczos path
    G = b.dense()
    E = G - h.compressed_product(np.eye(b.n))
    delta = _compression_error(b, h)
    assert np.linalg.norm(E, 2) <= delta <= 2 * np.linalg.norm(E, 2) + 1e-12 * np.abs(G).max()
    for r in range(0, b.n, 97):
        c = h.column(r)
        rho = -G @ c
        rho[r] += 1.0
        assert np.linalg.norm(rho) <= delta * np.linalg.norm(c)
    # with removals pending, a column of the current inverse on the set before its row leaves
    gone = np.random.default_rng(5).permutation(b.n)[:30]
    for u in gone:
        assert h.remove(int(u))
    assert h.k == 30
    live = np.flatnonzero(h.live)
    for r in live[::151]:
        c = h.column(int(r))[live]
        rho = -G[np.ix_(live, live)] @ c
        rho[np.searchsorted(live, r)] += 1.0
        assert np.linalg.norm(rho) <= delta * np.linalg.norm(c)


def test_a_removal_that_fills_the_buffer_is_folded_once(scene):
    pts, entries, A = scene
    h = _held(pts, entries, leaf=32, tol=1e-10, block=4)
    h.capacity = 4
    h.V = np.zeros((h.m, 4), order="F")
    gone = [3, 100, 250, 400, 777, 5]
    for u in gone:  # no caller folds: the buffer does
        assert h.remove(u)
    keep = np.setdiff1d(np.arange(900), gone)
    Ai = np.linalg.inv(A[np.ix_(keep, keep)])
    live = np.flatnonzero(h.live)
    bound = 10 * np.linalg.cond(A) * 1e-10 * np.abs(Ai).max()
    np.testing.assert_allclose(h.column(int(live[9]))[live], Ai[:, 9], rtol=0, atol=bound)


def test_memory_estimate_covers_what_is_held(rough):
    _, b, h = rough
    assert h.nbytes() <= hierarchical_bytes(b.n, block=h.block)
    assert HierarchicalInverse.memory_bytes(b.n, block=h.block) == hierarchical_bytes(
        b.n, block=h.block)


def test_what_the_compressed_inverse_does_not_certify_is_refused(rough):
    """Slip-weakening refines its decisions on the compressed inverse in double precision,
    not in single; the Coulomb law certifies its decisions in the x-only model only."""
    normal, _, _ = rough
    with pytest.raises(InputError, match="precision = 'single'"):
        pull(normal, slip_law="slip-weakening", method="hierarchical", lam_dynamic=0.1,
             slip_distance=0.05, precision="single")
    with pytest.raises(InputError, match="x-only model"):
        pull(normal, slip_law="coulomb", method="hierarchical", components="xy")


def test_a_definite_set_grows_and_a_full_buffer_folds_a_shift(scene):
    """Adding to a positive definite set borders its solution and compresses it afresh
    (a Schur complement that is not positive is refused); a shift that meets a full buffer
    is folded into the leaf at once."""
    pts, entries, A = scene
    h = _held(pts, entries, leaf=32, tol=1e-10)
    h.tracked["phi"] = Tracked(np.ones(900), h.apply(np.ones(900)), lambda ids: np.ones(ids.size))
    assert h.remove(4) and h.remove(600)
    assert h.add(np.array([600])) is True and h.pivot > 0
    keep = np.setdiff1d(np.arange(900), [4])
    live = np.flatnonzero(h.live)
    at = np.argsort(h.ids[live])
    Ai = np.linalg.inv(A[np.ix_(keep, keep)])
    bound = 10 * np.linalg.cond(A) * 1e-10 * np.abs(Ai).max()
    np.testing.assert_allclose(h.tracked["phi"].x[live][at], Ai.sum(1), rtol=0,
                               atol=bound * 900)

    dshift = np.zeros(900)
    g = HierarchicalInverse(_shifted(pts, dshift), 900, room=lambda m: True, points=pts,
                            definite=False, leaf=32, tol=1e-10, capacity=2, block=2)
    g.factor(np.arange(900))
    done = g.factorisations
    for u in (3, 5, 7):  # the third meets a full buffer
        assert g.shift(u, -3.0) is not None
        dshift[u] -= 3.0
    assert g.factorisations == done + 1 and g.k == 0 and g.negatives == 3
    Bi = np.linalg.inv(_shifted(pts, dshift)(np.arange(900), np.arange(900)))
    np.testing.assert_allclose(g.column(5), Bi[:, 5], rtol=0,
                               atol=10 * np.linalg.cond(Bi) * 1e-10 * np.abs(Bi).max())
