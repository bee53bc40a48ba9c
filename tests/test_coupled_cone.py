"""The frictional indentation of the coupled model under the faceted Coulomb cone with the
traction vector (roughslip/coupling/cone.py; docs/theory/coupled.rst#coupled-cone)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from roughslip.analysis.verify import hertz_scene
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import squeeze
from roughslip.coupling import cone as cone_module
from roughslip.coupling.cone import OUT, indent_cone
from roughslip.elastic.green import pixel_kernel
from roughslip.errors import InputError
from roughslip.friction.cone import Cone
from roughslip.surfaces.synthetic import sample_rng, self_affine

NAMES = ("z", "x", "y")


def _path(monkeypatch, problem, depth, **kw):
    """The indentation and every state of its path: the forces and displacements on the
    grid, (3, n) each, just before each event (recorded from the engine, checked by the
    test)."""
    states = []
    apply = cone_module.ConeIndent.apply

    def record(self, p, mode, face=0):
        if hasattr(self, "F0"):
            e = None if self.e is None else self.e.copy()
            free = np.zeros(self.base.size, bool)  # contacts without a bond
            free[self.sites[:self.used][self.mode[:self.used] == cone_module.FREE]] = True
            states.append((e, self.D, self.F0 + self.D * self.F1, self.U0 + self.D * self.U1,
                           free))
        apply(self, p, mode, face)

    monkeypatch.setattr(cone_module.ConeIndent, "apply", record)
    res = (indent_cone(problem, depth, **kw) if "direction" not in kw
           else cone_module.couple_cone(problem, depth, **{"gained": "bonded", **kw}))
    return res, states


def _dense(problem) -> np.ndarray:
    """The full (3n, 3n) operator on the grid, component-major, from the point-evaluated
    pixel kernels (not the operator's tables)."""
    ny, nx = problem.shape
    iy, ix = np.divmod(np.arange(ny * nx), nx)
    L, M = ix[:, None] - ix[None, :], iy[:, None] - iy[None, :]
    mat = problem.material
    a = problem.grid.a
    n = ny * nx
    G = np.empty((3 * n, 3 * n))
    for i, p in enumerate(NAMES):
        for j, q in enumerate(NAMES):
            G[i * n:(i + 1) * n, j * n:(j + 1) * n] = pixel_kernel(p + q, L, M, a=a, E=mat.E,
                                                                  nu=mat.nu)
    return G


def _certify(problem, states, lam, facets, depth=None, direction=0.0):
    r"""The path is the exact solution of the rate problem of the faceted cone: the
    displacements are those of the forces; every contact holds its overlap, every other site
    has no force and an open gap; every force is in its polygon; and between two states each
    contact's slip increment :math:`\Delta\mathbf s = -\Delta\mathbf u_t` lies in the normal
    cone of the polygon at the forces between them (maximum dissipation,
    :math:`\Delta\mathbf s\cdot(\lambda f_z\mathbf v_g - \mathbf f_t) \le 0` for every
    vertex :math:`\mathbf v_g`), and is zero where the force is inside. While pulling along
    :math:`\hat{\mathbf e}` at ``depth`` the slip is :math:`D\hat{\mathbf e} - \mathbf
    u_t` plus a constant."""
    G = _dense(problem)
    n = problem.base.size
    base = problem.base.ravel()
    cone = Cone(facets, direction)
    prev = None
    for e, D, F, U, free in states:
        fscale = float(np.abs(F).max())
        u = (G @ F.ravel()).reshape(3, n)
        uscale = float(np.abs(u).max())
        np.testing.assert_allclose(u, U, rtol=0, atol=1e-10 * uscale)
        touch = F[0] > 0
        assert F[0].min() >= -1e-12 * fscale
        assert np.abs(F[:, F[0] <= 0]).max(initial=0.0) <= 1e-12 * fscale
        gap = u[0] - ((D if e is None else depth) + base)
        assert np.abs(gap[touch]).max(initial=0.0) <= 1e-10 * uscale
        assert gap.min() >= -1e-10 * uscale
        over = (F[1:].T @ cone.normals.T).max(axis=1) - cone.rho * lam * F[0]
        assert over.max() <= 1e-10 * fscale
        assert np.abs(F[1:, free]).max(initial=0.0) == 0.0
        if prev is not None and D > prev[1] and (e is None) == (prev[0] is None):
            _, D0, F0, U0, _ = prev
            mid = 0.5 * (F0 + F)
            both = (F0[0] > 0) & touch & ~free
            ds = -(U[1:] - U0[1:]).T[both]
            if e is not None:
                ds += (D - D0) * e
            ft, cap = mid[1:].T[both], lam * mid[0][both]
            size = np.linalg.norm(ds, axis=1)
            worst = ((cap[:, None, None] * cone.vertices[None] - ft[:, None, :])
                     * ds[:, None, :]).sum(axis=2).max(axis=1)
            floor = 1e-10 * uscale
            assert (worst <= 1e-9 * fscale * size + floor * fscale).all()
            inside = (ft @ cone.normals.T).max(axis=1) - cone.rho * cap < -1e-9 * fscale
            if inside.any():
                assert size[inside].max() <= floor
        prev = (e, D, F, U, free)


def _sphere(ah: int, nu: float) -> tuple[Problem, float]:
    heights, h, depth, _ = hertz_scene(ah)
    return Problem.from_arrays(heights, a=h, E=1.0, nu=nu), depth


@pytest.mark.parametrize("scene,nu,lam,facets", [("sphere", 0.0, 0.3, 16),
                                                  ("rough", 0.25, 0.2, 12)])
def test_the_event_path_solves_the_rate_problem(monkeypatch, scene, nu, lam, facets):
    if scene == "sphere":
        problem, depth = _sphere(4, nu)
    else:
        heights = self_affine((14, 14), hurst=0.8, rms_height=1.0, rng=sample_rng(3, 0))
        problem, depth = Problem.from_arrays(heights, nu=nu), 2.2
    res, states = _path(monkeypatch, problem, depth, lam=lam, facets=facets)
    assert res.residual < 1e-10 and res.events == len(states) > 20
    _certify(problem, states, lam, facets)
    # the slip zone carries tangential forces, and some contact still sticks
    assert res.stick.any() and (res.contact & ~res.stick).any()


def test_at_nu_one_half_the_indentation_is_frictionless_and_stuck():
    """At nu = 1/2 nothing couples: the normal forces are the frictionless squeeze's, no
    tangential force appears, and every contact sticks."""
    problem, depth = _sphere(5, 0.5)
    res = indent_cone(problem, depth, lam=0.3, facets=16)
    normal = squeeze(problem, depth=depth, tol=1e-13)
    scale = float(normal.fz.max())
    np.testing.assert_allclose(res.fz, normal.fz, rtol=0, atol=1e-10 * scale)
    assert np.abs(res.fx).max() == 0.0 and np.abs(res.fy).max() == 0.0
    assert (res.stick == (normal.fz > 0)).all()


@pytest.mark.parametrize("nu,lam", [(0.0, 0.2986), (0.25, 0.15)])
def test_spence_sphere_stick_ratio(nu, lam):
    """Spence's sphere: at nu = 0 and lam = 0.2986 the continuum stick radius is half the
    contact radius; the ring-element solution gives c/a at any nu
    (:func:`~roughslip.contact.analytic.sphere_indentation_stick_ratio`: 0.4998 there, 0.356
    at nu = 0.25, lam = 0.15). At a/h = 8 (208 contact sites) the model's c/a, averaged over
    the second half of the loading in depth, is within h/(5a) = 0.025 of it (0.017 and 0.019
    off; docs/results.md: the resolution study). Over that half it stays within a ring of
    pixels at each edge of the stick zone (self-similarity), and the slip zone's tractions
    point outwards, within two facets' angle of the radius (4.1 degrees at most at nu = 0)."""
    from roughslip.contact.analytic import sphere_indentation_stick_ratio

    problem, depth = _sphere(8, nu)
    res = indent_cone(problem, depth, lam=lam, facets=32)
    ratio, low, high = res.loading_ratio(depth / 2)
    assert abs(ratio - sphere_indentation_stick_ratio(lam, nu=nu, n=20)) < 0.025
    assert high - low < 2.0 / 8
    slip = res.contact & ~res.stick
    ny, nx = problem.shape
    y, x = np.mgrid[:ny, :nx] - (np.array([ny, nx])[:, None, None] - 1) / 2
    r = np.hypot(x, y)[slip]
    ft = np.stack([res.fx[slip], res.fy[slip]])
    cos = (ft[0] * x[slip] + ft[1] * y[slip]) / (r * np.hypot(*ft))
    assert cos.min() > math.cos(2 * math.pi / 32)  # a vertex is within pi/m of its slip
    # the slip zone carries the full friction of its polygon
    assert (np.hypot(*ft) >= math.cos(math.pi / 32) * lam * res.fz[slip] * (1 - 1e-9)).all()


def test_mode_and_fields_agree():
    problem, depth = _sphere(4, 0.2)
    res = indent_cone(problem, depth, lam=0.25, facets=8)
    assert ((res.mode == OUT) == (res.fz == 0)).all()
    assert (np.diff(res.path_depth) >= 0).all() and res.path_depth[0] == 0.0
    assert res.path_contact[-1] == res.contact.sum() and res.path_stick[-1] == res.stick.sum()
    # a sphere pressed deeper carries more: F_z grows along the path and on to the end
    assert (np.diff(res.path_force) >= -1e-12 * res.fz.sum()).all()
    assert res.fz.sum() >= res.path_force[-1]


@pytest.mark.parametrize("kw,match", [({"lam": 0.0}, "lam = 0.0"),
                                      ({"facets": 3}, "facets = 3"),
                                      ({"facets": 8.0}, "facets = 8.0")])
def test_bad_input_is_refused_in_one_line(kw, match):
    problem, depth = _sphere(3, 0.0)
    with pytest.raises(InputError, match=match) as err:
        indent_cone(problem, depth, **kw)
    assert "\n" not in str(err.value)
    with pytest.raises(InputError, match="depth = -1"):
        indent_cone(problem, -1.0)


def test_the_pull_solves_the_rate_problem(monkeypatch):
    """The indentation, then the pull along 30 degrees at nu = 0.3 to full sliding: the whole
    path is the rate problem's solution (dense point-evaluated kernels), and at full
    sliding every contact carries lam f_z along the drive (a vertex is on it)."""
    problem, depth = _sphere(4, 0.3)
    res, states = _path(monkeypatch, problem, depth, lam=0.3, facets=12, direction=30.0)
    assert res.converged and res.residual < 1e-10
    pulled = [s for s in states if s[0] is not None]
    assert len(pulled) == res.curve.drive.size - 1 > 20
    _certify(problem, states, 0.3, 12, depth=depth, direction=30.0)
    e = np.array([math.cos(math.radians(30)), math.sin(math.radians(30))])
    end = res.curve.force[-1]
    assert end @ e == pytest.approx(0.3 * res.curve.fz[-1], rel=1e-10)
    assert abs(end @ np.array([-e[1], e[0]])) < 1e-10 * res.friction_force


@pytest.mark.parametrize("gained", ["bonded", "unbonded"])
def test_a_pull_that_gains_contacts_solves_the_rate_problem(monkeypatch, gained):
    """A rough scene pulled at lam = 0.8 gains contacts during the pull: bonded where they
    touch (a new contact starts at the cone's apex and slips at once), or without a bond
    (no tangential force). The path is still the rate problem's solution."""
    heights = self_affine((18, 18), hurst=0.8, rms_height=1.0, rng=sample_rng(1, 0))
    problem = Problem.from_arrays(heights, nu=0.0)
    res, states = _path(monkeypatch, problem, 2.0, lam=0.8, facets=12, direction=30.0,
                        gained=gained)
    assert res.converged and res.residual < 1e-10
    assert "gained" in res.curve.kind
    _certify(problem, states, 0.8, 12, depth=2.0, direction=30.0)


def test_periodic_grids_gain_contacts_anywhere():
    """On a periodic grid the coupled squeeze may touch far from the geometric overlap: the
    engine makes room for every site that touches, and certifies the path."""
    heights = self_affine((16, 16), hurst=0.8, rms_height=1.0, rng=sample_rng(6, 0))
    problem = Problem.from_arrays(heights, nu=0.25, boundary="periodic")
    depth = 0.5 * problem.depth_limit()
    res = cone_module.couple_cone(problem, depth, lam=0.5, facets=12, direction=30.0)
    assert res.converged and res.residual < 1e-10
    assert (res.start.contact & ~(problem.overlap(depth) >= 0)).any()


def test_at_nu_one_half_the_coupled_pull_is_the_decoupled_one():
    """At nu = 1/2 the coupled pull with the traction vector is the decoupled Coulomb cone's
    from the frictionless squeeze: the same curve (interpolated at its events) and the same
    friction force, lam F_n."""
    from roughslip import couple, pull

    problem, depth = _sphere(5, 0.5)
    res = couple(problem, depth=depth, lam=0.3, slip_law="coulomb", history="indent",
                 components="xy", direction=40.0, facets=16)
    normal = squeeze(problem, depth=depth, tol=1e-13)
    ref = pull(normal, lam=0.3, slip_law="coulomb", components="xy", direction=40.0,
               facets=16)
    assert res.friction_force == pytest.approx(ref.friction_force, rel=1e-12)
    scale = ref.friction_force
    for c in (0, 1):
        mine = np.interp(ref.curve.drive, res.curve.drive, res.curve.force[:, c])
        np.testing.assert_allclose(mine, ref.curve.force[:, c], rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(res.start.fz, normal.fz, rtol=0, atol=1e-10 * normal.fz.max())


@pytest.mark.parametrize("kw,key", [({"slip_law": "break"}, "slip_law = 'break'"),
                                    ({"history": "bonded"}, "history = 'bonded'"),
                                    ({"pull_control": "force"}, "pull_control = 'force'"),
                                    ({"method": "cg"}, "method = 'cg'"),
                                    ({"components": "x", "direction": 30.0}, "direction = 30"),
                                    ({"reference": True}, "reference = True"),
                                    ({"components": "z"}, "components = 'z'")])
def test_the_coupled_vector_pull_refuses_in_one_line(kw, key):
    from roughslip import couple

    problem, depth = _sphere(3, 0.3)
    args = {"depth": depth, "lam": 0.3, "slip_law": "coulomb", "history": "indent",
            "components": "xy", **kw}
    with pytest.raises(InputError) as err:
        couple(problem, **args)
    assert str(err.value).startswith(key) and "\n" not in str(err.value)
