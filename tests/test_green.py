"""Pixel Green functions and periodic symbols against independent references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from roughslip.elastic import green
from roughslip.errors import InputError


@pytest.mark.parametrize("key", ["zz", "xx", "yy", "zx", "xz", "xy"])
def test_matches_reference_vectors(green_values, key):
    off = np.array(green_values["offsets"])
    L, M = np.meshgrid(off, off, indexing="ij")  # kernels[key][nu][i][j]: l = off[i], m = off[j]
    for nus, table in green_values["kernels"][key].items():
        ref = np.array(table)
        got = green.pixel_kernel(key, L, M, a=1.0, E=1.0, nu=float(nus))
        nz = ref != 0
        assert np.all(np.abs(got[nz] - ref[nz]) <= 1e-12 * np.abs(ref[nz])), (key, nus)
        assert np.all(np.abs(got[~nz]) <= 1e-15), (key, nus)


def test_self_terms_closed_form(green_values):
    for nus, vals in green_values["self_terms_values"].items():
        nu = float(nus)
        zz = 4 * math.log(1 + math.sqrt(2)) * (1 - nu * nu) / math.pi
        xx = 2 * (1 + nu) * (2 - nu) * math.log(1 + math.sqrt(2)) / math.pi
        assert green.pixel_kernel("zz", 0, 0, nu=nu) == pytest.approx(zz, rel=1e-14)
        assert green.pixel_kernel("xx", 0, 0, nu=nu) == pytest.approx(xx, rel=1e-14)
        assert green.pixel_kernel("yy", 0, 0, nu=nu) == pytest.approx(vals["yy"], rel=1e-14)
        assert green.pixel_kernel("zx", 0, 0, nu=nu) == 0.0


@pytest.mark.parametrize(
    ("comp", "l", "m"),
    [("zz", 2000, 3), ("xx", 2000, 3), ("xx", 3, 2000), ("zx", 2000, 3), ("xy", 1500, -700),
     ("zz", 2, 1), ("xx", -1, 2), ("zx", -2, 1), ("xy", 2, -1), ("yy", 0, 3), ("zy", 1, -3)],
)
def test_matches_quadrature_of_point_force(comp, l, m):
    """The pixel kernel is the pixel average of the point-force solution
    (docs/theory/halfspace.rst#pixel-kernels)."""
    a, E, nu = 0.5, 3.0, 0.27

    def f(y, x):
        return green.point_kernel(comp, x, y, E=E, nu=nu)

    v, _ = integrate.dblquad(f, (l - 0.5) * a, (l + 0.5) * a, (m - 0.5) * a, (m + 0.5) * a,
                             epsabs=0, epsrel=1e-13)
    got = green.pixel_kernel(comp, l, m, a=a, E=E, nu=nu)
    assert got == pytest.approx(v / a**2, rel=1e-10)


def test_scaling_with_a_and_E():
    base = green.pixel_kernel("xx", 3, -2, a=1.0, E=1.0, nu=0.2)
    assert green.pixel_kernel("xx", 3, -2, a=2.0, E=5.0, nu=0.2) == pytest.approx(base / 10)


def test_layout_odd_kernel_changes_sign_along_axis_1():
    """zx is odd in l (x offset), which runs along axis 1 of a table
    (docs/theory/halfspace.rst#conventions)."""
    t = green.kernel_table("zx", 4, 3, nu=0.3)  # shape (2*3-1, 2*4-1), centre (2, 3)
    assert t.shape == (5, 7)
    assert t[2, 4] > 0 and t[2, 2] == -t[2, 4]  # l = +1 / -1 at m = 0
    assert t[3, 4] == t[1, 4]  # even in m
    # G_zx(1, 0), docs/theory/halfspace.rst#kernel-verification
    assert t[2, 4] == pytest.approx(0.08148377806714294, rel=1e-14)


def test_table_matches_direct_evaluation():
    for comp in ("zz", "xx", "yy", "zx", "xy", "zy"):
        t = green.kernel_table(comp, 5, 4, nu=-0.4)
        m, l = np.mgrid[-3:4, -4:5]
        assert np.allclose(t, green.pixel_kernel(comp, l, m, nu=-0.4), rtol=1e-14, atol=1e-16)


def test_yy_and_zy_are_transposes():
    l, m = np.mgrid[-4:5, -3:4]
    assert np.array_equal(green.pixel_kernel("yy", l, m), green.pixel_kernel("xx", m, l))
    assert np.array_equal(green.pixel_kernel("zy", l, m), green.pixel_kernel("zx", m, l))


def test_rejects_bad_material():
    with pytest.raises(InputError, match="nu"):
        green.pixel_kernel("zz", 0, 0, nu=0.7)
    with pytest.raises(InputError, match="nu"):
        green.pixel_kernel("zz", 0, 0, nu=-1.0)
    with pytest.raises(InputError, match="E"):
        green.pixel_kernel("zz", 0, 0, E=0.0)


def test_continuous_symbol_eigenvalues():
    """The 3x3 symbol is Hermitian with eigenvalues 1/(2 mu q), 1/(mu q), (3-4nu)/(2 mu q)."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        E, nu = rng.uniform(0.5, 3), rng.uniform(-0.95, 0.5)
        qx, qy = rng.normal(size=2)
        q = math.hypot(qx, qy)
        mu = E / (2 * (1 + nu))
        s = {c: complex(green.continuous_symbol(c, qx, qy, E=E, nu=nu))
             for c in ("zz", "xx", "yy", "xy", "zx", "zy")}
        mat = np.array([
            [s["xx"], s["xy"], -s["zx"]],
            [s["xy"], s["yy"], -s["zy"]],
            [s["zx"], s["zy"], s["zz"]],
        ])
        assert np.allclose(mat, mat.conj().T, atol=1e-14)
        ev = np.sort(np.linalg.eigvalsh(mat))
        ref = np.sort([1 / (2 * mu * q), 1 / (mu * q), (3 - 4 * nu) / (2 * mu * q)])
        assert np.allclose(ev, ref, rtol=1e-12)


# ---------------------------------------------------------------- periodic pixel symbol (P2)


def _brute_periodic(comp, f, images, nu=0.3):
    """Displacement of a zero-moment force pattern summed directly over periodic images."""
    ny, nx = f.shape
    iy, ix = np.mgrid[0:ny, 0:nx]
    u = np.zeros_like(f)
    for sy, sx in np.argwhere(f != 0):
        for py in range(-images, images + 1):
            for px in range(-images, images + 1):
                u += f[sy, sx] * green.pixel_kernel(
                    comp, ix - (sx + px * nx), iy - (sy + py * ny), nu=nu)
    return u


@pytest.mark.parametrize("comp", ["zz", "xx", "xy", "zx"])
def test_periodic_pixel_symbol_equals_image_sum(comp):
    """P2 equals the lattice sum of the pixel kernel (docs/theory/boundaries.rst#periodic-boundary,
    zero-moment pattern)."""
    n = 12
    f = np.zeros((n, n))
    st = np.array([1, -4, 6, -4, 1.0])
    f[3:8, 4:9] = np.outer(st, st)  # zero force and zero moments up to order 3
    k = green.periodic_symbol(comp, (n, n), nu=0.3, kind="pixel")
    u = np.fft.irfft2(k * np.fft.rfft2(f), s=(n, n))
    ref = _brute_periodic(comp, f, images=10)
    assert np.max(np.abs(u - ref)) <= 1e-11 * np.max(np.abs(u))


@pytest.mark.parametrize("comp", ["zz", "xx", "yy", "xy", "zx", "zy"])
def test_periodic_pixel_symbol_independent_of_ewald_parameter(comp):
    a = green.periodic_symbol(comp, (10, 13), a=0.3, nu=0.1)
    b = green.periodic_symbol(comp, (10, 13), a=0.3, nu=0.1, alpha=0.6 / 0.3, images=3,
                              window=12)
    assert np.max(np.abs(a - b)) <= 1e-13 * np.max(np.abs(a))


def test_pixel_over_continuous_ratios():
    """docs/theory/boundaries.rst#periodic-boundary: K_P2/K_P1 for zz at k = 1, 2, 4, 8 along the
    axis and the diagonal (N = 16)."""
    p2 = green.periodic_symbol("zz", (16, 16), kind="pixel")
    p1 = green.periodic_symbol("zz", (16, 16), kind="continuous")
    axis = [p2[0, k] / p1[0, k] for k in (1, 2, 4, 8)]
    diag = [p2[k, k] / p1[k, k] for k in (1, 2, 4, 8)]
    assert np.round(axis, 4).tolist() == [0.9945, 0.9816, 0.9586, 1.1662]
    assert np.round(diag, 4).tolist() == [0.9897, 0.9691, 0.9563, 1.2900]


def test_periodic_symbol_zero_mode_and_nyquist():
    for kind in ("pixel", "continuous"):
        k = green.periodic_symbol("zx", (8, 8), kind=kind)
        assert k[0, 0] == 0
        assert np.all(k[:, 4] == 0)  # odd in x: zero at the x Nyquist frequency
        assert np.all(k.real == 0)
        kz = green.periodic_symbol("zz", (8, 8), kind=kind)
        assert kz.dtype == float and kz[0, 0] == 0 and np.all(kz.flat[1:] > 0)
