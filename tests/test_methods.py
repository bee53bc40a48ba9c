"""Every registered pull method on every slip law it runs: the shared suite that a new
method or law joins by registering (docs/extending.md), and the stick-solver protocol held
against its callers and its implementations."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest

import roughslip
from roughslip.contact.squeeze import squeeze
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import METHODS, pull
from roughslip.linalg.stick import StickSolver
from roughslip.surfaces.synthetic import sample_rng, self_affine

#: the parameters of the laws that have their own
PARAMS = {"slip-weakening": {"lam_dynamic": 0.1, "slip_distance": 0.05}}
PAIRS = [(m, law) for m in METHODS.names() for law in LAWS.names()
         if METHODS.get(m).runs(LAWS.get(law))]
TOL = 1e-12


@pytest.fixture(scope="module")
def scene():
    """A rough 24 x 24 contact, and the condition number of G_xx on the whole grid, which
    bounds that of every stick set's block (interlacing)."""
    h = self_affine((24, 24), hurst=0.8, rms_height=1.0, rng=sample_rng(7, 0), oversample=2)
    normal = squeeze(h, depth=1.5, nu=0.3, tol=1e-13)
    op = normal.problem.operator("xx")
    n = h.size
    G = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1.0
        G[:, j] = op.apply("xx", e.reshape(h.shape)).ravel()
    w = np.linalg.eigvalsh(0.5 * (G + G.T))
    return normal, w[-1] / w[0]


def test_the_pairs_cover_every_law_and_every_method():
    """Each law has a method that runs it, and each method but auto runs a law."""
    assert {law for _, law in PAIRS} == set(LAWS.names())
    assert {m for m, _ in PAIRS} == set(METHODS.names()) - {"auto"}


@pytest.mark.parametrize(("method", "law"), PAIRS)
def test_every_method_runs_every_law_it_declares(scene, method, law):
    """Against the updated inverse: an exact method gives the same events and the friction
    force within 4 cond(G) tol (each certified to tol); an approximate one breaks several
    bonds per solve, and its friction force is biased low."""
    normal, kappa = scene
    ref = pull(normal, slip_law=law, method="inverse", tol=TOL, **PARAMS.get(law, {}))
    res = pull(normal, slip_law=law, method=method, tol=TOL, **PARAMS.get(law, {}))
    assert res.method == method and res.slip_law == law and res.converged, res.message
    if not METHODS.get(method).exact:
        assert res.friction_force <= ref.friction_force * (1 + 4 * kappa * TOL)
        return
    n = min(len(ref.curve.site[1:]), len(res.curve.site[1:]))  # the exact early stop differs
    assert n and np.array_equal(res.curve.site[1:][:n], ref.curve.site[1:][:n])
    assert res.curve.kind[1:][:n] == ref.curve.kind[1:][:n]
    assert res.friction_force == pytest.approx(ref.friction_force, rel=4 * kappa * TOL)


@pytest.mark.parametrize("method", [m for m in METHODS.names() if METHODS.get(m).solver])
def test_every_stick_solver_implements_the_protocol(method):
    """Every method's solver has every member of the protocol, with its parameters."""
    solver = METHODS.get(method).solver
    for name, member in inspect.getmembers(StickSolver, inspect.isfunction):
        if name.startswith("_"):
            continue
        have = getattr(solver, name, None)
        assert callable(have), f"{method}: {name}"
        want = list(inspect.signature(member).parameters)
        assert list(inspect.signature(have).parameters)[: len(want)] == want, f"{method}: {name}"


def _solver_uses(tree: ast.AST) -> set[str]:
    """Attributes read on a stick solver: names ``inv`` and ``self.inv``, and what is passed
    on as the first argument of ``rows.remove`` and ``rows.fold``."""
    used = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            v = node.value
            if (isinstance(v, ast.Name) and v.id == "inv") or (
                    isinstance(v, ast.Attribute) and v.attr == "inv"):
                used.add(node.attr)
    return used


def test_the_callers_use_nothing_outside_the_protocol():
    """Every attribute the pull's event logic reads on its stick solver is in the protocol
    (the certified engine's two optional reads excepted: the dense inverse's float32 matrix,
    and a compressed inverse's matrix, ``compressed_product``, read only where present; and
    slip-weakening's read of a compressed inverse's count of negative eigenvalues, only on an
    inexact inverse)."""
    members = {n for n in dir(StickSolver) if not n.startswith("_")}
    members |= set(StickSolver.__annotations__)
    pkg = Path(roughslip.__file__).parent / "friction"
    for path in sorted(pkg.glob("*.py")):
        used = _solver_uses(ast.parse(path.read_text()))
        if path.name == "breaking_single.py":
            used -= {"buf", "compressed_product"}
        if path.name == "weakening.py":
            used -= {"negatives"}
        assert used <= members, f"{path.name}: {sorted(used - members)}"


def test_names_kept_from_earlier_versions_warn_and_say_what_replaces_them():
    from roughslip.friction import events, laws
    from roughslip.friction import pull as pull_module

    with pytest.warns(DeprecationWarning, match="events.TIE"):
        assert pull_module.TIE_TOL == events.TIE
    with pytest.warns(DeprecationWarning, match="LAWS.names"):
        assert pull_module.SLIP_LAWS == laws.LAWS.names()
    with pytest.raises(AttributeError):
        pull_module.NO_SUCH_NAME  # noqa: B018
