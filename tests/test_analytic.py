"""The exact solutions module: identities between the forms the literature states."""

from __future__ import annotations

import math

import numpy as np
import pytest

from roughslip.contact import analytic as A


def test_hertz_identities():
    R, d, E, nu = 2.0, 0.01, 3.0, 0.25
    h = A.hertz(R, d, E, nu)
    es = E / (1 - nu * nu)
    assert h.force == pytest.approx(4 * es * h.radius**3 / (3 * R), rel=1e-14)
    assert h.p0 == pytest.approx(3 * h.force / (2 * math.pi * h.radius**2), rel=1e-14)
    assert h.radius**2 / R == pytest.approx(d, rel=1e-14)


def test_westergaard_limits():
    amp, lam = 0.01, 2.0
    p_star = A.westergaard(0.0, amp, lam).p_star
    assert p_star == pytest.approx(math.pi * A.e_star() * amp / lam)
    near = A.westergaard(p_star * (1 - 1e-12), amp, lam)
    full = A.westergaard(p_star, amp, lam)
    assert near.contact_fraction == pytest.approx(1.0, abs=1e-5)
    assert near.crest_pressure == pytest.approx(full.crest_pressure, rel=1e-5)  # continuous
    assert A.westergaard(0.0, amp, lam).contact_fraction == 0.0


def test_cattaneo_mindlin_limits_and_the_mindlin_stiffness():
    P, a, lam, E, nu = 2.0, 0.5, 0.3, 1.0, 0.3
    cm = A.cattaneo_mindlin(P, a, lam, E, nu)
    assert cm.force(0.0) == 0.0 and cm.force(cm.delta_s) == pytest.approx(lam * P)
    assert cm.force(2 * cm.delta_s) == pytest.approx(lam * P)  # gross sliding
    assert cm.stick_radius(0.0) == a and cm.stick_radius(lam * P) == 0.0
    # initial slope dQ/ddelta = 3 lam P / (2 delta_s) = 8 mu a / (2 - nu): Mindlin's stiffness
    slope = 1.5 * lam * P / cm.delta_s
    assert slope == pytest.approx(A.mindlin_bonded_punch_stiffness(a, E, nu), rel=1e-14)
    G = A.shear_modulus(E, 0.5)
    assert A.mindlin_bonded_punch_stiffness(a, E, 0.5) == pytest.approx(16 / 3 * G * a)


def test_plane_indentation_stick_ratio_converges_and_spans_no_stick_to_full_stick():
    """The stick fraction of the frictional plane indentation in the uncoupled-pressure limit:
    the collocation converges (n = 40 and 80 give the same Richardson value to 5e-4), c/a
    grows with lam / beta, with no stick zone at lam / beta = 0.2 and a stuck contact at 3."""
    from roughslip.contact.analytic import plane_indentation_stick_ratio

    ratios = [0.4, 0.6, 1.0, 1.5]
    k80 = [plane_indentation_stick_ratio(r) for r in ratios]
    k40 = [plane_indentation_stick_ratio(r, n=40) for r in ratios]
    assert np.allclose(k40, k80, rtol=0, atol=5e-4)
    assert np.all(np.diff(k80) > 0) and 0 < k80[0] and k80[-1] < 1
    assert plane_indentation_stick_ratio(0.2) == 0.0
    assert plane_indentation_stick_ratio(3.0) == 1.0
    with pytest.raises(ValueError, match="lam_over_beta"):
        plane_indentation_stick_ratio(-1.0)


def test_sphere_indentation_reference():
    """Spence's sphere by ring elements: without the shear's feedback on the pressure it is
    Goodman's closed form, lam/beta = artanh(k) / (k K'(k)), to 2e-5 at k = 0.2 and 0.5;
    with it, c/a = 1/2 needs lam = 0.2986 at nu = 0 (Spence's value, quoted to four
    figures), and the extrapolations from 20 and 40 elements agree to 2e-4."""
    from scipy.special import ellipk

    from roughslip.contact.analytic import (
        sphere_indentation_friction,
        sphere_indentation_stick_ratio,
    )

    for k in (0.2, 0.5):
        goodman = 0.5 * math.atanh(k) / (k * float(ellipk(1 - k * k)))
        assert sphere_indentation_friction(k, feedback=False) == pytest.approx(goodman,
                                                                              abs=2e-5)
    lam = sphere_indentation_friction(0.5)
    assert lam == pytest.approx(0.2986, abs=2e-4)
    assert sphere_indentation_friction(0.5, n=20) == pytest.approx(lam, abs=2e-4)
    coarse = sphere_indentation_friction(0.5, n=10)
    assert sphere_indentation_stick_ratio(coarse, n=10) == pytest.approx(0.5, abs=1e-6)
    with pytest.raises(ValueError, match=r"lam = 5\.0: c/a lies outside"):
        sphere_indentation_stick_ratio(5.0, n=10)
    # more friction, a larger stick zone; a less compressible solid, less shear
    assert sphere_indentation_friction(0.7) > lam > sphere_indentation_friction(0.3)
    assert sphere_indentation_friction(0.5, nu=0.3) < lam
    with pytest.raises(ValueError, match="stick_ratio"):
        sphere_indentation_friction(1.0)
    with pytest.raises(ValueError, match=r"nu = 0\.5"):
        sphere_indentation_friction(0.5, nu=0.5)
