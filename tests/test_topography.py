"""Measured topographies: instrument formats from independent writers, units, missing data,
preparation, tiles, statistics, and bad files."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from roughslip.cli import cli
from roughslip.errors import ConfigError, InputError
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.executor import run
from roughslip.run.store import journal_dir, read_run
from roughslip.surfaces.synthetic import sample_rng, self_affine, sphere
from roughslip.surfaces.topography import detrend, harmonic_fill, metres_per, read_raw, statistics
from roughslip.testing import differences, write_sdf, write_x3p

pytest.importorskip("SurfaceTopography", reason="the topography extra is not installed")

# ------------------------------------------------------------------ independent writers


def write_gwy(path: Path, h: np.ndarray, dx: float, dy: float,
              mask: np.ndarray | None = None) -> None:
    """Gwyddion's native format through gwyfile (an independent implementation)."""
    from gwyfile.objects import GwyContainer, GwyDataField, GwySIUnit

    ny, nx = h.shape
    c = GwyContainer()
    c["/0/data"] = GwyDataField(np.ascontiguousarray(h, dtype=float), xreal=nx * dx,
                                yreal=ny * dy, si_unit_xy=GwySIUnit(unitstr="m"),
                                si_unit_z=GwySIUnit(unitstr="m"))
    c["/0/data/title"] = "Height"
    if mask is not None:
        c["/0/mask"] = GwyDataField(mask.astype(float), xreal=nx * dx, yreal=ny * dy)
    c.tofile(str(path))


WRITERS = {"x3p": write_x3p, "gwy": write_gwy, "sdf": write_sdf}


@pytest.fixture(scope="module")
def scan() -> np.ndarray:
    """An asymmetric 48 x 56 map in metres (rms 0.1 um): orientation errors would show."""
    return self_affine((48, 56), hurst=0.8, rms_height=1.0, rng=sample_rng(3, 0)) * 1e-7


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("fmt", sorted(WRITERS))
def test_independent_writers_round_trip(tmp_path, scan, fmt):
    p = tmp_path / f"scan.{fmt}"
    WRITERS[fmt](p, scan, 5e-7, 7.5e-7)
    raw = read_raw(p)
    m = metres_per(raw.unit, str(p))
    assert raw.heights.shape == scan.shape  # [iy, ix]
    assert rel(raw.heights * m, scan) < 1e-12
    assert raw.pixel_size is not None
    assert np.allclose(np.array(raw.pixel_size) * m, [7.5e-7, 5e-7], rtol=1e-12, atol=0)


def _cfg(tmp_path: Path, surface: dict, **extra) -> Path:
    data = {"surface": {"kind": "file", **surface}, "squeeze": {"depths": [0.02, 0.05]},
            **extra}
    p = tmp_path / "run.toml"
    p.write_text(dumps_toml(data))
    return p


@pytest.mark.parametrize("fmt", ["x3p", "gwy"])
def test_run_stores_the_file_heights_in_the_run_unit(tmp_path, scan, fmt):
    p = tmp_path / f"scan.{fmt}"
    WRITERS[fmt](p, scan, 5e-7, 5e-7)
    out = tmp_path / "out.h5"
    r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": p.name},
                                                 units={"length": "um"})),
                                 "-o", str(out), "--quiet"])
    assert r.exit_code == 0, r.output
    with h5py.File(out, "r") as f:
        stored = f["samples/s000000/rigid_surface"][()]
        assert json.loads(f.attrs["units"])["length"] == "um"
        assert f.attrs["pixel_size"] == pytest.approx(0.5, rel=1e-12)
        prov = json.loads(f.attrs["topography"])["surface"]
    assert rel(stored, scan * 1e6) < 1e-12
    assert prov["format"] == fmt and prov["file_unit"] == "m" and prov["missing_points"] == 0
    r = CliRunner().invoke(cli, ["topography", str(p)])
    assert r.exit_code == 0, r.output
    for word in ("format:", "48 x 56", "pixel size:", "missing points:  0", "rms height:",
                 "rms slope:", "rms curvature:", "Hurst exponent:"):
        assert word in r.output, word
    r = CliRunner().invoke(cli, ["topography", str(out), "--json"])  # a run's surface
    assert r.exit_code == 0 and json.loads(r.output)["unit"] == "um"


def test_topography_plot_and_formats(tmp_path, scan):
    p = tmp_path / "scan.x3p"
    write_x3p(p, scan, 5e-7, 5e-7)
    png = tmp_path / "t.png"
    r = CliRunner().invoke(cli, ["topography", str(p), "--plot", str(png)])
    assert r.exit_code == 0 and png.stat().st_size > 0
    r = CliRunner().invoke(cli, ["topography", "--formats"])
    assert r.exit_code == 0 and "X3P" in r.output and "Gwyddion" in r.output


# ------------------------------------------------------------------ units and pixel size


