r"""Principal sub-blocks :math:`A_{KK}` of a symmetric operator, as linear operators.

Every solver of the contact problems works on a principal sub-block of a convolution
operator: :math:`G_{zz}` on the contact set for the squeeze, :math:`G_{xx}` on the stick set for
the pull, and the coupled :math:`(z, x)` block on the contact and stick sets. A principal
sub-block of a symmetric positive definite operator is symmetric positive definite (Cauchy
interlacing), so one conjugate-gradient routine (:func:`roughslip.linalg.cg.cg`) serves all of
them.

A :class:`Restricted` operator has two faces:

* the :class:`scipy.sparse.linalg.LinearOperator` contract on compressed vectors of length
  :math:`|K|` (``matvec``, ``rmatvec``, ``@``), for SciPy's eigensolvers and for checks;
* :meth:`Restricted.apply_masked` on full fields with zeros off :math:`K`, which is what
  conjugate gradients use: no gathering or scattering per iteration.

Fields may carry a leading component axis: the coupled block acts on ``(2, ny, nx)`` arrays
``[f_z, f_x]`` with a mask of the same shape.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.sparse.linalg import LinearOperator

from roughslip.errors import InputError

#: ``apply(v, out) -> out``: the full operator on a field (``out`` may not alias ``v``)
Apply = Callable[[np.ndarray, np.ndarray], np.ndarray]


class Restricted(LinearOperator):
    r""":math:`A_{KK}` for a symmetric operator :math:`A` on fields and a mask :math:`K`.

    Parameters
    ----------
    apply : callable ``(v, out) -> out``
        The full operator on fields of ``mask.shape``.
    mask : ndarray of bool
        The sites (and components) :math:`K`; the compressed vectors list them in C order.

    Notes
    -----
    ``matvec(x)`` scatters :math:`x` onto the field, applies :math:`A` once and gathers the
    result on :math:`K`; the operator is symmetric, so ``rmatvec`` is the same map.
    """

    def __init__(self, apply: Apply, mask: np.ndarray) -> None:
        mask = np.asarray(mask, dtype=bool)
        self.mask = mask
        self.weights = mask.astype(float)
        self.sites = np.flatnonzero(mask)
        self._apply = apply
        self._work = np.empty(mask.shape)
        n = int(self.sites.size)
        super().__init__(dtype=np.dtype(float), shape=(n, n))

    # -- fields -----------------------------------------------------------------------------
    def apply_masked(self, v: np.ndarray, out: np.ndarray) -> np.ndarray:
        """``out = 1_K (A v)`` for a field ``v`` that is zero off :math:`K`."""
        self._apply(v, out)
        np.multiply(out, self.weights, out=out)
        return out

    def apply_full(self, v: np.ndarray, out: np.ndarray) -> np.ndarray:
        """``out = A v`` on the whole grid (the displacement everywhere)."""
        return self._apply(v, out)

    def scatter(self, x: np.ndarray) -> np.ndarray:
        """The field that is ``x`` on :math:`K` and zero elsewhere."""
        x = np.asarray(x, dtype=float).ravel()
        if x.size != self.sites.size:
            raise InputError(f"vector of length {x.size} for a restriction to {self.sites.size} "
                             "sites")
        f = np.zeros(self.mask.shape)
        f.ravel()[self.sites] = x
        return f

    def gather(self, field: np.ndarray) -> np.ndarray:
        """The values of a field on :math:`K` (compressed)."""
        return np.asarray(field).ravel()[self.sites]

    # -- LinearOperator ---------------------------------------------------------------------
    def _matvec(self, x: np.ndarray) -> np.ndarray:
        self._apply(self.scatter(x), self._work)
        return self._work.ravel()[self.sites].copy()

    def _rmatvec(self, x: np.ndarray) -> np.ndarray:
        return self._matvec(x)

    def _adjoint(self) -> Restricted:
        return self
