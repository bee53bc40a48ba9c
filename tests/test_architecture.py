"""The shape of the package: layers, the import graph, registries, restricted operators, the
output schema, and files of the previous format."""

from __future__ import annotations

import ast
import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

import roughslip
from roughslip.cli import cli
from roughslip.contact.problem import Problem
from roughslip.elastic.boundaries import BOUNDARIES
from roughslip.elastic.operators import Grid, Material
from roughslip.errors import InputError
from roughslip.linalg.cg import cg
from roughslip.linalg.restricted import Restricted

PKG = Path(roughslip.__file__).parent
DATA = Path(__file__).parent / "data"

#: lower layers first; a module may import from its own layer or from layers below it
RANK = {"errors": 0, "_version": 0, "registry": 0, "linalg": 1, "elastic": 2, "contact": 3,
        "friction": 4,
        "coupling": 5, "surfaces": 6, "run": 7, "analysis": 8, "cli": 9, "testing": 10,
        "__init__": 11, "__main__": 11}


def _module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path) -> set[str]:
    """Modules of the package that a file imports anywhere: at the top, inside functions and
    inside ``if TYPE_CHECKING:`` blocks (a type named from a higher layer is a dependency
    too)."""
    tree = ast.parse(path.read_text())
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and \
                node.module.startswith("roughslip"):
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                out.add(sub if (PKG.parent / (sub.replace(".", "/") + ".py")).exists() or
                        (PKG.parent / sub.replace(".", "/")).is_dir() else node.module)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("roughslip"))
        elif isinstance(node, ast.ImportFrom) and node.level:
            raise AssertionError(f"{path}: relative import (the package uses absolute ones)")
    return out


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _graph() -> dict[str, set[str]]:
    return {_module_name(p): _imports(p) - {_module_name(p)} for p in PKG.rglob("*.py")}


def test_no_upward_imports():
    bad = []
    for mod, deps in _graph().items():
        for d in deps:
            if d == "roughslip":
                bad.append((mod, d))
            elif RANK[_layer(d)] > RANK[_layer(mod)]:
                bad.append((mod, d))
    assert not bad, f"imports from a higher layer: {bad}"


def test_import_graph_has_no_cycles():
    graph = _graph()
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(graph.get(m, ())):
            if state.get(d) == 1:
                cycle = [*stack[stack.index(d):], d]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if d in graph and not state.get(d):
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if not state.get(m):
            visit(m)


def test_the_run_layer_keeps_one_job_per_file():
    """The run layer was split so that each file does one job; none may grow past 500 lines
    again (the size at which the configuration module held five)."""
    sizes = {f.name: len(f.read_text().splitlines()) for f in (PKG / "run").glob("*.py")}
    assert sizes and max(sizes.values()) <= 500, sorted(sizes.items(), key=lambda kv: -kv[1])


def test_the_checker_sees_an_upward_import(tmp_path):
    """The layer check is not vacuous: a contact module importing the run layer is caught,
    also when the import is only for type checking or inside a function."""
    f = tmp_path / "x.py"
    f.write_text("from roughslip.run.config import RunConfig\n"
                 "from typing import TYPE_CHECKING\n"
                 "if TYPE_CHECKING:\n    from roughslip.analysis.fit import fit_files\n"
                 "def f():\n    import roughslip.cli\n")
    deps = _imports(f)
    assert deps == {"roughslip.run.config", "roughslip.analysis.fit", "roughslip.cli"}
    assert RANK[_layer("roughslip.run.config")] > RANK[_layer("roughslip.contact.squeeze")]


# -- registries ----------------------------------------------------------------------------------
def test_method_names_come_from_the_registries():
    from roughslip.contact import squeeze
    from roughslip.coupling import coupled
    from roughslip.friction import pull
    from roughslip.run.config import PullConfig, SqueezeConfig

    meta = {f.name: f.metadata for f in __import__("dataclasses").fields(SqueezeConfig)}
    assert tuple(meta["method"]["choices"]) == squeeze.METHODS.names() == ("pk", "active-set")
    meta = {f.name: f.metadata for f in __import__("dataclasses").fields(PullConfig)}
    assert tuple(meta["method"]["choices"]) == pull.METHODS.names()  # live
    # the package's own; registering more (a test-only method) adds to them
    assert {"auto", "literal", "inverse", "cg", "batch"} <= set(pull.METHODS.names())
    assert coupled.SOLVERS.names()[:2] == ("dense", "cg")  # the package's own, dense first
    with pytest.raises(InputError, match=r"method = 'nope': unknown pull method; choose one "
                                         rf"of {', '.join(pull.METHODS.names())}$"):
        pull.METHODS.get("nope")
    h = np.zeros((4, 4))
    with pytest.raises(InputError, match="unknown squeeze method"):
        roughslip.squeeze(h, depth=0.1, method="pkk")
    with pytest.raises(InputError, match="unknown coupled solver"):
        roughslip.squeeze_pull_coupled(h, depth=0.1, method="lu")


