r"""Error estimates of a decoupled pull: the solves' own part, the squeeze's part, and the
condition of :math:`G_{xx}` on the bonds (docs/methods.rst#estimates-against-truth).
"""

from __future__ import annotations

import math

import numpy as np

from roughslip.contact.estimates import REFINE_TOL as SQUEEZE_REFINE_TOL
from roughslip.contact.estimates import squeeze_correction
from roughslip.contact.squeeze import NormalResult
from roughslip.errors import InputError, NumericalError
from roughslip.friction.bonds import Bonds
from roughslip.friction.laws import LAWS
from roughslip.friction.result import PullResult
from roughslip.linalg.cg import cg
from roughslip.linalg.threads import blas_threads

#: relative tolerance of the correction solve in :func:`refinement_estimate` (the squeeze's
#: correction in :func:`normal_share` has its own, ``SQUEEZE_REFINE_TOL``)
REFINE_TOL = 1e-2


def _peak_force(phi: np.ndarray, cap: np.ndarray) -> float:
    r""":math:`F_{x,\rm lim} = \sum_S\varphi \,/\, \max_i |\varphi_i|/(\lambda f_{z,i})`."""
    return float(phi.sum()) / float(np.max(np.abs(phi) / cap))


def refinement_estimate(normal: NormalResult, result: PullResult, *,
                        tol: float = REFINE_TOL) -> float:
    r"""A-posteriori estimate of the relative error of a break-law friction force.

    At the peak the stick set :math:`S` carries :math:`\varphi` with
    :math:`G_{xx}[S,S]\varphi \approx 1_S`, and the friction force is
    :math:`F = \sum_S\varphi / \max_i |\varphi_i|/(\lambda f_{z,i})` (module docstring).
    One step of iterative refinement (Higham, *Accuracy and Stability of Numerical
    Algorithms*, 2nd ed. 2002, ch. 12): the residual :math:`r = 1_S - G_{xx}[S,S]\varphi`
    by the FFT operator, the correction
    :math:`\delta = G_{xx}[S,S]^{-1} r` by CG to the relative residual ``tol``, and

    .. math:: \hat e = \frac{|F(\varphi) - F(\varphi + \delta)|}{F(\varphi + \delta)}.

    What it is
        An *estimate*, first-order accurate: :math:`\varphi + \delta` differs from the exact
        solution by at most :math:`\kappa\,` ``tol`` times :math:`\|\delta\|`, so
        :math:`\hat e` is the true error of the peak state up to that fraction. It does not see
        a wrong choice of peak state (a break order changed by the solver's error) by
        itself, but such a change moves the friction force by about as much as the error
        of the states: on 90 pulls of 9 rough scenes (N = 32-96, methods ``literal`` and
        ``cg``, tolerances 1e-3 to 1e-10; ``scripts/estimate_check.py``), 25 of them with a
        break order other than the exact one, the estimate was 0.49-1.74 times the true
        error wherever that exceeded 1e-13. With ``"inverse"`` both lie at the rounding
        level (below 3e-15).

        It is the error of the pull *given* the normal forces :math:`f_z`: the squeeze's
        error enters the friction force through :math:`\lambda f_z` and is not in it
        (:func:`normal_share` estimates that part).

    Returns
    -------
    float
        :math:`\hat e`; 0 when the peak state has no stick sites.
    """
    if LAWS.get(result.slip_law).slides:
        raise InputError("refinement_estimate needs a break-law result, whose friction force "
                         f"is a peak of the pull curve (slip_law = {result.slip_law!r} slides)")
    stick = np.asarray(result.peak.stick, dtype=bool)
    if not stick.any() or not result.peak_dx > 0:
        return 0.0
    A = normal.problem.restricted("xx", stick)
    phi = A.gather(result.peak.fx) / result.peak_dx
    cap = result.details.lam * A.gather(normal.fz)
    r = 1.0 - A.matvec(phi)
    delta = A.gather(cg(A, A.scatter(r), tol=tol).x)
    refined = _peak_force(phi + delta, cap)
    return abs(_peak_force(phi, cap) - refined) / refined


def normal_share(normal: NormalResult, result: PullResult, *,
                 tol: float = SQUEEZE_REFINE_TOL) -> float:
    r"""Estimated relative error of a friction force caused by the error of the squeeze's
    normal forces, signed: :math:`(F - F^{\rm exact})/F^{\rm exact}`.

    :math:`\delta \approx f_z^{\rm exact} - f_z` is
    :func:`~roughslip.contact.estimates.squeeze_correction`. The stick forces
    :math:`\varphi` depend on the stick set only, so with the same break sequence:

    - break law: :math:`F = \lambda f_{z,k}\sum_S\varphi/|\varphi_k|` with :math:`k` the
      bond that breaks at the peak, and the share is
      :math:`-\delta_k / (f_{z,k} + \delta_k)`;
    - Coulomb law: :math:`F = \lambda\sum_i s_i f_{z,i}`, and the share is
      :math:`-\sum_i s_i\delta_i / \sum_i s_i (f_{z,i} + \delta_i)`.

    What it is
        An *estimate*, first order in the squeeze's error, for the same contact and stick
        sets. On 32 pulls of 4 rough scenes (N = 32 and 64, squeeze tolerances 1e-4 to 1e-10,
        both laws, ``inverse`` at 1e-10) it was 0.999 to 1.01 times the true error against a
        squeeze and pull at 1e-13, also where the break order differed. A site wrongly in or
        out of contact is not seen.
    """
    delta = squeeze_correction(normal, tol=tol).ravel()
    fz = normal.fz.ravel()
    if LAWS.get(result.slip_law).slides:  # F = sum of w_i f_z,i, w_i = s_i |w_i|
        s = np.sign(np.asarray(result.peak.fx).ravel())
        total = float((s * (fz + delta)).sum())
        return -float((s * delta).sum()) / total if total else 0.0
    if result.peak_event == 0:
        return 0.0
    k = int(result.curve.site[result.peak_event])
    return -float(delta[k]) / float(fz[k] + delta[k])