def test_unit_rules(tmp_path, scan):
    write_x3p(tmp_path / "s.x3p", scan, 5e-7, 5e-7)
    np.save(tmp_path / "s.npy", scan * 1e6)
    cases = [  # (surface, extra sections, message)
        ({"path": "s.x3p"}, {}, "set units.length"),
        ({"path": "s.npy"}, {"units": {"length": "um"}}, "set surface.unit"),
        ({"path": "s.x3p"}, {"units": {"length": "um"}, "grid": {"pixel_size": 0.4}},
         "override_pixel_size"),
        ({"path": "s.x3p", "unit": "nm"}, {"units": {"length": "um"}}, "contradicts"),
    ]
    for surface, extra, message in cases:
        out = tmp_path / "o.h5"
        r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, surface, **extra)), "-o",
                                     str(out)])
        assert r.exit_code == 2 and message in r.output, (surface, r.output)
        assert len(r.output.strip().splitlines()) == 1 and not out.exists()
    # the override, and a file without units given one
    ok = load_config(_cfg(tmp_path, {"path": "s.x3p", "override_pixel_size": True},
                          units={"length": "um"}, grid={"pixel_size": 0.4}))
    run(ok, tmp_path / "a.h5")
    assert read_run(tmp_path / "a.h5").attrs["pixel_size"] == 0.4
    ok = load_config(_cfg(tmp_path, {"path": "s.npy", "unit": "nm"},
                          units={"length": "um"}))
    run(ok, tmp_path / "b.h5")
    with h5py.File(tmp_path / "b.h5") as f:
        assert rel(f["samples/s000000/rigid_surface"][()], scan * 1e3) < 1e-12


def test_non_square_pixels_are_resampled_linearly(tmp_path):
    h = np.random.default_rng(1).standard_normal((9, 12)) * 1e-6
    p = tmp_path / "rect.x3p"
    write_x3p(p, h, 1e-6, 2e-6)  # dy twice dx
    cfg = load_config(_cfg(tmp_path, {"path": p.name}, units={"length": "um"}))
    out = tmp_path / "r.h5"
    run(cfg, out)
    with h5py.File(out) as f:
        g = f["samples/s000000/rigid_surface"][()]
        assert f.attrs["pixel_size"] == pytest.approx(1.0)
    assert g.shape == (17, 12)  # 8 intervals of 2 um -> 16 of 1 um
    assert np.allclose(g[::2], h * 1e6, rtol=1e-12, atol=0)  # original rows kept
    assert np.allclose(g[1::2], 0.5 * (h[:-1] + h[1:]) * 1e6, rtol=1e-12, atol=1e-18)
    assert "resampled to square" in " ".join(json.loads(read_run(out).attrs["notes"]))


# ------------------------------------------------------------------ missing data


def test_missing_points_error_by_default(tmp_path):
    h = sphere((24, 24), radius=40.0)
    h[3:5, 7:10] = np.nan
    np.save(tmp_path / "holes.npy", h)
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": "holes.npy"})), "-o",
                                 str(out)])
    assert r.exit_code == 2 and "holes.npy" in r.output and "6 missing point(s)" in r.output
    assert not out.exists() and not journal_dir(out).exists()


def test_interpolation_is_harmonic(tmp_path):
    y, x = np.mgrid[0:20, 0:30].astype(float)
    plane = 0.3 * x - 0.2 * y + 1.0  # harmonic: filled exactly
    h = plane.copy()
    h[5:9, 10:15] = np.nan
    h[12, 13] = np.nan
    assert np.allclose(harmonic_fill(h), plane, atol=1e-10)
    h[0, 0] = np.nan  # at the edge the normal derivative is zero: mean of its neighbours
    assert harmonic_fill(h)[0, 0] == pytest.approx((plane[0, 1] + plane[1, 0]) / 2)


def test_voids_never_touch(tmp_path):
    h = sphere((32, 32), radius=30.0)
    apex = (slice(14, 18), slice(14, 18))
    h[apex] = np.nan  # the highest points are missing: in the model a void is a void
    np.save(tmp_path / "void.npy", h)
    cfg = load_config(_cfg(tmp_path, {"path": "void.npy", "missing": "void"},
                           output={"fields": ["contact", "fz"]}))
    out = tmp_path / "v.h5"
    run(cfg, out)
    r = read_run(out)
    assert r.complete.all() and np.all(r.scalars["normal_force"] > 0)
    for k in range(2):
        assert not r.field(0, k, "contact")[apex].any()
        assert np.all(r.field(0, k, "fz")[apex] == 0)
    stored = r.surface(0)
    assert np.isnan(stored[apex]).all() and np.isfinite(stored[~np.isnan(h)]).all()
    prov = json.loads(r.attrs["topography"])["surface"]
    assert prov["missing"] == "void" and prov["missing_points"] == 16


def _scan_with_holes(rms: float = 42.0, missing: int = 7) -> np.ndarray:
    """A 64 x 64 self-affine scan of rms ``rms`` with ``missing`` NaN points at distinct
    places (a profilometer's dropouts)."""
    h = self_affine((64, 64), hurst=0.8, rms_height=rms, rng=sample_rng(11, 0), oversample=2)
    pick = np.random.default_rng(5).choice(h.size, missing, replace=False)
    h.ravel()[pick] = np.nan
    return h


