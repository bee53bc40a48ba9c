"""Slip-weakening under coupling: the certified path-follower against its limits."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import linalg

from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import squeeze
from roughslip.coupling.coupled import couple, indent
from roughslip.coupling.histories import HISTORIES
from roughslip.errors import InputError, NumericalError
from roughslip.friction.events import EventKind
from roughslip.friction.pull import pull
from roughslip.surfaces.synthetic import sample_rng, self_affine

LAM = 0.2


def rough(n=16, seed=1):
    return self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0),
                       oversample=2)


def _weak(pb, ld, dc, **kw):
    return couple(pb, lam=LAM, slip_law="slip-weakening", lam_dynamic=ld, slip_distance=dc,
                  **kw)


@pytest.mark.parametrize("history", HISTORIES.names())
@pytest.mark.parametrize(("seed", "depth", "ld", "dc"), [(1, 1.0, 0.1, 0.05),
                                                         (2, 1.0, 0.0, 0.05)])
def test_half_poisson_ratio_is_the_decoupled_weakening_pull(history, seed, depth, ld, dc):
    """At nu = 1/2 nothing couples: f_z is the frictionless squeeze's and the path is the
    decoupled law's, bursts included, after every history; the friction to 1e-10."""
    h = rough(16, seed)
    d = pull(squeeze(h, depth=depth, nu=0.5, tol=1e-13), lam=LAM, slip_law="slip-weakening",
             lam_dynamic=ld, slip_distance=dc, early_stop=False)
    c = _weak(Problem.from_arrays(h, nu=0.5), ld, dc, depth=depth, history=history)
    assert c.converged, c.message
    assert c.details.released == 0
    assert c.friction_force == pytest.approx(d.friction_force, rel=1e-10)
    fails = sorted(e.site for e in c.events if e.kind in ("slip+", "slip-"))
    assert fails == sorted(d.curve.site[np.isin(d.curve.kind, ["slip+", "slip-"])].tolist())


@pytest.mark.parametrize("history", ["frictionless", "indent"])
@pytest.mark.parametrize("control", ["depth", "force"])
def test_equal_coefficients_are_the_coupled_coulomb_pull(history, control):
    """lam_d = lam_s is the Coulomb law: the same events, slip for slip, and the same
    forces to 1e-10, under both controls."""
    pb = Problem.from_arrays(rough(16, 2), nu=0.25)
    kw = dict(depth=1.5) if control == "depth" else dict(force=20.0, pull_control="force")
    ref = couple(pb, lam=LAM, slip_law="coulomb", history=history, **kw)
    w = _weak(pb, LAM, 0.05, history=history, **kw)
    assert ref.converged and w.converged, w.message
    assert [(e.kind, e.site) for e in w.events] == [(e.kind, e.site) for e in ref.events]
    scale = np.abs(ref.curve.fx).max()
    assert np.allclose(w.curve.fx, ref.curve.fx, rtol=0, atol=1e-10 * scale)
    assert np.allclose(w.curve.dx, ref.curve.dx, rtol=1e-10)
    assert w.friction_force == pytest.approx(ref.friction_force, rel=1e-10)


def test_equal_coefficients_indent_as_the_coulomb_indentation():
    """The frictional indentation under the law with lam_d = lam_s is today's Coulomb
    indentation: the same events and final forces."""
    pb = Problem.from_arrays(rough(16, 3), nu=0.25)
    ref = indent(pb, depth=1.5, lam=LAM, slip_law="coulomb")
    w = indent(pb, depth=1.5, lam=LAM, slip_law="slip-weakening", lam_dynamic=LAM,
               slip_distance=0.05)
    assert w.converged, w.message
    assert [(e.kind, e.site) for e in w.events] == [(e.kind, e.site) for e in ref.events]
    scale = np.abs(ref.fz).max()
    assert np.allclose(w.fz, ref.fz, rtol=0, atol=1e-10 * scale)
    assert np.allclose(w.fx, ref.fx, rtol=0, atol=1e-10 * scale)
    assert np.array_equal(w.stick, ref.stick)


def test_vanishing_slip_distance_is_the_coupled_break_law():
    """lam_d = 0 with d_c far below the pixel's weakening scale: every failure is a burst
    that relaxes the bond to zero force, so the failed bonds and the friction are the
    coupled break law's."""
    pb = Problem.from_arrays(rough(16, 1), nu=0.25)
    ref = couple(pb, depth=1.0, lam=LAM, slip_law="break", history="frictionless")
    w = _weak(pb, 0.0, 1e-9, depth=1.0, history="frictionless")
    assert w.converged, w.message
    assert w.friction_force == pytest.approx(ref.friction_force, rel=1e-6)
    broke = sorted(e.site for e in ref.events if e.kind in ("slip+", "slip-"))
    failed = sorted(e.site for e in w.events if e.kind in ("slip+", "slip-"))
    assert failed == broke


