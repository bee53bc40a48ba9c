"""The pull stage: exact methods against the literal algorithm, closed forms, invariances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from roughslip.analysis.verify import hertz_scene
from roughslip.contact.analytic import mindlin_bonded_punch_stiffness
from roughslip.contact.squeeze import squeeze
from roughslip.errors import InputError, MemoryLimitError
from roughslip.friction.bonds import Bonds as _Bonds
from roughslip.friction.pull import (
    bond_spectrum,
    choose_method,
    coulomb_force_at,
    pull,
    refinement_estimate,
)
from roughslip.linalg import memory
from roughslip.surfaces.synthetic import punch, sample_rng, self_affine, sphere
from tests.mindlin import assert_cattaneo_mindlin


@pytest.fixture(scope="module")
def rough_contact():
    h = self_affine((40, 36), hurst=0.8, rms_height=1.0, rng=sample_rng(11, 0), oversample=2)
    return squeeze(h, depth=1.6, tol=1e-12)


@pytest.fixture(scope="module")
def hertz_contact():
    h = sphere((24, 24), radius=30.0)
    return squeeze(h, depth=2.0, nu=0.25, tol=1e-12)


@pytest.fixture(scope="module")
def literal(rough_contact, hertz_contact):
    return {
        "rough": pull(rough_contact, lam=0.2, method="literal", tol=1e-12),
        "hertz": pull(hertz_contact, lam=0.2, method="literal", tol=1e-12),
    }


@pytest.mark.parametrize("scene", ["rough", "hertz"])
@pytest.mark.parametrize("method", ["inverse", "cg"])
def test_fast_exact_methods_equal_literal(rough_contact, hertz_contact, literal, scene, method):
    normal = rough_contact if scene == "rough" else hertz_contact
    ref = literal[scene]
    assert ref.details.n_bonds > 40 and ref.steps == ref.details.n_bonds
    assert not ref.details.early_stopped
    res = pull(normal, lam=0.2, method=method, tol=1e-12, block=16)
    assert res.converged and math.isnan(res.details.error_estimate)  # not asked for: not estimated
    assert res.friction_force == pytest.approx(ref.friction_force, rel=1e-8)
    assert res.peak_event == ref.peak_event
    k = res.steps
    assert np.array_equal(res.curve.site[1:], ref.curve.site[1:][:k])
    assert np.allclose(res.curve.fx[1:], ref.curve.fx[1:][:k], rtol=1e-8)
    assert np.array_equal(res.peak.stick, ref.peak.stick)


@pytest.fixture(scope="module")
def lanczos_contact():
    """A squeeze with enough bonds (> 500) for the matrix-free Lanczos path."""
    h = self_affine((48, 48), hurst=0.8, rms_height=1.0, rng=sample_rng(4, 0), oversample=2)
    normal = squeeze(h, depth=4.0, tol=1e-12)
    b = _Bonds(normal, 1.0)
    assert b.n > 500
    return normal, b, np.linalg.eigvalsh(b.dense())


def test_interlacing_bound_holds_on_random_stick_sets(lanczos_contact):
    """The claimed bound: every stick set's spectrum lies inside that of the initial bonds,
    so kappa(S0) bounds kappa(S) (dense eigenvalues, 24 random stick sets of all sizes)."""
    _normal, b, w = lanczos_contact
    rng = np.random.default_rng(2024)
    slack = 1e-12 * w[-1]  # rounding of two dense eigensolvers
    for size in np.linspace(2, b.n - 1, 24).astype(int):
        keep = np.sort(rng.choice(b.n, size, replace=False))
        ws = np.linalg.eigvalsh(b.dense(keep))
        assert w[0] - slack <= ws[0] and ws[-1] <= w[-1] + slack
        assert ws[-1] / ws[0] <= (w[-1] + slack) / (w[0] - slack)


def test_lanczos_estimate_is_inside_the_spectrum_and_reproducible(lanczos_contact):
    """Ritz values are Rayleigh quotients: the estimate lies inside the spectrum (so it never
    overstates the condition number), here within rtol of the ends; and it is a pure function
    of the bonds (fixed start vector), bitwise."""
    normal, _b, w = lanczos_contact
    rtol = 1e-3
    lo, hi = bond_spectrum(normal, rtol=rtol)
    slack = 1e-12 * w[-1]
    assert w[0] - slack <= lo <= w[0] * (1 + rtol)
    assert w[-1] * (1 - rtol) <= hi <= w[-1] + slack
    assert bond_spectrum(normal, rtol=rtol) == (lo, hi)
    assert bond_spectrum(normal, rtol=rtol, threads=2) == bond_spectrum(normal, rtol=rtol,
                                                                         threads=2)


def test_error_bound_is_condition_times_residual(rough_contact):
    tol = 1e-12
    res = pull(rough_contact, method="inverse", tol=tol, estimate_error=True)
    lo, hi = bond_spectrum(rough_contact)
    assert res.details.condition == hi / lo and res.details.condition > 1
    assert res.details.error_bound == res.details.condition * res.residual
    # the peak state is certified (residual > 0 even with fewer breaks than one block), and
    # converged means every certification met tol
    assert res.steps < 128 and res.converged and 0 < res.residual <= tol
    again = pull(rough_contact, method="inverse", tol=tol, estimate_error=True)
    assert (again.details.condition, again.details.error_bound, again.details.error_estimate) == (
        res.details.condition, res.details.error_bound, res.details.error_estimate)
    cg = pull(rough_contact, method="cg", tol=1e-9, estimate_error=True)
    assert cg.details.error_bound == pytest.approx(cg.details.condition * cg.residual)
    # here the bounds cover the measured difference between the two exact methods
    diff = abs(cg.friction_force - res.friction_force) / res.friction_force
    assert diff <= cg.details.error_bound + res.details.error_bound
    plain = pull(rough_contact, method="inverse")
    assert math.isnan(plain.details.condition) and math.isnan(plain.details.error_bound)


@pytest.mark.parametrize("method", ["cg", "literal"])
@pytest.mark.parametrize("tol", [1e-4, 1e-6, 1e-8])
def test_error_estimate_is_within_a_factor_two_of_the_truth(rough_contact, method, tol):
    """The refinement estimate against the error measured from a reference exact to rounding
    (docs/methods.rst#estimates-against-truth states factor 2; the bound overstates)."""
    ref = pull(rough_contact, method="inverse", tol=1e-13)
    res = pull(rough_contact, method=method, tol=tol, estimate_error=True)
    err = abs(res.friction_force - ref.friction_force) / ref.friction_force
    assert err > 1e-12  # the loose solve has a measurable error
    # the reference shares the squeeze: the pull's own part is the comparable one
    assert err / 2 <= res.details.solve_error_estimate <= 2 * err
    est = res.details
    assert est.error_estimate == est.solve_error_estimate + est.normal_error_estimate
    assert res.details.error_bound >= err


def test_error_estimate_of_the_inverse_is_at_rounding(rough_contact):
    res = pull(rough_contact, method="inverse", tol=1e-10, estimate_error=True)
    assert 0 <= res.details.solve_error_estimate < 1e-14
    assert 0 < res.details.normal_error_estimate < 1e-10  # the squeeze, at 1e-12, dominates
    coulomb = pull(rough_contact, slip_law="coulomb", estimate_error=True)
    assert coulomb.details.solve_error_estimate == 0.0  # lambda F_n does not depend on the solves
    assert coulomb.details.error_estimate == coulomb.details.normal_error_estimate
    with pytest.raises(InputError, match="break-law"):
        refinement_estimate(rough_contact, coulomb)


def test_early_stop_is_exact(rough_contact):
    full = pull(rough_contact, method="inverse", early_stop=False, block=8)
    fast = pull(rough_contact, method="inverse", early_stop=True, block=8)
    assert full.steps == full.details.n_bonds
    assert fast.details.early_stopped and fast.steps < full.steps
    assert fast.friction_force == full.friction_force


def test_pull_curve_maximum_and_peak_state(rough_contact):
    res = pull(rough_contact, lam=0.3)
    assert res.friction_force == res.curve.fx.max() == res.curve.fx[res.peak_event]
    # the forces at the peak sum to the friction force; only stick sites carry them
    assert res.peak.fx.sum() == pytest.approx(res.friction_force, rel=1e-10)
    assert np.all(res.peak.fx[~res.peak.stick] == 0)
    # the peak bond sits at its limit, every other one below it
    ratio = np.abs(res.peak.fx[res.peak.stick]) / (0.3 * rough_contact.fz[
        res.peak.stick])
    assert ratio.max() == pytest.approx(1.0, rel=1e-10)
    assert res.peak.stick.sum() == res.details.n_bonds + 1 - res.peak_event


def test_hertz_stick_forces_are_positive(hertz_contact):
    res = pull(hertz_contact, lam=0.2)
    f = res.peak.fx[res.peak.stick]
    assert f.size > 0 and np.all(f > 0)


def test_lambda_scaling(rough_contact):
    a = pull(rough_contact, lam=0.2)
    for s in (1e-6, 3.0, 1e4):
        b = pull(rough_contact, lam=0.2 * s)
        assert b.friction_force == pytest.approx(s * a.friction_force, rel=1e-10)
        assert np.array_equal(b.curve.site[1:], a.curve.site[1:])
        assert np.allclose(b.curve.dx[1:], s * a.curve.dx[1:], rtol=1e-10)


def test_deterministic_tie_breaking_lowest_flat_index():
    """A centred sphere on an even grid is symmetric under 8 reflections: ties everywhere."""
    h = sphere((8, 8), radius=4.0)
    normal = squeeze(h, depth=1.0, tol=1e-13)
    assert normal.n_contact >= 12
    for method in ("literal", "inverse", "cg"):
        res = pull(normal, method=method, tol=1e-13)
        fx = res.peak.fx
        first = res.curve.site[1:][0]
        # the first bond to break is the lowest flat index among the equal maxima
        iy, ix = divmod(int(first), 8)
        twins = {(iy, 7 - ix), (7 - iy, ix), (7 - iy, 7 - ix)}
        assert all(first <= y * 8 + x for y, x in twins)
        assert np.isfinite(fx).all()
    seqs = {tuple(pull(normal, method=m, tol=1e-13).curve.site[1:7])
            for m in ("literal", "inverse", "cg")}
    assert len(seqs) == 1


def test_only_sites_with_positive_normal_force_are_bonds(rough_contact):
    res = pull(rough_contact)
    assert res.details.n_bonds == int(np.count_nonzero(rough_contact.fz > 0))
    assert np.all(rough_contact.fz.ravel()[res.curve.site[1:]] > 0)


def test_single_bond_and_full_contact():
    h = self_affine((10, 10), hurst=0.7, rms_height=1.0, rng=sample_rng(2, 0))
    one = squeeze(h, depth=1e-9)
    res = pull(one, lam=0.25)
    assert res.details.n_bonds == 1 and res.steps == 1
    assert res.friction_force == pytest.approx(0.25 * one.normal_force, rel=1e-12)
    full = squeeze(h, depth=30 * (h.max() - h.min()))
    assert full.contact.all()
    for method in ("inverse", "cg", "literal"):
        r = pull(full, lam=0.25, method=method, tol=1e-11)
        assert r.details.n_bonds == 100 and r.converged
        assert 0 < r.friction_force <= 0.25 * full.normal_force
    assert pull(full, method="inverse").friction_force == pytest.approx(
        pull(full, method="literal", tol=1e-12).friction_force, rel=1e-8)


def test_no_contact_gives_zero():
    normal = squeeze(np.zeros((5, 5)), depth=0.0)
    res = pull(normal)
    assert res.friction_force == 0.0 and res.steps == 0 and res.converged


def test_bonded_punch_follows_mindlin_before_the_first_break():
    """Q = 8 G a delta / (2 - nu) (docs/methods.rst#mindlin), with the punch's -0.12 h/a staircase
    error."""
    nu, ah = 0.3, 16
    h = 1.0 / ah
    normal = squeeze(punch((2 * ah + 2, 2 * ah + 2), radius=1.0, a=h), depth=1e-3, a=h, nu=nu)
    res = pull(normal, lam=0.3)
    a_eq = math.sqrt(normal.n_contact * h * h / math.pi)
    k_exact = mindlin_bonded_punch_stiffness(a_eq, nu=nu)
    err = (res.curve.fx[1:][0] / res.curve.dx[1:][0] - k_exact) / k_exact
    assert -0.2 * h < err < 0, f"bonded punch stiffness off by {err:.3e}"


@pytest.mark.parametrize("a_over_h", [8, 16])
def test_coulomb_matches_cattaneo_mindlin(a_over_h):
    """docs/methods.rst#cattaneo-mindlin at nu = 0.3, lambda = 0.3, delta/delta_s = 0.3 and 0.7."""
    nu, lam, R, d = 0.3, 0.3, 1.0, 1 / 16
    heights, h, depth, ac = hertz_scene(a_over_h, R, d)
    normal = squeeze(heights, depth=depth, a=h, nu=nu, tol=1e-12)
    res = pull(normal, lam=lam, slip_law="coulomb", block=64)
    P = normal.normal_force
    assert res.converged and res.friction_force == pytest.approx(lam * P, rel=1e-12)
    assert np.all(np.diff(res.curve.fx[1:]) >= -1e-12 * lam * P)  # Q(delta) never decreases
    assert_cattaneo_mindlin(res, P, ac, h, lam, nu)


def test_batch_is_approximate_and_says_so(rough_contact):
    exact = pull(rough_contact, method="inverse")
    approx = pull(rough_contact, method="batch", batch_size=8)
    assert approx.method == "batch" and math.isnan(approx.details.error_estimate)
    assert approx.friction_force <= exact.friction_force * (1 + 1e-12)
    assert "no error estimate" in approx.message
    # asked for, it still has none: its error is a staircase in the batch size
    asked = pull(rough_contact, method="batch", batch_size=8, estimate_error=True)
    assert math.isnan(asked.details.error_estimate) and asked.details.condition > 1


def test_auto_records_its_choice(rough_contact):
    res = pull(rough_contact)
    assert res.method == choose_method(res.details.n_bonds) == "inverse"
    assert "auto chose inverse" in res.message
    assert choose_method(10) == "literal"
    assert choose_method(10**6, memory=2**30) == "cg"
    # the Coulomb law has the inverse only: auto takes it for a tiny contact too (it chose
    # the literal algorithm, which then refused the law)
    assert choose_method(10, slip_law="coulomb") == "inverse"
    tiny = squeeze(sphere((9, 9), radius=20.0), depth=0.02, tol=1e-13)
    assert 0 < tiny.n_contact <= 12
    res = pull(tiny, slip_law="coulomb")
    assert res.method == "inverse"
    assert res.friction_force == pytest.approx(0.2 * tiny.normal_force, rel=1e-12)


def test_memory_guard_refuses_the_inverse(rough_contact):
    with memory.limited(1e-6):
        with pytest.raises(MemoryLimitError, match="GiB"):
            pull(rough_contact, method="inverse")
        assert pull(rough_contact).method == "cg"  # auto falls back to matrix-free


def test_bad_arguments(rough_contact):
    with pytest.raises(InputError, match="lam"):
        pull(rough_contact, lam=0.0)
    with pytest.raises(InputError, match="lam"):
        pull(rough_contact, lam=-1.0)
    with pytest.raises(InputError, match="slip_law"):
        pull(rough_contact, slip_law="stick")
    with pytest.raises(InputError, match="method"):
        pull(rough_contact, method="fast")


@pytest.mark.parametrize("slip_law", ["break", "coulomb"])
@pytest.mark.parametrize("squeeze_tol", [1e-5, 1e-8])
def test_error_estimate_covers_the_squeeze(slip_law, squeeze_tol):
    """On a loose squeeze the friction force's error is mostly the normal forces' error:
    the whole estimate against a squeeze and a pull at 1e-13 (normal_share, within 10 %)."""
    h = self_affine((40, 36), hurst=0.8, rms_height=1.0, rng=sample_rng(11, 0), oversample=2)
    ref = pull(squeeze(h, depth=1.6, tol=1e-13), method="inverse", tol=1e-13,
               slip_law=slip_law)
    loose = squeeze(h, depth=1.6, tol=squeeze_tol)
    res = pull(loose, method="inverse", tol=1e-10, slip_law=slip_law, estimate_error=True)
    err = abs(res.friction_force - ref.friction_force) / ref.friction_force
    assert err > 1e-12
    assert 0.9 * err <= res.details.error_estimate <= 1.1 * err
    assert res.details.normal_error_estimate > 100 * res.details.solve_error_estimate
    assert "normal forces" in res.message


def test_coulomb_force_at_follows_the_drive_past_an_avalanche():
    """Avalanche states are recorded at their own limits, below the drive that set them off;
    the curve under a monotone drive skips them (an interpolation through them would run
    backwards), and a break-law result is refused."""
    from dataclasses import replace

    from roughslip.friction.result import DecoupledDetails, PullResult, PullState, start_curve

    z = np.zeros((1, 3))
    curve = start_curve(np.array([1.0, 2.0, 1.5, 3.0]), np.array([1.0, 3.0, 2.5, 5.0]),
                        ("slip+",) * 4, np.arange(4), 10.0, 0.1)
    state = PullState(z, z, z.astype(bool), z.astype(bool))
    res = PullResult(friction_force=5.0, normal_force_at_peak=10.0, normal_force=10.0,
                     curve=curve, peak_event=4, peak=state, start=state, converged=True,
                     seconds=0.0, method="inverse", slip_law="coulomb", residual=0.0, solves=0,
                     message="", details=DecoupledDetails())
    q = coulomb_force_at(res, np.array([0.5, 1.5, 2.0, 2.5, 4.0]))
    np.testing.assert_allclose(q, [0.5, 2.0, 3.0, 4.0, 5.0])
    with pytest.raises(InputError, match="needs a result of a law whose bonds slip"):
        coulomb_force_at(replace(res, slip_law="break"), 1.0)


def test_a_slipping_bond_that_sticks_again_keeps_its_force_and_the_equilibrium():
    """The decoupled state's re-stick (no rough scene tested so far needs one, so it is
    forced here): after some slip events a slipping bond sticks again at the current pull;
    no force jumps, and on every stick bond, before and after further events, the FFT-free
    dense equilibrium G_xx f = D + offset holds, slip forces included."""
    from roughslip.friction.bonds import Bonds, PullOptions
    from roughslip.friction.laws import LAWS
    from roughslip.friction.sliding import TangentialState

    h = self_affine((20, 20), hurst=0.8, rms_height=1.0, rng=sample_rng(3, 0))
    normal = squeeze(h, depth=1.2, nu=0.3, tol=1e-13)
    b = Bonds(normal, 0.3)
    st = TangentialState(b, PullOptions(slip_law="coulomb", law=LAWS.get("coulomb"),
                                        tol=1e-12, block=4))
    G = b.dense()

    def check(D: float) -> None:
        f = st.at(D)[1].ravel()[b.sites]
        stick = st.S.ravel()[b.sites]
        u = G @ f
        want = D + st.offset[stick]
        assert np.abs(u[stick] - want).max() <= 1e-9 * np.abs(want).max()

    D = 0.0
    for _ in range(8):  # eight slip events along the pull
        _, hi, kind, j = st.interval(D)
        D = max(D, hi)
        st.apply(kind, j, D)
        check(D)
    j = int(b.sites[np.flatnonzero(st.sigma.any(axis=-1))[0]])
    before, refined = st.at(D)[1], st.refinements
    st.apply("stick", j, D)
    assert st.refinements == refined  # the fresh solutions needed no refinement
    np.testing.assert_allclose(st.at(D)[1], before, rtol=0, atol=1e-10 * np.abs(before).max())
    assert st.S.ravel()[j] and not st.sigma[st.position[j]].any()
    assert st.offset[st.position[j]] != 0
    check(D)
    for _ in range(6):  # the pull goes on with the offset in the equilibrium
        _, hi, kind, k = st.interval(D)
        D = max(D, hi)
        st.apply(kind, k, D)
        check(D)
    assert st.ok and st.worst <= 1e-12


class _Gaps:
    """A test observer of a break sequence: for each break, the relative gap between the two
    largest ratios |phi_i| / (lam f_z,i) (a near tie is a choice rounding may decide)."""

    def __init__(self, b) -> None:
        self.b, self.gaps, self.sites, self.drive = b, [], [], []

    def record(self, phi_sum, m, site_pos, stick) -> None:
        pos, phi = stick()
        r = np.sort(np.abs(phi) / self.b.cap[pos])[::-1]
        self.gaps.append(1.0 if r.size < 2 else (r[0] - r[1]) / r[0])
        self.sites.append(int(self.b.sites[site_pos]))
        self.drive.append(1.0 / m)

    def should_stop(self, cap_sum_after) -> bool:
        return False


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_break_fast_path_breaks_what_the_event_path_breaks(seed):
    """The break law's fast path and the event path are two strategies of one tangential
    state: on rough scenes they break the same bonds in the same order (an avalanche's next
    failure is the largest ratio too), up to the first near tie (relative gap below 1e-8, where
    the choice is rounding's), and give the same friction force. An observer of the fast path
    sees every break at the drive the curve records."""
    from roughslip.friction.bonds import PullOptions
    from roughslip.friction.events import EventKind, follow_events
    from roughslip.friction.laws import LAWS
    from roughslip.friction.sliding import BreakSequence, TangentialState

    h = self_affine((24, 24), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0), oversample=2)
    normal = squeeze(h, depth=1.8, nu=0.3, tol=1e-13)
    b = _Bonds(normal, 0.2)
    opt = PullOptions(slip_law="break", law=LAWS.get("break"), tol=1e-12, block=8,
                      early_stop=False)
    fast = TangentialState(b, opt)
    gaps = fast.observe(_Gaps(b))
    res = fast.run(BreakSequence(), 0.0)
    assert gaps.sites == list(res.curve.site[1:])
    assert np.array_equal(np.array(gaps.drive), res.curve.drive[1:])

    path = follow_events(TangentialState(b, opt), 20 * b.n + 100, False)
    failed = [e.site for e in path.events
              if e.kind in (EventKind.SLIP_PLUS, EventKind.SLIP_MINUS)]
    tie = next((k for k, g in enumerate(gaps.gaps) if g < 1e-8), len(gaps.gaps))
    assert failed[:tie] == gaps.sites[:tie] and tie > len(gaps.sites) // 2
    # both certified to 1e-12 on sets whose condition number is below 20 (bond_spectrum)
    assert path.peak.fx_total == pytest.approx(res.friction_force, rel=1e-8)
