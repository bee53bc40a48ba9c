"""FFT operators against dense matrix-vector products, on every backend."""

from __future__ import annotations

import numpy as np
import pytest

from roughslip.elastic.boundaries import BOUNDARIES
from roughslip.elastic.operators import ElasticOperator, Grid, Material
from roughslip.errors import InputError

BACKENDS = ["pyfftw", "scipy"]
SHAPES = [(7, 5), (8, 8), (1, 9), (6, 11), (2, 2), (1, 1), (9, 9)]
SETUPS = [("open", "pixel"), ("periodic", "pixel"), ("periodic", "continuous")]
ALL = ("zz", "xx", "yy", "zx", "xy", "zy")


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize(("boundary", "kind"), SETUPS)
def test_apply_equals_dense(backend, shape, boundary, kind):
    rng = np.random.default_rng(0)
    op = ElasticOperator(shape, a=0.7, material=Material(2.0, 0.3), boundary=boundary,
                         periodic_kernel=kind, components=ALL, fft=backend)
    for c in ("zz", "xx", "yy", "zx", "xz", "xy", "zy", "yz"):
        f = rng.standard_normal(shape)
        ref = (op.tables.dense(c) @ f.ravel()).reshape(shape)
        u = op.apply(c, f)
        # a kernel may vanish identically (odd kernels on a 2x2 periodic grid): then compare
        # against the size of the operator, not against round-off
        scale = max(np.max(np.abs(ref)), 1e-3 * np.max(np.abs(op.tables.dense("zz"))))
        assert np.max(np.abs(u - ref)) <= 1e-12 * scale, c


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("boundary", "kind"), SETUPS)
def test_block_operator_is_symmetric_and_dense(backend, boundary, kind):
    shape = (6, 7)
    rng = np.random.default_rng(2)
    op = ElasticOperator(shape, material=Material(1.0, 0.1), boundary=boundary,
                         periodic_kernel=kind, components=("zz", "zx", "xx"), fft=backend)
    A = op.block_linear_operator()
    x, y = rng.standard_normal((2, 2 * 42))
    # dot test: <A x, y> = <x, A y>
    assert abs(A @ x @ y - x @ (A @ y)) <= 1e-13 * np.linalg.norm(A @ x) * np.linalg.norm(y)
    d = op.tables.dense
    dense = np.block([[d("zz"), d("zx")], [d("xz"), d("xx")]])
    assert np.allclose(dense, dense.T, atol=1e-15)
    assert np.max(np.abs(A @ x - dense @ x)) <= 1e-12 * np.max(np.abs(dense @ x))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("boundary", "kind"), SETUPS)
def test_tangential_block_equals_dense(backend, boundary, kind):
    """u_x = G_xx f_x + G_xy f_y and u_y = G_yx f_x + G_yy f_y, summed in Fourier space,
    against the dense kernels; and the same numbers when the output overwrites the input."""
    shape = (7, 6)
    rng = np.random.default_rng(3)
    op = ElasticOperator(shape, a=0.7, material=Material(2.0, 0.35), boundary=boundary,
                         periodic_kernel=kind, components=("xx", "xy", "yy"), fft=backend)
    fx, fy = rng.standard_normal((2, *shape))
    d = op.tables.dense
    ref_x = (d("xx") @ fx.ravel() + d("xy") @ fy.ravel()).reshape(shape)
    ref_y = (d("yx") @ fx.ravel() + d("yy") @ fy.ravel()).reshape(shape)
    ux, uy = np.empty(shape), np.empty(shape)
    op.apply_tangential(fx, fy, ux, uy)
    scale = max(np.abs(ref_x).max(), np.abs(ref_y).max())
    assert np.abs(ux - ref_x).max() <= 1e-12 * scale
    assert np.abs(uy - ref_y).max() <= 1e-12 * scale
    gx, gy = fx.copy(), fy.copy()
    op.apply_tangential(gx, gy, gx, gy)
    assert np.array_equal(gx, ux) and np.array_equal(gy, uy)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("boundary", "kind"), SETUPS)
def test_full_block_equals_dense(backend, boundary, kind):
    """u_a = sum_b G_ab f_b for a, b in (z, x, y), summed in Fourier space, against the dense
    kernels; a zero force component is skipped and changes nothing."""
    shape = (7, 6)
    rng = np.random.default_rng(4)
    op = ElasticOperator(shape, a=0.7, material=Material(2.0, 0.3), boundary=boundary,
                         periodic_kernel=kind, components=("zz", "zx", "zy", "xx", "xy", "yy"),
                         fft=backend)
    F = rng.standard_normal((3, *shape))
    d = op.tables.dense
    for zero in (None, 1):
        if zero is not None:
            F[zero] = 0.0
        ref = np.array([sum(d(a + b) @ F[j].ravel() for j, b in enumerate("zxy"))
                        for a in "zxy"]).reshape(3, *shape)
        U = op.apply_full(F, np.empty_like(F))
        assert np.abs(U - ref).max() <= 1e-12 * np.abs(ref).max()
    assert not op.apply_full(np.zeros_like(F), np.ones_like(F)).any()


