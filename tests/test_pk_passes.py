"""The fused passes of the Polonsky–Keer iteration against their numpy reference: the same
numbers bit for bit, pass by pass and over whole solves."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.contact import pk_passes
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalSolver
from roughslip.elastic.operators import Grid, Material
from roughslip.errors import NumericalError
from roughslip.surfaces.synthetic import sample_rng, self_affine, sphere

pytestmark = pytest.mark.skipif(not pk_passes.HAVE_NUMBA, reason="numba is not installed")


def _fields(shape, seed):
    rng = np.random.default_rng(seed)
    u, ubar, t, r = (rng.standard_normal(shape) for _ in range(4))
    p = np.where(rng.random(shape) < 0.3, rng.random(shape), 0.0)
    p[rng.random(shape) < 0.05] = -0.0  # a negative zero is off contact too
    return u, ubar, p, t, r


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("shape", [(1, 1), (3, 5), (7, 9), (16, 16), (33, 31)])
def test_each_pass_matches_numpy_bitwise(shape):
    u, ubar, p, t, r = _fields(shape, sum(shape))
    outs = {}
    for fused in (True, False):
        g, Sf, gs, off = (np.full(shape, np.nan) for _ in range(4))
        stats = pk_passes.gap(u, ubar, p, g, Sf, gs, off, fused=fused)
        shifted = pk_passes.shift_gap(g, Sf, gs, off, 0.37, fused=fused)
        tt = t.copy()
        pk_passes.direction(tt, 0.61, Sf, gs, fused=fused)
        pp, uu = p.copy() + 0.5 * (Sf > 0), u.copy()
        clipped, entering = pk_passes.step(pp, tt, uu, r, g, Sf, 0.8, np.zeros(shape, np.int8),
                                           fused=fused)
        pk_passes.scale(pp, uu, 1.3, fused=fused)
        outs[fused] = (stats, shifted, g, Sf, gs, off, tt, pp, uu, clipped.copy(),
                       entering.copy())
    for a, b in zip(outs[True], outs[False], strict=True):
        assert _same(a, b) if isinstance(a, np.ndarray) else a == b


def test_step_lists_sites_in_order_and_skips_empty_words():
    shape = (5, 13)  # 65 sites: eight whole words and a tail of one
    p, t, u, r, g = (np.zeros(shape) for _ in range(5))
    Sf = np.ones(shape)
    clip, enter = [3, 8, 40, 64], [0, 9, 17, 63]
    p.ravel()[clip] = -1.0
    Sf.ravel()[enter] = 0.0
    g.ravel()[enter] = -2.0
    Sf.ravel()[[20, 21]] = 0.0  # off contact with a positive gap: not entering
    for fused in (True, False):
        c, e = pk_passes.step(p.copy(), t, u.copy(), r, g, Sf, 1.0,
                              np.zeros(shape, np.int8), fused=fused)
        assert c.tolist() == clip and e.tolist() == enter


def test_gap_propagates_nan():
    u, ubar, p, _, _ = _fields((4, 4), 1)
    u[2, 3] = np.nan
    for fused in (True, False):
        g, Sf, gs, off = (np.zeros((4, 4)) for _ in range(4))
        _, hi, lo, least = pk_passes.gap(u, ubar, p, g, Sf, gs, off, fused=fused)
        assert (np.isnan(hi) and np.isnan(lo)) or np.isnan(least)


def _solves(fused, monkeypatch):
    monkeypatch.setattr(pk_passes, "FUSED", fused)
    out = []
    for boundary in ("open", "periodic"):
        for n, h in ((48, self_affine((48, 48), hurst=0.8, rms_height=1.0,
                                      rng=sample_rng(5, 48))),
                     (40, sphere((40, 40), radius=80.0))):
            s = NormalSolver(Problem(h, Grid((n, n), 1.0, boundary), Material(1.0, 0.3)),
                             tol=1e-10)
            top = 0.3 * (h.max() - h.mean())
            r = s.solve(depth=top)
            out.append(r)
            out.append(s.solve(force=r.normal_force))
            out.append(s.solve(depth=1.1 * top, x0=r.fz))
    return out


def test_whole_solves_are_bitwise_those_of_numpy(monkeypatch):
    fused, plain = _solves(True, monkeypatch), _solves(False, monkeypatch)
    for a, b in zip(fused, plain, strict=True):
        assert a.iterations == b.iterations and a.convolutions == b.convolutions
        assert _same(a.fz, b.fz) and _same(a.uz, b.uz) and a.depth == b.depth


def test_non_finite_heights_still_stop_with_an_error(monkeypatch):
    monkeypatch.setattr(pk_passes, "FUSED", True)
    h = sphere((16, 16), radius=30.0)
    s = NormalSolver(Problem(h, Grid((16, 16)), Material(1.0, 0.3)), tol=1e-10)
    s._impl._base = s._impl._base.copy()
    s._impl._base[3, 3] = np.nan
    with pytest.raises(NumericalError, match="non-finite"):
        s.solve(depth=0.1)
