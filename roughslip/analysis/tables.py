"""Run files as tables for one's own analysis, and one sample's fields for other tools.

:func:`to_dataframe` gives a tidy :class:`pandas.DataFrame` (one row per sample and depth,
one column per stored scalar), :func:`to_xarray` the same numbers as an
:class:`xarray.Dataset` with the dimensions ``(sample, depth)``; both carry the run's
configuration, flattened to dotted keys (``"surface.hurst"``), in their ``attrs``.
:func:`sample_fields` gives the stored fields of one sample as a Dataset on the grid's
coordinates, and :func:`export_netcdf` writes them to a NetCDF-4 file that xarray, the
netCDF library and its tools, ParaView and MATLAB's ``ncread`` read.

The values are those of the run file, bit for bit: the scalars are ``float64`` as stored
(NaN where nothing was computed: docs/guide/hdf5.rst), the boolean fields come back
as booleans. pandas, xarray and h5netcdf are the ``tables`` extra
(``pip install 'roughslip[tables]'``); they are imported when a function needs them.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from roughslip.analysis.fit import flatten
from roughslip.errors import InputError, io_failure
from roughslip.run import schema
from roughslip.run.reading import RunData, group_name, open_file, read_run

if TYPE_CHECKING:  # pragma: no cover
    import pandas
    import xarray

__all__ = ["config_attrs", "export_netcdf", "sample_fields", "to_dataframe", "to_xarray"]

#: HDF5 attributes of the dimension scales, which describe the file's layout, not the data
_SCALE_ATTRS = {"DIMENSION_LIST", "DIMENSION_LABELS", "REFERENCE_LIST", "CLASS", "NAME",
                "_Netcdf4Dimid", "_Netcdf4Coordinates"}
#: the fields measured in a length or in a force
_FIELD_UNIT = {"fz": "force", "fx": "force", "fy": "force", "uz": "length", "ux": "length",
               "gap": "length"}


def _extra(module: str) -> Any:
    """Import ``module`` of the tables extra, or say in one line what to install."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputError(f"{module} is needed here; install the tables extra: "
                         "pip install 'roughslip[tables]'") from None


def _plain(v: Any) -> Any:
    return v.decode() if isinstance(v, bytes) else v


def config_attrs(run: RunData) -> dict[str, Any]:
    """The attributes :func:`to_dataframe` and :func:`to_xarray` attach: the stored
    configuration flattened to dotted keys, and the file's provenance.

    Parameters
    ----------
    run : RunData
        A run file read by :func:`~roughslip.run.reading.read_run`.

    Returns
    -------
    dict
        ``"section.key"`` for every key of the resolved configuration (``"grid.n"``,
        ``"pull.lam"``, ``"title"``), plus ``"file"`` (the run file's path), ``"version"``
        (of roughslip that wrote it), ``"units"`` (what the numbers are measured in, a dict)
        and ``"notes"`` (the run's notes, a list of str).
    """
    attrs = flatten(run.config_dict())
    attrs["file"] = str(run.path)
    attrs["version"] = str(run.attrs.get("version", ""))
    for name in ("units", "notes"):
        raw = run.attrs.get(name)
        try:
            attrs[name] = json.loads(raw) if isinstance(raw, str) else raw
        except ValueError:
            attrs[name] = raw
    attrs["units"] = attrs["units"] or {}
    attrs["notes"] = attrs["notes"] or []
    return attrs


def _rows(run: RunData, complete_only: bool) -> np.ndarray:
    rows = run.complete if complete_only else np.ones(run.complete.shape, bool)
    return np.flatnonzero(rows)


def to_dataframe(path: str | Path, *, complete_only: bool = True) -> pandas.DataFrame:
    """The scalars of a run file as a tidy table: one row per sample and depth.

    Parameters
    ----------
    path : path-like
        A run file (``roughslip run ... -o path``).
    complete_only : bool
        Keep the complete samples only (the default). With False every sample's rows are
        returned, with a ``complete`` column; the entries of an unfinished sample are NaN.

    Returns
    -------
    pandas.DataFrame
        Columns ``sample`` (the global sample number), ``depth_index``, the axis (``depth``,
        or ``force_target`` under load control, in ``squeeze.depth_unit`` or
        ``squeeze.force_unit``), then every scalar the run stored (``normal_force``,
        ``contact_area``, ``friction_force``, ...), ``float64`` as stored. Samples vary
        slowest. ``attrs`` holds :func:`config_attrs`.

    Raises
    ------
    InputError
        When the file is not a run file, or pandas is not installed.
    """
    pd = _extra("pandas")
    run = read_run(path)
    rows = _rows(run, complete_only)
    nd = len(run.axis)
    columns: dict[str, np.ndarray] = {
        "sample": np.repeat(run.sample_index[rows].astype(np.int64), nd),
        "depth_index": np.tile(np.arange(nd, dtype=np.int64), len(rows)),
        run.axis_name: np.tile(run.axis, len(rows)),
    }
    if not complete_only:
        columns["complete"] = np.repeat(run.complete[rows], nd)
    for name, values in run.scalars.items():
        columns[name] = values[rows].reshape(-1)
    frame = pd.DataFrame(columns)
    frame.attrs.update(config_attrs(run))
    return frame


