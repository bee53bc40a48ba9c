"""Topographies: statistics of generated surfaces, shapes, file loaders, scenes."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from roughslip.errors import InputError
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.scene import Scene
from roughslip.surfaces import synthetic as S

# ------------------------------------------------------------------------------ self-affine


@pytest.mark.parametrize("hurst", [0.3, 0.6, 0.8, 0.95])
@pytest.mark.parametrize("n", [128, 129])
def test_hurst_exponent_is_recovered(hurst, n):
    """Mean estimated H over 6 seeds within 0.04 of the target; each within 0.12.

    Periodic surfaces (no cropping): the estimate fits the radial PSD between 4x the lowest
    wavenumber and half the Nyquist wavenumber. Measured scatter of one estimate at this size:
    standard deviation ~0.035 with a bias of +0.01..0.02, so 0.12 is ~3 sigma per surface and
    0.04 covers the bias plus ~1.5 sigma of a six-surface mean.
    """
    est = [S.hurst_estimate(S.self_affine((n, n + 6), hurst=hurst, rms_height=1.0,
                                          rng=S.sample_rng(seed, 0)))
           for seed in range(6)]
    assert abs(np.mean(est) - hurst) < 0.04, est
    assert max(abs(e - hurst) for e in est) < 0.12, est


def test_hurst_of_cropped_surfaces_with_window():
    est = [S.hurst_estimate(S.self_affine((128, 128), hurst=0.7, rms_height=1.0, oversample=4,
                                          rng=S.sample_rng(seed, 0)), window="hann")
           for seed in range(6)]
    assert abs(np.mean(est) - 0.7) < 0.06, est


@pytest.mark.parametrize("shape", [(64, 64), (63, 65), (1, 50), (30, 1)])
def test_rms_scaling_is_exact(shape):
    rng = S.sample_rng(1, 2)
    h = S.self_affine(shape, hurst=0.5, rms_height=2.5, rng=rng, a=0.1)
    assert S.rms_height_of(h) == pytest.approx(2.5, rel=1e-13)
    assert abs(h.mean()) < 1e-12
    h = S.self_affine(shape, hurst=0.5, rms_slope=0.3, rng=S.sample_rng(1, 2), a=0.1)
    assert S.rms_slope_of(h, 0.1) == pytest.approx(0.3, rel=1e-13)


def test_statistics_of_a_map_with_missing_points_use_the_valid_ones():
    """Missing points (NaN) are left out of the rms height and slope, not spread over them;
    a spectrum, which needs every point, refuses them by name."""
    y, x = np.mgrid[0:6, 0:8].astype(float)
    h = 0.5 * x - 0.25 * y  # slopes 0.5 and -0.25 everywhere
    holes = h.copy()
    holes[2, 3] = holes[4, 6] = np.nan
    valid = h[np.isfinite(holes)]
    # the same arithmetic on the valid points: within a few roundings
    assert S.rms_height_of(holes) == pytest.approx(np.std(valid), rel=1e-14)
    assert S.rms_slope_of(holes, a=0.5) == pytest.approx(np.hypot(0.5, 0.25) / 0.5,
                                                         rel=1e-14)
    assert np.isnan(S.rms_height_of(np.full((4, 4), np.nan)))
    with pytest.raises(InputError, match="2 missing"):
        S.radial_psd(holes)
    with pytest.raises(InputError, match="missing"):
        S.hurst_estimate(np.pad(holes, 30))


def test_sample_generation_is_order_independent():
    a = [S.self_affine((16, 16), hurst=0.8, rms_height=1, rng=S.sample_rng(7, i))
         for i in range(4)]
    b = S.self_affine((16, 16), hurst=0.8, rms_height=1, rng=S.sample_rng(7, 2))
    assert np.array_equal(a[2], b)
    assert not np.allclose(a[1], a[2])
    child = np.random.SeedSequence(7).spawn(4)[3]
    c = S.self_affine((16, 16), hurst=0.8, rms_height=1, rng=np.random.default_rng(child))
    assert np.array_equal(a[3], c)


def test_cutoff_and_rolloff_shape_the_spectrum():
    n = 256
    h = S.self_affine((n, n), hurst=0.8, rms_height=1.0, rng=S.sample_rng(0, 0),
                      rolloff_wavelength=n / 8, cutoff_wavelength=8.0)
    spec = np.abs(np.fft.fft2(h)) ** 2
    q = np.hypot(*np.meshgrid(np.fft.fftfreq(n), np.fft.fftfreq(n), indexing="xy"))
    assert spec[q > 1 / 8 + 1e-9].max() < 1e-20 * spec.max()  # nothing shorter than the cut-off
    low = spec[(q > 0) & (q < 8 / n)]
    mid = spec[(q > 16 / n) & (q < 20 / n)]
    assert np.mean(low) > 2 * np.mean(mid)
    # flat below the roll-off: the mean power does not grow toward q -> 0
    ring1 = spec[(q > 0) & (q <= 2.5 / n)].mean()
    ring2 = spec[(q > 4.5 / n) & (q <= 7.5 / n)].mean()
    assert 0.3 < ring1 / ring2 < 3.0


def test_cropping_removes_periodicity():
    def wrap_ratio(h):
        inner = np.mean(np.diff(h, axis=1) ** 2)
        wrap = np.mean((h[:, 0] - h[:, -1]) ** 2)
        return wrap / inner

    per = [wrap_ratio(S.self_affine((64, 64), hurst=0.8, rms_height=1, rng=S.sample_rng(s, 0)))
           for s in range(5)]
    crop = [wrap_ratio(S.self_affine((64, 64), hurst=0.8, rms_height=1, oversample=3,
                                     rng=S.sample_rng(s, 0))) for s in range(5)]
    assert np.mean(per) < 3 and np.mean(crop) > 10 * np.mean(per)


def test_generator_rejects_bad_parameters():
    rng = S.sample_rng(0, 0)
    with pytest.raises(InputError, match="hurst"):
        S.self_affine((8, 8), hurst=1.0, rms_height=1, rng=rng)
    with pytest.raises(InputError, match="exactly one"):
        S.self_affine((8, 8), hurst=0.5, rng=rng)
    with pytest.raises(InputError, match="flat"):
        S.self_affine((8, 8), hurst=0.5, rms_height=1, rng=rng, cutoff_wavelength=1e6)


# ------------------------------------------------------------------------------ analytic shapes


def test_sphere_punch_sinusoid_plane():
    h = S.sphere((4, 5), radius=2.0, a=0.5)  # apex at (x, y) = (1.0, 0.75): between rows 1, 2
    assert h[1:3, 2].tolist() == [-1 / 64, -1 / 64] and h.max() == -1 / 64
    h = S.sphere((5, 5), radius=2.0, center=(0.0, 0.0))
    assert h[0, 0] == 0.0 and h[0, 1] == -0.25
    p = S.punch((9, 9), radius=2.1)
    assert np.count_nonzero(p == 0) == 13 and p.min() == -9.0
    w = S.sinusoid((2, 8), amplitude=3.0, wavelength=8.0)
    assert w[0, 0] == 3.0 and w[1, 4] == -3.0 and np.allclose(w[0], w[1])
    wy = S.sinusoid((8, 2), amplitude=1.0, wavelength=4.0, direction="y")
    assert wy[0, 1] == 1.0 and wy[2, 0] == pytest.approx(-1.0)
    pl = S.plane((3, 4), a=2.0, slope=(0.5, -1.0))
    assert pl[2, 3] == pytest.approx(0.5 * 6 - 1.0 * 4)
    with pytest.raises(InputError, match="no pixel centre"):
        S.punch((4, 4), radius=0.1, center=(0.5, 0.5))


# ------------------------------------------------------------------------------ files


@pytest.fixture
def topo():
    return S.self_affine((12, 9), hurst=0.7, rms_height=1e-6, rng=S.sample_rng(9, 0))


def test_loaders_round_trip(tmp_path, topo):
    np.save(tmp_path / "t.npy", topo)
    np.savez(tmp_path / "t.npz", heights=topo, other=np.zeros(3))
    np.savetxt(tmp_path / "t.txt", topo, header="heights in m")
    np.savetxt(tmp_path / "t.csv", topo, delimiter=",")
    with h5py.File(tmp_path / "t.h5", "w") as f:
        f["group/heights"] = topo
    for name, key in [("t.npy", None), ("t.npz", "heights"), ("t.h5", "group/heights"),
                      ("t.h5", None)]:
        assert np.array_equal(S.load_topography(tmp_path / name, key), topo), name
    for name in ("t.txt", "t.csv"):
        assert np.allclose(S.load_topography(tmp_path / name), topo, rtol=1e-15, atol=1e-22)
    assert np.allclose(S.load_topography(tmp_path / "t.npy", scale=1e6), topo * 1e6)


def test_loaders_reject_bad_files(tmp_path, topo):
    bad = topo.copy()
    bad[3, 4] = np.nan
    np.save(tmp_path / "nan.npy", bad)
    with pytest.raises(InputError, match=r"nan\.npy: 1 non-finite height\(s\), first at "
                                         r"\[iy, ix\] = \[3, 4\]"):
        S.load_topography(tmp_path / "nan.npy")
    np.save(tmp_path / "inf.npy", np.array([[1.0, np.inf]]))
    with pytest.raises(InputError, match="non-finite"):
        S.load_topography(tmp_path / "inf.npy")
    np.save(tmp_path / "oned.npy", np.zeros(5))
    with pytest.raises(InputError, match="2-D"):
        S.load_topography(tmp_path / "oned.npy")
    np.save(tmp_path / "empty.npy", np.zeros((0, 3)))
    with pytest.raises(InputError, match="empty"):
        S.load_topography(tmp_path / "empty.npy")
    np.save(tmp_path / "obj.npy", np.array([[{"a": 1}]], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match=r"obj\.npy"):
        S.load_topography(tmp_path / "obj.npy")
    (tmp_path / "ragged.txt").write_text("1 2 3\n4 5\n")
    with pytest.raises(InputError, match="ragged"):
        S.load_topography(tmp_path / "ragged.txt")
    (tmp_path / "words.txt").write_text("1 2\nx y\n")
    with pytest.raises(InputError, match="line 2"):
        S.load_topography(tmp_path / "words.txt")
    (tmp_path / "empty.txt").write_text("# nothing\n")
    with pytest.raises(InputError, match="empty"):
        S.load_topography(tmp_path / "empty.txt")
    (tmp_path / "fake.h5").write_bytes(b"not hdf5")
    with pytest.raises(InputError, match=r"fake\.h5"):
        S.load_topography(tmp_path / "fake.h5")
    np.savez(tmp_path / "two.npz", a=topo, b=topo)
    with pytest.raises(InputError, match=r"surface\.key"):
        S.load_topography(tmp_path / "two.npz")
    with pytest.raises(InputError, match="unknown topography format"):
        S.load_topography(_touch(tmp_path / "t.xyz"))
    with pytest.raises(InputError, match="no such file"):
        S.load_topography(tmp_path / "missing.npy")


def _touch(p):
    p.write_text("")
    return p


# ------------------------------------------------------------------------------ scenes


def _cfg(tmp_path, **sections):
    data = {"grid": {"n": 16}, "squeeze": {"depths": [0.5, 1.0]}, **sections}
    p = tmp_path / "run.toml"
    p.write_text(dumps_toml(data))
    return load_config(p)


def test_scene_builds_only_what_it_needs(tmp_path):
    rough = {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0}
    sc = Scene.from_config(_cfg(tmp_path, surface=rough))
    assert sc.components == ("zz",) and not sc.pull
    sc = Scene.from_config(_cfg(tmp_path, surface=rough, pull={"enabled": True}))
    assert sc.components == ("zz", "xx")
    sc = Scene.from_config(_cfg(tmp_path, surface=rough, pull={"enabled": True},
                                coupling={"enabled": True}))
    assert sc.components == ("zz", "zx", "xx")
    sc = Scene.from_config(_cfg(tmp_path, surface=rough, pull={"enabled": True},
                                coupling={"enabled": True}, material={"nu": 0.5}))
    assert sc.components == ("zz", "xx") and any("G_zx vanishes" in n for n in sc.notes)


def test_scene_fixed_shape_runs_one_sample(tmp_path):
    sc = Scene.from_config(_cfg(tmp_path, surface={"kind": "sphere", "radius": 5.0},
                                ensemble={"samples": 7}))
    assert sc.n_samples == 1 and sc.sample_indices == [0]
    assert any("running 1 sample" in n for n in sc.notes)
    assert sc.surfaces(0).rigid is sc.surfaces(0).rigid  # computed once


def test_two_surfaces_composite_and_independence(tmp_path):
    rough = {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0}
    sc = Scene.from_config(_cfg(tmp_path, surface=rough, ensemble={"samples": 3, "seed": 4},
                                elastic_surface={**rough, "hurst": 0.6, "rms_height": 0.5}))
    s = sc.surfaces(1)
    assert np.array_equal(s.composite, s.rigid + s.elastic)
    assert S.rms_height_of(s.elastic) == pytest.approx(0.5)
    alone = Scene.from_config(_cfg(tmp_path, surface=rough, ensemble={"samples": 3, "seed": 4}))
    assert np.array_equal(alone.surfaces(1).rigid, s.rigid)  # adding a surface changes nothing
    assert not np.allclose(s.rigid / S.rms_height_of(s.rigid), s.elastic / 0.5)


def test_scene_targets_in_units(tmp_path):
    rough = {"kind": "self-affine", "hurst": 0.8, "rms_height": 2.0}
    sc = Scene.from_config(_cfg(tmp_path, surface=rough,
                                squeeze={"depths": [0.5, 1.0], "depth_unit": "rms"}))
    h = sc.surfaces(0).composite
    assert np.allclose(sc.targets(h), [1.0, 2.0])
    sc = Scene.from_config(_cfg(tmp_path, surface=rough,
                                squeeze={"depths": [0.5], "depth_unit": "range"}))
    assert sc.targets(h)[0] == pytest.approx(0.5 * (h.max() - h.min()))
    sc = Scene.from_config(_cfg(tmp_path, surface=rough, material={"E": 2.0, "nu": 0.0},
                                squeeze={"forces": [0.1], "force_unit": "pressure"}))
    assert sc.targets(h)[0] == pytest.approx(0.1 * 2.0 * 256)


def test_scene_from_file_sets_the_grid(tmp_path, topo):
    np.save(tmp_path / "t.npy", topo)
    p = tmp_path / "run.toml"
    p.write_text(dumps_toml({"grid": {"pixel_size": 0.5},
                             "surface": {"kind": "file", "path": "t.npy"},
                             "squeeze": {"depths": [1e-7]}}))
    sc = Scene.from_config(load_config(p))
    assert sc.grid.shape == (12, 9) and sc.grid.a == 0.5
    p.write_text(dumps_toml({"grid": {"n": 10}, "surface": {"kind": "file", "path": "t.npy"},
                             "squeeze": {"depths": [1e-7]}}))
    with pytest.raises(InputError, match=r"t\.npy: heights have shape \[12, 9\]"):
        Scene.from_config(load_config(p))


def test_anisotropy_one_is_the_isotropic_surface_bit_for_bit():
    a = S.self_affine((64, 48), hurst=0.7, rms_height=1.0, rng=S.sample_rng(3, 0))
    b = S.self_affine((64, 48), hurst=0.7, rms_height=1.0, rng=S.sample_rng(3, 0), anisotropy=1.0)
    assert np.array_equal(a, b)


class _Given:
    """An rng whose normal deviates are a given array (the noise of another surface)."""

    def __init__(self, noise: np.ndarray) -> None:
        self.noise = noise

    def standard_normal(self, shape):
        assert tuple(shape) == self.noise.shape
        return self.noise.copy()


def test_anisotropy_is_the_transposed_surface_with_the_inverse_ratio():
    r"""The filter at :math:`(q_x, \gamma q_y)` is, up to a constant factor (removed by the rms
    scaling), the filter of ratio :math:`1/\gamma` at :math:`(q_y, q_x)` with the roll-off and
    cut-off wavelengths times :math:`\gamma`: transposed noise gives the transposed surface."""
    noise = np.random.default_rng(5).standard_normal((64, 64))
    g = 2.5
    a = S.self_affine((64, 64), hurst=0.8, rms_height=1.0, rng=_Given(noise), anisotropy=g,
                    rolloff_wavelength=16.0, cutoff_wavelength=3.0)
    b = S.self_affine((64, 64), hurst=0.8, rms_height=1.0, rng=_Given(noise.T.copy()),
                    anisotropy=1 / g, rolloff_wavelength=16.0 * g, cutoff_wavelength=3.0 * g)
    np.testing.assert_allclose(b.T, a, rtol=0, atol=1e-12)


def test_anisotropy_sets_the_ratio_of_the_rms_slopes():
    r"""The surface is the isotropic one stretched by :math:`\gamma` along y, so its rms slope
    along y is that along x over :math:`\gamma`; with the roll-off and cut-off inside the grid
    the finite differences see it to a few per cent (8 samples of 256^2; 2.94 measured for 3)."""
    g = 3.0
    sx = sy = 0.0
    for s in range(8):
        h = S.self_affine((256, 256), hurst=0.8, rms_height=1.0, rng=S.sample_rng(s, 0),
                        anisotropy=g, rolloff_wavelength=32.0, cutoff_wavelength=4.0)
        sx += float(np.mean(np.diff(h, axis=1) ** 2))
        sy += float(np.mean(np.diff(h, axis=0) ** 2))
    assert (sx / sy) ** 0.5 == pytest.approx(g, rel=0.05)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("inf"), float("nan")])
def test_anisotropy_must_be_finite_and_positive(bad):
    with pytest.raises(InputError, match=r"anisotropy = .*: must be a finite number > 0"):
        S.self_affine((16, 16), hurst=0.8, rms_height=1.0, rng=S.sample_rng(0, 0), anisotropy=bad)
