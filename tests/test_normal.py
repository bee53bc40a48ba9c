"""The squeeze against closed-form solutions (docs/methods.rst#exact-solutions) and invariances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from roughslip.contact.analytic import flat_punch_force, hertz, westergaard
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver, squeeze
from roughslip.elastic.boundaries import BOUNDARIES
from roughslip.elastic.operators import Grid, Material
from roughslip.errors import ConvergenceError, InputError
from roughslip.surfaces.synthetic import punch, sample_rng, self_affine, sinusoid, sphere

E, NU = 1.0, 0.0


def hertz_run(a_over_h: int, corner: bool, method: str = "pk"):
    """Hertz sphere R = 1 at true approach d = 1/16 (docs/methods.rst#hertz)."""
    R, d = 1.0, 1 / 16
    ac = math.sqrt(R * d)
    h = ac / a_over_h
    n = math.ceil(2.4 * ac / h)
    n += (n % 2) if corner else (1 - n % 2)  # even: apex on a pixel corner
    heights = sphere((n, n), radius=R, a=h)
    # depth is measured from the highest pixel, which sits below the apex when it is a corner
    r = squeeze(heights, depth=d + heights.max(), a=h, E=E, nu=NU, method=method, tol=1e-10)
    exact = hertz(R, d, E, NU)
    return r, exact.force, exact.p0, exact.radius, h


@pytest.mark.parametrize("corner", [True, False])
def test_hertz_force_and_pressure_converge_at_second_order(corner):
    errs = []
    for ah in (8, 16):
        r, F, p0, ac, h = hertz_run(ah, corner)
        assert r.converged and r.residual <= 1e-10
        ferr = (r.normal_force - F) / F
        perr = (r.fz.max() / h**2 - p0) / p0
        assert abs(ferr) < 2e-3, f"Hertz total force off by {ferr:.2e} at a/h = {ah}"
        assert abs(perr) < 5e-3, f"Hertz central pressure off by {perr:.2e} at a/h = {ah}"
        # contact radius from the pixel count: first order and erratic, within one pixel
        a_eq = math.sqrt(r.n_contact * h * h / math.pi)
        assert abs(a_eq - ac) < h, f"Hertz contact radius {a_eq:.4f} vs {ac:.4f}"
        errs.append((ferr, perr))
    # second order: halving h divides the errors by ~4 (docs/methods.rst#hertz: 4.7, 4.1 and 3.3,
    # 4.1)
    assert 2.5 < errs[0][0] / errs[1][0] < 6.0
    if corner:
        assert 3.0 < errs[0][1] / errs[1][1] < 5.5


def test_hertz_reference_numbers_of_green():
    """docs/methods.rst#hertz, apex at a pixel corner: +1.6e-3 (a/h = 8) and +3.4e-4 (a/h = 16)."""
    r8, F, *_ = hertz_run(8, True)
    r16, *_ = hertz_run(16, True)
    assert (r8.normal_force - F) / F == pytest.approx(1.6e-3, rel=0.05)
    assert (r16.normal_force - F) / F == pytest.approx(3.4e-4, rel=0.05)


@pytest.mark.parametrize("method", ["pk", "active-set"])
@pytest.mark.parametrize("a_over_h", [8, 16])
def test_flat_punch_stiffness(method, a_over_h):
    """Boussinesq punch: F = 2 a E* d, error ~ -0.12 h/a against a_eq
    (docs/methods.rst#flat-punch)."""
    radius, d = 1.0, 1e-3
    h = radius / a_over_h
    n = 2 * a_over_h + 2
    heights = punch((n, n), radius=radius, a=h)
    r = squeeze(heights, depth=d, a=h, E=E, nu=NU, method=method, tol=1e-10)
    assert r.converged, r.message
    a_eq = math.sqrt(r.n_contact * h * h / math.pi)
    F = flat_punch_force(a_eq, d, E, NU)
    err = (r.normal_force - F) / F
    assert abs(err) < 0.2 * h / radius, f"punch stiffness off by {err:.2e}"
    assert err < 0  # the staircase edge is softer than the disc
    assert r.n_contact == np.count_nonzero(heights == 0)  # the whole face touches


@pytest.mark.parametrize("kind", ["pixel", "continuous"])
@pytest.mark.parametrize("ratio", [0.2, 0.6])
def test_westergaard_wavy_surface_periodic(kind, ratio):
    """Periodic 1-D wavy surface under load control (docs/methods.rst#westergaard)."""
    n, lam, amp = 64, 1.0, 0.01
    a = lam / n
    heights = sinusoid((4, n), amplitude=amp, wavelength=lam, a=a)
    pbar = ratio * westergaard(0.0, amp, lam, E, NU).p_star
    exact = westergaard(pbar, amp, lam, E, NU)
    F = pbar * (4 * n) * a * a
    r = squeeze(heights, force=F, a=a, E=E, nu=NU, boundary="periodic", periodic_kernel=kind,
                tol=1e-10)
    assert r.converged and r.force_error < 1e-12
    crest = exact.crest_pressure
    got = r.fz[:, 0].mean() / a**2
    assert abs(got - crest) / crest < 5e-3, f"crest pressure {got} vs Westergaard {crest}"
    frac = exact.contact_fraction
    assert abs(r.contact_area - frac) <= 2.5 / n, "contact fraction beyond +-1 pixel per edge"


def test_westergaard_full_contact():
    n, amp = 32, 0.01
    a = 1.0 / n
    heights = sinusoid((2, n), amplitude=amp, wavelength=1.0, a=a)
    p_star = westergaard(0.0, amp, 1.0, E, NU).p_star
    pbar = 1.5 * p_star
    assert westergaard(pbar, amp, 1.0, E, NU).contact_fraction == 1.0
    r = squeeze(heights, force=pbar * 2 * n * a * a, a=a, E=E, nu=NU, boundary="periodic")
    assert r.contact_area == 1.0
    x = np.arange(n) * a
    # complete contact: p = pbar + p* cos(2 pi x / lam) up to the discretisation
    p = r.fz[0] / a**2
    assert np.allclose(p, pbar + p_star * np.cos(2 * np.pi * x), rtol=0, atol=1e-2 * p_star)


@pytest.fixture(scope="module")
def rough():
    return self_affine((48, 40), hurst=0.8, rms_height=1.0, rng=sample_rng(3, 0))


@pytest.mark.parametrize("boundary", BOUNDARIES.names())
def test_pk_and_active_set_agree_on_rough_surfaces(rough, boundary):
    h = rough
    # a periodic grid's force diverges as the mean gap closes: less deep there
    depth = 1.0 if math.isinf(BOUNDARIES.get(boundary).depth_limit(h.max(), h.mean())) else 0.6
    pk = squeeze(h, depth=depth, boundary=boundary, method="pk", tol=1e-11)
    ac = squeeze(h, depth=depth, boundary=boundary, method="active-set", tol=1e-11)
    assert pk.converged and ac.converged, (pk.message, ac.message)
    assert np.array_equal(pk.contact, ac.contact)
    assert pk.normal_force == pytest.approx(ac.normal_force, rel=1e-9)
    assert np.max(np.abs(pk.fz - ac.fz)) < 1e-8 * np.max(pk.fz)
    assert 0.02 < pk.contact_area < 0.5


def test_load_control_inverts_displacement_control(rough):
    for method in ("pk", "active-set"):
        d = squeeze(rough, depth=0.8, method=method)
        f = squeeze(rough, force=d.normal_force, method=method, tol=1e-11)
        assert f.converged and f.control == "force"
        assert f.depth == pytest.approx(0.8, rel=1e-7)
        assert f.normal_force == pytest.approx(d.normal_force, rel=1e-12)
        assert np.array_equal(f.contact, d.contact)


def test_scaling_of_heights_depth_and_modulus(rough):
    base = squeeze(rough, depth=0.7, E=1.0)
    for s in (1e-9, 1e-3, 37.0, 1e3):
        r = squeeze(rough * s, depth=0.7 * s, E=1.0)
        assert r.normal_force == pytest.approx(s * base.normal_force, rel=1e-8)
        assert np.array_equal(r.contact, base.contact)
    for s in (1e-6, 2.5, 1e12):
        r = squeeze(rough, depth=0.7, E=s)
        assert r.normal_force == pytest.approx(s * base.normal_force, rel=1e-9)
        assert np.array_equal(r.contact, base.contact)


def test_translation_of_the_surface_changes_nothing(rough):
    base = squeeze(rough, depth=0.7)
    r = squeeze(rough + 123.0, depth=0.7)
    assert r.normal_force == pytest.approx(base.normal_force, rel=1e-10)


def test_zero_depth_and_zero_force(rough):
    for r in (squeeze(rough, depth=0.0), squeeze(rough, depth=-1.0), squeeze(rough, force=0.0)):
        assert r.converged and r.normal_force == 0.0 and not r.contact.any()
        assert np.all(r.gap >= 0) and np.all(np.isfinite(r.gap))


def test_single_contact_site_at_first_touch(rough):
    r = squeeze(rough, depth=1e-9)
    assert r.n_contact == 1
    assert r.fz.flat[np.argmax(rough)] == pytest.approx(1e-9 / r.uz.max() * r.fz.max())


def test_full_contact_open_and_periodic():
    h = self_affine((12, 12), hurst=0.7, rms_height=1.0, rng=sample_rng(4, 0))
    rng_ = h.max() - h.min()
    r = squeeze(h, depth=20 * rng_)  # open: the patch edges need depth well beyond the range
    assert r.converged and r.contact.all()
    hp = self_affine((16, 16), hurst=0.7, rms_height=1.0, rng=sample_rng(4, 1))
    r = squeeze(hp, force=20.0 * hp.size, boundary="periodic")  # mean pressure 20 E
    assert r.converged and r.contact.all()
    assert r.depth == pytest.approx(hp.max() - hp.mean(), rel=1e-9)


def test_periodic_displacement_control_limit():
    h = self_affine((16, 16), hurst=0.7, rms_height=1.0, rng=sample_rng(4, 1))
    with pytest.raises(InputError, match="periodic grid displacement control"):
        squeeze(h, depth=h.max() - h.mean(), boundary="periodic")


def test_warm_start_gives_the_same_answer(rough):
    shallow = squeeze(rough, depth=0.5)
    cold = squeeze(rough, depth=0.9)
    warm = squeeze(rough, depth=0.9, x0=shallow.fz)
    assert np.array_equal(cold.contact, warm.contact)
    assert warm.normal_force == pytest.approx(cold.normal_force, rel=1e-9)


def test_max_iter_reports_instead_of_hiding(rough):
    r = squeeze(rough, depth=1.0, max_iter=3)
    assert not r.converged and "max_iter" in r.message
    assert np.all(np.isfinite(r.fz)) and r.residual > 1e-10
    with pytest.raises(ConvergenceError, match="did not converge"):
        squeeze(rough, depth=1.0, max_iter=3, strict=True)


def test_tiny_grids_and_strips():
    r = squeeze(np.zeros((1, 1)), depth=0.5, E=2.0, nu=0.25)
    g00 = 4 * math.log(1 + math.sqrt(2)) * (1 - 0.25**2) / (math.pi * 2.0)
    assert r.normal_force == pytest.approx(0.5 / g00, rel=1e-12)
    strip = sinusoid((1, 97), amplitude=1.0, wavelength=30.0)
    for method in ("pk", "active-set"):
        r = squeeze(strip, depth=0.5, method=method)
        assert r.converged and 0 < r.n_contact < 97
    r2 = squeeze(np.zeros((2, 2)), depth=1.0)
    assert r2.contact.all() and np.allclose(r2.fz, r2.fz[0, 0])


def test_active_set_reports_penetration_check(rough):
    r = squeeze(rough, depth=0.9, method="active-set")
    assert r.penetration <= 1e-10 and "penetration" not in r.message


def test_bad_input():
    with pytest.raises(InputError, match="non-finite"):
        squeeze(np.array([[0.0, np.nan]]), depth=1.0)
    with pytest.raises(InputError, match="2-D"):
        squeeze(np.zeros(5), depth=1.0)
    with pytest.raises(InputError, match="exactly one"):
        squeeze(np.zeros((3, 3)), depth=1.0, force=1.0)
    with pytest.raises(InputError, match="force"):
        squeeze(np.zeros((3, 3)), force=-1.0)
    with pytest.raises(InputError, match="method"):
        squeeze(np.zeros((3, 3)), depth=1.0, method="newton")
    with pytest.raises(InputError, match="depth"):
        squeeze(np.zeros((3, 3)), depth=float("nan"))
    with pytest.raises(InputError, match="periodic 1x1"):
        squeeze(np.zeros((1, 1)), depth=1.0, boundary="periodic")


def test_solver_settings_changed_after_construction_apply_to_the_next_solve():
    s = NormalSolver(Problem(sphere((32, 32), radius=40.0)))
    tight = s.solve(depth=0.3)
    s.tol = 1e-3
    loose = s.solve(depth=0.3)
    assert loose.iterations < tight.iterations and loose.residual <= 1e-3
    s.max_iter = 2
    assert not s.solve(depth=0.3).converged


def test_solver_reuse_records_work():
    h = sphere((32, 32), radius=20.0)
    s = NormalSolver(Problem(h, Grid((32, 32)), Material(1.0, 0.3)))
    r = s.solve(depth=0.5)
    assert r.convolutions >= r.iterations > 0 and r.fft_seconds > 0 and r.seconds > 0
    assert r.grid.shape == (32, 32) and r.material.nu == 0.3


# ------------------------------------------------------------------------------ error estimate


@pytest.mark.parametrize("control", ["depth", "force"])
@pytest.mark.parametrize("method", ["pk", "active-set"])
def test_squeeze_correction_recovers_the_tight_solution(control, method):
    """f + delta is far closer to the tight solution than f (same contact set): the correction
    is the error of the loose solve, to the correction solve's tolerance."""
    from roughslip.analysis.verify import hertz_scene
    from roughslip.contact.estimates import squeeze_correction, squeeze_error_estimate

    heights, h, depth, _ = hertz_scene(16)
    kw = {"depth": depth} if control == "depth" else {"force": 0.01}
    ref = squeeze(heights, a=h, nu=0.0, tol=1e-13, **kw)
    loose = squeeze(heights, a=h, nu=0.0, method=method, tol=1e-5, **kw)
    assert np.array_equal(loose.contact, ref.contact)
    delta = squeeze_correction(loose)
    err = np.linalg.norm(loose.fz - ref.fz)
    assert err > 1e-12 * np.linalg.norm(ref.fz)
    assert np.linalg.norm(loose.fz + delta - ref.fz) < 0.05 * err
    assert np.all(delta[~loose.contact] == 0)
    est = squeeze_error_estimate(loose)
    if control == "force":
        assert est == 0.0 and abs(delta.sum()) < 1e-12 * loose.normal_force  # F_n is held
    else:
        true = abs(loose.normal_force - ref.normal_force) / ref.normal_force
        assert true / 2 <= est <= 2 * true


def test_squeeze_correction_refuses_full_periodic_contact_under_load():
    """Full contact on a periodic grid leaves the depth undefined by F_n: a clear error, not
    NaN."""
    from roughslip.contact.estimates import squeeze_correction
    from roughslip.errors import NumericalError

    h = sinusoid((4, 32), amplitude=0.01, wavelength=1.0, a=1 / 32)
    p_star = westergaard(0.0, 0.01, 1.0, E=1.0, nu=0.0).p_star
    r = squeeze(h, force=2 * p_star * 4 / 32, a=1 / 32, E=1.0, nu=0.0, boundary="periodic")
    assert r.contact.all()
    with pytest.raises(NumericalError, match="full contact on a periodic grid"):
        squeeze_correction(r)