def _dataset_attrs(dset: Any) -> dict[str, Any]:
    return {k: _plain(v) for k, v in dset.attrs.items() if k not in _SCALE_ATTRS}


def to_xarray(path: str | Path, *, complete_only: bool = True) -> xarray.Dataset:
    """The scalars of a run file as an :class:`xarray.Dataset` with dimensions
    ``(sample, depth)``.

    Parameters
    ----------
    path : path-like
        A run file.
    complete_only : bool
        Keep the complete samples only (the default); with False every sample, and a
        ``complete`` variable along ``sample``.

    Returns
    -------
    xarray.Dataset
        One variable per stored scalar, each of shape ``(sample, depth)`` with the
        attributes of its HDF5 dataset (its ``description``). The coordinate ``sample``
        holds the global sample numbers, the coordinate of the second dimension the
        configured targets: it is named ``depth``, or ``force_target`` under load control,
        with its unit in the attribute ``unit``. ``attrs`` holds :func:`config_attrs`.

    Raises
    ------
    InputError
        When the file is not a run file, or xarray is not installed.
    """
    xr = _extra("xarray")
    run = read_run(path)
    rows = _rows(run, complete_only)
    dims = ("sample", run.axis_name)
    data: dict[str, Any] = {}
    with open_file(run.path) as f:
        for name, values in run.scalars.items():
            data[name] = (dims, values[rows], _dataset_attrs(f[name]))
        axis_attrs = _dataset_attrs(f[run.axis_name])
    if not complete_only:
        data["complete"] = (("sample",), run.complete[rows])
    axis_attrs.setdefault("unit", run.axis_unit)
    coords = {"sample": ("sample", run.sample_index[rows].astype(np.int64),
                         {"description": schema.ROOT["sample_index"]}),
              run.axis_name: (run.axis_name, run.axis, axis_attrs)}
    return xr.Dataset(data, coords=coords, attrs=config_attrs(run))