def test_the_path_agrees_with_the_direct_reference():
    """The updated inverse against a fresh factorisation and dense sums at every state:
    the same events, forces within the block's conditioning times the tolerance."""
    pb = Problem.from_arrays(rough(12, 4), nu=0.25)
    kw = dict(depth=1.2, history="bonded")
    ref = _weak(pb, 0.1, 0.05, method="dense", reference=True, **kw)
    fast = _weak(pb, 0.1, 0.05, **kw)
    assert [(e.kind, e.site) for e in fast.events] == [(e.kind, e.site) for e in ref.events]
    assert fast.friction_force == pytest.approx(ref.friction_force, rel=1e-8)


@pytest.mark.parametrize(("history", "seed", "dc"), [("indent", 1, 0.05), ("bonded", 3, 0.01),
                                                     ("frictionless", 3, 0.01)])
def test_the_reference_inverse_follows_the_fresh_one(monkeypatch, history, seed, dc):
    """The path served from the updated reference inverse against one that inverts the
    augmented Jacobian afresh at every step (UPDATES = 0): the same events, and the curve
    within a few rounding errors of the Jacobian's conditioning."""
    from roughslip.coupling import weakening as wk

    pb = Problem.from_arrays(rough(24, seed), nu=0.25)
    kw = dict(depth=1.5, history=history)
    calls = []
    real = wk.NearInverse.of

    def fresh(A, X):
        calls.append(A.shape[0])
        return real(A, X)

    monkeypatch.setattr(wk.NearInverse, "of", staticmethod(fresh))
    served = _weak(pb, 0.1, dc, **kw)
    inverted = len(calls)
    monkeypatch.setattr(wk, "UPDATES", 0)
    direct = _weak(pb, 0.1, dc, **kw)
    assert inverted < (len(calls) - inverted) / 2  # the reference served most steps
    assert [(e.kind, e.site) for e in served.events] == [(e.kind, e.site)
                                                          for e in direct.events]
    scale = np.abs(direct.curve.force).max()
    np.testing.assert_allclose(served.curve.force, direct.curve.force, rtol=0,
                               atol=1e-10 * scale)


def test_a_gained_site_lands_closed_and_keeps_its_contact(monkeypatch):
    """A Hertz indentation at a/h = 32 gained a site whose gap was located on its open side
    (2.9e-14, inside the tie): in contact it pulled a tension of 2.6 TIE of the largest
    force, was lost at once, gained again, and the path stopped as a cycle at D_z = 7.5e-5.
    Landed just past the root, the new contact carries no tension and the indentation goes
    on; every gained site starts with its normal force at or above the contacts' tie."""
    from roughslip.coupling import weakening as wk
    from roughslip.elastic.operators import Grid, Material
    from roughslip.surfaces.synthetic import sphere

    a, n = 0.1, 128
    h = a / 32
    pb = Problem(sphere((n, n), radius=1.0, a=h), Grid((n, n), h), Material(1.0, 0.25))
    starts = []
    real = wk._Events.apply

    def apply(self, kind, j):
        real(self, kind, j)
        if kind == EventKind.GAINED:
            starts.append(float(self.fields(self.s, self.D)[0][j]) / self.fscale())

    monkeypatch.setattr(wk._Events, "apply", apply)
    got = indent(pb, depth=8e-5, lam=LAM, slip_law="slip-weakening", lam_dynamic=0.1,
                 slip_distance=5e-4)
    assert got.converged
    assert got.depth == pytest.approx(8e-5)
    assert len(starts) > 20
    assert min(starts) >= -wk.TIE


def test_coupled_weakening_rejects_bad_input():
    pb = Problem.from_arrays(rough(8), nu=0.25)
    with pytest.raises(InputError, match="slip_distance: slip_law = 'slip-weakening' needs"):
        couple(pb, depth=0.5, lam=LAM, slip_law="slip-weakening", lam_dynamic=0.1)
    with pytest.raises(InputError, match=r"lam_dynamic = 0\.3: must satisfy"):
        _weak(pb, 0.3, 0.05, depth=0.5)