@pytest.mark.parametrize(("unit", "per_nm"), [("nm", 1.0), ("m", 1e-9)])
def test_missing_points_keep_the_scan_s_own_height_prefix(tmp_path, unit, per_nm):
    """A 42 nm rms scan with 7 missing points, given in nm or in m, is drawn in nm: the
    colour bar's label says nm and its limits are the scan's extreme heights in nm (the rms
    of a field with NaN is NaN, which once chose pm and heights 1000 times too large)."""
    from roughslip.analysis.topography_report import describe, display_unit, stats_figure

    h = _scan_with_holes()
    p = tmp_path / "holes.npy"
    np.save(p, h * per_nm)
    st, shown = describe(p, unit=unit, pixel=50 * per_nm)
    assert st.unit == "nm" and st.missing == 7
    assert st.rms_height == pytest.approx(np.sqrt(np.nanmean((h - np.nanmean(h)) ** 2)),
                                          rel=0.01)  # the harmonic fill moves 7 of 4096
    fig = stats_figure(st, shown)
    image, bar = fig.axes[0], fig.axes[2]
    assert bar.get_ylabel() == "height (nm)"
    lo, hi = image.images[0].get_clim()
    # h in nm, scaled to m and back: two roundings, each within 1.1e-16 relative
    assert lo == pytest.approx(np.nanmin(h), rel=1e-15)
    assert hi == pytest.approx(np.nanmax(h), rel=1e-15)
    ticks = [t for t in bar.get_yticks() if lo <= t <= hi]
    assert ticks and max(abs(t) for t in ticks) < 1000  # ticks in nm, not pm
    assert "7 missing point(s)" in image.get_title()
    assert display_unit(float("nan"), "nm") == ("nm", 1.0)
    png = tmp_path / "t.png"
    r = CliRunner().invoke(cli, ["topography", str(p), "--unit", unit, "--pixel-size",
                                 str(50 * per_nm), "--plot", str(png)])
    assert r.exit_code == 0 and png.stat().st_size > 0, r.output
    assert "height unit:     nm" in r.output


def test_masked_points_of_an_instrument_file(tmp_path, scan):
    mask = np.zeros(scan.shape)
    mask[10:12, 20:25] = 1.0
    p = tmp_path / "masked.gwy"
    write_gwy(p, scan, 5e-7, 5e-7, mask=mask)
    raw = read_raw(p)
    assert np.array_equal(np.isnan(raw.heights), mask > 0)  # Gwyddion's mask: undefined
    out = tmp_path / "m.h5"
    r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": p.name},
                                                 units={"length": "um"})), "-o", str(out)])
    assert r.exit_code == 2 and "masked.gwy: 10 missing point(s)" in r.output
    cfg = load_config(_cfg(tmp_path, {"path": p.name, "missing": "interpolate"},
                           units={"length": "um"}))
    run(cfg, out)
    stored = read_run(out).surface(0)
    assert np.isfinite(stored).all()
    assert rel(stored[mask == 0], scan[mask == 0] * 1e6) < 1e-12


# ------------------------------------------------------------------ preparation and tiles


def test_detrend_removes_exact_trends():
    y, x = np.mgrid[0:16, 0:20].astype(float)
    bumps = np.sin(x) * np.cos(y)
    assert np.allclose(detrend(bumps + 0.5 * x - 0.1 * y + 3, "tilt"),
                       detrend(bumps, "tilt"), atol=1e-12)
    quad = 0.01 * x**2 - 0.02 * x * y + 0.03 * y**2
    assert np.allclose(detrend(bumps + quad, "curvature"), detrend(bumps, "curvature"),
                       atol=1e-12)
    assert abs(detrend(bumps + 7, "mean").mean()) < 1e-12


def test_tiles_are_an_ensemble(tmp_path):
    big = self_affine((40, 60), hurst=0.8, rms_height=1.0, rng=sample_rng(5, 0))
    np.save(tmp_path / "big.npy", big)
    surface = {"path": "big.npy", "crop": [2, 40, 0, 60], "downsample": 1, "tiles": [2, 3],
               "detrend": "tilt"}
    cfg_path = _cfg(tmp_path, surface, pull={"enabled": True},
                    output={"fields": ["contact", "pull_curve"]})
    cfg = load_config(cfg_path)
    assert cfg.n_samples == 6
    one, two = tmp_path / "one.h5", tmp_path / "two.h5"
    run(cfg, one)
    run(cfg, two, workers=2)
    assert differences(one, two) == []
    r = read_run(one)
    assert list(r.sample_index) == list(range(6)) and r.complete.all()
    for i in range(6):
        ty, tx = divmod(i, 3)
        tile = big[2:40][ty * 19:(ty + 1) * 19, tx * 20:(tx + 1) * 20]
        assert np.allclose(r.surface(i), detrend(tile, "tilt"), rtol=0, atol=1e-12)
    # a resumed tiled run gives the same numbers
    r2 = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(one), "--resume"])
    assert r2.exit_code == 0 and differences(one, two) == []


