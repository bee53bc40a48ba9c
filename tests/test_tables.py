"""roughslip.analysis.tables: the run file as a pandas table and an xarray Dataset, and one
sample's fields as NetCDF, each with the run file's values bit for bit."""

from __future__ import annotations

import shutil
import sys

import h5py
import numpy as np
import pytest

import roughslip
from roughslip.analysis import tables
from roughslip.errors import InputError
from roughslip.run.executor import run
from roughslip.run.schema import all_columns

pytest.importorskip("pandas", reason="the tables extra is not installed")
xr = pytest.importorskip("xarray", reason="the tables extra is not installed")
pytest.importorskip("h5netcdf", reason="the tables extra is not installed")

FIELDS = ["contact", "stick", "fz", "fx", "uz", "ux", "gap"]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """A run of 3 samples at 3 depths (rms), every grid field stored, pixel size 0.5."""
    path = tmp_path_factory.mktemp("tables") / "sweep.h5"
    config = roughslip.load_config(data={
        "title": "tables",
        "grid": {"n": 16, "pixel_size": 0.5},
        "material": {"E": 1.0, "nu": 0.3},
        "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0},
        "squeeze": {"depths": [0.5, 1.0, 2.0], "depth_unit": "rms"},
        "pull": {"enabled": True, "lam": 0.2},
        "ensemble": {"samples": 3, "seed": 11},
        "output": {"fields": [*FIELDS, "pull_curve"]},
    })
    run(config, path, workers=1)
    return path