def test_growth_rate_of_a_flow_block():
    """The largest real part of a block's eigenvalues (the flow's step bound, the stability
    test): proved negative when the symmetric part is negative definite, else from the
    eigenvalues, also for a non-normal block whose symmetric part is indefinite."""
    from roughslip.coupling.weakening import _abscissa

    rng = np.random.default_rng(4)
    X = rng.standard_normal((6, 6))
    nd = -(X @ X.T) - 0.1 * np.eye(6)
    assert _abscissa(nd) < 0
    shifted = nd + 2.0 * np.eye(6)
    want = float(np.linalg.eigvals(shifted).real.max())
    assert want > 0 and _abscissa(shifted) == pytest.approx(want, rel=1e-12)
    # eigenvalues -1, -1 with a large off-diagonal coupling: stable, symmetric part not
    nonnormal = np.array([[-1.0, 10.0], [0.0, -1.0]])
    assert np.linalg.eigvalsh(-(nonnormal + nonnormal.T) / 2).min() < 0
    assert _abscissa(nonnormal) == pytest.approx(-1.0)
    assert _abscissa(np.zeros((0, 0))) < 0


def test_growth_bound_of_a_flow_block():
    """The flow's step bound uses the numerical abscissa: never below the largest real part
    of the eigenvalues, equal to it for a symmetric block, -inf when the symmetric part is
    negative definite."""
    from roughslip.coupling.weakening import _abscissa, _growth_bound

    rng = np.random.default_rng(5)
    for _ in range(20):
        J = rng.standard_normal((7, 7)) - 1.5 * np.eye(7)
        mu, om = _abscissa(J), _growth_bound(J)
        assert om >= mu - 1e-12 * np.abs(J).max()
    X = rng.standard_normal((6, 6))
    sym = X @ X.T - 3.0 * np.eye(6)
    assert _growth_bound(sym) == pytest.approx(float(np.linalg.eigvalsh(sym).max()), rel=1e-12)
    assert _growth_bound(-(X @ X.T) - 0.1 * np.eye(6)) == -np.inf
    nonnormal = np.array([[-1.0, 10.0], [0.0, -1.0]])
    assert _growth_bound(nonnormal) == pytest.approx(4.0)  # symmetric part: -1 +- 5
    assert _growth_bound(np.zeros((0, 0))) == -np.inf


@pytest.mark.parametrize("control", ["depth", "force"])
def test_gap_gradient_bound_holds(monkeypatch, control):
    """The gaps' gradient bound that certifies a step (one product with the positive kernel)
    is at least the exact 1-norm of every gap's gradient, each column taken through the FFT
    operator, at every set of a pull."""
    import roughslip.coupling.weakening as wk

    seen = []
    norms = wk.WeakeningContact._norms

    def check(self):
        norms(self)
        lin = self.lin
        off = np.flatnonzero(~self.C)
        zero = np.zeros(self.base.size)
        exact = np.abs(self.gaps(lin.fz1, lin.fx1, lin.dep1)[off] + self.base[off])
        for r in range(lin.sites.size):
            fz = lin.spread(zero, np.ones(1), lin.Nz[r:r + 1])
            fx = lin.spread(zero, np.ones(1), lin.Nx[r:r + 1])
            exact += np.abs(self.gaps(fz, fx, lin.dN[r])[off] + self.base[off])
        seen.append(float((exact / lin.gn).max(initial=0.0)))

    monkeypatch.setattr(wk.WeakeningContact, "_norms", check)
    pb = Problem.from_arrays(rough(16, 2), nu=0.25)
    kw = dict(depth=1.5) if control == "depth" else dict(force=20.0, pull_control="force")
    w = _weak(pb, 0.1, 0.05, history="frictionless", **kw)
    assert w.converged and len(seen) > 10
    assert max(seen) <= 1.0
    assert max(seen) > 0.1  # a bound that means something, not the kernel's largest entry


def test_a_stopped_bond_beyond_its_strength_moves_again(monkeypatch):
    """A bond stopped in one flow whose excess a change of the sets has put above the flow's
    threshold moves in the next: it starts the flow mobile, so the burst lands where it
    lands with no bond held. Injected before the first flows of a bonded history's
    release, the pull is the one without the injection, event for event."""
    from roughslip.coupling import weakening as wk

    pb = Problem.from_arrays(rough(16, 3), nu=0.25)
    kw = dict(depth=1.5, history="bonded")
    ref = _weak(pb, 0.1, 0.05, **kw)
    flow = wk.WeakeningContact._flow
    injected = []

    def held_flow(self):
        R = self.residual(self.s, self.D)
        over = np.flatnonzero(R > 10 * wk.FLOW_EPS * self.fscale())
        if len(injected) < 3 and over.size:
            j = int(self.lin.sites[over[np.argmax(R[over])]])
            self._stopped.add(j)
            injected.append(j)
        return flow(self)

    monkeypatch.setattr(wk.WeakeningContact, "_flow", held_flow)
    w = _weak(pb, 0.1, 0.05, **kw)
    assert injected, "the scene has no flow with a bond beyond its strength"
    assert w.converged, w.message
    assert [(e.kind, e.site) for e in w.events] == [(e.kind, e.site) for e in ref.events]
    assert w.friction_force == ref.friction_force