def test_downsampling_averages_blocks(tmp_path):
    h = np.arange(64.0).reshape(8, 8)  # 4 x 4 blocks: the smallest scan a run takes
    h[0, 0] = np.nan
    np.save(tmp_path / "d.npy", h)
    cfg = load_config(_cfg(tmp_path, {"path": "d.npy", "downsample": 2, "missing": "void"},
                           grid={"pixel_size": 0.5}))
    out = tmp_path / "d.h5"
    run(cfg, out)
    g = read_run(out).surface(0)
    assert g.shape == (4, 4) and g[0, 0] == pytest.approx((1 + 8 + 9) / 3)
    assert g[1, 1] == pytest.approx(h[2:4, 2:4].mean())
    assert read_run(out).attrs["pixel_size"] == 0.5 * 2


# ------------------------------------------------------------------ bad files


def _bad_files(tmp_path: Path, scan: np.ndarray) -> dict[str, str]:
    good = tmp_path / "good.x3p"
    write_x3p(good, scan, 5e-7, 5e-7)
    raw = good.read_bytes()
    (tmp_path / "truncated.x3p").write_bytes(raw[: len(raw) // 2])
    (tmp_path / "corrupt.gwy").write_bytes(b"GWYP" + bytes(range(256)) * 4)
    (tmp_path / "words.sur").write_text("this is not a Digital Surf file\n")
    (tmp_path / "empty.x3p").write_bytes(b"")
    np.save(tmp_path / "nans.npy", np.full((8, 8), np.nan))
    write_gwy(tmp_path / "nanonly.gwy", np.full((8, 8), np.nan), 1e-6, 1e-6)
    return {"truncated.x3p": "cannot read", "corrupt.gwy": "cannot read",
            "words.sur": "cannot read", "empty.x3p": "empty", "nans.npy": "missing",
            "nanonly.gwy": "missing"}


def test_bad_files_exit_2_with_one_line_and_leave_nothing(tmp_path, scan):
    for name, what in _bad_files(tmp_path, scan).items():
        out = tmp_path / f"{name}.h5"
        r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": name},
                                                     units={"length": "um"})),
                                     "-o", str(out)])
        assert r.exit_code == 2, (name, r.output)
        lines = r.output.strip().splitlines()
        assert len(lines) == 1 and name in lines[0] and what in lines[0], (name, r.output)
        assert "Traceback" not in r.output
        assert not out.exists() and not journal_dir(out).exists()
        r = CliRunner().invoke(cli, ["topography", str(tmp_path / name)])
        assert r.exit_code == 2 and name in r.output, (name, r.output)


def test_missing_extra_is_named(tmp_path, scan, monkeypatch):
    p = tmp_path / "s.gwy"
    write_gwy(p, scan, 5e-7, 5e-7)
    monkeypatch.setitem(sys.modules, "SurfaceTopography", None)  # as if not installed
    with pytest.raises(InputError, match=r"topography extra: pip install 'roughslip\["):
        read_raw(p)
    np.save(tmp_path / "s.npy", scan)
    assert read_raw(tmp_path / "s.npy").heights.shape == scan.shape  # built in: no extra
    write_x3p(tmp_path / "s.x3p", scan, 5e-7, 5e-7)
    assert read_raw(tmp_path / "s.x3p").heights.shape == scan.shape  # X3P too


# ------------------------------------------------------------------ statistics


@pytest.mark.parametrize("hurst", [0.3, 0.6, 0.8, 0.95])
def test_hurst_estimate_recovers_h(hurst):
    """Stated tolerance (measured bias -0.012..-0.018 for four 256^2 surfaces, cropped from
    a twice larger periodic grid, Hann window): every surface within 0.07, the mean of four
    within 0.03."""
    est = [statistics(self_affine((256, 256), hurst=hurst, rms_height=1.0,
                                  rng=sample_rng(s, 0), oversample=2)).hurst
           for s in range(4)]
    assert max(abs(e - hurst) for e in est) < 0.07, est
    assert abs(np.mean(est) - hurst) < 0.03, est