def _bits(a) -> np.ndarray:
    """The bit patterns of an array of floats (NaNs compare by their bits too)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def test_dataframe_is_the_file_bit_for_bit(sweep):
    df = tables.to_dataframe(sweep)
    with h5py.File(sweep, "r") as f:
        depth = f["depth"][()]
        names = [c.name for c in all_columns() if c.name in f]
        stored = {name: f[name][()] for name in names}
        samples = f["sample_index"][()]
    assert list(df.columns) == ["sample", "depth_index", "depth", *names]
    assert len(df) == len(samples) * len(depth)
    assert df["sample"].tolist() == np.repeat(samples, len(depth)).tolist()
    assert df["depth_index"].tolist() == [0, 1, 2] * len(samples)
    assert np.array_equal(_bits(df["depth"].to_numpy()), _bits(np.tile(depth, len(samples))))
    for name in names:
        assert df[name].dtype == np.float64
        assert np.array_equal(_bits(df[name].to_numpy()), _bits(stored[name].ravel())), name
    assert np.isnan(df["pull_error_estimate"]).all()  # not asked for: NaN, kept as NaN
    assert df.attrs["grid.n"] == 16 and df.attrs["pull.lam"] == 0.2
    assert df.attrs["squeeze.depths"] == [0.5, 1.0, 2.0] and df.attrs["title"] == "tables"
    assert df.attrs["file"] == str(sweep) and df.attrs["version"] == roughslip.__version__
    assert isinstance(df.attrs["units"], dict) and isinstance(df.attrs["notes"], list)


def test_xarray_has_the_dimensions_and_the_files_values(sweep):
    ds = tables.to_xarray(sweep)
    assert dict(ds.sizes) == {"sample": 3, "depth": 3}
    with h5py.File(sweep, "r") as f:
        assert np.array_equal(ds["sample"].values, f["sample_index"][()])
        assert np.array_equal(_bits(ds["depth"].values), _bits(f["depth"][()]))
        for name in ds.data_vars:
            assert ds[name].dims == ("sample", "depth")
            assert np.array_equal(_bits(ds[name].values), _bits(f[name][()])), name
            assert ds[name].attrs["description"] == f[name].attrs["description"]
            assert "DIMENSION_LIST" not in ds[name].attrs
    assert ds["depth"].attrs["unit"] == "rms"
    assert ds.attrs["pull.lam"] == 0.2


def test_incomplete_samples_are_left_out_unless_asked_for(sweep, tmp_path):
    part = tmp_path / "part.h5"
    shutil.copy(sweep, part)
    with h5py.File(part, "r+") as f:
        f["complete"][1] = 0
    df = tables.to_dataframe(part)
    assert sorted(set(df["sample"])) == [0, 2]
    every = tables.to_dataframe(part, complete_only=False)
    assert len(every) == 9 and every["complete"].tolist() == [True] * 3 + [False] * 3 + [True] * 3
    assert tables.to_xarray(part)["sample"].values.tolist() == [0, 2]
    ds = tables.to_xarray(part, complete_only=False)
    assert ds["complete"].values.tolist() == [True, False, True]
    with pytest.raises(InputError, match="sample 1 is not a complete sample"):
        tables.sample_fields(part, 1)


def test_netcdf_export_round_trips_bit_for_bit(sweep, tmp_path):
    out = tables.export_netcdf(sweep, tmp_path / "s2.nc", sample=2)
    with xr.open_dataset(out) as back, h5py.File(sweep, "r") as f:
        assert dict(back.sizes) == {"depth": 3, "y": 16, "x": 16}
        assert set(back.data_vars) == {*FIELDS, "rigid_surface"}
        for name in FIELDS:
            stored = np.stack([f[f"samples/s000002/d{k:03d}/{name}"][()] for k in range(3)])
            got = back[name].values
            if name in ("contact", "stick"):
                assert got.dtype == bool and np.array_equal(got, stored.astype(bool)), name
            else:
                assert got.dtype == np.float64
                assert np.array_equal(_bits(got), _bits(stored)), name
        assert np.array_equal(_bits(back["rigid_surface"].values),
                              _bits(f["samples/s000002/rigid_surface"][()]))
        assert np.array_equal(back["x"].values, np.arange(16) * 0.5)
        # a run without units names none: no "length" or "E x length^2" on the plots
        assert "units" not in back["fz"].attrs and "units" not in back["gap"].attrs
        assert "units" not in back["x"].attrs and back["depth"].attrs["units"] == "rms"
        assert back["x"].attrs["long_name"] == "x, the pull direction"
        assert back.attrs["sample"] == 2 and back.attrs["grid.n"] == 16
        assert back.attrs["config"] == f.attrs["config"]


def test_sample_fields_names_and_refusals(sweep):
    ds = tables.sample_fields(sweep, 0, names=["fz"])
    assert set(ds.data_vars) == {"fz", "rigid_surface"}
    with pytest.raises(InputError, match="not a grid field"):
        tables.sample_fields(sweep, 0, names=["dx_lim"])
    with pytest.raises(InputError, match="not a complete sample"):
        tables.sample_fields(sweep, 7)


def test_a_missing_extra_is_named_in_one_line(sweep, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas raises ImportError
    with pytest.raises(InputError) as err:
        tables.to_dataframe(sweep)
    assert "pip install 'roughslip[tables]'" in str(err.value)
    assert "\n" not in str(err.value)


def test_sample_fields_carry_the_named_units(tmp_path):
    """With a length and a stress unit the fields and coordinates carry them (forces in the
    named force unit), as the figures label them."""
    path = tmp_path / "units.h5"
    config = roughslip.load_config(data={
        "grid": {"n": 8, "pixel_size": "0.5 um"},
        "material": {"E": "70 GPa", "nu": 0.3},
        "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": "1 um"},
        "squeeze": {"depths": [1.0], "depth_unit": "rms"},
        "ensemble": {"samples": 1, "seed": 3},
        "output": {"fields": ["fz", "gap"]},
    })
    run(config, path, workers=1)
    ds = tables.sample_fields(path, 0)
    assert ds["fz"].attrs["units"] == "mN" and ds["gap"].attrs["units"] == "um"
    assert ds["x"].attrs["units"] == "um" and ds["rigid_surface"].attrs["units"] == "um"
