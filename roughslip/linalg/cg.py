r"""Conjugate gradients on a principal sub-block of a symmetric positive definite operator.

One routine for every restricted solve of the package: the active-set squeeze
(:math:`G_{zz}` on the contact set), the ``literal``, ``cg`` and ``batch`` pulls
(:math:`G_{xx}` on the stick set), certification refinements, and the matrix-free coupled model
(the :math:`(z, x)` block on the contact and stick sets). The reduced system is SPD whenever the
full operator is (Cauchy interlacing), so plain CG converges; the iterations grow like
:math:`\sqrt{\mathrm{cond}} \sim \sqrt N`. Fields live on the full grid (with a leading
component axis for blocks) with zeros off the mask: one operator application per iteration and
no gathering.

The Polonsky-Keer squeeze keeps its own loop (:mod:`roughslip.contact.squeeze`): its set changes
inside the iteration, which a fixed restriction cannot express.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from roughslip.errors import NumericalError
from roughslip.linalg.restricted import Restricted


@dataclass(frozen=True)
class CGResult:
    """Outcome of :func:`cg`."""

    x: np.ndarray
    converged: bool
    iterations: int
    residual: float  # ||b - A x|| / ||b|| on the mask, recomputed from x at the end


def cg(
    A: Restricted,
    b: np.ndarray,
    *,
    x0: np.ndarray | None = None,
    tol: float = 1e-10,
    max_iter: int = 10_000,
) -> CGResult:
    r"""Solve :math:`(A x)_K = b_K` with :math:`x = 0` off :math:`K`.

    Parameters
    ----------
    A : Restricted
        The operator and the mask :math:`K` (:class:`roughslip.linalg.restricted.Restricted`).
    b : ndarray, shape ``A.mask.shape``
        Right-hand side (only its values on the mask are used).
    x0 : ndarray, optional
        Start (its values off the mask are ignored).
    tol : float
        Relative residual :math:`\|b_K - (Ax)_K\|_2 / \|b_K\|_2`.
    max_iter : int
        Iteration limit.

    Returns
    -------
    CGResult
        The residual is that of the returned ``x``, computed afresh with one more application
        (it guards against drift of the recursive residual); ``converged`` compares it with
        ``tol``.

    Notes
    -----
    Hestenes & Stiefel (1952), *J. Res. Nat. Bur. Standards* 49:409, Algorithm (3:1), on the
    masked fields.
    """
    m = A.weights
    if b.shape != m.shape:
        raise NumericalError(f"cg: right-hand side of shape {b.shape} for a mask of shape "
                             f"{m.shape}")
    x = np.zeros_like(b) if x0 is None else x0 * m
    bk = b * m
    bnorm = float(np.sqrt(np.dot(bk.ravel(), bk.ravel())))
    if bnorm == 0.0:
        return CGResult(np.zeros_like(b), True, 0, 0.0)
    ax = np.empty_like(b)
    r = np.empty_like(b)
    if x0 is None or not np.any(x):
        np.copyto(r, bk)
    else:
        A.apply_masked(x, ax)
        np.subtract(bk, ax, out=r)
    z = r.ravel()
    rr = float(np.dot(z, z))
    d = r.copy()
    q = np.empty_like(b)
    it = 0
    res = np.sqrt(rr) / bnorm
    while res > tol and it < max_iter:
        it += 1
        A.apply_masked(d, q)
        dq = float(np.dot(d.ravel(), q.ravel()))
        if not dq > 0.0:  # breakdown: exact solution or loss of definiteness
            break
        alpha = rr / dq
        x += alpha * d
        r -= alpha * q
        rr_new = float(np.dot(z, z))
        np.multiply(d, rr_new / rr, out=d)
        d += r
        rr = rr_new
        res = np.sqrt(rr) / bnorm
        if not np.isfinite(res):
            raise NumericalError(f"conjugate gradients: non-finite residual at iteration {it}")
    A.apply_masked(x, ax)
    true = float(np.linalg.norm((bk - ax).ravel())) / bnorm
    return CGResult(x, bool(true <= max(tol, 10 * np.finfo(float).eps)), it, true)