def _validation():
    """scripts/hurst_validation.py, whose generators are not roughslip's."""
    import importlib.util

    path = Path(__file__).parents[1] / "scripts" / "hurst_validation.py"
    spec = importlib.util.spec_from_file_location("hurst_validation", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_hurst_of_independent_surfaces_lies_within_its_stated_uncertainty():
    """Eight 256 x 256 surfaces from two generators that are not roughslip's (fixed and
    Gaussian amplitudes), with and without a roll-off at L/8: each estimate within 4 stated
    standard deviations of the truth. Were the stated deviation honest and the errors
    Gaussian, P(|z| > 4) = 6.3e-5 per surface, 5e-4 for eight: a failure means the statement
    is wrong, not bad luck. Where the self-affine range spans the whole default range (4
    octaves, no roll-off) the deviation is useful, too: below 0.1, where the report calls an
    exponent uncertain."""
    from roughslip.surfaces.hurst import fit_hurst

    v = _validation()
    n = 256
    for k, (gen, hurst, rolloff) in enumerate(
            [(g, h, r) for g in (v.fixed_amplitudes, v.gaussian_amplitudes)
             for h in (0.3, 0.8) for r in (None, 8)]):
        q_r = None if rolloff is None else 2 * np.pi * rolloff / n
        fit = fit_hurst(gen(n, hurst, q_r, np.random.default_rng(k)))
        assert abs(fit.hurst - hurst) < 4 * fit.std, (gen.__name__, hurst, rolloff, fit)
        if rolloff is None:
            assert fit.std < 0.1, (gen.__name__, hurst, fit)
        assert fit.std >= fit.std_statistical > 0


def test_a_rolloff_and_a_noise_floor_are_found_and_left_out_of_the_fit():
    """A plateau below q_r = 2 pi / (L/8) is found within half an octave of q_r (two bins
    of a quarter octave: one for the bin, one for the Hann window's smoothing of the knee)
    and the fit starts above it; white noise that equals the power law at q_c = pi/4 is found
    below q_c (where it adds half the power) and the fit ends below that."""
    from roughslip.surfaces.hurst import fit_hurst

    v = _validation()
    n, hurst = 256, 0.7
    q_r = 2 * np.pi * 8 / n
    fit = fit_hurst(v.fixed_amplitudes(n, hurst, q_r, np.random.default_rng(1)))
    assert fit.rolloff is not None and abs(np.log2(fit.rolloff / q_r)) <= 0.5, fit
    assert fit.qmin > q_r and fit.bend is None
    assert abs(fit.hurst - hurst) < 4 * fit.std  # as in the test above
    h = v.fixed_amplitudes(n, hurst, None, np.random.default_rng(2))
    q_c = np.pi / 4
    # C(q) = q^-2(1+H) / n^2 with this normalisation; white noise of variance s^2 has C = s^2
    level = np.sqrt(q_c ** (-2 * (1 + hurst))) / n
    noisy = h + level * np.random.default_rng(3).standard_normal(h.shape)
    fit = fit_hurst(noisy)
    assert fit.bend is not None and fit.bend <= q_c and fit.qmax < q_c, fit
    assert abs(fit.hurst - hurst) < 4 * fit.std, fit


def test_hurst_warnings_name_the_problem():
    small = statistics(self_affine((48, 64), hurst=0.8, rms_height=1.0, oversample=2,
                                   rng=sample_rng(5, 0)))
    assert any("only" in w and "bins" in w for w in small.warnings)
    assert small.hurst_std > 0.1 and any("uncertain" in w for w in small.warnings)
    y, x = np.mgrid[0:64, 0:64].astype(float)
    smooth = statistics(np.sin(x / 20) * np.cos(y / 25))  # no self-affine range: H > 1
    assert not 0 < smooth.hurst < 1
    assert any("outside (0, 1)" in w for w in smooth.warnings)
    assert set(smooth.as_dict()) >= {"hurst_std", "hurst_std_statistical", "hurst_sys_low",
                                     "hurst_sys_high", "hurst_rolloff", "hurst_bend",
                                     "warnings"}


def test_topography_pixel_size_unit_and_prefix_for_a_bare_file(tmp_path):
    h = self_affine((48, 56), hurst=0.8, rms_height=1.0, rng=sample_rng(3, 0)) * 0.2
    p = tmp_path / "bare.txt"
    np.savetxt(p, h)
    r = CliRunner().invoke(cli, ["topography", str(p), "--unit", "um", "--pixel-size", "0.5",
                                 "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["unit"] == "nm"  # rms 0.2 um: shown in nm
    assert d["pixel_size"] == pytest.approx([500.0, 500.0])
    assert d["rms_height"] == pytest.approx(200.0, rel=1e-9)
    r = CliRunner().invoke(cli, ["topography", str(p)])
    assert "not in the file" in r.output
    x3p = tmp_path / "s.x3p"
    write_x3p(x3p, h * 1e-6, 5e-7, 5e-7)
    r = CliRunner().invoke(cli, ["topography", str(x3p), "--pixel-size", "0.7", "--unit", "um"])
    assert r.exit_code == 2 and "contradicts" in r.output


def test_statistics_of_a_plane_and_a_parabola():
    y, x = np.mgrid[0:32, 0:32].astype(float)
    st = statistics(0.25 * x, a=0.5)
    assert st.rms_slope == pytest.approx(0.5, rel=1e-12)  # d/dx over spacing 0.5
    assert st.rms_curvature == pytest.approx(0.0, abs=1e-12)
    st = statistics(0.5 * (x**2 + y**2), a=1.0)  # Laplacian 2: curvature (mean) 1
    assert st.rms_curvature == pytest.approx(1.0, rel=1e-12)


def test_shipped_scan_example_runs(tmp_path):
    root = Path(__file__).parents[1]
    out = tmp_path / "tiles.h5"
    r = CliRunner().invoke(cli, ["run", str(root / "configs" / "scan_tiles.toml"), "-o",
                                 str(out), "--set", "squeeze.depths=[0.5]", "--quiet"])
    assert r.exit_code == 0, r.output
    run_data = read_run(out)
    assert run_data.complete.all() and run_data.complete.size == 4
    assert run_data.attrs["pixel_size"] == pytest.approx(0.25, rel=1e-12)
    raw = read_raw(root / "configs" / "data" / "scan.x3p")
    tile3 = raw.heights[64:, 64:] * 1e6  # metres -> um
    assert np.allclose(run_data.surface(3), detrend(tile3, "tilt"), rtol=0, atol=1e-12)


# ------------------------------------------------------------------ X3P from another writer


@pytest.fixture
def x3pio():
    """The independent X3P writer (the dev extra has it); only these tests need it."""
    return pytest.importorskip("x3pio", reason="x3pio (the independent X3P writer) is not "
                               "installed")


#: stored type -> the largest error its quantisation allows, relative to the height range
X3P_TYPES = {"D": 0.0, "F": 1e-7, "L": 1e-9, "I": 2e-5}


@pytest.mark.parametrize("revision", ["ISO5436_2000", "ISO25178_72_2017_DAM1"])
@pytest.mark.parametrize("ztype", list(X3P_TYPES))
def test_x3p_of_either_revision_written_by_another_library(tmp_path, scan, x3pio, revision, ztype):
    """Heights, pixel size, unit and missing points of X3P files that x3pio writes, in both
    revisions of the standard and every stored type (binary), read without the extra."""
    h = scan.copy()  # metres
    h[3, 5] = np.nan
    p = tmp_path / "s.x3p"
    x3pio.write(p, h, x_scale=5e-7, y_scale=2.5e-7, z_type=x3pio.DataType(ztype),
                revision=getattr(x3pio.Revision, revision))
    raw = read_raw(p)
    assert raw.unit == "m" and raw.format == "x3p"
    assert raw.pixel_size == (2.5e-7, 5e-7)  # (dy, dx)
    assert raw.heights.shape == h.shape
    assert np.array_equal(np.isnan(raw.heights), np.isnan(h))
    ok = ~np.isnan(h)
    span = np.ptp(h[ok])
    assert np.max(np.abs(raw.heights[ok] - h[ok])) <= max(X3P_TYPES[ztype] * span, 1e-12 * span)


def test_x3p_2017_as_xml_text_and_in_a_run(tmp_path, scan, x3pio):
    """The 2017 revision that SurfaceTopography refuses: written by x3pio with the heights as
    XML text and as binary, both run, and the run stores the heights (in um) to 1e-12."""
    h = scan  # metres
    for name, storage in (("xml.x3p", x3pio.DataStorage.XML),
                          ("bin.x3p", x3pio.DataStorage.BINARY)):
        x3pio.write(tmp_path / name, h, x_scale=5e-7, y_scale=5e-7, storage=storage)
        assert rel(read_raw(tmp_path / name).heights, h) < 1e-12
        out = tmp_path / f"{name}.h5"
        r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": name},
                                                     units={"length": "um"})),
                                     "-o", str(out), "--quiet"])
        assert r.exit_code == 0, r.output
        with h5py.File(out, "r") as f:
            stored = f["samples/s000000/rigid_surface"][()]
            assert f.attrs["pixel_size"] == pytest.approx(0.5, rel=1e-12)
        assert rel(stored, scan * 1e6) < 1e-12


