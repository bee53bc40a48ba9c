"""The one result type of a pull (:class:`~roughslip.friction.result.PullResult`): the names
of earlier versions still work, warn, and give the same values."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

import roughslip
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import squeeze
from roughslip.coupling.coupled import couple
from roughslip.elastic.operators import Grid, Material
from roughslip.friction.pull import pull
from roughslip.friction.result import _RENAMED, CoupledDetails, DecoupledDetails, PullResult
from roughslip.surfaces.synthetic import sample_rng, self_affine


@pytest.fixture(scope="module")
def results() -> dict[str, PullResult]:
    h = self_affine((16, 16), hurst=0.8, rms_height=1.0, rng=sample_rng(3, 0))
    normal = squeeze(h, depth=1.2, nu=0.3, tol=1e-12)
    pb = Problem(h, Grid((16, 16), 1.0), Material(1.0, 0.3))
    return {"break": pull(normal, lam=0.3, estimate_error=True),
            "coulomb": pull(normal, lam=0.3, slip_law="coulomb"),
            "coupled": couple(pb, depth=1.2, lam=0.3)}


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    return a == b or (a != a and b != b)


@pytest.mark.parametrize("which", ["break", "coulomb", "coupled"])
def test_every_old_name_warns_and_gives_what_replaces_it(results, which):
    r = results[which]
    for name, (instead, get) in _RENAMED.items():
        with pytest.warns(DeprecationWarning, match=f"PullResult.{name} is deprecated; use "):
            old = getattr(r, name)
        assert _same(old, get(r)), name
        assert re.match(r"\w+", instead)[0] in {f.name for f in dataclasses.fields(r)}
    for f in dataclasses.fields(r.details):
        with pytest.warns(DeprecationWarning, match=f"use details.{f.name}"):
            assert _same(getattr(r, f.name), getattr(r.details, f.name))
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        r.nonsense  # noqa: B018


def test_the_old_names_mean_what_they_meant(results):
    """The decoupled curve of earlier versions began with the first event, the coupled one
    with the start; the peak index counted the events after the start."""
    d, c = results["break"], results["coupled"]
    with pytest.warns(DeprecationWarning):
        assert d.fx_lim[d.peak_index] == d.friction_force == d.fx_lim.max()
        assert d.dx_lim.size == d.steps == d.curve.dx.size - 1
        assert d.broken_site.dtype == np.int64 and d.fx_at_peak.sum() == pytest.approx(
            d.friction_force, rel=1e-10)
        assert c.dx.size == len(c.events) and c.dx[0] == 0 and c.fx[c.peak_event] == max(c.fx)
        assert c.fz0.sum() == pytest.approx(c.normal_force) and c.released >= 0


def test_the_old_types_build_a_pull_result_and_recognise_one(results):
    from roughslip.friction.result import CoupledResult, SlipResult

    d, c = results["break"], results["coupled"]
    old = dict(friction_force=d.friction_force, peak_index=d.peak_event - 1,
               dx_lim=d.curve.dx[1:], fx_lim=d.curve.fx[1:], broken_site=d.curve.site[1:],
               stick_at_peak=d.peak.stick, fx_at_peak=d.peak.fx, converged=True, seconds=0.0,
               method="inverse", lam=0.3, n_bonds=d.details.n_bonds)
    with pytest.warns(DeprecationWarning, match="SlipResult is deprecated"):
        again = SlipResult(**old)
    assert isinstance(again, PullResult) and isinstance(d, SlipResult)
    assert isinstance(again.details, DecoupledDetails) and again.details.lam == 0.3
    assert again.peak_event == d.peak_event and again.steps == d.steps
    np.testing.assert_array_equal(again.curve.fx, d.curve.fx)
    with pytest.raises(TypeError):
        with pytest.warns(DeprecationWarning):
            SlipResult(**old, not_a_field=1)

    old = dict(friction_force=c.friction_force, normal_force_at_peak=c.normal_force_at_peak,
               peak_dx=c.peak_dx, events=c.events, normal_force=c.normal_force,
               fz0=c.start.fz, fx0=c.start.fx, contact0=c.start.contact, stick0=c.start.stick,
               fz_peak=c.peak.fz, fx_peak=c.peak.fx, stick_peak=c.peak.stick,
               contact_peak=c.peak.contact, converged=c.converged, seconds=c.seconds,
               solves=c.solves, method=c.method, released=c.details.released,
               contact_area=c.details.contact_area, depth=c.details.depth)
    with pytest.warns(DeprecationWarning, match="CoupledResult is deprecated"):
        again = CoupledResult(**old)
    assert isinstance(again.details, CoupledDetails) and isinstance(c, CoupledResult)
    assert again.peak_event == c.peak_event and again.details.released == c.details.released
    for name in ("dx", "fx", "fz", "dz"):
        np.testing.assert_array_equal(getattr(again.curve, name), getattr(c.curve, name))


@pytest.mark.parametrize("module, name", [
    ("roughslip", "SlipResult"), ("roughslip", "CoupledResult"),
    ("roughslip.friction.pull", "SlipResult"), ("roughslip.friction.bonds", "SlipResult"),
    ("roughslip.coupling.coupled", "CoupledResult")])
def test_the_old_type_names_still_import_and_warn(module, name):
    import importlib

    mod = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=f"{name} is deprecated"):
        old = getattr(mod, name)
    assert old.__name__ == name
    assert name not in getattr(mod, "__all__", ())
    assert "PullResult" in roughslip.__all__


def test_a_curve_carries_the_drive_and_the_force_as_vectors():
    """The one-component curve is pulled along x with F_y = 0, its x components are its
    stored numbers bit for bit; a curve along another unit vector splits its drive into
    components and gives the force along the drive as F . e."""
    from roughslip.friction.events import X_AXIS, Curve, unit_vector

    d, fx = np.array([0.0, 0.1, 0.25]), np.array([0.0, 1.5, -0.0])
    c = Curve.x_only(d, fx, np.ones(3), np.ones(3), ("start", "break", "break"),
                     np.array([-1, 3, 4]))
    assert c.direction == X_AXIS and np.array_equal(c.fy, np.zeros(3))
    assert c.dx.tobytes() == d.tobytes() and c.fx.tobytes() == fx.tobytes()
    np.testing.assert_array_equal(c.drive_vector, np.column_stack([d, np.zeros(3)]))
    np.testing.assert_array_equal(c.along, fx)
    e = unit_vector((3.0, 4.0))
    assert e == (0.6, 0.8)
    force = np.array([[0.0, 0.0], [1.0, 2.0], [-2.0, 1.0]])
    v = Curve(d, force, np.ones(3), np.ones(3), c.kind, c.site, e)
    np.testing.assert_allclose(v.dx, 0.6 * d)
    np.testing.assert_allclose(v.dy, 0.8 * d)
    np.testing.assert_allclose(v.along, [0.0, 2.2, -0.4])
    for bad in ((0.0, 0.0), (1.0, float("nan")), (1.0,)):
        with pytest.raises(ValueError, match="direction"):
            unit_vector(bad)
    with pytest.raises(ValueError, match="unit vector"):
        Curve(d, force, np.ones(3), np.ones(3), c.kind, c.site, (1.0, 1.0))
    with pytest.raises(ValueError, match="shape"):
        Curve(d, fx, np.ones(3), np.ones(3), c.kind, c.site)
