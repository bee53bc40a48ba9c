"""The Coulomb law's event path on an inexact inverse (float32, compressed in double and in
single precision) with certified decisions, against the double-precision dense path."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.contact.squeeze import squeeze
from roughslip.errors import InputError
from roughslip.friction.bonds import Bonds, PullOptions, stick_residual, tracked_rhs
from roughslip.friction.events import EventKind
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import (
    METHODS,
    choose_precision,
    inverse_memory_bytes,
    pull,
    single_ok,
)
from roughslip.friction.sliding import FollowEvents, TangentialState
from roughslip.friction.sliding_single import CertifiedSlide
from roughslip.surfaces.synthetic import sample_rng, self_affine, sphere

VARIANTS = [("inverse", "single"), ("hierarchical", "double"), ("hierarchical", "single")]


def _scenes():
    """Rough contacts (open and periodic, several nu), symmetric spheres (exact ties, broken
    by the lowest index) and spheres whose symmetry is broken at 1e-7 (near-ties inside the
    single-precision error)."""
    out = []
    for k, (n, depth, nu, boundary) in enumerate([
            (48, 2.2, 0.3, "open"), (64, 2.0, 0.25, "open"), (64, 2.6, 0.45, "open"),
            (48, 1.6, 0.3, "periodic"), (64, 1.6, 0.3, "periodic")]):
        h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(100 + k, 0))
        out.append((f"rough{k}-{boundary}", h, depth, nu, boundary))
    rng = np.random.default_rng(7)
    for n, radius, depth in [(24, 20.0, 1.5), (32, 30.0, 2.0)]:
        out.append((f"sphere{n}", sphere((n, n), radius=radius), depth, 0.3, "open"))
        h = sphere((n, n), radius=radius) + 1e-7 * rng.standard_normal((n, n))
        out.append((f"near-tie{n}", h, depth, 0.3, "open"))
    return out


SCENES = _scenes()


@pytest.fixture(scope="module")
def pulls():
    out = {}
    for name, h, depth, nu, boundary in SCENES:
        normal = squeeze(h, depth=depth, nu=nu, boundary=boundary, tol=1e-13)
        out[name] = [pull(normal, slip_law="coulomb", method=m, precision=p, tol=1e-10)
                     for m, p in [("inverse", "double"), *VARIANTS]]
    return out


@pytest.mark.parametrize("variant", range(len(VARIANTS)))
@pytest.mark.parametrize("name", [s[0] for s in SCENES])
def test_an_inexact_inverse_gives_the_double_slip_events(pulls, name, variant):
    """The same events at the same sites in the same order, the same friction force (the
    slipping forces' sum at full sliding), every curve point within its reported bound."""
    d, s = pulls[name][0], pulls[name][1 + variant]
    method, precision = VARIANTS[variant]
    assert (s.method, s.details.precision) == (method, precision)
    assert d.curve.kind == s.curve.kind
    np.testing.assert_array_equal(s.curve.site, d.curve.site)
    assert s.friction_force == d.friction_force
    bound = float(s.message.split("curve points within ")[1].split(" ")[0])
    assert np.all(np.abs(s.curve.fx - d.curve.fx) <= bound * np.abs(d.curve.fx) + 1e-300)
    np.testing.assert_allclose(s.curve.dx, d.curve.dx, rtol=bound)
    assert s.converged and d.converged
    assert "bound exceeded 0 times" in s.message


def _counts(message: str) -> tuple[int, int]:
    """Decisions sharpened and refined in full, from a certified pull's message."""
    sharpened = int(message.split(" of ")[0].split()[-1])
    full = int(message.split(" refined in full")[0].split()[-1])
    return sharpened, full


def test_decisions_the_bounds_leave_open_are_sharpened_or_refined(pulls):
    """Exact ties (the symmetric spheres) and near-ties leave decisions open: those were
    sharpened, or refined in full where a tie outlives the sharpening, and came out as in
    double precision (previous test)."""
    counts = {name: [_counts(r.message) for r in rs[1:]] for name, rs in pulls.items()}
    assert all(min(f for _, f in counts[f"sphere{n}"]) > 0 for n in (24, 32))
    assert sum(s + f for k, v in counts.items() if k.startswith("near-tie") for s, f in v) > 0
    assert sum(s for v in counts.values() for s, _ in v) > sum(f for v in counts.values()
                                                              for _, f in v)


def _rough48():
    """The bonds of a rough 48^2 contact and the Coulomb law."""
    h = self_affine((48, 48), hurst=0.8, rms_height=1.0, rng=sample_rng(100, 0))
    b = Bonds(squeeze(h, depth=2.2, nu=0.3, tol=1e-13), 0.2)
    return b, LAWS.get("coulomb").bind(0.2)


def _dense(b, law):
    """The dense double-precision state, both solutions tracked."""
    st = TangentialState(b, PullOptions(law=law, method=METHODS.get("inverse")))
    st.track_slip()
    return st


def test_sharpened_values_hold_the_dense_state_within_their_bounds():
    """One residual per solution sharpens phi and psi on chosen rows: after slip events
    applied to both states, the dense double state's values lie within the sharpened bounds,
    which are tighter than the running ones."""
    b, law = _rough48()
    for method, precision in VARIANTS:
        opt = PullOptions(law=law, method=METHODS.get(method), precision=precision)
        certified = CertifiedSlide(b, opt)
        D, st = 0.0, _dense(b, law)
        for _ in range(40):
            _, hi, kind, j = st.interval(D)
            D = max(D, hi)
            for s in (st, certified):
                s.apply(kind, j, D)
        rows = np.flatnonzero(certified.inv.live)[::7]
        e_phi, e_psi = certified._errors()
        _, phi, psi, ep, es = certified._sharpen(rows)
        ref = dict(zip(st.inv.ids[st.inv.live].tolist(),
                       zip(st.inv.tracked["phi"].x[st.inv.live],
                           st.inv.tracked["psi"].x[st.inv.live], strict=True), strict=True))
        # the dense state's own error, by its residuals against the FFT operator
        pos = st.inv.ids[st.inv.live]
        own = [np.linalg.norm(stick_residual(b, pos, st.inv.tracked[name].x[st.inv.live],
                                             tracked_rhs(b, pos, load, st.offset))[0])
               for name, load in (("phi", None), ("psi", st._load()))]
        for k, r in enumerate(rows):
            p, q = ref[int(certified.inv.ids[r])]
            scale = np.sqrt(certified.bound.nu * certified.bound.d[r])
            assert abs(phi[k] - p) <= ep[k] + scale * own[0]
            assert abs(psi[k] - q) <= es[k] + scale * own[1]
        assert np.all(ep < e_phi[rows]) and np.all(es < e_psi[rows])
        assert certified.exceeded == 0


@pytest.mark.parametrize("name", ["rough0-open", "near-tie24"])
def test_every_event_drive_is_within_its_bound_of_the_exact_one(monkeypatch, name):
    """At every event the drive of each inexact path is within its bound on the drive's error
    of the dense double path's, which carries its own bound (the same certified state on the
    dense double inverse): their sum bounds the difference."""
    _, h, depth, nu, boundary = next(s for s in SCENES if s[0] == name)
    b = Bonds(squeeze(h, depth=depth, nu=nu, boundary=boundary, tol=1e-13), 0.2)
    law = LAWS.get("coulomb").bind(0.2)
    seen: list[tuple[str, int, float, float]] = []
    apply = CertifiedSlide.apply

    def recorded(self, kind, j, D=0.0):
        apply(self, kind, j, D)
        seen.append((kind, j, D, self._drive_error))

    monkeypatch.setattr(CertifiedSlide, "apply", recorded)
    paths = []
    for method, precision in [("inverse", "double"), *VARIANTS]:
        seen.clear()
        opt = PullOptions(law=law, method=METHODS.get(method), precision=precision)
        CertifiedSlide(b, opt).run(FollowEvents(), 0.0)
        paths.append(list(seen))
    exact = paths[0]
    for path in paths[1:]:
        assert [e[:2] for e in path] == [e[:2] for e in exact]
        for (_, _, D, err), (_, _, D0, err0) in zip(path, exact, strict=True):
            assert abs(D - D0) <= err + err0


def test_a_bond_that_sticks_again_keeps_the_solutions_within_their_bounds():
    """A bond that sticks again factorises the inverse afresh on the larger set, with its
    bounds: phi and psi stay within them of the dense state's after the same events."""
    b, law = _rough48()
    dense = _dense(b, law)
    certified = CertifiedSlide(b, PullOptions(law=law, method=METHODS.get("hierarchical")))
    D = 0.0
    for _ in range(6):  # the first slip events, applied to both
        _, hi, kind, j = dense.interval(D)
        _, hi_c, kind_c, j_c = certified.interval(D)
        assert (kind_c, j_c) == (kind, j) and hi_c == pytest.approx(hi, rel=1e-6)
        D = hi
        for st in (dense, certified):
            st.apply(kind, j, D)
    slipped = int(np.flatnonzero(dense.sigma.any(axis=-1))[0])
    refinements, certified.worst = certified.refinements, 0.5  # the pull's so far
    for st in (dense, certified):
        st.apply(EventKind.STICK, int(b.sites[slipped]), D)
    phi, psi, _, live = certified._rows()
    e_phi, e_psi = certified._errors()
    ref = dict(zip(dense.inv.ids[dense.inv.live].tolist(),
                   zip(dense.inv.tracked["phi"].x[dense.inv.live],
                       dense.inv.tracked["psi"].x[dense.inv.live], strict=True), strict=True))
    rows = np.flatnonzero(live)
    assert sorted(ref) == sorted(certified.inv.ids[rows].tolist())
    for r in rows:
        p, q = ref[int(certified.inv.ids[r])]
        assert abs(phi[r] - p) <= e_phi[r] and abs(psi[r] - q) <= e_psi[r]
    # the new factorisation's bounds start afresh, the pull's counts go on
    assert certified.exceeded == 0 and certified.refinements > refinements
    assert certified.worst == 0.5 and not certified.ok


def test_the_traction_vector_has_no_certified_coulomb_path():
    """The faceted Coulomb cone decides on the dense double inverse only: single precision and
    the compressed inverse are refused for it, and still run the x-only Coulomb pull."""
    normal = squeeze(sphere((16, 16), radius=12.0), depth=1.0, nu=0.3, tol=1e-12)
    assert single_ok("coulomb", "inverse") and not single_ok("coulomb", "inverse", "xy")
    assert single_ok("break", "hierarchical", "xy")
    with pytest.raises(InputError, match="method 'hierarchical' runs "
                       "slip_law = 'coulomb' in the x-only model only"):
        pull(normal, slip_law="coulomb", components="xy", method="hierarchical")
    with pytest.raises(InputError, match="precision = 'single'"):
        pull(normal, slip_law="coulomb", components="xy", precision="single")
    n = 5000  # unknowns: the dense inverse fits in single precision only
    between = (inverse_memory_bytes(n) + inverse_memory_bytes(n, precision="single")) // 2
    assert choose_precision(n, memory=between, slip_law="coulomb") == "single"
    assert choose_precision(n, memory=between, slip_law="coulomb", per_point=2,
                            components="xy") == "double"