def test_x3p_reader_agrees_with_surfacetopography_on_the_2000_revision(tmp_path, scan, x3pio):
    """Two independent readers of one x3pio file of the revision SurfaceTopography reads."""
    st = pytest.importorskip("SurfaceTopography")
    h = scan
    p = tmp_path / "s.x3p"
    x3pio.write(p, h, x_scale=5e-7, y_scale=2.5e-7, revision=x3pio.Revision.ISO5436_2000)
    t = st.open_topography(str(p)).topography()
    theirs = np.asarray(t.heights(), dtype=float).T  # [ix, iy] -> [iy, ix]
    assert np.array_equal(read_raw(p).heights, theirs)
    assert tuple(t.pixel_size)[::-1] == read_raw(p).pixel_size


def test_x3p_damage_is_one_line(tmp_path, scan, x3pio):
    import zipfile

    good = tmp_path / "good.x3p"
    x3pio.write(good, scan, x_scale=5e-7, y_scale=5e-7)
    with zipfile.ZipFile(good) as z:
        files = {n: z.read(n) for n in z.namelist()}
    data = bytearray(files["bindata/data.bin"])
    data[8] ^= 0xFF
    with zipfile.ZipFile(tmp_path / "flipped.x3p", "w") as z:
        for n, b in files.items():
            z.writestr(n, bytes(data) if n == "bindata/data.bin" else b)
    with pytest.raises(InputError, match="checksum of the point data does not match"):
        read_raw(tmp_path / "flipped.x3p")
    with zipfile.ZipFile(tmp_path / "nodata.x3p", "w") as z:
        for n, b in files.items():
            if n != "bindata/data.bin":
                z.writestr(n, b)
    with pytest.raises(InputError, match=r"has no 'bindata/data\.bin'"):
        read_raw(tmp_path / "nodata.x3p")
    with pytest.raises(InputError, match="layer number"):
        read_raw(good, key="height")


# ------------------------------------------------------------------ what a scan must hold


