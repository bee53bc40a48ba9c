r"""The inverse of a non-symmetric matrix that drifts, from the exact inverse of a nearby one.

A path-follower needs, at every point :math:`x` of its path, solves with the Jacobian
:math:`A(x)` and rigorous bounds on :math:`\|A(x)^{-1}\|_\infty` and on :math:`|A(x)^{-1}|\,v`.
Inverting :math:`A(x)` afresh costs :math:`O(m^3)` at every point. :class:`NearInverse` keeps
instead a *reference* matrix :math:`A_r` and its inverse :math:`X = A_r^{-1}`, and serves a
nearby :math:`A = A_r + E` through the Neumann series (Horn & Johnson, *Matrix Analysis*,
1985, corollary 5.6.16): with
:math:`\theta = \|X\|_\infty \|E\|_\infty < 1`,

.. math:: A^{-1} = (I + XE)^{-1}X, \qquad
          \|A^{-1}\|_\infty \le \frac{\|X\|_\infty}{1 - \theta},

and, for :math:`v \ge 0`, from :math:`A^{-1} = X - XEA^{-1}` entrywise,

.. math:: |A^{-1}|\,v \le |X|\,v + \beta\,\|E\|_\infty\|v\|_\infty\,|X|\mathbf 1,
          \qquad \beta = \frac{\|X\|_\infty}{1 - \theta}.

Solves iterate :math:`z \leftarrow z + X(b - Az)` (the package's iterative refinement
with :math:`X` as the approximate inverse), which contracts by :math:`\theta` per sweep.
Every bound and solve costs :math:`O(m^2)`.

The reference follows the index set without a new factorisation:

* **bordering** with a new index :math:`k` (row :math:`c^T`, column :math:`b`, diagonal
  :math:`d`) through the Schur complement :math:`\sigma = d - c^TXb`:
  :math:`X' = \begin{pmatrix} X + Xb\,c^TX/\sigma & -Xb/\sigma \\ -c^TX/\sigma &
  1/\sigma\end{pmatrix}`;
* **replacing** row :math:`i` by Sherman & Morrison's rank-one formula;
* **removing** index :math:`i`: the inverse of :math:`A_r` without row and column :math:`i` is
  :math:`X_{\bar i\bar i} - X_{\bar i i}X_{i\bar i}/X_{ii}` (the same Schur identity read
  backwards).

All three are exact in exact arithmetic; in floating point each adds rounding of order
:math:`\varepsilon\,\kappa(A_r)`, as a fresh inverse does once. The owner bounds the number of
updates between fresh inversions (``updates``), and asks for a fresh inversion when
:math:`\theta` grows past what its contraction needs.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from roughslip.linalg.inverse import refine

#: a border or removal whose pivot is below this fraction of its row's scale is refused
#: (the caller inverts afresh)
PIVOT = 1e-10
#: refinement sweeps before a solve gives up (then a direct solve)
SWEEPS = 60
#: the normwise backward error :math:`\|b - Az\|_\infty/(\|A\|_\infty\|z\|_\infty +
#: \|b\|_\infty)` a solve is refined to
BACKWARD = 1e-14


class Singular(ArithmeticError):
    """A fresh inverse of a numerically singular matrix."""


class NearInverse:
    r"""The reference :math:`A_r` (``m x m``), its inverse :math:`X`, and the updates since
    :math:`X` was computed afresh (module docstring).

    Parameters
    ----------
    A : numpy.ndarray
        The reference matrix (copied).

    Raises
    ------
    Singular
        If LAPACK finds :math:`A` singular.
    """

    def __init__(self, A: np.ndarray) -> None:
        self.A = np.array(A, dtype=float)
        try:
            self.X = linalg.inv(self.A, check_finite=False)
        except linalg.LinAlgError:
            raise Singular("a singular reference matrix") from None
        self.updates = 0
        self._abs: np.ndarray | None = None
        self._norm: float | None = None

    @classmethod
    def of(cls, A: np.ndarray, X: np.ndarray) -> NearInverse:
        """A reference from a matrix (copied) and an inverse the caller computed (kept)."""
        obj = cls.__new__(cls)
        obj.A, obj.X, obj.updates, obj._abs, obj._norm = A.copy(), X, 0, None, None
        return obj

    @property
    def size(self) -> int:
        return self.A.shape[0]

    def abs_x(self) -> np.ndarray:
        """:math:`|X|`, kept until :math:`X` changes."""
        if self._abs is None:
            self._abs = np.abs(self.X)
        return self._abs

    def norm(self) -> float:
        r""":math:`\|X\|_\infty`, kept until :math:`X` changes."""
        if self._norm is None:
            self._norm = float(self.abs_x().sum(axis=1).max(initial=0.0))
        return self._norm

    def border(self, k: int, row: np.ndarray, col: np.ndarray) -> bool:
        r"""Insert index ``k`` (``0 <= k <= m``) with ``row`` and ``col`` (length
        :math:`m + 1`, in the new numbering; ``row[k]`` is the diagonal, ``col[k]`` is
        ignored). False, and nothing changed, when the Schur complement is below
        :data:`PIVOT` of the row's scale."""
        m = self.size
        keep = np.r_[0:k, k + 1:m + 1]
        c, b, d = row[keep], col[keep], float(row[k])
        Xb, cX = self.X @ b, c @ self.X
        sigma = d - float(c @ Xb)
        scale = float(np.abs(row).sum())
        if not abs(sigma) > PIVOT * scale:
            return False
        X = np.empty((m + 1, m + 1))
        X[np.ix_(keep, keep)] = self.X + np.outer(Xb / sigma, cX)
        X[keep, k] = -Xb / sigma
        X[k, keep] = -cX / sigma
        X[k, k] = 1.0 / sigma
        A = np.empty((m + 1, m + 1))
        A[np.ix_(keep, keep)] = self.A
        A[k, :] = row
        A[keep, k] = b
        self.A, self.X, self._abs, self._norm = A, X, None, None
        self.updates += 1
        return True

    def remove(self, i: int) -> bool:
        r"""Drop index ``i``: the inverse of :math:`A_r` without row and column ``i``. False,
        and nothing changed, when :math:`|X_{ii}|` is below :data:`PIVOT` of its row's
        1-norm."""
        m = self.size
        piv = float(self.X[i, i])
        if not abs(piv) > PIVOT * float(np.abs(self.X[i]).sum()):
            return False
        keep = np.r_[0:i, i + 1:m]
        X = self.X[np.ix_(keep, keep)]
        X -= np.outer(self.X[keep, i] / piv, self.X[i, keep])
        self.A = self.A[np.ix_(keep, keep)]
        self.X, self._abs, self._norm = X, None, None
        self.updates += 1
        return True

    def replace_row(self, i: int, row: np.ndarray) -> bool:
        r"""Make ``row`` row ``i`` of :math:`A_r`: the rank-one change :math:`e_i w^T`,
        :math:`w` the difference, by Sherman & Morrison, :math:`X' = X - Xe_i\,w^TX/(1 +
        w^TXe_i)`. False, and nothing changed, when the denominator is below
        :data:`PIVOT`."""
        w = row - self.A[i]
        if not w.any():
            return True
        xi = self.X[:, i].copy()
        wX = w @ self.X
        den = 1.0 + float(wX[i])
        if not abs(den) > PIVOT * max(1.0, float(np.abs(w).sum()) * float(np.abs(xi).max())):
            return False
        self.X -= np.outer(xi / den, wX)
        self.A[i] = row
        self._abs = self._norm = None
        self.updates += 1
        return True

    def near(self, A: np.ndarray, moved: float | None = None) -> Near:
        r"""The matrix ``A`` (same order) served from this reference; ``moved``, when given,
        is :math:`\|A - A_r\|_\infty`."""
        return Near(self, A, moved)


