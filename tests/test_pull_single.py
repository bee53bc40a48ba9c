"""The single-precision inverse of the pull: the float32 kernels against float64 references,
and the certified break sequence against the double-precision path on many scenes."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from roughslip.contact.squeeze import squeeze
from roughslip.errors import InputError, MemoryLimitError
from roughslip.friction.bonds import Bonds
from roughslip.friction.pull import (
    HIERARCHICAL_ABOVE,
    choose_method,
    choose_precision,
    inverse_memory_bytes,
    pull,
)
from roughslip.friction.response import CompressedResponse
from roughslip.linalg import lapack64, memory
from roughslip.linalg.hierarchical import HierarchicalInverse
from roughslip.linalg.inverse import LOWER_RESERVE, UpdatableInverse, inverse_bytes
from roughslip.surfaces.synthetic import sample_rng, self_affine, sphere

EPS32 = float(np.finfo(np.float32).eps)


def _spd(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n, n))
    return a @ a.T / n + np.eye(n)


def _full(lower: np.ndarray) -> np.ndarray:
    low = np.tril(lower).astype(float)
    return low + np.tril(low, -1).T


@pytest.mark.parametrize("sweep", [False, True])
def test_float32_inverse_kernels_match_float64(sweep):
    A = _spd(200)
    ref = np.linalg.inv(A)
    B = np.asfortranarray(A.astype(np.float32))
    (lapack64.sweep_inverse(B, block=48) if sweep else lapack64.cholesky_inverse(B))
    assert B.dtype == np.float32
    err = np.abs(_full(B) - ref).max() / np.abs(ref).max()
    assert err < 50 * EPS32 * np.linalg.cond(A)
    assert err > 1e-12  # it really is single precision
    x = np.random.default_rng(1).standard_normal(200)
    y = lapack64.symv(B, x)
    assert y.dtype == np.float64
    np.testing.assert_allclose(y, _full(B) @ x, rtol=0, atol=1e-4 * np.abs(y).max())
    U = np.random.default_rng(2).standard_normal((200, 7))
    C = np.asfortranarray(A.astype(np.float32))
    lapack64.syrk_update(C, U, -1.0)
    np.testing.assert_allclose(np.tril(C), np.tril(A - U @ U.T), atol=1e-5 * np.abs(A).max())


def test_float32_storage_only_in_the_lower_layout():
    with pytest.raises(ValueError, match="float32"):
        UpdatableInverse(lambda i, j, o: None, 4, room=lambda m: True, dtype=np.float32)
    with pytest.raises(ValueError, match="float64 or float32"):
        lapack64.symv(np.asfortranarray(np.eye(3, dtype=np.float16)), np.ones(3))


def test_float32_inverse_tracks_removals_to_single_precision():
    """Removals on a float32 inverse: columns within a few single-precision units (relative to
    the condition number) of the inverse of the remaining block, computed in float64."""
    A = _spd(150, seed=3)

    def entries(i, j, order="F", dtype=float):
        return np.array(A[np.ix_(i, j)], order=order, dtype=dtype)

    inv = UpdatableInverse(entries, 150, room=lambda m: True, lower=True, block=8,
                           dtype=np.float32)
    inv.factor(np.arange(150))
    assert inv.buf.dtype == np.float32
    keep = np.ones(150, bool)
    for r in np.random.default_rng(4).permutation(150)[:40]:
        assert inv.remove(int(r))
        keep[r] = False
        if inv.k == inv.block:
            inv.flush()
    ref = np.linalg.inv(A[np.ix_(keep, keep)])
    rows = np.flatnonzero(inv.live)
    col = inv.column(int(rows[5]))[rows]
    assert col.dtype == np.float64
    bound = 100 * EPS32 * np.linalg.cond(A) * np.abs(ref[:, 5]).max()
    np.testing.assert_allclose(col, ref[:, 5], rtol=0, atol=bound)


def test_bond_matrix_in_float32_is_the_double_matrix_rounded():
    normal = squeeze(self_affine((24, 24), hurst=0.8, rms_height=1.0, rng=sample_rng(5, 0)),
                     depth=1.0, tol=1e-12)
    b = Bonds(normal, 0.2)
    G = b.dense()
    assert np.array_equal(b.dense(dtype=np.float32), G.astype(np.float32))
    assert np.array_equal(b.dense(order="C"), G)
    i, j = np.arange(0, b.n, 3), np.arange(1, b.n, 4)
    assert np.array_equal(b.entries(i, j, "C", np.float32), G[np.ix_(i, j)].astype(np.float32))


def test_per_row_bound_holds_against_the_dense_inverse():
    """The diagonal taken at a fold bounds the exact diagonal of the stick set's inverse
    after further removals, and sqrt(nu d_i) ||r|| bounds each row's error of the tracked
    solution (against a dense float64 solve)."""
    from roughslip.friction.bonds import BondRows, bond_inverse, track
    from roughslip.friction.breaking_single import _Bound

    normal = squeeze(self_affine((40, 40), hurst=0.8, rms_height=1.0, rng=sample_rng(9, 0)),
                     depth=2.0, tol=1e-13)
    b = Bonds(normal, 0.2)
    G = b.dense()
    inv = bond_inverse(b, 16, 1, dtype=np.float32)
    track(inv, "phi", np.ones(b.n))
    rows = BondRows(b)
    bound = _Bound(b, inv, 1e-10)
    bound.certify(rows.cap)
    checked = 0
    for _ in range(b.n // 2):
        phi = inv.tracked["phi"].x
        j = int(np.argmax(np.abs(phi) / rows.cap))
        c = inv.column(j)
        bound.removed(phi[j] / c[j], c)
        rows.remove(inv, j, c)
        live = inv.live
        pos = inv.ids[live]
        M = np.linalg.inv(G[np.ix_(pos, pos)])
        assert np.all(bound.d[live] >= np.diag(M))
        err = np.abs(inv.tracked["phi"].x[live] - M.sum(axis=1))
        assert np.all(err <= bound.beta(np.flatnonzero(live)))
        assert np.all(bound.beta(np.flatnonzero(live)) <= bound.nu * bound.residual_bound())
        checked += 1
        if rows.fold(inv, dead=0.15):
            bound.certify(rows.cap)
    assert checked >= 40


def test_lanczos_estimate_of_nu_against_the_dense_eigenvalue():
    """The Lanczos estimate of the largest eigenvalue of the stored inverse (the bound's
    nu before its safety factor) lies just below the largest eigenvalue of the exact
    inverse, 1 / lambda_min(G_SS), well within NU_SAFETY."""
    from roughslip.friction.bonds import bond_inverse
    from roughslip.friction.breaking_single import NU_SAFETY, _largest_eigenvalue

    normal = squeeze(self_affine((64, 64), hurst=0.8, rms_height=1.0, rng=sample_rng(4, 0)),
                     depth=4.5, tol=1e-13)
    b = Bonds(normal, 0.2)
    assert b.n > 500  # the Lanczos path, not the dense one
    inv = bond_inverse(b, 16, 1, dtype=np.float32)
    est = _largest_eigenvalue(inv, b.sites[inv.ids[: inv.m]], b.shape[1])
    w = np.linalg.eigvalsh(b.dense())
    true, kappa = 1.0 / w[0], w[-1] / w[0]
    # below: ARPACK's tolerance (1e-2) on the Ritz value; above: a Ritz value never exceeds
    # the eigenvalue of the stored matrix, which carries the float32 inverse's relative error,
    # at most a few kappa eps_32
    eps32 = float(np.finfo(np.float32).eps)
    assert true / NU_SAFETY < (1 - 1e-2) * true <= est <= (1 + 4 * kappa * eps32) * true


def _scenes():
    """22 scenes: rough (open and periodic, several seeds, depths, sizes and nu), symmetric
    spheres (exact ties, broken by the lowest flat index) and spheres with their symmetry
    broken at 1e-7 (near-ties inside the single-precision error)."""
    out = []
    for k, (n, depth, nu, boundary) in enumerate([
            (48, 2.2, 0.3, "open"), (48, 2.8, 0.3, "open"), (64, 2.0, 0.25, "open"),
            (64, 2.6, 0.45, "open"), (80, 2.2, 0.3, "open"), (96, 2.0, 0.3, "open"),
            (48, 2.0, 0.3, "periodic"), (64, 2.4, 0.3, "periodic"),
            (80, 2.0, 0.2, "periodic"), (64, 1.4, 0.3, "open"), (96, 2.6, 0.3, "open"),
            (96, 2.0, 0.35, "periodic")]):
        h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(100 + k, 0))
        out.append((f"rough{k}-{boundary}", h, depth, nu, boundary))
    for n, radius, depth in [(16, 12.0, 1.0), (24, 20.0, 1.5), (32, 30.0, 2.0), (20, 8.0, 1.2),
                             (28, 25.0, 1.0)]:
        out.append((f"sphere{n}", sphere((n, n), radius=radius), depth, 0.3, "open"))
    rng = np.random.default_rng(7)
    for n, radius, depth in [(16, 12.0, 1.0), (24, 20.0, 1.5), (32, 30.0, 2.0), (20, 8.0, 1.2),
                             (28, 25.0, 1.0)]:
        h = sphere((n, n), radius=radius) + 1e-7 * rng.standard_normal((n, n))
        out.append((f"near-tie{n}", h, depth, 0.3, "open"))
    return out


SCENES = _scenes()


@pytest.fixture(scope="module")
def pairs():
    out = {}
    for name, h, depth, nu, boundary in SCENES:
        normal = squeeze(h, depth=depth, nu=nu, boundary=boundary, tol=1e-13)
        out[name] = (*(pull(normal, method="inverse", precision=p, tol=1e-10)
                       for p in ("double", "single")),
                     *(pull(normal, method="hierarchical", precision=p, tol=1e-10)
                       for p in ("double", "single")))
    return out


def test_at_least_twenty_scenes_with_ties_and_near_ties(pairs):
    assert len(pairs) >= 20
    assert min(d.details.n_bonds for d, *_ in pairs.values()) >= 20


@pytest.mark.parametrize(("inexact", "method", "precision"),
                         [(1, "inverse", "single"), (2, "hierarchical", "double"),
                          (3, "hierarchical", "single")])
@pytest.mark.parametrize("name", [s[0] for s in SCENES])
def test_an_inexact_inverse_gives_the_double_break_sequence(pairs, name, inexact, method,
                                                            precision):
    """The float32 inverse and the compressed one in double and in single precision, each
    with certified decisions: the double-precision method's bonds in its order, its peak and
    its friction force."""
    d, s = pairs[name][0], pairs[name][inexact]
    assert (d.details.precision, s.details.precision) == ("double", precision)
    assert s.method == method
    np.testing.assert_array_equal(s.curve.site[1:], d.curve.site[1:])
    assert s.peak_event == d.peak_event
    assert abs(s.friction_force - d.friction_force) <= 1e-10 * abs(d.friction_force)
    np.testing.assert_array_equal(s.peak.stick, d.peak.stick)
    np.testing.assert_allclose(s.peak.fx, d.peak.fx, rtol=0,
                               atol=1e-9 * np.abs(d.peak.fx).max())
    # the other points of the curve carry the single-precision error, inside their bound
    bound = float(s.message.split("curve points within ")[1].split(" ")[0])
    assert np.all(np.abs(s.curve.fx - d.curve.fx) <= bound * np.abs(d.curve.fx) + 1e-300)
    assert s.converged and d.converged
    assert "bound exceeded 0 times" in s.message


def test_near_ties_are_sharpened(pairs):
    """The broken symmetry leaves gaps below the single-precision error: those decisions
    were sharpened, and still came out as in double precision (previous test)."""
    sharpened = [int(s.message.split(" of ")[0].split()[-1])
                 for name, (_, s, *_) in pairs.items() if name.startswith("near-tie")]
    assert sum(sharpened) > 0


def test_auto_chooses_double_when_it_fits_and_single_when_only_that_fits():
    n = HIERARCHICAL_ABOVE - 1  # below the crossover: the dense inverse while it fits
    double, single = inverse_memory_bytes(n), inverse_memory_bytes(n, precision="single")
    assert single < 0.6 * double
    assert choose_precision(n, memory=double) == "double"
    assert choose_precision(n, memory=(single + double) // 2) == "single"
    sw = {"slip_law": "slip-weakening"}
    assert choose_precision(n, memory=(single + double) // 2, **sw) == "double"
    assert choose_method(n, memory=double) == "inverse"
    assert choose_method(n, memory=(single + double) // 2) == "inverse"
    assert choose_method(n, memory=double, precision="single") == "inverse"
    # no dense inverse fits: the compressed one while its estimate fits, then matrix-free
    compressed = HierarchicalInverse.memory_bytes(n)
    assert compressed < single
    assert choose_method(n, memory=(single + double) // 2, precision="double") == "hierarchical"
    assert choose_method(n, memory=compressed) == "hierarchical"
    # and in single precision when only that estimate fits
    half = HierarchicalInverse.memory_bytes(n, itemsize=4)
    assert half < compressed
    between = (half + compressed) // 2
    assert choose_method(n, memory=between) == "hierarchical"
    assert choose_precision(n, memory=between, method="hierarchical") == "single"
    assert choose_precision(n, memory=compressed, method="hierarchical") == "double"
    assert choose_method(n, memory=between, precision="double") == "cg"
    # slip-weakening: the dense inverse with spare rows and its bursts' two, else compressed
    sw_dense = 3 * inverse_bytes(n, block=128)
    sw_compressed = compressed + CompressedResponse.memory_bytes(n)
    assert sw_compressed < sw_dense
    assert choose_method(n, memory=sw_dense, **sw) == "inverse"
    assert choose_method(n, memory=sw_dense - 1, **sw) == "hierarchical"
    assert choose_method(n, memory=sw_compressed, **sw) == "hierarchical"
    assert choose_precision(n, memory=sw_compressed, method="hierarchical", **sw) == "double"
    assert choose_method(n, memory=half // 2) == "cg"
    assert choose_method(5, precision="single") == "inverse"  # not the literal algorithm


def test_auto_takes_the_compressed_inverse_above_the_crossover():
    """From the measured crossover on, the compressed inverse is faster than the dense one:
    auto takes it whenever its estimate fits, in double precision when that fits, and keeps
    the dense inverse for the laws it does not run."""
    n = HIERARCHICAL_ABOVE
    roomy = 2 * inverse_memory_bytes(n)
    assert choose_method(n, memory=roomy) == "hierarchical"
    assert choose_precision(n, memory=roomy, method="hierarchical") == "double"
    assert choose_method(n, memory=roomy, precision="single") == "hierarchical"
    assert choose_method(n, memory=roomy, slip_law="coulomb") == "inverse"
    assert choose_method(n - 1, memory=roomy) == "inverse"
    half = HierarchicalInverse.memory_bytes(n, itemsize=4)
    assert choose_method(n, memory=half // 2) == "cg"


def test_memory_guard_knows_both_precisions():
    normal = squeeze(self_affine((32, 32), hurst=0.8, rms_height=1.0, rng=sample_rng(9, 0)),
                     depth=1.0, tol=1e-12)
    n = Bonds(normal, 0.2).n
    double, single = inverse_memory_bytes(n), inverse_memory_bytes(n, precision="single")
    ref = pull(normal)
    assert (ref.method, ref.details.precision) == ("inverse", "double")
    with memory.limited((single + double) / 2 / 2**30):
        with pytest.raises(MemoryLimitError, match="precision 'single'"):
            pull(normal, method="inverse", precision="double")
        res = pull(normal)
        assert (res.method, res.details.precision) == ("inverse", "single")
        assert res.friction_force == pytest.approx(ref.friction_force, rel=1e-10)
    with memory.limited(single / 2 / 2**30):
        with pytest.raises(MemoryLimitError, match="single precision"):
            pull(normal, method="inverse", precision="single")
        res = pull(normal)
        assert res.method == "hierarchical"
        assert res.friction_force == pytest.approx(ref.friction_force, rel=1e-10)
    compressed = HierarchicalInverse.memory_bytes(n, block=128)
    with memory.limited(0.75 * compressed / 2**30):  # its single-precision estimate fits
        res = pull(normal, method="hierarchical")
        assert res.details.precision == "single"
        assert res.friction_force == pytest.approx(ref.friction_force, rel=1e-10)
        with pytest.raises(MemoryLimitError, match="hierarchical"):
            pull(normal, method="hierarchical", precision="double")
    with memory.limited(compressed / 4 / 2**30):
        with pytest.raises(MemoryLimitError, match="hierarchical"):
            pull(normal, method="hierarchical")
        assert pull(normal).method == "cg"


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_memory_estimate_covers_the_inverse_with_its_work_panels(monkeypatch, dtype):
    """The estimate the guard checks covers what building the bond inverse allocates, also
    by the block sweep that large orders take (forced here at a small order), whose two
    n x SWEEP_BLOCK panels once went uncounted: an N = 512 pull of 77 036 bonds peaked
    0.37 GiB above that estimate."""
    from roughslip.friction.bonds import bond_inverse

    normal = squeeze(self_affine((64, 64), hurst=0.8, rms_height=1.0, rng=sample_rng(9, 0)),
                     depth=1.5, tol=1e-12)
    b = Bonds(normal, 0.2)
    assert b.n > 200
    b.entries(np.arange(2), np.arange(2))  # the kernel tables exist before the count
    monkeypatch.setattr(lapack64, "SWEEP_MIN_N", b.n - 1)
    assert lapack64.cholesky_inverse_work_bytes(b.n, 4) > 8 * b.n * lapack64.SWEEP_BLOCK
    # once before the count: what is made once per process (compiled kernels, caches of
    # the first call in this precision) is not the inverse's to carry
    bond_inverse(b, 16, 1, dtype=dtype)
    tracemalloc.start()
    try:
        inv = bond_inverse(b, 16, 1, dtype=dtype)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    itemsize = np.dtype(dtype).itemsize
    assert inv.buf.dtype == dtype
    assert peak > itemsize * b.n**2 + 2 * itemsize * b.n * lapack64.SWEEP_BLOCK  # the panels
    reserve = LOWER_RESERVE[0] + itemsize * b.n**2 * LOWER_RESERVE[1]
    estimate = inverse_memory_bytes(b.n, 16, "single" if itemsize == 4 else "double")
    assert peak <= estimate - reserve  # covered without the reserve for the rest


def test_bad_precision():
    normal = squeeze(sphere((12, 12), radius=10.0), depth=1.0, tol=1e-12)
    with pytest.raises(InputError, match="precision"):
        pull(normal, precision="half")
    only = "only slip_law 'break', 'coulomb' with method 'inverse'"
    with pytest.raises(InputError, match=only):
        pull(normal, precision="single", slip_law="slip-weakening", lam_dynamic=0.1,
             slip_distance=0.05)
    with pytest.raises(InputError, match=only):
        pull(normal, precision="single", method="cg")


@pytest.mark.parametrize("depth", [0.005, 0.05, 0.3])
def test_tiny_contacts_in_single_precision(depth):
    """One bond, a handful and a few dozen: the bound's eigenvalue estimate is dense there."""
    normal = squeeze(sphere((9, 9), radius=20.0), depth=depth, tol=1e-13)
    d = pull(normal, method="inverse", precision="double")
    s = pull(normal, precision="single")
    assert s.method == "inverse" and s.details.precision == "single"
    np.testing.assert_array_equal(s.curve.site[1:], d.curve.site[1:])
    assert abs(s.friction_force - d.friction_force) <= 1e-10 * abs(d.friction_force)
