r"""Conjugate gradients on a principal sub-block of an SPD convolution operator.

For a mask :math:`K` (contact or stick set) the reduced system :math:`G_{KK} x_K = b_K` is SPD
whenever :math:`G` is (Cauchy interlacing, docs/theory/halfspace.rst#matrix-properties), so plain CG
converges; the iterations grow like :math:`\sqrt{\mathrm{cond}} \sim \sqrt N`. Fields live on the
full grid with zeros off :math:`K`; one FFT convolution per iteration.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from roughslip.errors import NumericalError


@dataclass(frozen=True)
class CGResult:
    """Outcome of :func:`masked_cg`."""

    x: np.ndarray
    converged: bool
    iterations: int
    residual: float  # ||b - A x|| / ||b|| on the mask


def masked_cg(
    apply: Callable[[np.ndarray, np.ndarray], np.ndarray],
    b: np.ndarray,
    mask: np.ndarray,
    *,
    x0: np.ndarray | None = None,
    tol: float = 1e-10,
    max_iter: int = 10_000,
) -> CGResult:
    r"""Solve :math:`(G x)_K = b_K` with :math:`x = 0` off :math:`K`.

    Parameters
    ----------
    apply : callable ``(v, out) -> out``
        The full-grid operator :math:`v \mapsto G v` (an FFT convolution).
    b : ndarray
        Right-hand side (only its values on ``mask`` are used).
    mask : ndarray of bool
        The sites of the reduced system.
    x0 : ndarray, optional
        Start (its values off ``mask`` are ignored).
    tol : float
        Relative residual :math:`\|b_K - (Gx)_K\|_2 / \|b_K\|_2`.
    """
    m = mask.astype(float)
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
        apply(x, ax)
        np.subtract(bk, ax * m, out=r)
    z = r.ravel()
    rr = float(np.dot(z, z))
    d = r.copy()
    q = np.empty_like(b)
    it = 0
    res = np.sqrt(rr) / bnorm
    while res > tol and it < max_iter:
        it += 1
        apply(d, q)
        np.multiply(q, m, out=q)
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
    # true residual (guards against drift of the recursive one)
    apply(x, ax)
    true = np.linalg.norm(((bk - ax * m)).ravel()) / bnorm
    return CGResult(x, bool(true <= max(tol, 10 * np.finfo(float).eps)), it, float(true))