def test_open_block_is_positive_definite():
    op = ElasticOperator((6, 6), material=Material(1.0, -0.9), components=("zz", "zx", "xx"))
    d = op.tables.dense
    dense = np.block([[d("zz"), d("zx")], [d("xz"), d("xx")]])
    assert np.linalg.eigvalsh(dense).min() > 0.05


@pytest.mark.parametrize(("boundary", "kind"), SETUPS)
def test_linearity_and_out_argument(boundary, kind):
    rng = np.random.default_rng(3)
    op = ElasticOperator((10, 12), boundary=boundary, periodic_kernel=kind, components=("xx",))
    f, g = rng.standard_normal((2, 10, 12))
    lhs = op.apply("xx", 2.5 * f - g)
    rhs = 2.5 * op.apply("xx", f) - op.apply("xx", g)
    assert np.allclose(lhs, rhs, rtol=0, atol=1e-13 * np.max(np.abs(lhs)))
    out = np.empty((10, 12))
    res = op.apply("xx", f, out=out)
    assert res is out and np.array_equal(out, op.apply("xx", f))
    op.apply("xx", out, out=out)  # aliasing input and output is allowed
    assert np.allclose(out, op.apply("xx", op.apply("xx", f)))


def test_linear_operator_adjoint():
    rng = np.random.default_rng(4)
    op = ElasticOperator((5, 8), components=("zx",))
    L = op.as_linear_operator("zx")
    x, y = rng.standard_normal((2, 40))
    assert abs((L @ x) @ y - x @ (L.rmatvec(y))) < 1e-13


def test_builds_only_requested_components():
    op = ElasticOperator((8, 8), components=("zz",))
    assert op.components == ("zz",)
    with pytest.raises(InputError, match="not requested"):
        op.apply("xx", np.zeros((8, 8)))
    op2 = ElasticOperator((8, 8), components=("xz",))
    assert op2.components == ("zx",)


def test_padding_uses_fast_lengths():
    op = ElasticOperator((1000, 97), components=("zz",))
    assert op.padded_shape == (2000, 200)


def test_backends_agree_bitwise_with_themselves():
    rng = np.random.default_rng(5)
    f = rng.standard_normal((32, 32))
    a = ElasticOperator((32, 32), fft="pyfftw").apply("zz", f)
    b = ElasticOperator((32, 32), fft="pyfftw").apply("zz", f)
    assert np.array_equal(a, b)


def test_bad_arguments():
    with pytest.raises(InputError, match="boundary"):
        ElasticOperator((4, 4), boundary="closed")
    with pytest.raises(InputError, match="pixel size"):
        ElasticOperator((4, 4), a=0.0)
    with pytest.raises(InputError, match="shape"):
        ElasticOperator((0, 4))
    with pytest.raises(InputError, match="fft"):
        ElasticOperator((4, 4), fft="fftw3")
    op = ElasticOperator((4, 4))
    with pytest.raises(InputError, match="shape"):
        op.apply("zz", np.zeros((4, 5)))


def test_auto_falls_back_to_scipy_with_one_warning(monkeypatch):
    from roughslip.elastic import fft

    monkeypatch.setattr(fft, "_PYFFTW", None)
    monkeypatch.setattr(fft, "_PYFFTW_ERROR", "ImportError: no pyfftw here")
    monkeypatch.setattr(fft, "_WARNED", False)
    with pytest.warns(RuntimeWarning, match="pyfftw unavailable.*scipy"):
        assert fft.resolve_backend("auto") == "scipy"
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert fft.resolve_backend("auto") == "scipy"  # only one warning per process
    with pytest.raises(InputError, match="cannot be imported"):
        fft.resolve_backend("pyfftw")
    op = ElasticOperator((6, 6), fft="auto")
    assert op.fft.backend == "scipy"
    f = np.random.default_rng(0).standard_normal((6, 6))
    assert np.allclose(op.apply("zz", f), (op.tables.dense("zz") @ f.ravel()).reshape(6, 6),
                       rtol=1e-12)