#: seed of the fixed Lanczos start vector: the estimate is a pure function of the bonds
LANCZOS_SEED = 20030101


def bond_spectrum(normal: NormalResult, *, rtol: float = 1e-2, threads: int | None = None
                  ) -> tuple[float, float]:
    r"""Estimates :math:`(\theta_{\min}, \theta_{\max})` of the extreme eigenvalues of
    :math:`A_0 = G_{xx}[S_0,S_0]` on the bonds :math:`S_0` of a squeeze.

    Small sets (at most 500 bonds) use a dense symmetric eigensolver (exact to rounding);
    larger ones Lanczos (ARPACK) on the FFT operator, started from a fixed, seeded vector
    (:data:`LANCZOS_SEED`), so that the result is bitwise reproducible for a given thread
    count and FFT backend.

    What is an estimate and what is a bound
        *Estimate.* Every Ritz value is a Rayleigh quotient of :math:`A_0`, hence
        :math:`\lambda_{\min} \le \theta_{\min}` and :math:`\theta_{\max} \le
        \lambda_{\max}`: the estimate :math:`\hat\kappa = \theta_{\max}/\theta_{\min}`
        never exceeds the true condition number :math:`\kappa(A_0)`. How far below it lies is
        not bounded rigorously: ARPACK's ``tol`` bounds the Ritz residual
        :math:`\|A_0y-\theta y\| \le` ``rtol`` :math:`|\theta|`, which places *an*
        eigenvalue within ``rtol`` :math:`|\theta|` of :math:`\theta`, not necessarily the
        extreme one. Measured against dense eigenvalues (tests): within ``rtol``.

        *Bound (exact eigenvalues).* For every stick set :math:`S \subseteq S_0` the pull
        visits, :math:`\kappa(G_{xx}[S,S]) \le \kappa(A_0)`. Proof: :math:`G_{xx}[S,S]` is a
        principal submatrix of the symmetric positive definite :math:`A_0`. For
        :math:`x \ne 0` supported on :math:`S`, with :math:`\tilde x` its extension by zeros,
        :math:`x^T G_{xx}[S,S] x / x^T x = \tilde x^T A_0 \tilde x / \tilde x^T\tilde x
        \in [\lambda_{\min}(A_0), \lambda_{\max}(A_0)]`, so every eigenvalue of
        :math:`G_{xx}[S,S]` (a Rayleigh quotient at its eigenvector) lies in that interval
        (Cauchy interlacing, e.g. Horn & Johnson, *Matrix Analysis*, 2nd ed. 2013,
        Thm. 4.3.28). Then for :math:`G\varphi = 1_S` solved with residual :math:`r`,
        :math:`\|\delta\varphi\|/\|\varphi\| \le \kappa\,\|r\|/\|1_S\|`, and the
        same holds for :math:`\sum_S\varphi`: :math:`|1^T\delta\varphi| =
        |\varphi^T r| \le \|\varphi\|\|r\|`, :math:`\|\varphi\| \le
        \sqrt{n}/\lambda_{\min}` and :math:`\sum\varphi = 1^T G^{-1} 1 \ge
        n/\lambda_{\max}`.

        ``pull(..., estimate_error=True)`` multiplies :math:`\hat\kappa` by the worst
        certified residual: an *estimate* of that bound.

    Measured on a rough surface (H = 0.8, :math:`\nu = 0.3`): 3 275 bonds, estimate 64
    (dense: 64.3); 52 259 bonds, estimate 231, about 930 operator applications.

    Returns
    -------
    (theta_min, theta_max) : tuple of float
        Dense eigenvalues (small sets) or Ritz values converged to ``rtol``.

    Raises
    ------
    NumericalError
        When Lanczos does not converge or the smallest estimate is not positive.
    """
    from scipy.sparse.linalg import ArpackError, ArpackNoConvergence, eigsh

    b = Bonds(normal, 1.0, threads)
    if b.n == 0:
        raise InputError("bond_spectrum: the squeeze has no contact sites")
    if b.n <= 500:
        with blas_threads(1):
            w = np.linalg.eigvalsh(b.dense())
        lo, hi = float(w[0]), float(w[-1])
    else:
        A = b.restricted()
        v0 = np.random.default_rng(LANCZOS_SEED).standard_normal(b.n)
        try:
            with blas_threads(1):
                hi = float(eigsh(A, k=1, which="LA", tol=rtol, v0=v0,
                                 return_eigenvectors=False)[0])
                lo = float(eigsh(A, k=1, which="SA", tol=rtol, v0=v0,
                                 return_eigenvectors=False)[0])
        except (ArpackError, ArpackNoConvergence) as exc:
            raise NumericalError(f"bond_spectrum: Lanczos did not converge ({exc})") from None
    if not (lo > 0 and math.isfinite(hi)):
        raise NumericalError(f"G_xx on the bonds is not positive definite (smallest "
                             f"eigenvalue estimate {lo:.3e})")
    return lo, hi
