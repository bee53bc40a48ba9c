"""Slip-weakening without dense matrices: the response K = G_xx^-1 of a burst, dense and
compressed (the compressed one against the dense inverse, the pull on it against the pull on
the dense one, the choice between them by memory), and the pull on the compressed inverse of
M (``method="hierarchical"``) against the dense inverse."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.contact.squeeze import squeeze
from roughslip.errors import MemoryLimitError
from roughslip.friction import response, weakening
from roughslip.friction.bonds import Bonds
from roughslip.friction.pull import pull
from roughslip.friction.response import CompressedResponse, DenseResponse, burst_response
from roughslip.linalg.hierarchical import HierarchicalInverse
from roughslip.surfaces.synthetic import sample_rng, self_affine

EPS = float(np.finfo(float).eps)


def _normal(seed: int, depth: float):
    h = self_affine((64, 64), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0))
    return squeeze(h, depth=depth, nu=0.3, tol=1e-13)


@pytest.fixture(scope="module")
def scene():
    """A rough scene whose slip-weakening pull bursts ten times (396 bonds)."""
    return _normal(2, 2.0)


def test_the_compressed_response_is_the_dense_inverse_to_its_tolerance(scene):
    """Each column and product has a residual within tol against the FFT operator, so it is
    within ||K|| tol of the exact one; the dense inverse within cond(G) eps ||K|| of it."""
    b = Bonds(scene, 0.2)
    G = b.dense()
    K = np.linalg.inv(G)
    tol = 1e-12
    c = CompressedResponse(b, tol)
    assert c.inv.ranks().max() > 0  # really compressed
    normK = np.linalg.norm(K, 2)
    err = 10 * (tol + np.linalg.cond(G) * EPS * b.n) * normK
    np.testing.assert_allclose(c.row_sums, K.sum(1), rtol=0, atol=err * np.sqrt(b.n))
    for q in (0, 57, b.n - 1):
        np.testing.assert_allclose(c.column(q), K[:, q], rtol=0, atol=err)
    i, j = np.arange(5, 60, 3), np.array([2, 40, 300])
    np.testing.assert_allclose(c.block(i, j), K[np.ix_(i, j)], rtol=0, atol=err)
    np.testing.assert_allclose(c.diagonal(j), np.diag(K)[j], rtol=0, atol=err)
    v = np.random.default_rng(0).standard_normal(b.n)
    np.testing.assert_allclose(c.times(v), K @ v, rtol=0, atol=err * np.linalg.norm(v))
    assert 0 < c.worst <= tol and c.refinements > 0
    assert np.array_equal(c.times(np.zeros(b.n)), np.zeros(b.n))


def test_a_dropped_column_comes_back_with_the_same_bits(scene):
    b = Bonds(scene, 0.2)
    c = CompressedResponse(b, 1e-10)
    c.capacity = 2
    first = c.column(7).copy()
    c.column(8), c.column(9)  # 7 is dropped
    assert 7 not in c.columns
    assert np.array_equal(c.column(7), first) and c.computed == 4


def test_the_diagonal_outlives_the_columns(scene):
    """A burst's stability tests read one diagonal entry from each of many columns: each is
    computed once, kept beyond the column budget, and is its column's entry, bit for bit."""
    b = Bonds(scene, 0.2)
    c = CompressedResponse(b, 1e-10)
    c.capacity = 2
    q = np.arange(0, b.n, 7)
    d = c.diagonal(q)
    assert c.computed == q.size and len(c.columns) == 2
    assert np.array_equal(c.diagonal(q[::-1]), d[::-1]) and c.computed == q.size
    assert all(c.column(int(k))[k] == d[r] for r, k in enumerate(q[:5]))


@pytest.mark.parametrize(("seed", "depth", "lam_d", "dc"), [(2, 2.0, 0.0, 0.05),
                                                           (3, 2.5, 0.1, 0.01)])
