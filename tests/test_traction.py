r"""The traction vector: bonds that carry :math:`(f_x, f_y)` and a drive in any direction of
the surface plane, against a dense brute-force reference and the model's exact symmetries."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.contact.squeeze import squeeze
from roughslip.elastic.green import pixel_kernel
from roughslip.errors import InputError
from roughslip.friction.bonds import Bonds
from roughslip.friction.events import plane_direction
from roughslip.friction.pull import choose_method, pull
from roughslip.surfaces.synthetic import sample_rng, self_affine

EPS = float(np.finfo(float).eps)


def _rough(n: int, seed: int) -> np.ndarray:
    return self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0))


def _brute(normal, nu: float, direction: float, lam: float = 0.2):
    r"""The break law of the traction vector done literally: on each stick set the dense
    :math:`2n \times 2n` system of the point-evaluated pixel kernels
    (:func:`~roughslip.elastic.green.pixel_kernel`, not the operator's tables) solved afresh,
    the bond with the largest :math:`|\boldsymbol\varphi_i|/(\lambda f_{z,i})` broken next.
    Returns the broken sites in order, the pull force along the drive of each break, and the
    least relative gap between the two largest ratios (how near a tie the sequence came)."""
    nx = normal.fz.shape[1]
    sites = np.flatnonzero((normal.contact & (normal.fz > 0)).ravel())
    iy, ix = np.divmod(sites, nx)
    L, M = ix[:, None] - ix[None, :], iy[:, None] - iy[None, :]
    Gxy = pixel_kernel("xy", L, M, nu=nu)
    G = np.block([[pixel_kernel("xx", L, M, nu=nu), Gxy], [Gxy, pixel_kernel("yy", L, M, nu=nu)]])
    e = np.array(plane_direction(direction))
    cap = lam * normal.fz.ravel()[sites]
    n = sites.size
    alive = np.arange(n)
    seq, force, gap = [], [], np.inf
    while alive.size:
        idx = np.concatenate([alive, alive + n])
        phi = np.linalg.solve(G[np.ix_(idx, idx)], np.repeat(e, alive.size))
        px, py = phi[: alive.size], phi[alive.size:]
        ratio = np.hypot(px, py) / cap[alive]
        j = int(np.argmax(ratio))
        if alive.size > 1:
            top = np.sort(ratio)[-2:]
            gap = min(gap, (top[1] - top[0]) / top[1])
        force.append((e[0] * px.sum() + e[1] * py.sum()) / ratio[j])
        seq.append(int(sites[alive[j]]))
        alive = np.delete(alive, j)
    return np.array(seq), np.array(force), gap


@pytest.mark.parametrize("seed,nu,direction", [(1, 0.25, 30.0), (2, 0.45, 0.0),
                                               (3, 0.25, 135.0), (4, 0.45, 71.0)])
def test_break_sequence_matches_the_dense_reference(seed, nu, direction):
    normal = squeeze(_rough(24, seed), depth=2.2, nu=nu, tol=1e-13)
    r = pull(normal, method="inverse", components="xy", direction=direction, early_stop=False)
    seq, force, gap = _brute(normal, nu, direction)
    # the decisions are far from ties here (checked), so the order is the model's, not rounding's
    assert gap > 1e-8
    np.testing.assert_array_equal(r.curve.site[1:], seq)
    # both sides solve SPD systems of condition ~1e2-1e3 (24^2 grids): a few hundred eps
    np.testing.assert_allclose(r.curve.fx[1:], force, rtol=1e-11, atol=0)
    assert r.friction_force == pytest.approx(force.max(), rel=1e-11)
    assert r.converged and r.residual < 1e-10
    assert r.details.components == "xy" and r.details.direction == direction


def _engine(normal, direction: float):
    """The traction vector's own engine (two unknowns per bond), which ``pull`` bypasses at
    nu = 0."""
    import time

    from roughslip.friction.bonds import PullOptions
    from roughslip.friction.breaking import break_sequence
    from roughslip.friction.laws import LAWS
    from roughslip.friction.pull import METHODS

    b = Bonds(normal, 0.2, components=("x", "y"), direction=direction)
    opt = PullOptions(law=LAWS.get("break").bind(0.2), method=METHODS.get("inverse"))
    return break_sequence(b, opt, time.perf_counter())


@pytest.mark.parametrize("direction", [0.0, 30.0, 45.0, 90.0, 200.0])
def test_at_nu_zero_the_vector_model_is_the_x_model_turned(direction):
    """At nu = 0 the pixel kernels are isotropic (G_xx = G_yy, G_xy = 0): every bond's force
    points along the drive and the break sequence is the x-only model's, whatever the
    direction. The vector engine on 2n unknowns gives it, and ``pull`` takes the x-only model
    turned, which is the same to rounding."""
    normal = squeeze(_rough(32, 5), depth=2.5, nu=0.0, tol=1e-13)
    ref = pull(normal, method="inverse")
    fast = pull(normal, method="inverse", components="xy", direction=direction)
    assert fast.message.startswith("nu = 0: the x-only model along the drive, turned")
    assert np.array_equal(fast.curve.fx, ref.curve.fx)
    r = _engine(normal, direction)  # the 2n-unknown engine, independently
    np.testing.assert_array_equal(r.curve.site, ref.curve.site)
    np.testing.assert_allclose(r.curve.fx, ref.curve.fx, rtol=1e-12, atol=0)
    top = abs(ref.peak.fx).max()
    np.testing.assert_allclose(fast.peak.fx, r.peak.fx, rtol=0, atol=1e-12 * top)
    np.testing.assert_allclose(fast.peak.fy, r.peak.fy, rtol=0, atol=1e-12 * top)
    np.testing.assert_array_equal(r.curve.site, ref.curve.site)
    np.testing.assert_allclose(r.curve.fx, ref.curve.fx, rtol=1e-12, atol=0)
    e = np.array(plane_direction(direction))
    F = np.array(r.friction_vector)
    np.testing.assert_allclose(F, r.friction_force * e, rtol=0,
                               atol=1e-12 * r.friction_force)
    # the peak's forces are the x model's, turned
    np.testing.assert_allclose(r.peak.fx, ref.peak.fx * e[0], atol=1e-12 * abs(ref.peak.fx).max())
    np.testing.assert_allclose(r.peak.fy, ref.peak.fx * e[1], atol=1e-12 * abs(ref.peak.fx).max())


@pytest.mark.parametrize("direction", [0.0, 25.0])
def test_swapping_x_and_y_turns_the_drive(direction):
    """The half-space has no preferred direction: the transposed surface pulled at
    90 - theta degrees is the original pulled at theta, at nu > 0 too (G_xx and G_yy swap,
    G_xy is symmetric in x and y). The break sequence maps site (iy, ix) to (ix, iy)."""
    h = _rough(32, 6)
    n = h.shape[0]
    a = squeeze(h, depth=2.2, nu=0.3, tol=1e-13)
    b = squeeze(np.ascontiguousarray(h.T), depth=2.2, nu=0.3, tol=1e-13)
    ra = pull(a, method="inverse", components="xy", direction=direction, early_stop=False)
    rb = pull(b, method="inverse", components="xy", direction=90.0 - direction,
              early_stop=False)
    # the two squeezes agree to rounding only: the order is compared where no decision is
    # nearer a tie than rounding could move it
    assert _brute(a, 0.3, direction)[2] > 1e-8
    iy, ix = np.divmod(ra.curve.site[1:], n)
    np.testing.assert_array_equal(rb.curve.site[1:], ix * n + iy)
    np.testing.assert_allclose(rb.curve.fx, ra.curve.fx, rtol=1e-10, atol=0)
    fa, fb = ra.friction_vector, rb.friction_vector
    assert fb[0] == pytest.approx(fa[1], rel=1e-10, abs=1e-12)
    assert fb[1] == pytest.approx(fa[0], rel=1e-10, abs=1e-12)


def test_reversed_drive_gives_the_same_sequence():
    """Pulling at theta + 180 degrees flips every force: the same breaks, the same curve."""
    normal = squeeze(_rough(32, 7), depth=2.0, nu=0.3, tol=1e-13)
    assert _brute(normal, 0.3, 20.0)[2] > 1e-8  # cos 200 is -cos 20 to rounding only
    a = pull(normal, method="inverse", components="xy", direction=20.0)
    b = pull(normal, method="inverse", components="xy", direction=200.0)
    np.testing.assert_array_equal(a.curve.site, b.curve.site)
    np.testing.assert_allclose(a.curve.fx, b.curve.fx, rtol=1e-12, atol=0)
    np.testing.assert_allclose(a.friction_vector, -np.array(b.friction_vector), rtol=1e-12)


def test_x_model_is_unchanged_by_the_new_keys():
    """``components="x"`` with ``direction=0`` is the report's model, bit for bit, and its
    result says so."""
    normal = squeeze(_rough(32, 8), depth=2.0, nu=0.3, tol=1e-13)
    a = pull(normal, method="inverse")
    b = pull(normal, method="inverse", components="x", direction=0.0)
    np.testing.assert_array_equal(a.curve.fx, b.curve.fx)
    np.testing.assert_array_equal(a.peak.fx, b.peak.fx)
    assert a.friction_force == b.friction_force
    assert a.peak.fy is None and a.friction_vector[1] == 0.0
    assert a.details.components == "x" and a.details.direction == 0.0


def test_the_vector_force_sticks_in_both_directions():
    """At nu > 0 on a rough surface, bonds pulled along x carry f_y (the half-space couples x
    and y); the stick sites hold u = D e in both components, checked by the FFT operator."""
    normal = squeeze(_rough(32, 9), depth=2.5, nu=0.45, tol=1e-13)
    r = pull(normal, method="inverse", components="xy", direction=0.0)
    assert np.abs(r.peak.fy).max() > 1e-3 * np.abs(r.peak.fx).max()
    b = Bonds(normal, 0.2, components=("x", "y"))
    u = b.apply(np.stack([r.peak.fx, r.peak.fy]), np.empty((2, *normal.fz.shape)))
    D = r.peak_dx
    s = r.peak.stick
    np.testing.assert_allclose(u[0][s], D, rtol=1e-10)
    np.testing.assert_allclose(u[1][s], 0.0, atol=1e-10 * D)
    # every stick bond within its strength, |f_t| <= lambda f_z
    ft = np.hypot(r.peak.fx, r.peak.fy)[s]
    assert np.all(ft <= 0.2 * normal.fz[s] * (1 + 1e-9))


def test_bonds_assemble_the_vector_matrix_from_the_tables():
    """The assembler of the stick solver gives the interleaved (x, y) matrix of the kernels,
    symmetric to the last bit, and the operator's product agrees with it."""
    normal = squeeze(_rough(16, 10), depth=2.0, nu=0.3, tol=1e-13)
    b = Bonds(normal, 0.2, components=("x", "y"))
    A = b.entries(np.arange(b.size), np.arange(b.size))
    assert np.array_equal(A, A.T)
    iy, ix = np.divmod(b.sites, 16)
    L, M = ix[:, None] - ix[None, :], iy[:, None] - iy[None, :]
    np.testing.assert_allclose(A[0::2, 0::2], pixel_kernel("xx", L, M, nu=0.3), rtol=1e-13)
    np.testing.assert_allclose(A[1::2, 1::2], pixel_kernel("yy", L, M, nu=0.3), rtol=1e-13)
    np.testing.assert_allclose(A[0::2, 1::2], pixel_kernel("xy", L, M, nu=0.3), rtol=1e-13,
                               atol=1e-15)
    v = np.random.default_rng(0).standard_normal(b.size)
    u = np.arange(b.size)
    np.testing.assert_allclose(b.product(u, v), A @ v, rtol=0, atol=1e-12 * np.abs(A @ v).max())
    # an off-diagonal block, as the stick solver asks for it
    i, j = np.arange(0, b.size, 3), np.arange(1, b.size, 2)
    np.testing.assert_array_equal(b.entries(i, j), A[np.ix_(i, j)])


def test_auto_chooses_a_method_that_runs_the_vector():
    assert choose_method(1000, slip_law="break", components="xy") == "inverse"
    # the unknowns count: from the crossover on, the compressed inverse
    assert choose_method(20_000, slip_law="break", components="xy") == "hierarchical"
    normal = squeeze(_rough(24, 11), depth=2.0, nu=0.3, tol=1e-13)
    r = pull(normal, components="xy", direction=10.0)
    assert r.method == "inverse" and r.details.precision == "double"


@pytest.mark.parametrize("kwargs,match", [
    (dict(components="z"), r"pull.components = 'z': must be one of 'x', 'xy'"),
    (dict(direction=30.0), r"pull.direction = 30.0: the x-only model"),
    (dict(components="xy", direction=float("nan")),
     r"pull.direction = nan: must be a finite angle"),
    (dict(components="xy", slip_law="slip-weakening", lam_dynamic=0.1, slip_distance=0.05),
     r"pull.components = 'xy': slip_law = 'slip-weakening' has no exact pull"),
    (dict(components="xy", slip_law="coulomb", method="hierarchical"),
     r"method 'hierarchical' runs slip_law = 'coulomb' in the x-only model only"),
    (dict(components="xy", method="cg"), r"pull.components = 'xy': method 'cg' runs "
                                         r"slip_law = 'break' in the x-only model only; use "
                                         r"method 'auto', 'inverse', 'hierarchical'"),
])
def test_what_the_vector_model_does_not_run_is_refused_in_one_line(kwargs, match):
    normal = squeeze(_rough(16, 12), depth=2.0, nu=0.3, tol=1e-13)
    with pytest.raises(InputError, match=match) as e:
        pull(normal, **kwargs)
    assert "\n" not in str(e.value)


BASE = {"grid": {"n": 24}, "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0},
        "squeeze": {"depths": [1.5, 2.5], "depth_unit": "rms"}, "pull": {"enabled": True}}


def _config(tmp_path, sets):
    from roughslip.run.config import dumps_toml, load_config

    p = tmp_path / "run.toml"
    p.write_text(dumps_toml(BASE))
    return load_config(p, sets)


@pytest.mark.parametrize("sets,match", [
    (["pull.components='x'", "pull.direction=30"], r"pull\.direction = 30\.0: the x-only model"),
    (["pull.components='xy'", "coupling.enabled=true", "coupling.history='indent'"],
     r"pull\.components = \"xy\": the coupled model with the traction vector holds "
     r"slip_law 'coulomb'"),
    (["pull.components='xy'", "coupling.enabled=true", "pull.slip_law='coulomb'"],
     r"coupling\.history = \"bonded\": the coupled model with the traction vector starts "
     r"from the frictional indentation"),
    (["pull.components='xy'", "coupling.enabled=true", "pull.slip_law='coulomb'",
      "coupling.history='indent'", "coupling.pull_control='force'"],
     r"coupling\.pull_control = \"force\": the coupled model with the traction vector "
     r"holds the depth"),
    (["pull.components='xy'", "pull.slip_law='slip-weakening'", "pull.lam_dynamic=0.1",
      "pull.slip_distance=0.05"],
     r"pull\.components = \"xy\": slip_law = 'slip-weakening' has no pull of the traction "
     r"vector"),
    (["pull.components='xy'", "pull.slip_law='coulomb'", "pull.method='hierarchical'"],
     r"pull\.method = \"hierarchical\": pull\.components = 'xy' needs one of auto, "
     r"inverse"),
    (["pull.facets=3"], r"pull\.facets = 3: must be an integer from 4 to 4096"),
    (["pull.components='xy'", "pull.method='cg'"],
     r"pull\.method = \"cg\": pull\.components = 'xy' needs one of auto, inverse, "
     r"hierarchical"),
    (["pull.components='xy'", "pull.error_estimate=true"], r"pull\.error_estimate = true"),
    (["output.fields=['fy']"], r"'fy' needs pull\.components = 'xy'"),
    (["pull.components='z'"], r"pull\.components = \"z\": must be one of"),
    (["pull.components='xy'", "pull.direction=inf"], r"pull\.direction = inf: must be finite"),
])
def test_the_configuration_refuses_what_the_vector_model_lacks(tmp_path, sets, match):
    from roughslip.errors import ConfigError

    with pytest.raises(ConfigError, match=match) as e:
        _config(tmp_path, sets)
    assert str(e.value).count("\n") == 0


def test_a_drive_off_x_pulls_the_vector_unless_told_otherwise(tmp_path):
    """``pull.direction`` set and ``pull.components`` not: the traction vector (the x-only
    model cannot pull off x); at direction 0 the default stays the x-only model."""
    assert _config(tmp_path, ["pull.direction=30"]).pull.components == "xy"
    assert _config(tmp_path, []).pull.components == "x"
    assert _config(tmp_path, ["pull.direction=0"]).pull.components == "x"


def test_a_run_stores_the_force_vector(tmp_path):
    """``pull.components = "xy"``: the run stores the peak's force vector beside the force
    along the drive, and the y forces when asked; the x-only run has neither column."""
    from roughslip.run.executor import run
    from roughslip.run.store import read_run

    cfg = _config(tmp_path, ["pull.components='xy'", "pull.direction=60",
                             "output.fields=['fx', 'fy', 'stick']", "ensemble.samples=2"])
    run(cfg, tmp_path / "v.h5", workers=1)
    r = read_run(tmp_path / "v.h5")
    F = r.scalars["friction_force"]
    Fx, Fy = r.scalars["friction_force_x"], r.scalars["friction_force_y"]
    e = plane_direction(60.0)
    assert np.all(np.isfinite(Fx)) and np.all(np.isfinite(Fy))
    # the force along the drive is the vector's projection on it (the peak's sums)
    np.testing.assert_allclose(e[0] * Fx + e[1] * Fy, F, rtol=1e-12)
    np.testing.assert_allclose(r.field(0, 1, "fy").sum(), Fy[0, 1], rtol=1e-12)
    cfg = _config(tmp_path, ["ensemble.samples=1"])
    run(cfg, tmp_path / "x.h5", workers=1)
    assert "friction_force_x" not in read_run(tmp_path / "x.h5").scalars


def test_a_coupled_run_stores_the_force_vector(tmp_path):
    """The coupled model with the traction vector in a run: the Coulomb cone from the
    frictional indentation; the run stores the force vector and its projection, and the same
    numbers as the API."""
    from roughslip import Problem, couple
    from roughslip.run.executor import run
    from roughslip.run.scene import Scene
    from roughslip.run.store import read_run

    cfg = _config(tmp_path, ["grid.n=16", "pull.components='xy'", "pull.direction=30",
                             "pull.slip_law='coulomb'", "pull.facets=16",
                             "coupling.enabled=true", "coupling.history='indent'",
                             "output.fields=['fz', 'fy', 'ux', 'uz']", "ensemble.samples=1"])
    run(cfg, tmp_path / "c.h5", workers=1)
    r = read_run(tmp_path / "c.h5")
    F = r.scalars["friction_force"]
    Fx, Fy = r.scalars["friction_force_x"], r.scalars["friction_force_y"]
    e = plane_direction(30.0)
    np.testing.assert_allclose(e[0] * Fx + e[1] * Fy, F, rtol=1e-12)
    scene = Scene.from_config(cfg)
    problem = Problem.from_arrays(scene.surfaces(0).composite, a=scene.grid.a,
                                  E=scene.material.E, nu=scene.material.nu)
    api = couple(problem, depth=float(r.scalars["depth_length"][0, 1]), lam=0.2,
                 slip_law="coulomb", history="indent", components="xy", direction=30.0,
                 facets=16, tol=1e-10)
    assert F[0, 1] == pytest.approx(api.friction_force, rel=1e-12)
    # the stored u_z holds the overlap on the contacts to the FFT's rounding: it includes the
    # y forces' part G_zy f_y (without it the check fails)
    uz, fz = r.field(0, 1, "uz"), r.field(0, 1, "fz")
    touch = fz > 0
    target = problem.overlap(float(r.scalars["depth_length"][0, 1]))
    assert np.abs(uz - target)[touch].max() <= 1e-9 * np.abs(uz).max()
    np.testing.assert_allclose(r.field(0, 1, "fy"), api.peak.fy, rtol=0,
                               atol=1e-12 * float(np.abs(api.peak.fy).max()))


@pytest.mark.parametrize("direction", [0.0, 30.0, 45.0])
def test_coulomb_cattaneo_mindlin_in_any_direction(direction):
    """Cattaneo-Mindlin at nu = 0 (the isotropic half-space, where the isotropic cone keeps
    every force along the drive), lambda = 0.3, at delta/delta_s = 0.3 and 0.7: the force
    along the drive and the stick radius to the x-only test's tolerances, the force vector
    along the drive, and at full sliding lambda P."""
    from roughslip.analysis.verify import hertz_scene
    from tests.mindlin import assert_cattaneo_mindlin

    lam, R, d = 0.3, 1.0, 1 / 16
    heights, h, depth, ac = hertz_scene(8, R, d)
    normal = squeeze(heights, depth=depth, a=h, nu=0.0, tol=1e-12)
    res = pull(normal, lam=lam, slip_law="coulomb", components="xy", direction=direction)
    P = normal.normal_force
    e = np.array(plane_direction(direction))
    assert res.converged and res.friction_force == pytest.approx(lam * P, rel=1e-12)
    np.testing.assert_allclose(res.friction_vector, lam * P * e, rtol=0, atol=1e-12 * lam * P)
    ft = np.hypot(res.peak.fx, res.peak.fy)
    np.testing.assert_allclose(ft, lam * normal.fz, rtol=1e-12, atol=1e-15)  # all slipping
    assert_cattaneo_mindlin(res, P, ac, h, lam, 0.0)


def test_every_law_runs_the_vector_at_nu_zero():
    """Slip-weakening and the single-precision and compressed inverses run the traction
    vector at nu = 0 (the x-only model turned), and refuse it at nu > 0 in one line."""
    normal = squeeze(_rough(32, 13), depth=2.2, nu=0.0, tol=1e-13)
    sw = dict(slip_law="slip-weakening", lam_dynamic=0.1, slip_distance=0.05)
    a = pull(normal, **sw)
    b = pull(normal, **sw, components="xy", direction=60.0)
    assert a.friction_force == b.friction_force and b.peak.fy is not None
    for kw in (dict(precision="single"), dict(method="hierarchical"), dict(method="cg")):
        assert pull(normal, components="xy", direction=10.0, **kw).friction_force == \
            pull(normal, **kw).friction_force
    stiff = squeeze(_rough(16, 13), depth=2.2, nu=0.3, tol=1e-13)
    with pytest.raises(InputError, match=r"pull.components = 'xy': slip_law = 'slip-weakening'"
                                         r" has no exact pull of the traction vector at nu > 0"):
        pull(stiff, **sw, components="xy")


def test_the_configuration_takes_every_law_with_the_vector_at_nu_zero(tmp_path):
    for sets in (["pull.slip_law='coulomb'"], ["pull.precision='single'"],
                 ["pull.method='cg'"], ["pull.error_estimate=true"]):
        cfg = _config(tmp_path, ["material.nu=0", "pull.components='xy'", *sets])
        assert cfg.pull.components == "xy"


def test_the_memory_guard_names_the_vector_model():
    from roughslip.errors import MemoryLimitError
    from roughslip.linalg import memory

    normal = squeeze(_rough(24, 14), depth=2.0, nu=0.3, tol=1e-13)
    with memory.limited(1e-6), pytest.raises(MemoryLimitError,
                                             match=r"G_tt \(2 components\) on \d+ bonds .*"
                                                   r"use pull.components = 'x'") as e:
        pull(normal, components="xy")
    assert "\n" not in str(e.value)


def _vector_scenes():
    """Rough scenes (open and periodic, two nu, several drive angles) and symmetric spheres,
    whose exact ties the tie rule breaks by the lowest index."""
    from roughslip.surfaces.synthetic import sphere

    out = []
    for k, (n, depth, nu, boundary, direction) in enumerate([
            (48, 2.2, 0.25, "open", 0.0), (48, 2.8, 0.45, "open", 30.0),
            (64, 2.0, 0.3, "open", 100.0), (48, 2.0, 0.3, "periodic", 45.0),
            (64, 2.4, 0.45, "periodic", 0.0)]):
        out.append((f"rough{k}-{boundary}", _rough(n, 200 + k), depth, nu, boundary, direction))
    for n, radius, depth, direction in [(16, 12.0, 1.0, 0.0), (24, 20.0, 1.5, 45.0)]:
        out.append((f"sphere{n}", sphere((n, n), radius=radius), depth, 0.3, "open", direction))
    return out


@pytest.mark.parametrize("scene", _vector_scenes(), ids=lambda s: s[0])
def test_certified_paths_give_the_double_sequence(scene):
    """The single-precision and the compressed inverses decide each break of the traction
    vector against a bound on the norm of its two components, and give the double-precision
    path's breaks and friction force."""
    _, h, depth, nu, boundary, direction = scene
    normal = squeeze(h, depth=depth, nu=nu, boundary=boundary, tol=1e-13)
    ref = pull(normal, method="inverse", precision="double", components="xy",
               direction=direction)
    for method, precision in [("inverse", "single"), ("hierarchical", "double"),
                              ("hierarchical", "single")]:
        r = pull(normal, method=method, precision=precision, components="xy",
                 direction=direction)
        np.testing.assert_array_equal(r.curve.site, ref.curve.site)
        # the peak is solved again by CG to 1e-4 tol against the FFT operator (as in x)
        assert r.friction_force == pytest.approx(ref.friction_force, rel=1e-10)
        assert r.converged
        np.testing.assert_allclose(r.friction_vector, ref.friction_vector, rtol=1e-9,
                                   atol=1e-10 * ref.friction_force)


def test_the_compressed_estimate_counts_both_components():
    """A block between two point sets carries both components of the vector: its rank about
    doubles, and the memory estimate, given the unknowns per point, stays above what the
    inverse holds (the x-only rank model alone fell 9 % below it)."""
    from roughslip.friction.bonds import bond_inverse
    from roughslip.linalg.hierarchical import HierarchicalInverse

    normal = squeeze(_rough(64, 15), depth=2.4, nu=0.3, tol=1e-13)
    b = Bonds(normal, 0.2, components=("x", "y"))
    h = bond_inverse(b, 128, 1, solver=HierarchicalInverse)
    assert h.nbytes() <= HierarchicalInverse.memory_bytes(b.size, block=128, per_point=2)
    assert (HierarchicalInverse.memory_bytes(b.size, block=128, per_point=2)
            > HierarchicalInverse.memory_bytes(b.size, block=128))


def test_the_api_refuses_what_the_vector_model_has_not_at_nu_above_zero():
    """The x-only model's error estimate, and a law without the vector named with a method
    that has it: one line naming what is missing."""
    normal = squeeze(_rough(16, 16), depth=2.0, nu=0.3, tol=1e-13)
    with pytest.raises(InputError, match=r"pull.error_estimate: .* none for pull.components = "
                                         r"'xy' at nu > 0"):
        pull(normal, components="xy", estimate_error=True)
    with pytest.raises(InputError, match=r"pull.components = 'xy': slip_law = "
                                         r"'slip-weakening' has no exact pull of the traction "
                                         r"vector at nu > 0"):
        pull(normal, components="xy", slip_law="slip-weakening", method="inverse",
             lam_dynamic=0.1, slip_distance=0.05)


def test_the_stored_ux_holds_the_drive_on_the_stick_sites(tmp_path):
    """u_x at the peak includes G_xy f_y: on the stick sites it is the drive's x part."""
    from roughslip.run.executor import run
    from roughslip.run.store import read_run

    cfg = _config(tmp_path, ["pull.components='xy'", "pull.direction=90",
                             "material.nu=0.45", "output.fields=['ux', 'stick', 'pull_curve']",
                             "ensemble.samples=1"])
    run(cfg, tmp_path / "u.h5", workers=1)
    r = read_run(tmp_path / "u.h5")
    ux, stick = r.field(0, 1, "ux"), r.field(0, 1, "stick")
    D = float(r.field(0, 1, "dx_lim").max())
    assert stick.any()
    # the drive is along y: u_x = 0 on the stick sites, to the solves' tolerance
    np.testing.assert_allclose(ux[stick], 0.0, atol=1e-9 * D)