@pytest.mark.timeout(600)  # a regression here hangs: that is a failure too
@pytest.mark.parametrize(("sample", "nu", "depth", "history"),
                         [(2, 0.25, 1.369, "frictionless"), (18, 0.45, 2.0, "bonded")])
def test_a_burst_leaves_a_slow_mode_whatever_its_push(monkeypatch, sample, nu, depth, history):
    """Two 32^2 scenes whose bursts start from modes that grow slowly. In the first, a fold
    located on its stable side (rate about 1e-9 of the stiffest bond's): a push of 1e-9 d_c
    left the flow at the residual's rounding floor, integrating for ever. In the second, a
    mode growing at 1e-5: the flow's residual stayed below 1e-6 of the largest normal force
    and the polish took the state back to the unstable one it was pushed from, for ever.
    The push grows until the mode escapes, and the landing does not depend on it: on a
    ladder of pushes three times larger, the same events and the same friction."""
    from roughslip.coupling import weakening as wk

    h = self_affine((32, 32), hurst=0.8, rms_height=1.0, rng=sample_rng(8, sample),
                    oversample=2)
    pb = Problem.from_arrays(h, nu=nu)
    kw = dict(depth=depth * float(h.std()), history=history)
    push, pushes = wk.WeakeningContact._push, []

    def logged(self, mode):
        s0 = self.s.copy()
        push(self, mode)
        pushes.append((mode[1], float(np.abs(self.s - s0).max()) / self.law.dc))

    monkeypatch.setattr(wk.WeakeningContact, "_push", logged)
    ref = _weak(pb, 0.1, 0.05, **kw)
    assert ref.converged, ref.message
    slow = [k for rate, k in pushes if rate < wk.ESCAPE or k >= 1e-3]
    assert slow, "no burst of the scene starts at a slow mode"
    # every push on a ladder half a decade up (the slow mode's push among them)
    monkeypatch.setattr(wk, "PUSHES", tuple(3 * k for k in wk.PUSHES))
    pushes.clear()
    w = _weak(pb, 0.1, 0.05, **kw)
    assert w.converged, w.message
    assert [(e.kind, e.site) for e in w.events] == [(e.kind, e.site) for e in ref.events]
    assert w.friction_force == pytest.approx(ref.friction_force, rel=1e-12)


def test_a_fold_no_push_can_leave_is_refused(monkeypatch):
    """A mode that would not grow at the least escape rate after the largest push is an
    error naming the fold, never an endless flow."""
    from roughslip.coupling import weakening as wk

    monkeypatch.setattr(wk, "ESCAPE", np.inf)
    pb = Problem.from_arrays(rough(16, 1), nu=0.25)
    with pytest.raises(NumericalError, match="cannot leave the state at D_x"):
        _weak(pb, 0.1, 0.05, depth=1.5, history="frictionless")


def test_a_stalled_flow_is_refused(monkeypatch):
    """A burst's flow that reaches no event within its budget of rate evaluations is an
    error naming the drive, never an endless integration."""
    from roughslip.coupling import weakening as wk

    monkeypatch.setattr(wk, "FLOW_EVALS", 2)
    pb = Problem.from_arrays(rough(16, 1), nu=0.25)
    with pytest.raises(NumericalError, match=r"flow at D_x = .* reached no event in 2 "):
        _weak(pb, 0.1, 0.05, depth=1.5, history="frictionless")


def test_a_push_the_flow_brings_back_grows(monkeypatch):
    """A flow that lands back on the state it was pushed from, with no set changed, is
    pushed again ten times harder, through every push to the refusal: never the same
    push, flow and polish for ever."""
    from roughslip.coupling import weakening as wk

    levels = []

    def back(self):
        levels.append(self._origin[2])
        self.s = self._origin[1].copy()
        self._pushed = False

    monkeypatch.setattr(wk.WeakeningContact, "_flow", back)
    pb = Problem.from_arrays(rough(16, 1), nu=0.25)
    with pytest.raises(NumericalError, match="or the flow came back"):
        _weak(pb, 0.1, 0.05, depth=1.5, history="frictionless")
    assert levels == list(range(levels[0], len(wk.PUSHES)))