def test_a_pull_on_the_compressed_response_takes_the_same_events(monkeypatch, seed, depth,
                                                                  lam_d, dc):
    """Rough scenes with 10 and 203 bursts: the same events, kinds and sites, in the same
    order, and the same friction force within 1e-10, as on the dense inverse."""
    normal = _normal(seed, depth)
    kw = dict(lam=0.2, slip_law="slip-weakening", lam_dynamic=lam_d, slip_distance=dc,
              threads=1)
    dense = pull(normal, **kw)
    monkeypatch.setattr(weakening, "burst_response",
                        lambda b, tol, threads, compressed: CompressedResponse(b, tol, threads))
    comp = pull(normal, **kw)
    assert dense.curve.kind.count("jump") >= 10
    assert list(comp.curve.kind) == list(dense.curve.kind)
    assert np.array_equal(comp.curve.site, dense.curve.site)
    assert abs(comp.friction_force - dense.friction_force) <= 1e-10 * dense.friction_force
    assert comp.converged and "compressed" in comp.message
    assert "compressed" not in dense.message


def test_the_dense_response_when_it_fits_else_the_compressed_one(scene, monkeypatch):
    b = Bonds(scene, 0.2)
    assert isinstance(burst_response(b, 1e-10), DenseResponse)
    assert isinstance(burst_response(b, 1e-10, compressed=True), CompressedResponse)
    monkeypatch.setattr(response, "CACHE_BYTES", 2**16)
    room = CompressedResponse.memory_bytes(b.n)
    assert room < 2 * response.inverse_bytes(b.n)  # what the dense response takes
    monkeypatch.setattr(response, "available_bytes", lambda: room)
    c = burst_response(b, 1e-10)
    assert isinstance(c, CompressedResponse)
    assert c.room(b.n // 8)
    with pytest.raises(MemoryLimitError, match="a burst moves"):
        c.room(2 * b.n)
    monkeypatch.setattr(response, "available_bytes", lambda: 2**10)
    with pytest.raises(MemoryLimitError, match=f"G_xx\\^-1 on all {b.n} bonds"):
        burst_response(b, 1e-10)


@pytest.mark.parametrize(("seed", "depth", "nu", "lam_d", "dc", "early_stop"), [
    (3, 2.5, 0.3, 0.1, 0.01, True),  # 591 bonds, 203 bursts
    (3, 2.5, 0.45, 0.1, 0.01, False),  # to full sliding: residual bonds join the set
    (2, 2.5, 0.3, 0.2, 0.05, True),  # lam_d = lam_s: the Coulomb law
])
def test_the_pull_on_the_compressed_inverse_takes_the_dense_inverse_events(
        monkeypatch, seed, depth, nu, lam_d, dc, early_stop):
    """method="hierarchical" under slip-weakening: every event, kind and site, in the same
    order as on the dense inverse, and the same friction force within 1e-10. The second scene
    goes on past the peak, where bursts land with residual bonds stuck again, which join the
    set (a compressed set is compressed afresh)."""
    h = self_affine((64, 64) if early_stop else (48, 48), hurst=0.8, rms_height=1.0,
                    rng=sample_rng(seed, 0))
    normal = squeeze(h, depth=depth, nu=nu, tol=1e-13)
    kw = dict(lam=0.2, slip_law="slip-weakening", lam_dynamic=lam_d, slip_distance=dc,
              threads=1, early_stop=early_stop)
    dense = pull(normal, method="inverse", **kw)
    joined = []  # the compressed sets of M factorised after the first (bonds joined them)
    factor = HierarchicalInverse.factor

    def count(self, ids, positive=None):
        if not self.definite and self.factorisations:
            joined.append(ids.size)
        return factor(self, ids, positive)
    monkeypatch.setattr(HierarchicalInverse, "factor", count)
    comp = pull(normal, method="hierarchical", **kw)
    assert list(comp.curve.kind) == list(dense.curve.kind)
    assert np.array_equal(comp.curve.site, dense.curve.site)
    assert abs(comp.friction_force - dense.friction_force) <= 1e-10 * dense.friction_force
    assert comp.converged and "hierarchical inverse every solution" in comp.message
    assert "the bursts read G_xx^-1 compressed" in comp.message or not comp.curve.kind.count(
        "jump")
    if not early_stop:
        assert joined
