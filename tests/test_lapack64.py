"""The 64-bit-integer dense kernels agree with scipy's (and fall back to them)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from roughslip.errors import NumericalError, SizeLimitError
from roughslip.linalg import lapack64


def spd(n, seed=0):
    a = np.random.default_rng(seed).standard_normal((n, n))
    return np.asfortranarray(a @ a.T + n * np.eye(n))


@pytest.mark.parametrize("n", [1, 7, 300])
def test_kernels_match_scipy(n):
    a = spd(n)
    inv = np.linalg.inv(a)
    b = a.copy(order="F")
    lapack64.cholesky_inverse(b)
    low = np.tril_indices(n)
    assert np.allclose(b[low], inv[low], rtol=1e-10, atol=1e-14)
    x = np.random.default_rng(1).standard_normal(n)
    assert np.allclose(lapack64.symv(b, x), inv @ x, rtol=1e-10)
    u = np.random.default_rng(2).standard_normal((n, 5))
    c = a.copy(order="F")
    lapack64.syrk_update(c, u, -0.5)
    assert np.allclose(c[low], (a - 0.5 * u @ u.T)[low], rtol=1e-12)


def test_not_positive_definite_is_an_error():
    a = np.asfortranarray(-np.eye(4))
    with pytest.raises(Exception, match="not positive definite"):
        lapack64.cholesky_inverse(a)


def test_fallback_refuses_orders_beyond_32_bit_indexing(monkeypatch):
    monkeypatch.setattr(lapack64, "_load", lambda: None)
    with pytest.raises(SizeLimitError, match="64-bit integers"):
        lapack64.check_size(lapack64.LP64_MAX_N + 1)
    lapack64.check_size(lapack64.LP64_MAX_N)
    a = spd(50)
    b = a.copy(order="F")
    lapack64.cholesky_inverse(b)  # scipy path
    assert np.allclose(np.tril(b), np.tril(linalg.inv(a)), rtol=1e-10, atol=1e-14)


def test_the_64_bit_library_is_found_with_numpy_openblas():
    if "openblas64" not in str(np.__config__.CONFIG.get("Build Dependencies", {})):
        pytest.skip("numpy is not built with a 64-bit-integer OpenBLAS")
    assert lapack64.available() and lapack64.max_n() is None


@pytest.mark.parametrize(("n", "block"), [(1, 4), (37, 8), (300, 64), (257, 256)])
def test_block_sweep_inverse(n, block):
    if not lapack64.available():
        pytest.skip("needs the 64-bit-integer BLAS")
    a = spd(n, seed=n)
    b = a.copy(order="F")
    lapack64.sweep_inverse(b, block=block)
    low = np.tril_indices(n)
    assert np.allclose(b[low], np.linalg.inv(a)[low], rtol=1e-10, atol=1e-14)


def test_block_sweep_refuses_an_indefinite_matrix():
    if not lapack64.available():
        pytest.skip("needs the 64-bit-integer BLAS")
    a = spd(12, seed=3)
    a[9, 9] = -1.0  # the third pivot block's Schur complement is indefinite
    with pytest.raises(NumericalError, match="not positive definite"):
        lapack64.sweep_inverse(a, block=4)


@pytest.mark.parametrize(("n", "k", "block"), [(1, 1, 4), (37, 5, 8), (300, 128, 64)])
def test_panel_rank_k_update_equals_dense(n, k, block):
    """The GEMM-panel update used for large orders (OpenBLAS's threaded DSYRK crashes there)."""
    if not lapack64.available():
        pytest.skip("needs the 64-bit-integer BLAS")
    rng = np.random.default_rng(n)
    c = spd(n, seed=k)
    u = rng.standard_normal((n, k))
    got = c.copy(order="F")
    lapack64.syrk_panels(got, u, -0.5, block=block)
    low = np.tril_indices(n)
    assert np.allclose(got[low], (c - 0.5 * u @ u.T)[low], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("library", [True, False])
@pytest.mark.parametrize(("m", "cap", "k"), [(1, 1, 1), (37, 40, 5), (2100, 2110, 130)])
def test_gemm_update_on_a_leading_block_in_place(m, cap, k, library, monkeypatch):
    """The fold of the pending terms of an inverse that also grows: the leading m x m block of
    a larger buffer gains alpha P Q^T, with the library's GEMM or numpy's panels, and nothing
    outside that block changes."""
    if library and not lapack64.available():
        pytest.skip("needs the 64-bit-integer BLAS")
    if not library:
        monkeypatch.setattr(lapack64, "_load", lambda: None)
    rng = np.random.default_rng(m)
    c = np.asfortranarray(rng.standard_normal((cap, cap)))
    p = np.asfortranarray(rng.standard_normal((cap, k + 3)))
    q = np.asfortranarray(rng.standard_normal((cap, k + 3)))
    got = c.copy(order="F")
    lapack64.gemm_update(got, m, p, q, k, -0.5)
    want = c.copy()
    want[:m, :m] -= 0.5 * p[:m, :k] @ q[:m, :k].T
    assert np.allclose(got, want, rtol=1e-12, atol=1e-12)
    assert np.array_equal(got[m:], c[m:]) and np.array_equal(got[:, m:], c[:, m:])


def test_symv_on_a_leading_block_in_place():
    a = spd(40, seed=3)
    x = np.random.default_rng(4).standard_normal(25)
    assert np.allclose(lapack64.symv(a, x, 25), a[:25, :25] @ x, rtol=1e-12)
    with pytest.raises(ValueError, match="shape"):
        lapack64.symv(a, x, 30)