def _inject_contact_cycle(monkeypatch, limit: int) -> list[int]:
    """Make the bursts of a pull see, ``limit`` times, one site out of contact closing its
    gap and in contact pulling (its loss and its gain in turn); the sites seen."""
    from roughslip.coupling import weakening as wk

    violation, flips = wk.WeakeningContact._violation, []

    def flip(self):
        if self.drive == "x" and self.bursts and len(flips) < limit:
            j = flips[0] if flips else int(np.flatnonzero(~self.C)[0])
            flips.append(j)
            return (EventKind.LOST, j) if self.C[j] else (EventKind.GAINED, j)
        return violation(self)

    monkeypatch.setattr(wk.WeakeningContact, "_violation", flip)
    return flips


def test_a_contact_cycle_inside_a_burst_ends_the_pull_unconverged(monkeypatch):
    """A site that closes its gap out of contact and pulls in contact, inside a burst, has
    no quasi-static continuation: the burst stops on the site's second return (not after
    its iteration limit) and the pull ends there, reported as not converged, with the
    message naming the drive and the site. The site's two violations are injected into the
    first burst of the pull."""
    flips = _inject_contact_cycle(monkeypatch, 20)
    pb = Problem.from_arrays(rough(16, 1), nu=0.25)
    w = _weak(pb, 0.1, 0.05, depth=1.5, history="frictionless")
    assert flips, "the pull has no burst"
    assert not w.converged
    assert w.message.startswith("the events cycle inside a burst at D_x = ")
    assert f"'gained' at site {flips[0]} came back 2 times" in w.message
    assert len(flips) < 20  # stopped by the cycle, long before the injection runs out


def test_a_burst_whose_flow_stands_still_is_refused(monkeypatch):
    """A flow that changes neither the slips nor the sets while the state is not at rest
    would repeat for ever: on its third time the burst stops with an error naming the
    drive."""
    from roughslip.coupling import weakening as wk

    def still(self):
        self._pushed = False

    monkeypatch.setattr(wk.WeakeningContact, "_flow", still)
    pb = Problem.from_arrays(rough(16, 1), nu=0.25)
    with pytest.raises(NumericalError, match=r"flow makes no progress at D_x = "):
        _weak(pb, 0.1, 0.05, depth=1.5, history="frictionless")


def _viscous_slip(wc, j: int, sign: float, eta: float, span: float) -> float:
    """The slip of bond ``j``, in d_c, after the drive moves by ``span`` from the current
    point under the viscous law :math:`\\eta\\,\\dot s_i = \\max(e_i, 0)` on every bond (each
    slipping in the direction of its force, ``j`` in ``sign``'s), integrated by BDF: the
    regularisation whose limit the bursts follow, independent of the path-follower."""
    from scipy.integrate import solve_ivp

    from roughslip.coupling import weakening as wk

    law, lin = wc.law, wc.lin
    assert not wc.s.any()  # at an event's point: the slips are folded in
    fz, fx, _ = wc.fields(wc.s, wc.D)
    Q = np.flatnonzero(wc.Q)
    sg = np.where(wc.phase[Q] == wk.STICK, np.sign(fx[Q]), wc.sigma[Q])
    sg[Q == j] = sign
    Uz, Ux = wc.solver.unit_responses(Q)
    Az, Ax = -(sg[:, None] * Uz[:, Q]).T, -(sg[:, None] * Ux[:, Q]).T
    dl = wc.delta[Q]

    def excess(s, t):
        lam = law.lam_s - law.k * np.minimum(dl + s, law.dc)
        return (sg * (fx[Q] + t * lin.fx1[Q] + Ax @ s)
                - lam * (fz[Q] + t * lin.fz1[Q] + Az @ s))

    def jac(t, s):
        lam = law.lam_s - law.k * np.minimum(dl + s, law.dc)
        J = sg[:, None] * Ax - lam[:, None] * Az
        J[np.diag_indices(Q.size)] += np.where(dl + s < law.dc, law.k, 0.0) * (
            fz[Q] + t * lin.fz1[Q] + Az @ s)
        return (excess(s, t) > 0)[:, None] * J / eta

    sol = solve_ivp(lambda t, s: np.maximum(excess(s, t), 0.0) / eta, (0.0, span),
                    np.zeros(Q.size), method="BDF", jac=jac, rtol=1e-8,
                    atol=1e-14 * law.dc)
    assert sol.status == 0, sol.message
    return float(sol.y[np.flatnonzero(Q == j)[0], -1]) / law.dc