def _registered_names() -> set[str]:
    """The names of the registered slip laws, pull methods, coupled block solvers and squeeze
    methods."""
    from roughslip.contact import squeeze
    from roughslip.coupling.blocksolvers import SOLVERS
    from roughslip.friction.laws import LAWS
    from roughslip.friction.pull import METHODS

    return {*LAWS.names(), *METHODS.names(), *SOLVERS.names(), *squeeze.METHODS.names()}


def _name_comparisons(source: str, names: set[str]) -> list[str]:
    """The comparisons (``==``, ``!=``, ``in``) of ``source`` with a literal that is one of
    ``names``; a comparison of a ``precision`` (whose choices include ``"auto"`` too) is not
    one of a method."""
    import ast

    def literals(node):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            yield node.value
        elif isinstance(node, ast.Tuple | ast.List | ast.Set):
            for e in node.elts:
                yield from literals(e)

    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Compare):
            continue
        sides = [node.left, *node.comparators]
        if any("precision" in ast.unparse(x) for x in sides):
            continue
        if {v for x in sides for v in literals(x)} & names:
            found.append(f"{node.lineno}: {ast.unparse(node)}")
    return found


def test_no_law_or_method_name_is_compared_outside_the_registries():
    """What a law, a pull method, a block solver or a squeeze method does is read from its
    registered object (its capabilities), never from its name: no code of the package
    compares a name from the registries."""
    names = _registered_names()
    found = [f"{f.relative_to(PKG)}:{hit}" for f in sorted(PKG.rglob("*.py"))
             for hit in _name_comparisons(f.read_text(), names)]
    assert not found, found


def test_the_name_comparison_check_sees_one():
    names = _registered_names()
    code = ("if method == 'cg': pass\nif law in ('coulomb', 'x'): pass\n"
            "if precision == 'auto': pass\nif kind == EventKind.BREAK: pass\n")
    assert [x.split(":")[0] for x in _name_comparisons(code, names)] == ["1", "2"]


def test_coulomb_law_is_refused_by_the_methods_that_do_not_implement_it():
    """The matrix-free methods solve for phi afresh on each stick set: the Coulomb law needs
    solutions tracked through its slipping bonds, so they refuse it, naming the methods that
    run it (those whose stick solver offers what it needs)."""
    from roughslip.friction import pull

    h = -((np.arange(16) - 7.5)[None, :] ** 2 + (np.arange(16) - 7.5)[:, None] ** 2) / 40
    normal = roughslip.squeeze(h, depth=0.5)
    runs = pull.methods_for("coulomb")
    assert "inverse" in runs and "cg" not in runs
    with pytest.raises(InputError, match=f"supports methods {', '.join(runs)}, not 'cg'"):
        roughslip.pull(normal, slip_law="coulomb", method="cg")


# -- problem and restricted operators ------------------------------------------------------------
def test_problem_builds_only_the_kernels_a_solver_asks_for_and_shares_them():
    p = Problem(np.zeros((6, 7)), Grid((6, 7)), Material(1.0, 0.25))
    roughslip.squeeze(p.with_heights(-np.arange(42.0).reshape(6, 7) / 42), depth=0.3)
    q = p.with_heights(np.ones((6, 7)))
    op = p.operator("zz")
    assert op.components == ("zz",) and q.operator("zz") is op
    assert q.operator("xx").components == ("zz", "xx") and p.operator() is op
    assert float(q.overlap(0.25).max()) == 0.25
    with pytest.raises(InputError, match="heights shape"):
        p.with_heights(np.zeros((3, 3)))
    with pytest.raises(InputError, match="diagonal component"):
        p.restricted("zx", np.ones((6, 7), bool))


