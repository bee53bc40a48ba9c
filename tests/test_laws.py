"""Slip laws as registry entries: a law defined here, kinetic friction, runs through the
coupled model and the indentation with no change to the package."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import squeeze
from roughslip.coupling.coupled import couple, indent
from roughslip.elastic.operators import Grid, Material
from roughslip.errors import InputError
from roughslip.friction.events import TANGENTIAL, X
from roughslip.friction.laws import LAWS, CoulombLaw
from roughslip.friction.pull import pull
from roughslip.friction.result import CoupledDetails, DecoupledDetails, PullResult
from roughslip.surfaces.synthetic import sample_rng, self_affine


@dataclass(frozen=True)
class KineticLaw(CoulombLaw):
    r"""Static and kinetic friction: a bond fails at :math:`|f_x| = \lambda f_z` and then
    slips carrying :math:`\sigma\lambda_k f_z`, :math:`\lambda_k = r\lambda` (the limit of a
    slip-weakening law whose weakening length goes to zero)."""

    ratio: float = 1.0

    def carried(self, lam: float, sigma: np.ndarray) -> np.ndarray:
        return (self.ratio * lam) * sigma


@pytest.fixture
def kinetic():
    """Register kinetic laws at r = 1 and r = 0.6 for one test."""
    names = {"kinetic-1": 1.0, "kinetic-0.6": 0.6}
    for name, ratio in names.items():
        LAWS.register(name, f"kinetic friction, lam_k = {ratio} lam")(
            KineticLaw(name, failed="slipping", curve="slip events", reverses=True,
                       slides=True, ratio=ratio))
    yield names
    for name in names:
        LAWS.remove(name)


def _problem(n: int = 24, nu: float = 0.25, seed: int = 4) -> Problem:
    h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0))
    return Problem(h, Grid((n, n), 1.0), Material(1.0, nu))


def _same(a, b) -> None:
    for name in ("dx", "fx", "fz", "dz"):
        assert getattr(a.curve, name).tobytes() == getattr(b.curve, name).tobytes(), name
    assert [e.kind for e in a.events] == [e.kind for e in b.events]
    assert [e.site for e in a.events] == [e.site for e in b.events]
    for state in ("start", "peak"):
        for name in ("fz", "fx"):
            assert getattr(getattr(a, state), name).tobytes() == getattr(
                getattr(b, state), name).tobytes(), (state, name)


def test_a_registered_law_at_its_coulomb_limit_gives_the_coulomb_numbers(kinetic):
    """The law reaches the coupled model through the registry alone: at r = 1 the results
    are the Coulomb law's, bit for bit, event for event."""
    p = _problem()
    _same(couple(p, depth=1.2, lam=0.3, slip_law="kinetic-1"),
          couple(p, depth=1.2, lam=0.3, slip_law="coulomb"))


def test_a_registered_law_matches_the_dense_reference_and_its_own_bound(kinetic):
    """At r = 0.6: the updated inverse against the reference (every state factorised afresh,
    displacements by dense sums), and every slipping bond carries exactly
    sigma 0.6 lam f_z in every recorded state."""
    p = _problem(n=20)
    lam = 0.3
    ref = couple(p, depth=1.2, lam=lam, slip_law="kinetic-0.6", method="dense",
                 reference=True, record_states=True)
    fast = couple(p, depth=1.2, lam=lam, slip_law="kinetic-0.6", method="dense",
                  record_states=True)
    assert [e.kind for e in fast.events] == [e.kind for e in ref.events]
    assert fast.friction_force == pytest.approx(ref.friction_force, rel=1e-8)
    np.testing.assert_allclose(fast.curve.fx, ref.curve.fx, rtol=1e-7,
                               atol=1e-9 * np.abs(ref.curve.fx).max())
    kinds = {e.kind for e in fast.events}
    assert {"slip+"} <= kinds
    slipping = 0
    for (_, fz, fx, _, C, S) in fast.details.states:
        P = C & ~S & (fx != 0)
        slipping += int(P.sum())
        np.testing.assert_allclose(np.abs(fx[P]), 0.6 * lam * fz[P], rtol=1e-12)
        assert np.all(np.abs(fx[S]) <= lam * fz[S] * (1 + 1e-8) + 1e-12)
    assert slipping > 0
    # no bond carries more than lam f_z, so neither does the whole contact at the peak
    assert 0 < fast.friction_force <= lam * fast.normal_force_at_peak * (1 + 1e-9)


def test_a_registered_law_drives_the_indentation(kinetic):
    """The frictional indentation runs the same law; at r = 1 it is the Coulomb one."""
    n = 64
    x = np.arange(n) - n / 2 + 0.5
    h = np.tile(-(x**2) / (2 * 400.0), (1, 1))
    p = Problem(h, Grid((1, n), 1.0, boundary="periodic"), Material(1.0, 0.3))
    a = indent(p, depth=0.3, lam=0.3, slip_law="kinetic-1")
    b = indent(p, depth=0.3, lam=0.3, slip_law="coulomb")
    assert a.fx.tobytes() == b.fx.tobytes() and a.fz.tobytes() == b.fz.tobytes()
    assert a.slip_law == "kinetic-1"


