r"""Exact solutions of a rigid indenter on an elastic half-space, in one place.

The scenes ``roughslip verify``, the tests and the scripts compare with
(docs/methods.rst#exact-solutions). Each closed form was checked by integrating the
point-force solution over its traction; the stick fraction of frictional plane indentation
(:func:`plane_indentation_stick_ratio`) is the numerical solution of a singular integral
equation, converged to about 1e-5. ``E`` is Young's modulus, ``nu`` Poisson's ratio,
:math:`E^* = E/(1-\nu^2)` and :math:`\mu = E/(2(1+\nu))`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def e_star(E: float = 1.0, nu: float = 0.3) -> float:
    r""":math:`E^* = E/(1-\nu^2)`, the modulus of a rigid indenter on an elastic half-space."""
    return E / (1.0 - nu * nu)


def shear_modulus(E: float = 1.0, nu: float = 0.3) -> float:
    r""":math:`\mu = E/(2(1+\nu))`."""
    return E / (2.0 * (1.0 + nu))


@dataclass(frozen=True)
class Hertz:
    """Hertz contact of a rigid sphere (docs/methods.rst#hertz)."""

    radius: float  # contact radius a = sqrt(R d)
    force: float  # F = 4/3 E* R^(1/2) d^(3/2)
    p0: float  # central pressure 2 E* a / (pi R)


def hertz(R: float, d: float, E: float = 1.0, nu: float = 0.3) -> Hertz:
    r"""Rigid sphere of radius ``R`` at approach ``d``: :math:`a = \sqrt{Rd}`,
    :math:`F = \tfrac43 E^* R^{1/2} d^{3/2}`, :math:`p_0 = 2E^*a/(\pi R)`
    ([Johnson1985] §4.2)."""
    es = e_star(E, nu)
    a = math.sqrt(R * d)
    return Hertz(a, 4.0 / 3.0 * es * math.sqrt(R) * d**1.5, 2.0 * es * a / (math.pi * R))


def flat_punch_force(a: float, d: float, E: float = 1.0, nu: float = 0.3) -> float:
    r"""Boussinesq's flat circular punch of radius ``a`` at approach ``d``:
    :math:`F = 2aE^*d` (docs/methods.rst#flat-punch)."""
    return 2.0 * a * e_star(E, nu) * d


@dataclass(frozen=True)
class Westergaard:
    """Partial contact of a periodic wavy surface (docs/methods.rst#westergaard)."""

    p_star: float  # mean pressure of complete contact, pi E* amplitude / wavelength
    contact_fraction: float  # 2a/lambda = (2/pi) asin sqrt(pbar/p*)
    crest_pressure: float  # 2 pbar / sin(pi a / lambda)


def westergaard(pbar: float, amplitude: float, wavelength: float, E: float = 1.0,
                nu: float = 0.3) -> Westergaard:
    r"""Rigid surface :math:`\Delta\cos(2\pi x/\lambda)` at mean pressure ``pbar``
    (Westergaard 1939; :math:`\sin^2(\pi a/\lambda) = \bar p/p^*`). Full contact
    (``pbar >= p*``) gives fraction 1 and crest pressure :math:`\bar p + p^*`."""
    p_star = math.pi * e_star(E, nu) * amplitude / wavelength
    ratio = pbar / p_star
    if ratio <= 0.0:
        return Westergaard(p_star, 0.0, 0.0)
    if ratio >= 1.0:
        return Westergaard(p_star, 1.0, pbar + p_star)
    s = math.sqrt(ratio)
    return Westergaard(p_star, 2.0 / math.pi * math.asin(s), 2.0 * pbar / s)


def mindlin_bonded_punch_stiffness(a: float, E: float = 1.0, nu: float = 0.3) -> float:
    r"""Tangential stiffness :math:`Q/\delta = 8\mu a/(2-\nu)` of a bonded rigid punch of radius
    ``a`` (Mindlin 1949; decoupled model, docs/methods.rst#mindlin)."""
    return 8.0 * shear_modulus(E, nu) * a / (2.0 - nu)


@dataclass(frozen=True)
class CattaneoMindlin:
    """Partial slip of a Hertz contact under a tangential shift (docs/methods.rst#cattaneo-mindlin).
    """

    P: float  # normal force
    a: float  # contact radius
    lam: float  # friction coefficient
    delta_s: float  # shift of gross sliding, 3 lam P (2 - nu) / (16 mu a)

    def force(self, delta: float) -> float:
        r""":math:`Q(\delta) = \lambda P[1 - (1 - \delta/\delta_s)^{3/2}]` (``lam P`` beyond
        gross sliding)."""
        t = min(max(delta / self.delta_s, 0.0), 1.0)
        return self.lam * self.P * (1.0 - (1.0 - t) ** 1.5)

    def stick_radius(self, Q: float) -> float:
        r""":math:`c = a(1 - Q/(\lambda P))^{1/3}`."""
        return self.a * (1.0 - Q / (self.lam * self.P)) ** (1.0 / 3.0)


def cattaneo_mindlin(P: float, a: float, lam: float, E: float = 1.0,
                     nu: float = 0.3) -> CattaneoMindlin:
    """The Cattaneo-Mindlin solution for normal force ``P`` on contact radius ``a`` with the
    Coulomb coefficient ``lam`` (exact in the decoupled model with the scalar Coulomb law)."""
    delta_s = 3.0 * lam * P * (2.0 - nu) / (16.0 * shear_modulus(E, nu) * a)
    return CattaneoMindlin(P, a, lam, delta_s)


# ------------------------------------------------------------------------------------------------
# Frictional indentation of a half-plane by a rigid cylinder (the uncoupled-pressure limit)
# ------------------------------------------------------------------------------------------------


def _hilbert_cap(lo: float, hi: float, xi: np.ndarray) -> np.ndarray:
    r""":math:`\int_{lo}^{hi} \sqrt{1-s^2}/(s-\xi)\,ds` for :math:`\xi` outside
    :math:`[lo, hi] \subseteq [-1, 1]`, in closed form: with :math:`1 - s^2 = (1-\xi^2) -
    (s-\xi)(s+\xi)`, the antiderivatives :math:`-\ln|(1-\xi s+r\sqrt{1-s^2})/(s-\xi)|/r`
    (:math:`r = \sqrt{1-\xi^2}`) and :math:`-\sqrt{1-s^2}+\xi\arcsin s`."""
    r = np.sqrt(1.0 - xi * xi)

    def f(s: float) -> np.ndarray:
        root = math.sqrt(max(1.0 - s * s, 0.0))
        return -np.log(np.abs((1.0 - xi * s + r * root) / (s - xi))) / r

    def g(s: float) -> np.ndarray:
        return -math.sqrt(max(1.0 - s * s, 0.0)) + xi * math.asin(s)

    return (1.0 - xi * xi) * (f(hi) - f(lo)) - (g(hi) - g(lo))


def _stick_end_value(k: float, ratio: float, n: int) -> float:
    """The edge value :math:`w(1)` of the bounded part of the stick-zone traction for a
    stick zone ``|xi| < k`` (:func:`plane_indentation_stick_ratio`); zero at the solution."""
    i = np.arange(1, n + 1)
    t = np.cos(i * np.pi / (n + 1))  # Gauss-Chebyshev nodes (second kind)
    x = np.cos((2 * np.arange(1, n + 2) - 1) * np.pi / (2 * n + 2))  # collocation points
    xi = k * x
    pk = math.sqrt(1.0 - k * k)
    # J of the known traction: ratio * sign(s) P(s) outside, the line ratio P(k) s/k inside
    known = ratio * (_hilbert_cap(k, 1.0, xi) - _hilbert_cap(-1.0, -k, xi)
                     + pk * (2.0 * k + xi * np.log((k - xi) / (k + xi))) / k) / np.pi
    A = np.empty((n + 1, n + 1))
    A[:, :n] = ((1.0 - t * t) / (n + 1))[None, :] / (t[None, :] - x[:, None])
    A[:, n] = -k * np.abs(x)
    w = np.linalg.solve(A, np.sqrt(1.0 - xi * xi) - known)[:n]
    coef = np.polynomial.chebyshev.chebfit(t, w, n - 1)
    return float(np.polynomial.chebyshev.chebval(1.0, coef))


def plane_indentation_stick_ratio(lam_over_beta: float, n: int = 80) -> float:
    r"""Stick-zone fraction :math:`c/a` of a rigid parabolic cylinder pressed monotonically
    into an elastic half-plane with Coulomb friction :math:`\lambda`, in the limit where the
    shear does not change the pressure (:math:`\beta\lambda \to 0`,
    :math:`\beta = (1-2\nu)/(2(1-\nu))`); then :math:`c/a` depends on :math:`\lambda/\beta`
    only (the plane problem of [Spence1973], with the pressure uncoupled from the shear as in
    [Goodman1962]).

    Plane strain ([Johnson1985] ch. 2): :math:`\partial u_x/\partial x = -A(\beta p + Hq)`,
    :math:`A = 2(1-\nu^2)/E`, :math:`Hq(x) = \frac1\pi\,\mathrm{PV}\!\int q(s)/(x-s)\,ds`.
    With the Hertz pressure :math:`p = p_0\sqrt{1-\xi^2}` (:math:`\xi = x/a`) and
    :math:`q = \beta p_0 Q`, self-similarity (:math:`u_x = a^2 U(\xi)`) and a stick zone
    :math:`|\xi| < k` that grows with :math:`a` make every stuck point keep the displacement
    it had when it stuck: :math:`U \propto \xi|\xi|` there, so
    :math:`\sqrt{1-\xi^2} + HQ = -\kappa|\xi|` for :math:`|\xi| < k` (:math:`\kappa`
    unknown), while :math:`Q = (\lambda/\beta)\,\mathrm{sign}(\xi)\sqrt{1-\xi^2}` slips
    outwards for :math:`|\xi| > k`. The stick traction is the continuous extension of the
    slip traction plus a part bounded at :math:`\pm k`, solved by Gauss-Chebyshev collocation
    ([ErdoganGupta1972]; ``n`` nodes, the Hilbert transforms of the known parts in closed
    form), which also gives :math:`\kappa`. Among the stick zones, the one where the traction
    meets :math:`\lambda p` without a square-root edge (its bounded part vanishing at
    :math:`\pm k`) is the one admissible on both sides: a larger one exceeds
    :math:`|q| \le \lambda p` inside, a smaller one slips the wrong way just outside (both
    inequalities were evaluated around the root by quadrature when this was written). The
    root in :math:`k` converges as :math:`1/n`; the value returned is the Richardson
    extrapolation from ``n`` and ``2n`` (converged to about :math:`10^{-5}`).

    Returns 0.0 when the stick zone is below 1 % of the contact, 1.0 when above 99.5 %.
    """
    from scipy import optimize

    if not (math.isfinite(lam_over_beta) and lam_over_beta > 0):
        raise ValueError(f"lam_over_beta = {lam_over_beta!r}: must be a finite number > 0")

    def root(m: int) -> float:
        ks = np.linspace(0.01, 0.995, 40)
        vals = [_stick_end_value(k, lam_over_beta, m) for k in ks]
        for a, b, fa, fb in zip(ks[:-1], ks[1:], vals[:-1], vals[1:], strict=True):
            if fa * fb <= 0:
                return optimize.brentq(_stick_end_value, a, b, args=(lam_over_beta, m),
                                       xtol=1e-12)
        return 0.0 if vals[0] > 0 else 1.0

    k1, k2 = root(n), root(2 * n)
    if k1 in (0.0, 1.0) or k2 in (0.0, 1.0):
        return k2
    return 2.0 * k2 - k1