class Near:
    r""":math:`A = A_r + E` served from a :class:`NearInverse` (module docstring): ``theta``
    (:math:`\|X\|_\infty\|E\|_\infty`), ``beta`` (the bound of :math:`\|A^{-1}\|_\infty`,
    infinite when :math:`\theta \ge 1`), :meth:`solve` and :meth:`abs_bound`. When
    :math:`E = 0` and the reference is a fresh inverse, every answer is the reference's own:
    :math:`Xb`, :math:`\|X\|_\infty`, :math:`|X|v`. A ``Near`` holds for the reference as
    it was: its methods refuse to run after the reference was updated."""

    def __init__(self, ref: NearInverse, A: np.ndarray, moved: float | None = None) -> None:
        self.ref, self.A = ref, A
        self.version = ref.updates
        self.xn = ref.norm()
        self.en = (float(np.abs(A - ref.A).sum(axis=1).max(initial=0.0)) if moved is None
                   else moved)
        self.theta = self.xn * self.en
        self.beta = self.xn / (1.0 - self.theta) if self.theta < 1.0 else np.inf
        self._an: float | None = None

    def solve(self, b: np.ndarray) -> np.ndarray:
        r""":math:`A^{-1}b` by iterative refinement on :math:`X`
        (:func:`roughslip.linalg.inverse.refine`) to a normwise backward error of
        :data:`BACKWARD`; a direct solve when it stalls above that."""
        self._current()
        X = self.ref.X
        z = X @ b
        if self.en == 0.0 and self.ref.updates == 0:
            return z
        if self._an is None:
            self._an = float(np.abs(self.A).sum(axis=1).max(initial=0.0))
        bn = float(np.abs(b).max(initial=0.0))

        def residual(x):
            r = b - self.A @ x
            den = self._an * float(np.abs(x).max(initial=0.0)) + bn
            return r, float(np.abs(r).max(initial=0.0)) / den if den > 0 else 0.0

        z, res, _ = refine(z, residual, lambda x, r: x + X @ r, BACKWARD, SWEEPS)
        return z if res <= BACKWARD else linalg.solve(self.A, b, check_finite=False)

    def abs_bound(self, v: np.ndarray) -> np.ndarray:
        r"""An entrywise upper bound of :math:`|A^{-1}|\,v` for :math:`v \ge 0`."""
        self._current()
        aX = self.ref.abs_x()
        out = aX @ v
        vn = float(np.abs(v).max(initial=0.0))
        if self.en == 0.0 or vn == 0.0:
            return out
        return out + self.beta * self.en * vn * aX.sum(axis=1)

    def _current(self) -> None:
        if self.ref.updates != self.version:
            raise RuntimeError("the reference changed after this Near was made")