def _one_line(r, *words: str) -> str:
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.output, r.output
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.mark.parametrize("shape", [(1, 64), (64, 3), (2, 2), (3, 40)])
@pytest.mark.parametrize("fmt", ["npy", "txt", "x3p", "gwy"])
def test_a_scan_smaller_than_4_x_4_is_refused_naming_the_file(tmp_path, fmt, shape):
    """One minimum for every format and for both commands (a 1 x 64 scan was refused as
    "surface.tiles = None: tiles of 1 x 64", a key never set; 64 x 3 and 2 x 2 ran)."""
    from roughslip.surfaces.limits import MIN_SCAN_SIDE

    h = np.random.default_rng(2).standard_normal(shape) * 1e-7
    p = tmp_path / f"small.{fmt}"
    {"npy": lambda: np.save(p, h), "txt": lambda: np.savetxt(p, h),
     "x3p": lambda: write_x3p(p, h, 1e-6, 1e-6),
     "gwy": lambda: write_gwy(p, h, 1e-6, 1e-6)}[fmt]()
    rule = f"{shape[0]} x {shape[1]} pixels (ny x nx): a scan must be at least " \
           f"{MIN_SCAN_SIDE} x {MIN_SCAN_SIDE} pixels"
    with pytest.raises(InputError, match=re.escape(f"small.{fmt}: {rule}")):
        read_raw(p)
    _one_line(CliRunner().invoke(cli, ["topography", str(p)]), f"small.{fmt}: {rule}")
    unit = {} if fmt in ("npy", "txt") else {"units": {"length": "um"}}
    r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": p.name}, **unit)), "-o",
                                 str(tmp_path / "o.h5")])
    line = _one_line(r, f"small.{fmt}: {rule}")
    assert "tiles" not in line and not (tmp_path / "o.h5").exists()


def test_the_minimum_holds_after_crop_downsample_and_tiles_naming_the_key(tmp_path):
    h = self_affine((24, 32), hurst=0.8, rms_height=1.0, rng=sample_rng(4, 0))
    np.save(tmp_path / "s.npy", h)
    for surface, words in (
        ({"crop": [0, 3, 0, 32]}, ["surface.crop = [0, 3, 0, 32]: leaves 3 x 32 pixels (ny x "
                                   "nx) of ", "s.npy: a scan must be at least 4 x 4 pixels"]),
        ({"downsample": 7}, ["surface.downsample = 7: leaves 3 x 4 pixels (ny x nx) of the "
                             "[24, 32] grid of ", "s.npy: a scan must be at least 4 x 4"]),
        ({"tiles": [5, 2]}, []),
        ({"tiles": [7, 2]}, ["surface.tiles = [7, 2]: tiles of 3 x 16 pixels (ny x nx) from "
                             "the [24, 32] grid of ", "s.npy: a tile must be at least 4 x 4 "
                             "pixels; use fewer tiles"]),
    ):
        cfg = _cfg(tmp_path, {"path": "s.npy", **surface})
        r = CliRunner().invoke(cli, ["show-config", str(cfg)])
        assert r.exit_code == 0  # the configuration is fine: the file decides
        r = CliRunner().invoke(cli, ["run", str(cfg), "-o", str(tmp_path / "o.h5"), "--quiet",
                                     "--set", "squeeze.depths=[0.1]"])
        if surface == {"tiles": [5, 2]}:  # 4 x 16 tiles: the smallest allowed
            assert r.exit_code == 0, r.output
            (tmp_path / "o.h5").unlink()
            continue
        _one_line(r, *words)


def test_a_flat_topography_is_refused_naming_the_file(tmp_path):
    """Constant heights (every depth in rms units was 0, and the run said nothing), heights
    constant to rounding, and a tile left flat by the preparation."""
    from roughslip.surfaces.limits import FLAT_RELIEF

    y, x = np.mgrid[0:16, 0:16].astype(float)
    files = {"zeros.npy": np.zeros((16, 16)), "five.npy": np.full((16, 16), 5.0),
             "rounding.npy": 1e6 + 1e-7 * (x % 2)}  # varies by 1e-13 of its size
    for name, h in files.items():
        np.save(tmp_path / name, h)
        rule = "a topography needs an rms height above 1e-12 x its largest |height|"
        with pytest.raises(InputError, match=rf"{re.escape(name)}: the heights are constant "
                                             r"\(rms height [^,]+, largest \|height\| [^)]+\): "
                                             + re.escape(rule)):
            read_raw(tmp_path / name)
        r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": name},
                                                     squeeze={"depths": [0.5],
                                                              "depth_unit": "rms"})),
                                     "-o", str(tmp_path / "o.h5")])
        _one_line(r, name, "the heights are constant", rule)
        _one_line(CliRunner().invoke(cli, ["topography", str(tmp_path / name)]), name, rule)
        assert not (tmp_path / "o.h5").exists()
    np.save(tmp_path / "rough.npy", 1e6 + 1e-3 * np.sin(x) * np.cos(y / 2))  # 1e-9: kept
    assert read_raw(tmp_path / "rough.npy").heights.shape == (16, 16)
    assert FLAT_RELIEF == 1e-12
    # a plane is not flat, but nothing is left once its tilt is removed
    np.save(tmp_path / "plane.npy", 0.3 * x - 0.2 * y + 1.0)
    r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": "plane.npy",
                                                            "detrend": "tilt",
                                                            "tiles": [2, 1]})),
                                 "-o", str(tmp_path / "o.h5")])
    _one_line(r, "plane.npy: tile 0 (after surface.tiles, surface.detrend): the heights are "
                 "constant", "largest |height| of the file 5.5)")
    # every point missing (masked): named as such, not as flat
    write_gwy(tmp_path / "masked.gwy", x, 1e-6, 1e-6, mask=np.ones_like(x))
    with pytest.raises(InputError, match=r"masked\.gwy: every point is missing"):
        read_raw(tmp_path / "masked.gwy")


