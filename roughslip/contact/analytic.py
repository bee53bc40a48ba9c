r"""Exact solutions of a rigid indenter on an elastic half-space, in one place.

The scenes ``roughslip verify``, the tests and the scripts compare with
(docs/methods.rst#exact-solutions). Each was checked by integrating the point-force solution
over its traction. ``E`` is Young's modulus, ``nu`` Poisson's ratio,
:math:`E^* = E/(1-\nu^2)` and :math:`\mu = E/(2(1+\nu))`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


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