def test_a_law_without_decoupled_methods_says_so(kinetic):
    """The decoupled pull has no method for the new law: a one-line error naming them."""
    normal = squeeze(_problem(n=16).heights, depth=1.0, nu=0.25)
    with pytest.raises(InputError, match=r"slip_law = 'kinetic-0.6' has no exact decoupled "
                                         r"pull method; use the coupled model"):
        pull(normal, slip_law="kinetic-0.6")
    with pytest.raises(InputError, match=r"slip_law = 'nope': unknown slip law; choose one "
                                         r"of break, coulomb, slip-weakening"):
        pull(normal, slip_law="nope")


def test_the_configuration_offers_the_registered_laws():
    """``pull.slip_law`` takes its choices and help from the registry."""
    import dataclasses

    from roughslip.run.config import PullConfig

    meta = {f.name: f.metadata for f in dataclasses.fields(PullConfig)}["slip_law"]
    assert tuple(meta["choices"]) == LAWS.names()  # live: a law registered later is a choice
    assert {"break", "coulomb", "slip-weakening"} <= set(LAWS.names())
    assert LAWS.summary("coulomb") in meta["doc"]


def test_the_pull_and_the_coupled_model_give_one_result_type():
    """Both models return a PullResult whose curve starts at D_x = 0 (D_x, F_x, F_z, D_z, kind,
    site per event); at nu = 1/2 the Coulomb curves are the same events, and the peaks the
    same states."""
    p = _problem(n=20, nu=0.5)
    c = couple(p, depth=1.2, lam=0.3, slip_law="coulomb")
    normal = squeeze(p.heights, depth=1.2, nu=0.5, tol=1e-13)
    d = pull(normal, lam=0.3, slip_law="coulomb", tol=1e-13)
    assert type(c) is type(d) is PullResult
    assert isinstance(c.details, CoupledDetails) and isinstance(d.details, DecoupledDetails)
    cc, dc = c.curve, d.curve
    assert cc.kind == dc.kind and cc.kind[0] == "start"
    assert set(cc.kind[1:]) <= {"slip+", "slip-"}
    np.testing.assert_array_equal(dc.site, cc.site)
    for name in ("dx", "fx", "fz", "dz"):
        np.testing.assert_allclose(getattr(dc, name), getattr(cc, name), rtol=1e-7,
                                   err_msg=name)
    assert c.peak_event == d.peak_event == dc.dx.size - 1  # Coulomb: full sliding
    for r in (c, d):
        assert r.peak_dx == r.curve.dx[r.peak_event]
        assert r.steps == r.curve.dx.size - 1
    np.testing.assert_allclose(d.peak.fx, c.peak.fx, rtol=1e-7, atol=1e-12)
    np.testing.assert_array_equal(d.start.contact, c.start.contact)
    broken = pull(normal, lam=0.3)
    assert broken.curve.kind[0] == "start" and set(broken.curve.kind[1:]) == {"break"}
    assert broken.curve.fx[broken.peak_event] == broken.friction_force
    assert np.all(broken.curve.dz == normal.depth)  # the decoupled pull holds the depth


@pytest.mark.parametrize("name", LAWS.names())
def test_a_failed_bond_keeps_a_unit_slip_direction_or_none(name):
    """Each registered law's slip direction after a failure is a unit vector of the tangential
    components, pointing the way of the failure (slip+ along +x), or the zero vector for a
    law whose failed bonds carry nothing; what a slipping bond carries is lam times it."""
    law = LAWS.get(name).bind(0.3, **({"lam_dynamic": 0.1, "slip_distance": 0.05}
                                      if name == "slip-weakening" else {}))
    for kind, sign in (("slip+", 1.0), ("slip-", -1.0)):
        d = law.failed_direction(kind)
        assert d.shape == (len(TANGENTIAL),)
        norm = float(np.linalg.norm(d))
        assert norm == 0.0 if law.sequence else norm == 1.0
        if norm:
            assert d[X] == sign
            np.testing.assert_array_equal(law.carried(law.lam, d[None, :])[0], 0.3 * d)


def test_the_decoupled_state_holds_slip_directions_as_unit_vectors():
    """After a Coulomb pull's first slip events, the state holds one tangential vector per
    bond: a unit vector on each slipping bond, in the direction of its force, zero elsewhere."""
    from roughslip.friction.bonds import Bonds, PullOptions
    from roughslip.friction.sliding import TangentialState

    h = self_affine((16, 16), hurst=0.8, rms_height=1.0, rng=sample_rng(3, 0), oversample=2)
    normal = squeeze(h, depth=1.6, nu=0.25, tol=1e-12)
    st = TangentialState(Bonds(normal, 0.2), PullOptions(slip_law="coulomb",
                                                         law=LAWS.get("coulomb"), tol=1e-12))
    D = 0.0
    for _ in range(5):
        _, hi, kind, j = st.interval(D)
        D = max(D, hi)
        st.apply(kind, j, D)
    assert st.sigma.shape == (st.b.n, len(TANGENTIAL))
    norms = np.linalg.norm(st.sigma, axis=-1)
    assert set(np.unique(norms)) <= {0.0, 1.0} and np.count_nonzero(norms) == 5
    slipping = norms == 1.0
    assert np.all(np.sign(st.slip[slipping]) == st.sigma[slipping, X])