@pytest.mark.parametrize("boundary", BOUNDARIES.names())
def test_restricted_operators_pass_the_dot_test_and_match_the_dense_block(boundary):
    rng = np.random.default_rng(7)
    shape = (9, 8)
    p = Problem(np.zeros(shape), Grid(shape, 0.5, boundary), Material(2.0, 0.2))
    K = rng.random(shape) < 0.4
    for comp in ("zz", "xx"):
        A = p.restricted(comp, K)
        n = int(K.sum())
        assert A.shape == (n, n)
        x, y = rng.standard_normal(n), rng.standard_normal(n)
        # dot test: <A x, y> = <x, A^T y>, and A is symmetric
        assert np.dot(A @ x, y) == pytest.approx(np.dot(x, A.rmatvec(y)), rel=1e-12)
        assert np.dot(A @ x, y) == pytest.approx(np.dot(x, A @ y), rel=1e-12)
        D = p.operator(comp).tables.dense(comp)[np.ix_(K.ravel(), K.ravel())]
        np.testing.assert_allclose(A @ x, D @ x, rtol=1e-11, atol=1e-13 * np.abs(D @ x).max())
    C, S = rng.random(shape) < 0.5, rng.random(shape) < 0.3
    B = p.restricted_block(C, S)
    m = int(C.sum() + S.sum())
    x, y = rng.standard_normal(m), rng.standard_normal(m)
    assert B.shape == (m, m)
    assert np.dot(B @ x, y) == pytest.approx(np.dot(x, B.rmatvec(y)), rel=1e-12)
    assert np.dot(B @ x, y) == pytest.approx(np.dot(x, B @ y), rel=1e-11)
    if boundary == "open":  # the block from closed-form kernels: [[zz, zx], [xz, xx]]
        op = p.operator("zz", "zx", "xx")
        c, s = C.ravel(), S.ravel()
        d = op.tables.dense
        dense = np.block([[d("zz")[np.ix_(c, c)], d("zx")[np.ix_(c, s)]],
                          [d("xz")[np.ix_(s, c)], d("xx")[np.ix_(s, s)]]])
        np.testing.assert_allclose(B @ x, dense @ x, rtol=1e-10,
                                   atol=1e-12 * np.abs(dense @ x).max())


def test_one_cg_solves_scalar_and_block_restrictions_to_the_dense_solution():
    rng = np.random.default_rng(3)
    shape = (10, 10)
    p = Problem(np.zeros(shape), Grid(shape), Material(1.0, 0.3))
    K = rng.random(shape) < 0.5
    A = p.restricted("xx", K)
    b = rng.standard_normal(shape)
    r = cg(A, b, tol=1e-12)
    D = p.operator("xx").tables.dense("xx")[np.ix_(K.ravel(), K.ravel())]
    np.testing.assert_allclose(A.gather(r.x), np.linalg.solve(D, b.ravel()[K.ravel()]),
                               rtol=1e-9)
    assert r.converged and np.all(r.x[~K] == 0)
    B = p.restricted_block(K, K & (rng.random(shape) < 0.5))
    bb = rng.standard_normal((2, *shape))
    rb = cg(B, bb, tol=1e-12)
    Bd = np.column_stack([B @ e for e in np.eye(B.shape[0])])
    np.testing.assert_allclose(B.gather(rb.x), np.linalg.solve(Bd, B.gather(bb)), rtol=1e-8)
    assert isinstance(B, Restricted) and rb.converged


# -- the output schema ----------------------------------------------------------------------------
def test_run_file_axes_are_dimension_scales_and_uncomputed_values_are_nan(tmp_path,
                                                                          derived_column):
    out = tmp_path / "r.h5"
    res = CliRunner().invoke(cli, ["run", "configs/demo.toml", "-o", str(out), "--quiet",
                                   "--set", "grid.n=16", "--set", "ensemble.samples=2",
                                   "--set", "execution.workers=1"])
    assert res.exit_code == 0, res.output
    from roughslip.run import schema

    with h5py.File(out, "r") as f:
        assert f.attrs["format_version"] == schema.FORMAT_VERSION
        for c in schema.all_columns():
            if c.stage in ("coupled", "traction"):  # stages this run does not have
                assert c.name not in f
                continue
            ds = f[c.name]
            assert ds.dtype == np.float64 and ds.attrs["description"] == c.description
            assert ds.dims[0][0].name == "/sample_index" and ds.dims[1][0].name == "/depth"
            assert ds.dims[1].label == "depth"
        assert f["depth"].is_scale and f["sample_index"].is_scale
        # pull.error_estimate is off and the methods are exact: not estimated, NaN
        assert np.all(np.isnan(f["pull_error_estimate"][()]))
        assert np.all(f["converged"][()] == 1.0)
        # every derived column (here the test-only one) is its function of the others
        base = {c.name: f[c.name][()] for c in schema.COLUMNS if c.name in f}
        assert derived_column.name in schema.DERIVED
        for name in schema.DERIVED:
            c = schema.DERIVED.get(name)
            rows, cols = f[name].shape
            want = np.array([[c.derive({k: v[i, j] for k, v in base.items()})
                              for j in range(cols)] for i in range(rows)])
            assert f[name][()].tobytes() == want.tobytes()


