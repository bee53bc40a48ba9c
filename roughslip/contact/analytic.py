r"""Exact solutions of a rigid indenter on an elastic half-space, in one place.

The scenes ``roughslip verify``, the tests and the scripts compare with
(docs/methods.rst#exact-solutions). Each closed form was checked by integrating the
point-force solution over its traction; the stick fraction of frictional plane indentation
(:func:`plane_indentation_stick_ratio`) is the numerical solution of a singular integral
equation, converged to about 1e-5, and that of the frictional sphere
(:func:`sphere_indentation_friction`) an axisymmetric ring-element solution, to about 2e-5.
``E`` is Young's modulus, ``nu`` Poisson's ratio,
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


# --------------------------------------------------------------------------------------------
# Spence's frictional sphere: an axisymmetric ring-element solution
# --------------------------------------------------------------------------------------------

_GAUSS = np.polynomial.legendre.leggauss(16)


def _rings(r: float, lo: np.ndarray, hi: np.ndarray, near: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    r""":math:`\int s\,I_{00}(r, s)\,ds` and :math:`\int s\,I_{11}(r, s)\,ds` over the
    elements ``[lo, hi]``: the ring kernels of the normal and the radial response,
    :math:`I_{nn}(r, s) = \int_0^\infty J_n(tr)J_n(ts)\,dt` (closed forms in complete elliptic
    integrals of modulus :math:`k^2 = 4rs/(r+s)^2`). Their logarithmic singularity at
    :math:`s = r` is integrated on pieces that shrink geometrically towards it in the
    elements flagged ``near``."""
    from scipy.special import ellipe, ellipkm1

    x, w = _GAUSS

    def kernels(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = ((r - s) / (r + s)) ** 2  # 1 - k^2
        K, E = ellipkm1(p), ellipe(1.0 - p)
        k = np.sqrt(1.0 - p)
        i00 = 2.0 * K / (math.pi * (r + s))
        i11 = 2.0 / (math.pi * k * np.sqrt(r * s)) * ((1.0 - (1.0 - p) / 2.0) * K - E)
        return s * i00, s * i11

    def gauss(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = 0.5 * (b - a)[:, None] * x + 0.5 * (b + a)[:, None]
        f0, f1 = kernels(s)
        half = 0.5 * (b - a)
        return half * (f0 @ w), half * (f1 @ w)

    zz, rr = gauss(lo, hi)
    for j in np.flatnonzero(near):
        a, b = float(lo[j]), float(hi[j])
        pieces = [(a, b)] if not a < r < b else [(a, r), (r, b)]
        z = t = 0.0
        for pa, pb in pieces:
            toward_a = abs(pa - r) < abs(pb - r)  # the singular end
            cuts = (pb - pa) * 0.2 ** np.arange(10, -1, -1)  # 0.2^10 ... 1 of the length
            ends = np.concatenate([[0.0], cuts])
            e0, e1 = ends[:-1], ends[1:]
            sa, sb = (pa + e0, pa + e1) if toward_a else (pb - e1, pb - e0)
            g0, g1 = gauss(sa, sb)
            z, t = z + g0.sum(), t + g1.sum()
        zz[j], rr[j] = z, t
    return zz, rr


def _punch_mesh(k: float, n: int) -> np.ndarray:
    """Ring-element nodes on the unit disc: ``n`` elements in the stick zone ``r < k``,
    finer towards ``k``, and ``2n`` in the slip zone, finer towards both of its ends."""
    t = np.linspace(0.0, 1.0, n + 1)
    stick = k * np.sin(0.5 * math.pi * t)
    t = np.linspace(0.0, 1.0, 2 * n + 1)
    slip = k + (1.0 - k) * (1.0 - np.cos(math.pi * t)) / 2.0
    return np.concatenate([stick, slip[1:]])


def _punch_slip_start(lam: float, n: int, A: tuple) -> float:
    """The radial displacement rate just outside the ``n`` stick elements of the incremental
    flat-punch problem (:func:`sphere_indentation_friction`) with the collocation matrices
    ``A`` (:func:`_punch_matrices`), for friction ``lam``."""
    Azz, Azr, Arz, Arr = A
    m = Azz.shape[0]
    M = np.zeros((2 * m, 2 * m))
    rhs = np.zeros(2 * m)
    M[:m, :m], M[:m, m:], rhs[:m] = Azz, Azr, 1.0
    M[m:m + n, :m], M[m:m + n, m:] = Arz[:n], Arr[:n]  # stick: no radial displacement
    slip = np.arange(n, m)
    M[m + slip, m + slip], M[m + slip, slip] = 1.0, -lam  # slip: q = lam p
    x = np.linalg.solve(M, rhs)
    return float(Arz[n] @ x[:m] + Arr[n] @ x[m:])


def _punch_matrices(nodes: np.ndarray, nu: float, feedback: bool = True) -> tuple:
    r"""Collocation matrices (element centres, piecewise constant tractions, :math:`G = 1`)
    of the axisymmetric half-space: :math:`u_z` and :math:`u_r` from the pressure :math:`p`
    and the outward shear :math:`q`. The normal and the radial responses are
    :math:`u_z = \frac{1-\nu}{G}\int s\,p\,I_{00}\,ds`, :math:`u_r = \frac{1-\nu}{G}\int
    s\,q\,I_{11}\,ds`: Cerruti's symbol is :math:`(\delta_{ij} - \nu k_ik_j/k^2)/(Gk)`, so a
    radial load, parallel to :math:`\mathbf k`, feels :math:`(1-\nu)/(Gk)`, as the pressure
    does. The coupling is :math:`u_z(r) = -\frac{1-2\nu}{2G}\int_r^\infty q\,ds` and
    :math:`u_r(r) = -\frac{1-2\nu}{2G}\,\frac1r\int_0^r s\,p\,ds` (the axisymmetric
    Boussinesq and Cerruti solutions, [Johnson1985] ch. 3; ``feedback=False`` drops the
    first, Goodman's approximation)."""
    lo, hi = nodes[:-1], nodes[1:]
    rc = 0.5 * (lo + hi)
    m = rc.size
    c1, c2 = 1.0 - nu, (1.0 - 2.0 * nu) / 2.0
    Azz, Arr = np.empty((m, m)), np.empty((m, m))
    for i, r in enumerate(rc):
        near = np.maximum(np.maximum(lo - r, r - hi), 0.0) < 2.0 * (hi - lo)
        zz, rr = _rings(float(r), lo, hi, near)
        Azz[i], Arr[i] = c1 * zz, c1 * rr
    Azr = -c2 * np.maximum(hi[None, :] - np.maximum(lo[None, :], rc[:, None]), 0.0)
    Arz = -c2 / rc[:, None] * np.maximum(np.minimum(hi[None, :], rc[:, None]) ** 2
                                         - lo[None, :] ** 2, 0.0) / 2.0
    return Azz, (Azr if feedback else 0.0 * Azr), Arz, Arr


def sphere_indentation_friction(stick_ratio: float, nu: float = 0.0, n: int = 40,
                                feedback: bool = True) -> float:
    r"""The friction coefficient at which a rigid sphere pressed monotonically into an
    elastic half-space keeps a stick zone of radius ``stick_ratio`` times the contact radius
    (Spence's frictional Hertz problem, [Spence1975]), with the shear's feedback on the
    pressure.

    Self-similarity makes the loading increment the problem of a flat circular punch
    ([Spence1975]): under a uniform normal displacement increment on the unit disc, the
    stick zone :math:`r < c` has no radial displacement increment and the slip annulus
    carries :math:`q = \lambda p` outwards. Among the stick radii, the one that meets the slip
    zone without a singular shear is the one whose slip starts from zero at :math:`r = c`;
    for a given :math:`c` that fixes :math:`\lambda`. Here the punch is solved by axisymmetric
    ring elements (``n`` piecewise constant elements in the stick zone and ``2n`` in the slip
    zone, collocated at their centres; the normal and radial responses from ring kernels in
    complete elliptic integrals, and the exact axisymmetric coupling terms), the root in
    :math:`\lambda` found by bisection, and the values at ``n`` and ``2n`` extrapolated
    (the root converges as :math:`1/n`). At :math:`\nu = 0` and :math:`c/a = 1/2` it gives
    0.29871 (Spence's 0.2986); without the feedback it gives Goodman's closed form
    :math:`\lambda/\beta = \operatorname{artanh}(k)/(k K(\sqrt{1-k^2}))` to
    :math:`2\times 10^{-5}` (a test), with :math:`k = c/a`, :math:`K(m)` the complete
    elliptic integral of the first kind of modulus :math:`m`, and
    :math:`\beta = (1-2\nu)/(2(1-\nu))`.
    """
    from scipy import optimize

    k = float(stick_ratio)
    if not (0.0 < k < 1.0):
        raise ValueError(f"stick_ratio = {stick_ratio!r}: must lie strictly between 0 and 1")
    if not (-1.0 < nu < 0.5):
        raise ValueError(f"nu = {nu!r}: needs -1 < nu < 1/2 (at 1/2 nothing couples)")

    def root(m: int) -> float:
        A = _punch_matrices(_punch_mesh(k, m), nu, feedback)
        return optimize.brentq(lambda lam: _punch_slip_start(lam, m, A), 1e-4, 20.0,
                               xtol=1e-13)

    l1, l2 = root(n), root(2 * n)
    return 2.0 * l2 - l1


def sphere_indentation_stick_ratio(lam: float, nu: float = 0.0, n: int = 40) -> float:
    r"""The stick fraction :math:`c/a` of Spence's frictional sphere at friction ``lam``
    (the inverse of :func:`sphere_indentation_friction`, by bisection in :math:`c/a`)."""
    from scipy import optimize

    if not (math.isfinite(lam) and lam > 0):
        raise ValueError(f"lam = {lam!r}: must be a finite number > 0")
    lo, hi = (sphere_indentation_friction(k, nu, n) for k in (1e-3, 0.99))
    if not lo < lam < hi:
        raise ValueError(f"lam = {lam!r}: c/a lies outside 0.001 to 0.99 (lam from {lo:.4g} "
                         f"to {hi:.4g} at nu = {nu:g})")
    return optimize.brentq(lambda k: sphere_indentation_friction(k, nu, n) - lam, 1e-3,
                           0.99, xtol=1e-7)