@pytest.mark.parametrize("backend", ["pyfftw", "scipy"])
@pytest.mark.parametrize("boundary", BOUNDARIES.names())
def test_thread_view_gives_the_same_field_and_leaves_the_operator_alone(backend, boundary):
    op = ElasticOperator((20, 24), material=Material(1.0, 0.3), boundary=boundary,
                         components=("xx",), fft=backend, threads=2)
    f = np.random.default_rng(1).standard_normal((20, 24))
    ref = op.apply("xx", f)
    before = op.fft
    one = op.with_threads(1)
    assert one is not op and one.fft.threads == 1 and one.fft.pruned == before.pruned
    single = one.apply("xx", f)
    assert op.fft is before and op.fft.threads == 2
    np.testing.assert_allclose(single, ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())
    assert op.with_threads(1) is one  # built once and reused
    assert op.with_threads(2) is op
    # spectra added later through either are seen by both
    one.require(("zz",))
    np.testing.assert_allclose(op.apply("zz", f), one.apply("zz", f), rtol=1e-12, atol=1e-14)


def test_require_builds_only_missing_spectra():
    op = ElasticOperator((8, 8), components=("zz",))
    assert op.components == ("zz",)
    k = op.spectrum("zz")
    op.require(("zz", "xz"))
    assert op.components == ("zz", "zx") and op.spectrum("zz") is k
    with pytest.raises(InputError, match="unknown component"):
        op.require(("qq",))


@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_the_operator_reports_its_memory(boundary):
    """What an operator holds, with every table built, stays within the footprint it gives
    before it is built, and the bound exceeds it by exactly what the bound adds on purpose:
    the kernels' transform buffers (one real array and two half spectra on the FFT grid) and,
    per component, the room it allows for the tables beyond their real size (open: two
    tables of (2ny - 1)(2nx - 1) against 4 ny nx each; periodic: the pair table is a view of
    the window table, so one whole table)."""
    ny, nx = 24, 20
    comps = ("zz", "zx", "xx")
    op = ElasticOperator((ny, nx), material=Material(1.0, 0.3), boundary=boundary,
                         components=comps)
    bound = ElasticOperator.footprint((ny, nx), boundary, comps)
    before = op.nbytes
    for c in comps:
        op.tables.real_space(c)
        op.tables.pair(c)
    assert before < op.nbytes <= bound
    my, mx = op.padded_shape
    transforms = 8 * my * mx + 2 * 16 * my * (mx // 2 + 1)
    table = 8 * 4 * ny * nx
    slack = (2 * (table - 8 * (2 * ny - 1) * (2 * nx - 1)) if boundary == "open" else table)
    assert bound - op.nbytes == transforms + len(comps) * slack


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("boundary", ["open", "periodic"])
@pytest.mark.parametrize("threads", [1, 2])
def test_work_buffers_are_transformed_directly_with_the_same_numbers(backend, boundary,
                                                                      threads):
    shape = (20, 20)
    base = ElasticOperator(shape, material=Material(1.0, 0.3), boundary=boundary,
                           components=("zz", "xx", "zx"), fft=backend)
    op = base.with_threads(threads)
    f = np.random.default_rng(3).standard_normal(shape)
    ref = {c: op.apply(c, f) for c in ("zz", "xx", "zx")}
    a, b = op.work_buffer("a"), op.work_buffer("b")
    assert a.shape == shape and not a.any()
    assert op.work_buffer("a") is a and base.work_buffer("a") is a
    direct = boundary == "periodic" and backend == "pyfftw"
    assert op._transforms_directly(a) is direct
    a[...] = f
    for c, u in ref.items():
        assert op.apply(c, a, out=b).tobytes() == u.tobytes()
        assert a.tobytes() == f.tobytes()  # the input is kept
    # in place: the input is the output
    assert op.apply("zz", a, out=a).tobytes() == ref["zz"].tobytes()
    # a transposed view at the same address is not taken for the buffer
    assert not op._transforms_directly(a.T)
    a[...] = f.T
    assert op.apply("zz", a.T, out=b).tobytes() == ref["zz"].tobytes()


def test_solvers_on_one_operator_share_its_work_buffers_and_plans():
    """A new squeeze solver on the same problem (``squeeze(problem, ...)`` makes one per call)
    reuses the operator's work buffers and their FFT plans instead of adding its own."""
    from roughslip.contact.problem import Problem
    from roughslip.contact.squeeze import NormalSolver
    from roughslip.surfaces.synthetic import sphere

    n = 32
    pb = Problem(sphere((n, n), radius=80.0), Grid((n, n), 1.0, "periodic"), Material(1.0, 0.3))
    op = pb.operator("zz")
    first = NormalSolver(pb, tol=1e-10).solve(depth=0.5)
    plans, buffers = len(op.fft._plans), len(op._work_buffers)
    for depth in (0.5, 0.7, 0.5):
        r = NormalSolver(pb, tol=1e-10).solve(depth=depth)
    assert (len(op.fft._plans), len(op._work_buffers)) == (plans, buffers)
    assert r.fz.tobytes() == first.fz.tobytes() and r.iterations == first.iterations


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("boundary", "kind"), SETUPS)
def test_block_product_with_a_zero_field_transforms_one(backend, boundary, kind):
    """With f_z = 0 or f_x = 0 the block product transforms the other field only: the same
    numbers as the single products of its components (the same transforms), against the dense
    block too, and one forward transform fewer."""
    shape = (9, 8)
    rng = np.random.default_rng(4)
    op = ElasticOperator(shape, material=Material(1.0, 0.25), boundary=boundary,
                         periodic_kernel=kind, components=("zz", "zx", "xx"), fft=backend)
    d = op.tables.dense
    f, zero = rng.standard_normal(shape), np.zeros(shape)
    for fz, fx, cz, cx in ((zero, f, "zx", "xx"), (f, zero, "zz", "xz")):
        count = op.fft.count
        uz, ux = (u.copy() for u in op.apply_block(fz, fx))
        assert op.fft.count - count == 3  # one forward, two backward
        assert np.array_equal(uz, op.apply(cz, f)) and np.array_equal(ux, op.apply(cx, f))
        ref_z = d("zz") @ fz.ravel() + d("zx") @ fx.ravel()
        ref_x = d("xz") @ fz.ravel() + d("xx") @ fx.ravel()
        for u, ref in ((uz, ref_z), (ux, ref_x)):
            assert np.max(np.abs(u.ravel() - ref)) <= 1e-12 * np.max(np.abs(ref))
    count = op.fft.count
    op.apply_block(f, f)
    assert op.fft.count - count == 4