@pytest.mark.timeout(600)  # the old rule chattered to the event limit
def test_a_failure_into_an_unstable_mode_bursts_the_way_the_viscous_law_does(monkeypatch):
    """A 32^2 indentation (seed 8, sample 0, nu = 0.25, 2 rms, d_c = 0.01) where a fresh
    bond's failure makes the state unstable, and the drive alone (dR/dD at held slips)
    forces the mode backward while the path that led there loads the bond forward. The
    first sign held the bond and pushed the rest of the mode: it stuck again, its
    neighbours re-slipped one by one and it failed again, 12k events for 1e-4 of depth.
    The viscous law, integrated independently at eta = 1e-8 from the event, runs the bond
    forward through d_c at once: the burst's sign is the path's, and the indentation
    ends."""
    from roughslip.coupling import weakening as wk

    h = self_affine((32, 32), hurst=0.8, rms_height=1.0, rng=sample_rng(8, 0), oversample=2)
    pb = Problem.from_arrays(h, nu=0.25)
    mode, apply = wk.WeakeningContact.unstable_mode, wk.WeakeningContact.apply
    checked, last = [], []

    def logged_apply(self, kind, j):
        last[:] = [str(kind), j]
        return apply(self, kind, j)

    def logged(self, forcing=None):
        v, rate = mode(self, forcing)
        if (forcing is not None and not checked and self.drive == "z"
                and last[0] in ("slip+", "slip-")):
            JA = self.jacobian(self.s, self.D)
            w, vl = linalg.eig(JA[:, :-1], left=True, right=False)
            u = vl[:, int(np.argmax(w.real))].real
            if float(u @ forcing) * float(u @ JA[:, -1]) < 0:
                r = int(np.argmax(np.abs(forcing)))
                j = int(self.lin.sites[r])
                assert j == last[1]  # the forcing is the failed bond's loading
                assert v[r] > 0, "the failed bond is held"
                checked.append(_viscous_slip(self, j, self.sigma[j], 1e-8, 2e-6))
        return v, rate

    monkeypatch.setattr(wk.WeakeningContact, "apply", logged_apply)
    monkeypatch.setattr(wk.WeakeningContact, "unstable_mode", logged)
    w = _weak(pb, 0.1, 0.01, depth=2.0 * float(h.std()), history="indent")
    assert checked, "no failure of the scene loads a mode the drive alone would reverse"
    assert checked[0] >= 1.0  # the viscous law weakens the bond through d_c
    assert w.converged, w.message


@pytest.mark.timeout(600)
def test_a_violation_that_returns_shrinking_is_an_approach_not_a_cycle(monkeypatch):
    """A 32^2 indentation (seed 8, sample 3, nu = 0.25, 0.94 rms, d_c = 0.01): inside a
    burst, a site slips, pulls itself into tension through the coupling, is lost, closes its
    gap and is gained again, each time with a hundredth of the forces (a Zeno sequence onto
    a contact with no force). Its third loss was taken for a cycle, an error that killed the
    run. A return at less than a tenth of the last one's size does not count, and the
    indentation reaches its depth."""
    from roughslip.coupling import weakening as wk

    h = self_affine((32, 32), hurst=0.8, rms_height=1.0, rng=sample_rng(8, 3), oversample=2)
    pb = Problem.from_arrays(h, nu=0.25)
    size, sizes = wk.WeakeningContact._size, {}

    def logged(self, kind, j):
        out = size(self, kind, j)
        if self.drive == "z":
            sizes.setdefault((str(kind), j, self.D, self.signature()), []).append(out)
        return out

    monkeypatch.setattr(wk.WeakeningContact, "_size", logged)
    depth = 0.3 * (2.0 / 0.3) ** 0.6  # the fourth of six depths 0.3-2 rms, log-spaced
    w = _weak(pb, 0.1, 0.01, depth=depth * float(h.std()), history="indent")
    assert w.converged, w.message
    returns = [v for (kind, *_), v in sizes.items() if kind == "lost" and len(v) >= 3]
    assert any(all(b < wk.APPROACH * a for a, b in itertools.pairwise(v)) for v in returns), (
        "no loss of the scene returns three times, shrinking")


