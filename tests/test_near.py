"""The reference inverse of a drifting matrix: updates against fresh inverses, bounds that
hold."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.linalg.near import NearInverse


def _matrix(rng, m):
    """A non-symmetric, well-conditioned matrix with a dominant diagonal."""
    return rng.standard_normal((m, m)) / np.sqrt(m) + 3.0 * np.eye(m)


def _eps_kappa(A):
    return np.finfo(float).eps * np.linalg.cond(A, np.inf)


def test_updates_equal_fresh_inverses():
    """Border, remove and replace a row many times: X stays the inverse of A_r, to the
    rounding of the updates (each adds about eps kappa)."""
    rng = np.random.default_rng(3)
    A = _matrix(rng, 40)
    ref = NearInverse(A)
    for step in range(60):
        m = ref.size
        op = step % 3
        if op == 0:
            k = int(rng.integers(0, m + 1))
            row, col = rng.standard_normal(m + 1) / np.sqrt(m), rng.standard_normal(m + 1)
            col /= np.sqrt(m)
            row[k] = 3.0
            assert ref.border(k, row, col)
        elif op == 1:
            assert ref.remove(int(rng.integers(0, m)))
        else:
            i = int(rng.integers(0, m))
            row = ref.A[i] + 0.3 * rng.standard_normal(m) / np.sqrt(m)
            assert ref.replace_row(i, row)
    assert ref.updates == 60
    fresh = np.linalg.inv(ref.A)
    err = np.abs(ref.X - fresh).max() / np.abs(fresh).max()
    assert err < 60 * 10 * _eps_kappa(ref.A)
    assert np.abs(ref.A @ ref.X - np.eye(ref.size)).max() < 60 * 10 * _eps_kappa(ref.A)


def test_border_places_the_new_index():
    """The bordered reference is the matrix with the row and column inserted at k."""
    rng = np.random.default_rng(4)
    A = _matrix(rng, 6)
    full = _matrix(rng, 7)
    k = 2
    keep = [0, 1, 3, 4, 5, 6]
    full[np.ix_(keep, keep)] = A
    ref = NearInverse(A)
    col = full[:, k].copy()
    col[k] = 99.0  # ignored
    assert ref.border(k, full[k], col)
    np.testing.assert_array_equal(ref.A, full)
    np.testing.assert_allclose(ref.X, np.linalg.inv(full), atol=100 * _eps_kappa(full))


def test_singular_updates_are_refused_and_change_nothing():
    rng = np.random.default_rng(5)
    A = _matrix(rng, 5)
    ref = NearInverse(A)
    X0, A0 = ref.X.copy(), ref.A.copy()
    # a new row equal to an existing one and a matching diagonal: a zero Schur complement
    col = np.append(A[:, 1], A[1, 1])
    row = np.append(A[1], col[1])
    assert not ref.border(5, row, col)
    # replacing row 0 by row 1 makes A_r singular
    assert not ref.replace_row(0, A[1].copy())
    np.testing.assert_array_equal(ref.X, X0)
    np.testing.assert_array_equal(ref.A, A0)
    assert ref.updates == 0


@pytest.mark.parametrize("size", [1e-3, 1e-2, 5e-2])
def test_neumann_bounds_hold_and_solves_reach_rounding(size):
    """For A = A_r + E: beta bounds ||A^-1||_inf, abs_bound bounds |A^-1| v, solve agrees
    with a direct solve to a few eps kappa; with E = 0 every answer is X's own."""
    rng = np.random.default_rng(6)
    Ar = _matrix(rng, 50)
    ref = NearInverse(Ar)
    E = size * rng.standard_normal((50, 50)) / np.sqrt(50)
    A = Ar + E
    near = ref.near(A)
    assert near.theta < 1
    Ainv = np.linalg.inv(A)
    assert np.abs(Ainv).sum(axis=1).max() <= near.beta
    v = rng.random(50)
    assert np.all(np.abs(Ainv) @ v <= near.abs_bound(v) * (1 + 1e-12))
    b = rng.standard_normal(50)
    x = near.solve(b)
    np.testing.assert_allclose(x, np.linalg.solve(A, b),
                               atol=100 * _eps_kappa(A) * np.abs(x).max())
    same = ref.near(Ar.copy())
    assert same.theta == 0.0
    np.testing.assert_array_equal(same.solve(b), ref.X @ b)
    np.testing.assert_array_equal(same.abs_bound(v), np.abs(ref.X) @ v)
    assert same.beta == np.abs(ref.X).sum(axis=1).max()


def test_a_far_matrix_has_no_bound():
    rng = np.random.default_rng(7)
    Ar = _matrix(rng, 20)
    near = NearInverse(Ar).near(Ar + 10 * np.eye(20))
    assert near.theta >= 1
    assert near.beta == np.inf