def test_plans_are_found_again_for_the_same_arrays_and_for_fresh_views():
    """A transform of the same arrays reuses its plan without reading their addresses, a
    fresh view of a planned buffer finds the plan by address, and the plans looked up by
    identity stay few however many fresh views come."""
    from roughslip.elastic.fft import MEMO_LIMIT, RealFFT2

    fft = RealFFT2((16, 16), backend="pyfftw", rows=8)
    src, dst = fft.real_buffer(), fft.spectrum_buffer()
    rng = np.random.default_rng(1)
    src[:8] = rng.standard_normal((8, 16))
    want = np.fft.rfft2(src)
    fft.forward(src, dst)
    assert np.allclose(dst, want, atol=1e-12)
    plans = len(fft._plans)
    for _ in range(100):
        s, t = src[:], dst[:]  # new objects, the same memory
        t[...] = 0.0
        fft.forward(s, t)
        assert np.allclose(dst, want, atol=1e-12)
    assert len(fft._plans) == plans and len(fft._memo) <= MEMO_LIMIT


@pytest.mark.parametrize("boundary", BOUNDARIES.names())
@pytest.mark.parametrize("shape", [(7, 6), (1, 5), (12, 9)])
def test_every_boundary_applies_its_dense_matrix(boundary, shape):
    """The shared suite of a boundary: for every component, the FFT operator on its FFT grid
    (a registered boundary, test-only ones included) applies the boundary's dense matrix, and
    the window and pair tables reproduce its entries; a symmetric component stays
    symmetric."""
    b = BOUNDARIES.get(boundary)
    op = ElasticOperator(shape, material=Material(1.3, 0.27), a=0.7, boundary=b,
                         components=("zz", "xx", "yy", "xy", "zx", "zy"))
    my, mx = op.padded_shape
    assert my >= shape[0] and mx >= shape[1]
    f = np.random.default_rng(5).standard_normal(shape)
    for c in ("zz", "xx", "yy", "xy", "yx", "zx", "xz", "zy", "yz"):
        D = op.tables.dense(c)
        want = (D @ f.ravel()).reshape(shape)
        np.testing.assert_allclose(op.apply(c, f), want, rtol=1e-11,
                                   atol=1e-12 * np.abs(want).max())
        if c in ("zz", "xx", "yy", "xy"):
            np.testing.assert_allclose(D, D.T, rtol=0, atol=1e-14 * np.abs(D).max())
        T, w, off = op.tables.pair(c)
        iy, ix = np.divmod(np.arange(f.size), shape[1])
        dy, dx = iy[:, None] - iy[None, :], ix[:, None] - ix[None, :]
        np.testing.assert_allclose(T[dy * w + dx + off], D, rtol=1e-11,
                                   atol=1e-12 * np.abs(D).max())