def test_a_violation_that_keeps_shrinking_is_a_cycle_after_thirty_returns(monkeypatch):
    """Returns that shrink are an approach, but not for ever: the injected contact cycle of
    the test above, with every size a hundredth of the last, stops on its thirtieth
    return."""
    from roughslip.coupling import weakening as wk

    flips, sizes = _inject_contact_cycle(monkeypatch, 200), []

    def shrinking(self, kind, j):
        sizes.append(0.01 ** len(sizes))
        return sizes[-1]

    monkeypatch.setattr(wk.WeakeningContact, "_size", shrinking)
    pb = Problem.from_arrays(rough(16, 1), nu=0.25)
    w = _weak(pb, 0.1, 0.05, depth=1.5, history="frictionless")
    assert not w.converged
    assert f"'gained' at site {flips[0]} came back {wk.RETURNS} times" in w.message
    assert len(flips) < 200  # stopped by the cap, not by the injection running out


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_burst_leaves_a_flat_valley(monkeypatch):
    """A 64^2 bonded pull (the rough configuration's sample 11 at 2 rms, d_c = 0.01) has a
    fold whose mode grows (4e-6 of the stiffest bond's rate) but whose residual stays below
    the flow's threshold for every push of the ladder: it was refused. The push past the
    ladder is the root of the residual's exact quadratic along the mode; at that push the
    largest excess is FLAT flow thresholds (unless an event ends the push first), and the
    landing does not depend on it: at four times the excess, the same events and the same
    friction."""
    from pathlib import Path

    from roughslip.coupling import weakening as wk
    from roughslip.run.config import load_config
    from roughslip.run.sample import run_sample

    cfg = load_config(Path(__file__).parents[1] / "configs" / "rough_h08.toml", [
        "grid.n=64", "ensemble.samples=20", "squeeze.depths=[2.0]", "material.nu=0.25",
        "coupling.enabled=true", "pull.slip_law='slip-weakening'", "pull.lam_dynamic=0.1",
        "pull.slip_distance=0.01", "coupling.history='bonded'"])
    flat, pushes = wk.WeakeningContact._flat_push, []

    def logged(self, s0, v):
        x = flat(self, s0, v)
        if x is not None:
            R = self.residual(s0 + x * self.law.dc * v, self.D)
            below = self.residual(s0 + 0.999 * x * self.law.dc * v, self.D)
            self.s = s0 + x * self.law.dc * v
            event = self._violation() is not None
            self.s = s0
            unit = wk.FLOW_EPS * self.fscale()
            pushes.append((x, float(R.max()) / unit, float(below.max()) / unit, event))
        return x

    monkeypatch.setattr(wk.WeakeningContact, "_flat_push", logged)
    runs = []
    for excess in (wk.FLAT, 4 * wk.FLAT):
        monkeypatch.setattr(wk, "FLAT", excess)
        pushes.clear()
        res = run_sample(cfg, 11)
        assert res.scalars["pull_converged"][0] == 1.0
        assert pushes, "no burst of the scene left a flat valley"
        for x, at, before, event in pushes:
            assert x > 0
            assert before < excess
            if not event:  # else an event ended the push before the excess was reached
                assert at == pytest.approx(excess, rel=1e-6)
        runs.append(res.scalars)
    for key in ("pull_steps", "released_bonds"):
        assert runs[1][key][0] == runs[0][key][0]
    assert runs[1]["friction_force"][0] == pytest.approx(runs[0]["friction_force"][0],
                                                         rel=1e-12)


def test_a_weak_mode_lands_where_a_finer_flow_rests(monkeypatch):
    """A 64^2 indentation (the rough configuration's sample 7 at 1.37 rms, nu = 0.25,
    d_c = 0.01) has a burst whose mode grows at 6e-6 of the stiffest bond's rate and stops
    growing within 0.01 d_c: along it the excess peaks at 3e-10 of the largest normal force,
    below the flow's threshold, and the sample was refused. The rest beyond the peak is found
    by Newton's method: a stable state, every slip grown, no excess left. A flow with a ten
    times finer threshold resolves that burst itself, and gives the same friction force and
    the same released bonds."""
    from pathlib import Path

    from roughslip.coupling import weakening as wk
    from roughslip.run.config import load_config
    from roughslip.run.sample import run_sample

    cfg = load_config(Path(__file__).parents[1] / "configs" / "rough_h08.toml", [
        "grid.n=64", "ensemble.samples=20", "squeeze.depths=[1.3685108578372633]",
        "material.nu=0.25", "coupling.enabled=true", "pull.slip_law='slip-weakening'",
        "pull.lam_dynamic=0.1", "pull.slip_distance=0.01", "coupling.history='indent'"])
    weak, landings = wk.WeakeningContact._weak_landing, []

    def logged(self, s0, v):
        s1 = weak(self, s0, v)
        if s1 is not None:
            R = self.residual(s1, self.D)
            landings.append((float(np.abs(R).max()) / self.fscale(), self.stable(),
                             float((s1 - s0).min()) / self.law.dc,
                             float((s1 - s0).max()) / self.law.dc))
            self.s = s1
        return s1

    monkeypatch.setattr(wk.WeakeningContact, "_weak_landing", logged)
    newton = run_sample(cfg, 7).scalars
    assert newton["pull_converged"][0] == 1.0
    assert landings, "no burst of the scene landed by Newton's method"
    for excess, stable, least, most in landings:
        assert excess <= 1e-14 and stable and least >= -1e-9 * most and most > 1e-3
    monkeypatch.setattr(wk.WeakeningContact, "_weak_landing", lambda self, s0, v: None)
    monkeypatch.setattr(wk, "FLOW_EPS", wk.FLOW_EPS / 10)
    monkeypatch.setattr(wk, "REST", wk.REST / 10)
    flow = run_sample(cfg, 7).scalars
    assert flow["pull_converged"][0] == 1.0
    assert flow["released_bonds"][0] == newton["released_bonds"][0]
    assert flow["friction_force"][0] == pytest.approx(newton["friction_force"][0], rel=1e-12)


