"""The Cattaneo-Mindlin check of a Coulomb pull of a Hertz contact, shared by the x-only and
the traction-vector tests (docs/methods.rst#cattaneo-mindlin)."""

from __future__ import annotations

import math

from roughslip.contact.analytic import cattaneo_mindlin
from roughslip.friction.pull import coulomb_force_at


def assert_cattaneo_mindlin(res, P: float, ac: float, h: float, lam: float, nu: float) -> None:
    """The pull force along the drive and the stick radius at delta/delta_s = 0.3 and 0.7
    against the exact solution: the force within 3e-3 lambda P, the radius of the stick
    sites' equal area within 1.5 pixels."""
    cm = cattaneo_mindlin(P, ac, lam, nu=nu)
    for frac in (0.3, 0.7):
        q = float(coulomb_force_at(res, frac * cm.delta_s))
        q_exact = cm.force(frac * cm.delta_s)
        assert abs(q - q_exact) / (lam * P) < 3e-3, "Cattaneo-Mindlin tangential force"
        stick = int((res.curve.dx[1:] > frac * cm.delta_s).sum())
        c_eq = math.sqrt(stick * h * h / math.pi)
        assert abs(c_eq - cm.stick_radius(q_exact)) < 1.5 * h, "Cattaneo-Mindlin stick radius"