def test_the_config_reference_names_every_format_read_without_the_extra():
    """``surface.path``'s description, from which the configuration reference is made, names
    every suffix that is read without SurfaceTopography."""
    import dataclasses

    from roughslip.run.config import SECTIONS
    from roughslip.surfaces.topography import BUILTIN_SUFFIXES

    docs = {f.name: f.metadata["doc"] for f in dataclasses.fields(SECTIONS["surface"])}
    named = set(re.findall(r"\.\w+", docs["path"]))
    assert {*BUILTIN_SUFFIXES, ".x3p"} <= named, {*BUILTIN_SUFFIXES, ".x3p"} - named
    assert ".x3p" in docs["key"]


def test_surface_path_that_is_missing_or_a_directory(tmp_path):
    (tmp_path / "adir.npy").mkdir()
    for path, words in (("nothere.npy", ["surface.path = \"nothere.npy\": no such file"]),
                        ("adir.npy", ["surface.path = \"adir.npy\": is a directory"])):
        r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": path})), "-o",
                                     str(tmp_path / "o.h5")])
        _one_line(r, *words)
    with pytest.raises(InputError, match=r"adir\.npy: is a directory, not a topography file"):
        read_raw(tmp_path / "adir.npy")



def test_an_unreadable_topography_file_is_one_line(tmp_path, monkeypatch):
    import builtins
    import io

    np.save(tmp_path / "locked.npy", sphere((8, 8), radius=9.0))
    real = io.open

    def denied(file, *args, **kw):  # as for a file without read permission (tests run as root)
        if str(file).endswith("locked.npy"):
            raise PermissionError(13, "Permission denied", str(file))
        return real(file, *args, **kw)

    monkeypatch.setattr(io, "open", denied)
    monkeypatch.setattr(builtins, "open", denied)
    r = CliRunner().invoke(cli, ["run", str(_cfg(tmp_path, {"path": "locked.npy"})), "-o",
                                 str(tmp_path / "o.h5")])
    _one_line(r, "locked.npy: cannot read ([Errno 13] Permission denied")


def test_zip_based_instrument_files_are_checked_before_they_are_handed_over(tmp_path):
    """A format SurfaceTopography reads from a zip archive (here its NMM .zip): a member that
    would inflate by more than MAX_COMPRESSION_RATIO is refused before the reader opens it."""
    import zipfile

    p = tmp_path / "scan.zip"
    with zipfile.ZipFile(p, "w", zipfile.ZIP_BZIP2) as z:
        z.writestr("scan.dsc", b" " * 2_000_000)
    with pytest.raises(InputError, match=r"scan\.zip: 'scan\.dsc' declares 2000000 bytes "
                                         r"compressed to \d+ \(ratio \d+:1\): an archive "
                                         r"member may be compressed at most 1100:1"):
        read_raw(p)
    _one_line(CliRunner().invoke(cli, ["topography", str(p)]), "scan.zip", "1100:1")


def test_a_flat_generated_surface_with_depths_in_rms_units_is_refused(tmp_path):
    """A plane with no slope has rms height and range 0: depths in those units would all be
    0, and the run would say nothing. The configuration is refused in one line naming the
    key; with a slope, or depths in length units, it runs."""
    data = {"grid": {"n": 8}, "surface": {"kind": "plane"},
            "squeeze": {"depths": [0.5], "depth_unit": "rms"}}
    with pytest.raises(ConfigError, match=r"squeeze.depth_unit = \"rms\": needs a surface with "
                                         r"relief; a plane with no slope is flat"):
        load_config(data=data)
    load_config(data={**data, "surface": {"kind": "plane", "slope": [0.1, 0.0]}})
    load_config(data={**data, "squeeze": {"depths": [0.5], "depth_unit": "length"}})


def test_a_text_topography_is_refused_past_the_point_cap_while_it_is_read(tmp_path,
                                                                          monkeypatch):
    """Text files are read row by row, counted against the cap on points, so that a huge one
    is refused before it fills the memory (the cap lowered here to 8 x 8)."""
    from roughslip.surfaces import limits

    monkeypatch.setattr(limits, "MAX_SCAN_POINTS", 64)
    np.savetxt(tmp_path / "big.txt", np.ones((9, 8)) + np.arange(8))
    with pytest.raises(InputError, match=r"big.txt: more than 64 points by line 9"):
        read_raw(tmp_path / "big.txt")
    np.savetxt(tmp_path / "fits.txt", np.ones((8, 8)) + np.arange(8))
    assert read_raw(tmp_path / "fits.txt").heights.shape == (8, 8)