@pytest.mark.parametrize(("c0", "c1", "c2", "x"), [
    (0.0, 1e-8, 0.0, 1e8),  # linear
    (0.0, 1e-8, 1e-25, 1e8 * (1 - 1e-9)),  # near-linear: no cancellation to zero
    (0.0, 0.0, 4.0, 0.5),  # quadratic from rest
    (0.0, -1.0, 2.0, 1.0),  # falls first, then convex: the larger root
    (0.5, 1e-8, -1e-3, None),  # concave, never reaches it
    (0.0, 3.0, -2.0, 0.5),  # concave, the smaller root
    (0.0, -1.0, -1.0, None),  # falls for ever
    (1.5, -1.0, 0.0, 0.0),  # there already
])
def test_least_crossing_of_a_quadratic(c0, c1, c2, x):
    """The push that takes an excess quadratic along the mode to the target, in every sign
    case of its coefficients, against the roots computed by numpy."""
    from roughslip.coupling.weakening import _least_crossing

    got = _least_crossing(np.array([c0, 0.0]), np.array([c1, 0.0]), np.array([c2, 0.0]))
    if x is None:
        assert got is None
        return
    assert got == pytest.approx(x, rel=1e-7)
    if 0 < got:
        roots = np.roots([c2, c1, c0 - 1.0]) if c2 else np.array([(1.0 - c0) / c1])
        real = roots[np.isreal(roots)].real
        assert got == pytest.approx(real[real > 0].min(), rel=1e-7)


@pytest.mark.timeout(600)
def test_a_flow_that_overflows_goes_on_over_shorter_horizons(monkeypatch):
    """BDF can overflow on the huge steps it takes near rest (seen once on a 64^2 bonded
    pull: both horizons overflowed). Forced to overflow on every horizon above 1e3, each flow
    runs on the shortest and the burst's loop goes on from its end: the same events and the
    same friction. Overflowing on every horizon is a one-line error."""
    from roughslip.coupling import weakening as wk

    h = self_affine((32, 32), hurst=0.8, rms_height=1.0, rng=sample_rng(8, 2), oversample=2)
    pb = Problem.from_arrays(h, nu=0.25)
    kw = dict(depth=1.369 * float(h.std()), history="frictionless")
    ref = _weak(pb, 0.1, 0.05, **kw)
    assert ref.converged, ref.message
    real, spans = wk.solve_ivp, []

    def overflowing(fun, t_span, *args, **kwargs):
        spans.append(t_span[1])
        if t_span[1] > 1e3:
            raise FloatingPointError("overflow encountered")
        return real(fun, t_span, *args, **kwargs)

    monkeypatch.setattr(wk, "solve_ivp", overflowing)
    w = _weak(pb, 0.1, 0.05, **kw)
    assert 1e3 in spans, "the scene has no burst's flow"
    assert w.converged, w.message
    assert [(e.kind, e.site) for e in w.events] == [(e.kind, e.site) for e in ref.events]
    assert w.friction_force == pytest.approx(ref.friction_force, rel=1e-9)
    monkeypatch.setattr(wk, "FLOW_SPANS", (1e12, 1e6))
    with pytest.raises(NumericalError, match=r"coupled slip-weakening: the burst's flow "
                                             r"overflowed$") as e:
        _weak(pb, 0.1, 0.05, **kw)
    assert "\n" not in str(e.value)
