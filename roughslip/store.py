"""HDF5 run files: layout, provenance, resumable single writer, readers.

Layout of ``OUT.h5`` (``n_s`` samples, ``n_d`` depths or loads)::

    /                        attrs: format, format_version, version, command_line, config
                                    (resolved TOML), config_digest, control, libraries (JSON),
                                    fft_backend, threads, seed, units (JSON), notes (JSON)
    /sample_index  (n_s)     global sample numbers (ensemble.first_sample + i)
    /complete      (n_s)     1 once a sample is fully written (the last thing written)
    /depth         (n_d)     displacement control: the configured depths, in squeeze.depth_unit
    /force_target  (n_d)     load control: the configured loads, in squeeze.force_unit
    /depth_length  (n_s, n_d) D_z in length units (given, or found under load control)
    /normal_force, /contact_area (fraction of the grid), /friction_force (with the pull)
                   (n_s, n_d)
    /iterations, /residual, /converged, /seconds                    squeeze solver record
    /pull_seconds, /pull_converged, /pull_steps, /pull_error_estimate, /friction_normal_force
                   (n_s, n_d)                                       pull record (with the pull)
    /released_bonds (n_s, n_d) coupled model: bonds released already at D_x = 0
    /samples/s000007/        one group per sample (global number), attr complete
        rigid_surface, elastic_surface (two-surface scenes)
        d000/ ... d{n_d-1}/  per depth: the fields listed in output.fields
            fz, uz, gap, contact, fx, ux, stick            (ny, nx), chunked and compressed
            dx_lim, fx_lim, broken_site                    the pull curve ("pull_curve")

Entries of samples that are not complete are NaN (floats) or 0; read ``/complete`` first.

Writing is single-writer. Every finished sample is first written atomically (temporary file
and rename) to the journal folder ``OUT.h5.journal/`` and then into ``OUT.h5``, which is
flushed; ``--resume`` merges journalled samples that ``OUT.h5`` lacks and rebuilds an
unreadable ``OUT.h5`` from the journal. The journal is removed when every sample is done.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from .config import RunConfig
from .errors import InputError, OutputError

FORMAT = "roughslip-run"
FORMAT_VERSION = 1

#: per-(sample, depth) scalar datasets: name -> (dtype, fill)
SCALARS = {
    "depth_length": ("f8", np.nan),
    "normal_force": ("f8", np.nan),
    "contact_area": ("f8", np.nan),
    "iterations": ("i8", 0),
    "residual": ("f8", np.nan),
    "converged": ("u1", 0),
    "seconds": ("f8", np.nan),
}
PULL_SCALARS = {
    "friction_force": ("f8", np.nan),
    "friction_normal_force": ("f8", np.nan),
    "pull_seconds": ("f8", np.nan),
    "pull_converged": ("u1", 0),
    "pull_steps": ("i8", 0),
    "pull_error_estimate": ("f8", np.nan),
}
#: scalars of the coupled model only
COUPLED_SCALARS = {
    "released_bonds": ("i8", 0),  # contact sites whose bond breaks already at D_x = 0
}
BOOL_FIELDS = ("contact", "stick")


@dataclass
class SampleResult:
    """What one sample produces (plain arrays: picklable, sent from workers to the writer)."""

    sample: int
    scalars: dict[str, np.ndarray]  # name -> (n_d,)
    fields: list[dict[str, np.ndarray]]  # per depth: name -> array
    surfaces: dict[str, np.ndarray]  # rigid_surface, elastic_surface
    notes: list[str] = field(default_factory=list)


def journal_dir(path: Path) -> Path:
    """The journal folder of a run file."""
    return path.with_name(path.name + ".journal")


def _group_name(sample: int) -> str:
    return f"s{sample:06d}"


class RunWriter:
    """Creates or resumes ``OUT.h5`` and writes finished samples into it."""

    def __init__(self, path: Path, f: h5py.File, config: RunConfig, indices: list[int]):
        self.path = path
        self.f = f
        self.config = config
        self.indices = indices
        self.row = {s: i for i, s in enumerate(indices)}
        self.journal = journal_dir(path)

    # -- opening ---------------------------------------------------------------------------------
    @classmethod
    def create(cls, path: str | Path, config: RunConfig, indices: list[int], n_targets: int,
               attrs: dict[str, Any], overwrite: bool = False,
               keep_journal: bool = False) -> RunWriter:
        """Start a new run file; refuses to replace an existing file unless ``overwrite``.

        A new run removes any journal left beside the file, unless ``keep_journal`` (used to
        rebuild an unreadable file from its journal).
        """
        path = Path(path)
        if path.exists() and not overwrite:
            raise InputError(
                f"{path}: exists; use --resume to continue it or --overwrite to replace it")
        if path.is_dir():
            raise InputError(f"{path}: is a directory")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(path.name + ".creating")
            with h5py.File(tmp, "w", libver="latest") as f:
                _init_file(f, config, indices, n_targets, attrs)
            if not keep_journal:
                shutil.rmtree(journal_dir(path), ignore_errors=True)
            os.replace(tmp, path)
            f = h5py.File(path, "r+")
        except OSError as exc:
            raise OutputError(f"{path}: cannot create ({exc})") from None
        return cls(path, f, config, indices)

    @classmethod
    def resume(cls, path: str | Path, config: RunConfig, indices: list[int], n_targets: int,
               attrs: dict[str, Any]) -> RunWriter:
        """Reopen a run file; refuses when it was made with a different configuration."""
        path = Path(path)
        jdir = journal_dir(path)
        if not path.exists() and not jdir.exists():
            raise InputError(f"{path}: no such run file to resume")
        try:
            f = h5py.File(path, "r+")
            _check_format(f, path)
        except (OSError, InputError) as exc:
            if not jdir.exists():
                raise InputError(f"{path}: cannot be resumed: not a readable roughslip run "
                                 f"file ({exc})") from None
            # unreadable (e.g. killed during a write): rebuild it from the journal
            writer = cls.create(path, config, indices, n_targets, attrs, overwrite=True,
                                keep_journal=True)
            writer._merge_journal()
            return writer
        digest = f.attrs.get("config_digest", "")
        if digest != config.digest():
            f.close()
            raise InputError(
                f"{path}: was made with a different configuration (stored digest "
                f"{str(digest)[:12]}..., now {config.digest()[:12]}...); run "
                "`roughslip inspect` to see the stored one, or use --overwrite")
        writer = cls(path, f, config, indices)
        writer._merge_journal()
        return writer

    def _merge_journal(self) -> None:
        if not self.journal.is_dir():
            return
        done = set(self.completed())
        for p in sorted(self.journal.glob("s*.h5")):
            try:
                with h5py.File(p, "r") as jf:
                    if jf.attrs.get("config_digest") != self.config.digest():
                        continue
                    res = _read_sample_file(jf)
            except OSError:
                continue  # a journal file is only renamed into place when complete
            if res.sample in self.row and res.sample not in done:
                self._write_main(res)

    # -- state -----------------------------------------------------------------------------------
    def completed(self) -> list[int]:
        """Global numbers of the samples already complete."""
        c = self.f["complete"][()]
        return [s for s, i in self.row.items() if c[i]]

    # -- writing ---------------------------------------------------------------------------------
    def write_sample(self, res: SampleResult) -> None:
        """Journal the sample atomically, then write it into the run file and flush."""
        try:
            self.journal.mkdir(exist_ok=True)
            final = self.journal / f"{_group_name(res.sample)}.h5"
            tmp = final.with_suffix(".tmp")
            with h5py.File(tmp, "w") as jf:
                jf.attrs["config_digest"] = self.config.digest()
                jf.attrs["sample"] = res.sample
                _write_sample_group(jf, res, self.config)
                for k, v in res.scalars.items():
                    jf.create_dataset(f"scalars/{k}", data=v)
            os.replace(tmp, final)
            self._write_main(res)
        except OSError as exc:
            raise OutputError(
                f"{self.path}: cannot write sample {res.sample} ({exc}); completed samples "
                "are kept: free the problem and run again with --resume") from None

    def _write_main(self, res: SampleResult) -> None:
        f = self.f
        i = self.row[res.sample]
        name = f"samples/{_group_name(res.sample)}"
        if name in f:
            del f[name]
        for k, v in res.scalars.items():
            if k in f:
                f[k][i, :] = v
        g = f.create_group(name)
        _write_sample_group(g, res, self.config)
        g.attrs["complete"] = True
        f["complete"][i] = 1  # written last
        f.flush()

    def finish(self) -> None:
        """Close; remove the journal when every sample is complete."""
        all_done = bool(np.all(self.f["complete"][()]))
        self.f.close()
        if all_done:
            shutil.rmtree(self.journal, ignore_errors=True)

    def close(self) -> None:
        """Close without touching the journal (interrupted runs)."""
        try:
            self.f.flush()
        finally:
            self.f.close()


def _init_file(f: h5py.File, config: RunConfig, indices: list[int], n_targets: int,
               attrs: dict[str, Any]) -> None:
    f.attrs["format"] = FORMAT
    f.attrs["format_version"] = FORMAT_VERSION
    f.attrs["config"] = config.to_toml()
    f.attrs["config_digest"] = config.digest()
    f.attrs["control"] = config.control
    for k, v in attrs.items():
        f.attrs[k] = json.dumps(v) if isinstance(v, dict | list) else v
    ns = len(indices)
    f.create_dataset("sample_index", data=np.asarray(indices, dtype=np.int64))
    f.create_dataset("complete", data=np.zeros(ns, dtype=np.uint8))
    axis = np.asarray(config.targets, dtype=float)
    if config.control == "depth":
        d = f.create_dataset("depth", data=axis)
        d.attrs["unit"] = config.squeeze.depth_unit
    else:
        d = f.create_dataset("force_target", data=axis)
        d.attrs["unit"] = config.squeeze.force_unit
    for name, (dtype, fill) in scalar_specs(config).items():
        f.create_dataset(name, shape=(ns, n_targets), dtype=dtype, fillvalue=fill)
    f.create_group("samples")


def scalar_specs(config: RunConfig) -> dict[str, tuple[str, Any]]:
    """The per-(sample, depth) scalars a run of ``config`` stores: name -> (dtype, fill)."""
    specs = dict(SCALARS)
    if config.pull.enabled:
        specs.update(PULL_SCALARS)
    if config.coupling.enabled:
        specs.update(COUPLED_SCALARS)
    return specs


def _check_format(f: h5py.File, path: Path) -> None:
    if f.attrs.get("format") != FORMAT:
        raise InputError(f"{path}: not a roughslip run file (format attribute missing)")
    if int(f.attrs.get("format_version", -1)) > FORMAT_VERSION:
        raise InputError(f"{path}: written by a newer roughslip (format version "
                         f"{f.attrs['format_version']})")


def _compression(config: RunConfig) -> dict[str, Any]:
    c = config.output.compression
    if c == "none":
        return {}
    if c == "lzf":
        return {"compression": "lzf"}
    return {"compression": "gzip", "compression_opts": config.output.compression_level}


def _write_array(g: h5py.Group, name: str, a: np.ndarray, comp: dict[str, Any]) -> None:
    a = np.asarray(a)
    if a.dtype == bool:
        a = a.astype(np.uint8)
    if a.ndim == 2 and a.size >= 64:
        chunks = (min(a.shape[0], 256), min(a.shape[1], 256))
        g.create_dataset(name, data=a, chunks=chunks, shuffle=bool(comp), **comp)
    else:
        g.create_dataset(name, data=a)


def _write_sample_group(g: h5py.Group, res: SampleResult, config: RunConfig) -> None:
    comp = _compression(config)
    for name, a in res.surfaces.items():
        _write_array(g, name, a, comp)
    for k, fields in enumerate(res.fields):
        d = g.create_group(f"d{k:03d}")
        for name, a in fields.items():
            _write_array(d, name, a, comp)
    if res.notes:
        g.attrs["notes"] = json.dumps(res.notes)


def _read_sample_file(jf: h5py.File) -> SampleResult:
    sample = int(jf.attrs["sample"])
    scalars = {k: jf[f"scalars/{k}"][()] for k in jf["scalars"]}
    surfaces = {k: jf[k][()] for k in ("rigid_surface", "elastic_surface") if k in jf}
    fields = []
    k = 0
    while f"d{k:03d}" in jf:
        d = jf[f"d{k:03d}"]
        fields.append({n: (d[n][()].astype(bool) if n in BOOL_FIELDS else d[n][()])
                       for n in d})
        k += 1
    notes = json.loads(jf.attrs["notes"]) if "notes" in jf.attrs else []
    return SampleResult(sample, scalars, fields, surfaces, notes)


# ------------------------------------------------------------------------------------------------
# Reading
# ------------------------------------------------------------------------------------------------


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

    @property
    def n_complete(self) -> int:
        return int(self.complete.sum())

    def config_dict(self) -> dict[str, Any]:
        """The stored configuration as a dict."""
        import tomllib

        return tomllib.loads(self.config_toml)

    def field(self, sample: int, depth_index: int, name: str) -> np.ndarray:
        """One stored field of one sample (global number) and depth."""
        with open_file(self.path) as f:
            key = f"samples/{_group_name(sample)}/d{depth_index:03d}/{name}"
            if key not in f:
                raise InputError(f"{self.path}: no field {name!r} for sample {sample}, depth "
                                 f"index {depth_index} (stored: output.fields)")
            a = f[key][()]
            return a.astype(bool) if name in BOOL_FIELDS else a

    def surface(self, sample: int, name: str = "rigid_surface") -> np.ndarray:
        with open_file(self.path) as f:
            return f[f"samples/{_group_name(sample)}/{name}"][()]


def open_file(path: str | Path) -> h5py.File:
    """Open a run file for reading with a clear error when it is not one."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: no such file")
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        raise InputError(f"{p}: not a readable HDF5 file ({exc})") from None
    try:
        _check_format(f, p)
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
            scalars = {k: f[k][()] for k in (*SCALARS, *PULL_SCALARS, *COUPLED_SCALARS)
                       if k in f}
            return RunData(
                path=p, attrs=attrs, config_toml=str(attrs.get("config", "")),
                sample_index=f["sample_index"][()], complete=f["complete"][()].astype(bool),
                axis_name=axis_name, axis=f[axis_name][()], scalars=scalars,
            )
        except (KeyError, OSError) as exc:
            raise InputError(f"{p}: damaged run file ({exc})") from None