@pytest.mark.parametrize("name", ["run_v1_demo.h5", "run_v1_coupled.h5", "run_v1_load.h5"])
def test_files_of_the_previous_format_open_with_inspect_fit_and_plot(tmp_path, name):
    """Run files written by the previous version (format 1: integer counts, flags with fill 0,
    no dimension scales) still open with the readers."""
    src = tmp_path / name
    shutil.copy(DATA / name, src)
    with h5py.File(src, "r") as f:
        assert f.attrs["format_version"] == 1
    r = CliRunner().invoke(cli, ["inspect", str(src)])
    assert r.exit_code == 0 and "samples complete: 3 of 3" in r.output, r.output
    r = CliRunner().invoke(cli, ["fit", str(src), "--x", "normal_force", "--y", "contact_area",
                                 "--json"])
    assert r.exit_code == 0, r.output
    fit = json.loads(r.output)
    assert 0.5 < fit[0]["alpha"] < 1.5
    pytest.importorskip("matplotlib")
    r = CliRunner().invoke(cli, ["plot", str(src), "-o", str(tmp_path / "p")])
    assert r.exit_code == 0, r.output


def test_a_previous_format_run_resumes_as_the_same_configuration(tmp_path):
    """The stored configuration of a format-1 file (with the key retired since) loads, and its
    digest is recognised: --resume finds nothing to do."""
    src = tmp_path / "old.h5"
    shutil.copy(DATA / "run_v1_demo.h5", src)
    with h5py.File(src, "r") as f:
        text, digest = f.attrs["config"], f.attrs["config_digest"]
    assert "coulomb_steps" in text
    cfg_path = tmp_path / "old.toml"
    cfg_path.write_text(text)
    from roughslip.run.config import load_config

    cfg = load_config(cfg_path)
    assert cfg.matches(str(digest)) and cfg.digest() != digest
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(src), "--resume", "--quiet"])
    assert r.exit_code == 0, r.output


def test_a_coupled_run_of_the_version_before_squeeze_histories_resumes_and_reproduces(tmp_path):
    """A coupled run written before ``coupling.history`` existed (format 2): its configuration
    loads with the default history, ``bonded``, its digest is recognised, --resume finds
    nothing to do, and a fresh run reproduces it. The file was written on another machine
    (OpenBLAS's AVX-512 kernels), so the promise is the cross-machine one: the same events
    (every count, flag and contact area bitwise), every force within twice the certified
    tolerance times the condition number of the whole grid's block (which bounds every block
    the solves invert), the surfaces within FFT round-off, and the certified residuals, which
    measure round-off, below the tolerance. (On the machine that wrote it the numbers are
    bitwise equal; under other kernels they differ by about 1e-15.)"""
    import numpy as np

    from roughslip.contact.problem import Problem
    from roughslip.coupling.coupled import COUPLED_TOL
    from roughslip.run.config import load_config
    from roughslip.testing import dense_block

    src = tmp_path / "old.h5"
    shutil.copy(DATA / "run_v2_coupled.h5", src)
    with h5py.File(src, "r") as f:
        text, digest = f.attrs["config"], f.attrs["config_digest"]
        assert f.attrs["format_version"] == 2
        surface = f["samples/s000000/rigid_surface"][()]
    assert "history" not in text
    cfg_path = tmp_path / "old.toml"
    cfg_path.write_text(text)
    cfg = load_config(cfg_path)
    tol = min(cfg.pull.tol, COUPLED_TOL)  # the coupled solves' tolerance in a run
    assert cfg.coupling.history == "bonded"
    assert cfg.matches(str(digest)) and cfg.digest() != digest
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(src), "--resume", "--quiet"])
    assert r.exit_code == 0, r.output
    new = tmp_path / "new.h5"
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(new), "--quiet"])
    assert r.exit_code == 0, r.output
    w = np.linalg.eigvalsh(dense_block(Problem.from_arrays(surface, nu=cfg.material.nu)))
    kappa = w[-1] / w[0]
    eps = np.finfo(float).eps
    forces = ("friction_force", "friction_normal_force", "normal_force", "depth_length", "fx")
    with h5py.File(src, "r") as a, h5py.File(new, "r") as b:
        names: list[str] = []
        a.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
        compared = [n for n in names if "seconds" not in n]
        assert len(compared) > 15
        for n in compared:
            x, y, last = a[n][()], b[n][()], n.rsplit("/", 1)[-1]
            assert np.array_equal(np.isnan(x), np.isnan(y)), n
            if last == "residual":
                assert np.nanmax(y) <= tol and np.nanmax(x) <= tol, n
            elif last in forces:
                scale = np.nanmax(np.abs(x))
                assert np.nanmax(np.abs(x - y)) <= 2 * kappa * tol * scale, n
            elif last == "rigid_surface":  # the FFT's round-off: a few eps per level
                assert np.abs(x - y).max() <= 16 * np.log2(x.size) * eps * np.abs(x).max(), n
            else:  # the events: counts, flags, contact areas, the axis
                assert np.array_equal(x, y, equal_nan=True), n
