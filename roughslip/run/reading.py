"""Reading run files: the format check, the scalars and metadata, and fields on demand
(the layout is described in :mod:`roughslip.run.store`)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from roughslip.errors import InputError, shorten
from roughslip.run import schema
from roughslip.run.tomlio import loads_toml

FORMAT = schema.FORMAT
FORMAT_VERSION = schema.FORMAT_VERSION
BOOL_FIELDS = schema.BOOL_FIELDS


def group_name(sample: int) -> str:
    return f"s{sample:06d}"


def check_format(f: h5py.File, path: Path) -> None:
    if f.attrs.get("format") != FORMAT:
        raise InputError(f"{path}: not a roughslip run file (format attribute missing)")
    if int(f.attrs.get("format_version", -1)) > FORMAT_VERSION:
        raise InputError(f"{path}: written by a newer roughslip (format version "
                         f"{shorten(str(f.attrs['format_version']))})")


@dataclass
class RunData:
    """A run file read into memory (scalars only; fields on demand with :meth:`field`)."""

    path: Path
    attrs: dict[str, Any]
    config_toml: str
    sample_index: np.ndarray
    complete: np.ndarray
    axis_name: str
    axis: np.ndarray
    scalars: dict[str, np.ndarray]
    axis_unit: str = ""

    @property
    def n_complete(self) -> int:
        return int(self.complete.sum())

    def config_dict(self) -> dict[str, Any]:
        """The stored configuration as a dict (a ConfigError naming the file when it is not
        valid TOML or nested too deep: :func:`~roughslip.run.tomlio.loads_toml`)."""
        return loads_toml(self.config_toml, f"{self.path} (its stored configuration)")

    def field(self, sample: int, depth_index: int, name: str) -> np.ndarray:
        """One stored field of one sample (global number) and depth."""
        with open_file(self.path) as f:
            key = f"samples/{group_name(sample)}/d{depth_index:03d}/{name}"
            if key not in f:
                raise InputError(f"{self.path}: no field {name!r} for sample {sample}, depth "
                                 f"index {depth_index} (stored: output.fields)")
            a = f[key][()]
            return a.astype(bool) if name in BOOL_FIELDS else a

    def sample_attribute(self, name: str) -> dict[int, Any]:
        """A JSON attribute of each complete sample's group (``notes``: what the run said of
        it, ``solvers``: per depth, the methods that solved it), by global sample number;
        samples without it (files of earlier versions) are left out."""
        out: dict[int, Any] = {}
        with open_file(self.path) as f:
            for s in self.sample_index[self.complete]:
                g = f.get(f"samples/{group_name(int(s))}")
                if g is not None and name in g.attrs:
                    try:
                        out[int(s)] = json.loads(g.attrs[name])
                    except ValueError:
                        continue
        return out

    def surface(self, sample: int, name: str = "rigid_surface") -> np.ndarray:
        with open_file(self.path) as f:
            return f[f"samples/{group_name(sample)}/{name}"][()]


def open_file(path: str | Path) -> h5py.File:
    """Open a run file for reading with a clear error when it is not one."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such file")
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        raise InputError(f"{p}: not a readable HDF5 file ({shorten(str(exc))})") from None
    try:
        check_format(f, p)
    except InputError:
        f.close()
        raise
    return f


def read_run(path: str | Path) -> RunData:
    """Read the scalars and metadata of a run file."""
    p = Path(path)
    with open_file(p) as f:
        try:
            attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
            axis_name = "depth" if "depth" in f else "force_target"
            scalars = {c.name: f[c.name][()] for c in schema.all_columns() if c.name in f}
            unit = f[axis_name].attrs.get("unit", "")
            return RunData(
                path=p, attrs=attrs, config_toml=str(attrs.get("config", "")),
                sample_index=f["sample_index"][()], complete=f["complete"][()].astype(bool),
                axis_name=axis_name, axis=f[axis_name][()], scalars=scalars,
                axis_unit=unit.decode() if isinstance(unit, bytes) else str(unit),
            )
        except (KeyError, OSError) as exc:
            raise InputError(f"{p}: damaged run file ({exc})") from None