def sample_fields(path: str | Path, sample: int, *,
                  names: list[str] | tuple[str, ...] | None = None) -> xarray.Dataset:
    """The stored fields of one sample at every depth, on the grid's coordinates.

    Parameters
    ----------
    path : path-like
        A run file.
    sample : int
        The global sample number (a value of ``to_dataframe(path)["sample"]``).
    names : sequence of str, optional
        The fields to take (default: every grid field the run stored, ``output.fields``).
        The pull curves (one entry per event, ``dx_lim``, ``fx_lim``, ...) are not grid fields
        and stay in the run file.

    Returns
    -------
    xarray.Dataset
        Each field a variable of dimensions ``(depth, y, x)`` (``force_target`` instead of
        ``depth`` under load control); the surfaces (``rigid_surface``, and
        ``elastic_surface`` for two rough surfaces) of dimensions ``(y, x)``. ``x`` and ``y``
        are the pixel positions, index times pixel size; ``x`` is the pull direction of the x-only
        model (``pull.direction`` gives the drive of the traction vector). Each
        variable and coordinate has the attribute ``long_name`` of the NetCDF conventions,
        and ``units`` where the run names one, which plotting tools label axes with: lengths
        in the run's length unit (``units.length``) and forces in its force unit (``uN``, or
        ``E x um^2`` with only a length unit named). A dimensionless run (no ``[units]``)
        names none, so its lengths and forces have no ``units`` attribute (its numbers are
        in the units of ``grid.pixel_size`` and ``material.E``, as ``attrs["units"]`` says).
        ``attrs`` holds :func:`config_attrs` and ``sample``.

    Raises
    ------
    InputError
        When the sample is not complete, a field was not stored, or xarray is not installed.
    """
    from roughslip.analysis.model import units as run_units
    from roughslip.analysis.summary import axis_unit, pixel_size

    xr = _extra("xarray")
    run = read_run(path)
    sample = int(sample)
    done = set(run.sample_index[run.complete].tolist())
    if sample not in done:
        raise InputError(f"{run.path}: sample {sample} is not a complete sample of the run "
                         f"(complete: {sorted(done)[:8]}{' ...' if len(done) > 8 else ''})")
    grid = {f.name for f in schema.FIELDS if f.grid}
    attrs = config_attrs(run)
    u = run_units(run)

    def unit(dimension: str) -> dict[str, str]:
        """The ``units`` attribute of a ``dimension``: none where the run names no unit."""
        text = u.of_dimension(dimension)
        return {"units": text} if text else {}

    group = f"samples/{group_name(sample)}"
    with open_file(run.path) as f:
        stored = [k for k in f[f"{group}/d000"].keys() if k in grid] if "d000" in f[group] else []
        surfaces = [k for k in ("rigid_surface", "elastic_surface") if k in f[group]]
    if names is None:
        names = [f.name for f in schema.FIELDS if f.name in stored]
    for name in names:
        if name not in grid:
            raise InputError(f"{name!r} is not a grid field; grid fields: "
                             f"{', '.join(f.name for f in schema.FIELDS if f.grid)}")
        if name not in stored:
            raise InputError(f"{run.path}: the run stored no field {name!r} (stored: "
                             f"{', '.join(stored) or 'none'}; output.fields)")
    data: dict[str, Any] = {}
    nd = len(run.axis)
    for name in names:
        a = np.stack([run.field(sample, k, name) for k in range(nd)])
        meta = {"long_name": schema.FIELD_BY_NAME[name].description}
        if name in _FIELD_UNIT:
            meta.update(unit(_FIELD_UNIT[name]))
        data[name] = ((run.axis_name, "y", "x"), a, meta)
    for name in surfaces:
        data[name] = (("y", "x"), run.surface(sample, name),
                      {"long_name": f"heights of the {name.split('_')[0]} surface",
                       **unit("length")})
    if not data:
        raise InputError(f"{run.path}: sample {sample} has no fields stored")
    ny, nx = next(iter(data.values()))[1].shape[-2:]
    a = pixel_size(run)
    depth_unit = axis_unit(run)  # rms, range, pressure, or the run's named unit
    axis = {"long_name": schema.AXES[run.axis_name],
            **({"units": depth_unit} if depth_unit else {})}
    vector = run.config_dict().get("pull", {}).get("components", "x") != "x"
    coords = {run.axis_name: (run.axis_name, run.axis, axis),
              "y": ("y", np.arange(ny) * a, {"long_name": "y", **unit("length")}),
              "x": ("x", np.arange(nx) * a,
                    {"long_name": "x" if vector else "x, the pull direction",
                     **unit("length")})}
    return xr.Dataset(data, coords=coords, attrs={**attrs, "sample": sample})


def _netcdf_attr(v: Any) -> Any:
    """An attribute value NetCDF can store: numbers and strings as they are, booleans as 0/1,
    the rest (lists, dicts, None) as JSON text."""
    if isinstance(v, bool | np.bool_):
        return int(v)
    if isinstance(v, str | int | float | np.integer | np.floating):
        return v
    return json.dumps(v)


def export_netcdf(path: str | Path, out: str | Path, sample: int, *,
                  names: list[str] | tuple[str, ...] | None = None) -> Path:
    """Write one sample's fields (:func:`sample_fields`) to a NetCDF-4 file.

    Parameters
    ----------
    path : path-like
        A run file.
    out : path-like
        The NetCDF file to write (replaced if it exists).
    sample : int
        The global sample number.
    names : sequence of str, optional
        The fields (default: every grid field stored).

    Returns
    -------
    pathlib.Path
        ``out``.

    Notes
    -----
    The values are the run file's, bit for bit; boolean fields are stored as bytes with the
    attribute ``dtype = "bool"``, which xarray reads back as booleans. Attributes that NetCDF
    cannot hold (lists, tables, booleans) are written as JSON text or 0/1; the configuration
    is also kept whole, as TOML, in the attribute ``config``.
    """
    _extra("h5netcdf")
    ds = sample_fields(path, sample, names=names)
    ds.attrs = {k: _netcdf_attr(v) for k, v in ds.attrs.items()}
    ds.attrs["config"] = read_run(path).config_toml
    out = Path(out)
    try:
        ds.to_netcdf(out, engine="h5netcdf")
    except OSError as exc:
        raise io_failure(out, "cannot write the NetCDF file", exc) from exc
    return out
