"""HDF5 run files: layout, provenance and the resumable single writer (readers:
:mod:`roughslip.run.reading`).

Layout of ``OUT.h5`` (``n_s`` samples, ``n_d`` depths or loads)::

    /                        attrs: format, format_version (2), version, command_line, config
                                    (resolved TOML), config_digest, defaults_version (of the
                                    digest, :mod:`roughslip.run.digest`), control, libraries (JSON),
                                    blas (JSON, :mod:`roughslip.run.blas`),
                                    fft_backend, threads, seed, units (JSON), notes (JSON)
    /sample_index  (n_s)     global sample numbers (ensemble.first_sample + i)
    /complete      (n_s)     1 once a sample is fully written (the last thing written)
    /depth         (n_d)     displacement control: the configured depths, in squeeze.depth_unit
    /force_target  (n_d)     load control: the configured loads, in squeeze.force_unit
    /<column>      (n_s, n_d) one per scalar of the output schema that the run's stages give
    /samples/s000007/        one group per sample (global number), attr complete
        rigid_surface, elastic_surface (two-surface scenes); attrs notes and solvers (JSON:
                             per depth, the methods that solved it)
        d000/ ... d{n_d-1}/  per depth: the fields listed in output.fields, grids (ny, nx)
                             chunked and compressed, pull-curve arrays one entry per event

The scalars and fields are those of the output schema (:mod:`roughslip.run.schema`), which
describes each (also in its ``description`` attribute). Every scalar is ``float64``; a value
that was not computed (or a sample that is not complete) is NaN: read ``/complete`` first.
``/sample_index`` and ``/depth`` (or ``/force_target``) are HDF5 dimension scales attached to
the two axes of every per-depth dataset, so generic HDF5 tools label them.

Writing is single-writer (a run holds the lock of :mod:`roughslip.run.lock`, on
``OUT.h5.lock``, while it writes) and crash-safe. The journal folder ``OUT.h5.journal/`` is the
record of a run until it ends: it is made first (with ``run.json``, the configuration digest),
and every finished sample is written to it atomically (a temporary file, flushed to disk, then
renamed) before it goes into ``OUT.h5``, which is flushed after each sample. When every sample
is done the journal is renamed ``OUT.h5.journal.done`` and removed. ``--resume`` is therefore
always safe to pass, from any state a kill can leave:

* neither file nor journal: a new run starts;
* a journal (the run did not finish): ``OUT.h5`` is rebuilt from the journal into a temporary
  file that replaces it by a rename, whatever state ``OUT.h5`` was left in (missing, open for
  writing, cut in the middle of a write); a second kill during the rebuild leaves the journal
  as it was;
* no journal and a readable ``OUT.h5``: a finished run (nothing to do), or one of an older
  version;
* leftovers (``OUT.h5.creating``, ``OUT.h5.rebuilding``, ``*.tmp`` entries, a
  ``.journal.done`` folder) are removed.

Files are written with HDF5's earliest compatible format (superblock version 0, ``libver =
"earliest"``): readable by every HDF5 1.8+ tool, and without the superblock status flags of the
newer format, which a killed writer leaves set so that the file can no longer be opened
without ``h5clear``. The journal, not the format, guarantees integrity.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from roughslip.errors import InputError, OutputError, io_failure
from roughslip.run import schema
from roughslip.run.checkpoints import reached
from roughslip.run.reading import (
    BOOL_FIELDS,
    FORMAT,
    FORMAT_VERSION,
    RunData,
    check_format,
    group_name,
    open_file,
    read_run,
)
from roughslip.run.space import check_space
from roughslip.run.stamps import check_derived as _check_derived
from roughslip.run.stamps import check_stamp as _check_stamp
from roughslip.run.stamps import stored_config
from roughslip.run.stamps import stored_stamp as _stored_stamp

__all__ = ["Layout", "RunData", "RunWriter", "SampleResult", "journal_dir", "open_file",
           "read_run"]


@dataclass(frozen=True)
class Layout:
    """What the writer needs to know about a run, resolved once from its plan
    (:meth:`roughslip.run.scene.Scene.layout`): plain values, and the test of a stored digest.
    """

    config_text: str  # the resolved configuration as TOML, stored in the file
    digest: str
    defaults_version: int
    #: ``matches(digest, defaults_version)``: whether a stored digest is this run's
    matches: Callable[[str, int | None], bool]
    control: str  # "depth" or "force"
    axis: np.ndarray  # the configured targets
    axis_unit: str
    columns: tuple[schema.Column, ...]
    compression: dict[str, Any]

    @property
    def stamp(self) -> dict[str, Any]:
        """The digest and its defaults version, as stored with a run and each journal entry."""
        return {"config_digest": self.digest, "defaults_version": self.defaults_version}


@dataclass
class SampleResult:
    """What one sample produces (plain arrays: picklable, sent from workers to the writer)."""

    sample: int
    scalars: dict[str, np.ndarray]  # name -> (n_d,)
    fields: list[dict[str, np.ndarray]]  # per depth: name -> array
    surfaces: dict[str, np.ndarray]  # rigid_surface, elastic_surface
    notes: list[str] = field(default_factory=list)
    #: per depth, what solved it (``{"pull_method": "inverse", ...}``): attribute ``solvers``
    solvers: list[dict[str, str]] = field(default_factory=list)
    #: the digest of the configuration that computed it (checked by the writer)
    digest: str = ""


def journal_dir(path: Path) -> Path:
    """The journal folder of a run file."""
    return path.with_name(path.name + ".journal")


def _sibling(path: Path, suffix: str) -> Path:
    return path.with_name(path.name + suffix)


def _fsync(path: Path) -> None:
    """Flush a closed file's data to disk (so that a rename after it is durable)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data))
    _fsync(tmp)
    os.replace(tmp, path)


class RunWriter:
    """Creates or resumes ``OUT.h5`` and writes finished samples into it (see the module
    docstring for the journal and the states a resume recovers from)."""

    def __init__(self, path: Path, f: h5py.File, layout: Layout, indices: list[int]):
        self.path = path
        self.f = f
        self.layout = layout
        self.indices = indices
        self.row = {s: i for i, s in enumerate(indices)}
        self.journal = journal_dir(path)
        #: what :meth:`resume` found and did, for the user
        self.recovery = ""

    # -- opening ---------------------------------------------------------------------------------
    @classmethod
    def create(cls, path: str | Path, layout: Layout, indices: list[int], n_targets: int,
               attrs: dict[str, Any], overwrite: bool = False) -> RunWriter:
        """Start a new run file; refuses to replace an existing file unless ``overwrite``.

        Any journal left beside the file is replaced by the new run's.
        """
        reached("start")
        path = Path(path)
        if path.exists() and not overwrite:
            raise InputError(
                f"{path}: exists; use --resume to continue it or --overwrite to replace it")
        if path.is_dir():
            raise InputError(f"{path}: is a directory")
        jdir = journal_dir(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            for old in (jdir, _sibling(jdir, ".done")):
                shutil.rmtree(old, ignore_errors=True)
            jdir.mkdir()
            _write_json_atomic(jdir / "run.json", {**layout.stamp, "config": layout.config_text,
                                                   "format_version": FORMAT_VERSION})
            cls._build(path, ".creating", layout, indices, n_targets, attrs, [])
            f = h5py.File(path, "r+")
        except (OSError, RuntimeError) as exc:  # h5py reports a failed write as either
            raise io_failure(path, "cannot create the run file", exc) from exc
        return cls(path, f, layout, indices)

    @classmethod
    def _build(cls, path: Path, suffix: str, layout: Layout, indices: list[int],
               n_targets: int, attrs: dict[str, Any], samples: list[Path]) -> None:
        """Write a run file with the journalled ``samples`` into ``path + suffix``, then
        rename it to ``path`` (so that ``path`` is never half-written)."""
        tmp = _sibling(path, suffix)
        with h5py.File(tmp, "w", libver="earliest") as f:
            _init_file(f, layout, indices, n_targets, attrs)
            writer = cls(path, f, layout, indices)
            for p in samples:
                res = _read_journal_entry(p, layout)
                reached("rebuild")
                if res is not None and res.sample in writer.row:
                    writer._write_main(replace(res, scalars=schema.derived(layout.columns,
                                                                           res.scalars)))
        _fsync(tmp)
        if suffix == ".creating":
            reached("creating")
        os.replace(tmp, path)

    @classmethod
    def resume(cls, path: str | Path, layout: Layout, indices: list[int], n_targets: int,
               attrs: dict[str, Any]) -> RunWriter:
        """Continue a run from whatever state it was left in (module docstring); refuses a run
        made with a different configuration, and a file that is not a roughslip run file."""
        path = Path(path)
        jdir = journal_dir(path)
        for leftover in (_sibling(path, ".creating"), _sibling(path, ".rebuilding")):
            leftover.unlink(missing_ok=True)
        shutil.rmtree(_sibling(jdir, ".done"), ignore_errors=True)  # a finished run's journal
        if jdir.is_dir():
            return cls._rebuild(path, layout, indices, n_targets, attrs)
        if not path.exists():
            writer = cls.create(path, layout, indices, n_targets, attrs)
            writer.recovery = "no run file yet: started a new run"
            return writer
        try:
            f = h5py.File(path, "r+")
        except OSError as exc:
            if "already open for write" in str(exc):
                # superblock status flags left set by a writer that was killed before its
                # first sample was journalled (files of earlier versions): nothing to keep
                writer = cls.create(path, layout, indices, n_targets, attrs, overwrite=True)
                writer.recovery = (f"{path.name} was left open by a killed run with no "
                                   "sample journalled: started it anew")
                return writer
            raise InputError(f"{path}: cannot be resumed: not a readable HDF5 file and no "
                             f"journal to rebuild it from ({exc}); use --overwrite to replace "
                             "it") from None
        try:
            check_format(f, path)
            _check_stamp(path, _stored_stamp(f.attrs), layout, f.attrs.get("config"))
            _check_derived(path, f, layout)
        except InputError:
            f.close()
            raise
        return cls(path, f, layout, indices)

    @classmethod
    def _rebuild(cls, path: Path, layout: Layout, indices: list[int], n_targets: int,
                 attrs: dict[str, Any]) -> RunWriter:
        """Rebuild ``path`` from its journal (the record of an unfinished run)."""
        jdir = journal_dir(path)
        for tmp in jdir.glob("*.tmp"):
            tmp.unlink(missing_ok=True)
        stored = _journal_digest(jdir, path)
        if stored is not None:
            _check_stamp(path, stored, layout, stored_config(jdir, path))
        entries = sorted(jdir.glob("s*.h5"))
        try:
            if not (jdir / "run.json").exists():  # journal of an older version
                _write_json_atomic(jdir / "run.json", {**layout.stamp,
                                                       "format_version": FORMAT_VERSION})
            cls._build(path, ".rebuilding", layout, indices, n_targets, attrs, entries)
            f = h5py.File(path, "r+")
        except (OSError, RuntimeError) as exc:
            raise io_failure(path, "cannot rebuild the run file from its journal", exc,
                             resume=True) from exc
        writer = cls(path, f, layout, indices)
        writer.recovery = (f"rebuilt {path.name} from its journal "
                           f"({len(writer.completed())} sample(s) kept)")
        return writer

    # -- state -----------------------------------------------------------------------------------
    def completed(self) -> list[int]:
        """Global numbers of the samples already complete."""
        c = self.f["complete"][()]
        return [s for s, i in self.row.items() if c[i]]

    # -- writing ---------------------------------------------------------------------------------
    def write_sample(self, res: SampleResult) -> None:
        """Journal the sample atomically, then write it into the run file and flush.

        The free space is checked first (:func:`~roughslip.run.space.check_space`): HDF5
        does not recover from a write that fails half-way, and a run file it was writing into
        can be left unusable, so a full disk is found before anything is written.

        Raises
        ------
        OutputError
            When the sample was computed for another configuration (its digest is not this
            run's: results of another run sharing a scheduler), before anything is written;
            or when it cannot be written.
        """
        if res.digest != self.layout.digest:
            raise OutputError(
                f"{self.path}: sample {res.sample} was computed for configuration "
                f"{res.digest[:12] or '(none)'}..., not for this run's {self.layout.digest[:12]}"
                "...; it is not written (a result of another run?); the samples completed "
                "before are kept: run again with --resume")
        res = replace(res, scalars=schema.derived(self.layout.columns, res.scalars))
        try:
            check_space(self.path, [*res.scalars.values(), *res.surfaces.values(),
                                    *(a for f in res.fields for a in f.values())])
            self.journal.mkdir(exist_ok=True)
            final = self.journal / f"{group_name(res.sample)}.h5"
            tmp = final.with_suffix(".tmp")
            with h5py.File(tmp, "w", libver="earliest") as jf:
                jf.attrs.update(self.layout.stamp)
                jf.attrs["sample"] = res.sample
                _write_sample_group(jf, res, self.layout.compression)
                for k, v in res.scalars.items():
                    jf.create_dataset(f"scalars/{k}", data=v)
            _fsync(tmp)
            reached("journal-entry")
            os.replace(tmp, final)
            self._write_main(res)
        except (OSError, RuntimeError) as exc:  # h5py reports a failed write as either
            raise io_failure(self.path, f"cannot write sample {res.sample}", exc,
                             resume=True) from exc
        reached("sample-done")

    def _write_main(self, res: SampleResult) -> None:
        f = self.f
        i = self.row[res.sample]
        name = f"samples/{group_name(res.sample)}"
        if name in f:
            del f[name]
        for k, v in res.scalars.items():
            if k in f:
                f[k][i, :] = _stored(f[k].dtype, v)
        g = f.create_group(name)
        _write_sample_group(g, res, self.layout.compression,
                            first_written=lambda: reached("main-write"))
        g.attrs["complete"] = True
        f["complete"][i] = 1  # written last
        f.flush()

    def finish(self) -> None:
        """Close; retire the journal when every sample is complete (renamed first, so that a
        kill while it is removed cannot be mistaken for an unfinished run)."""
        try:
            all_done = bool(np.all(self.f["complete"][()]))
            self.f.close()
            if all_done and self.journal.is_dir():
                _fsync(self.path)
                done = _sibling(self.journal, ".done")
                shutil.rmtree(done, ignore_errors=True)
                os.replace(self.journal, done)
                reached("finish")
                shutil.rmtree(done, ignore_errors=True)
        except (OSError, RuntimeError) as exc:
            raise io_failure(self.path, "cannot close the run file", exc,
                             resume=True) from exc

    def close(self) -> None:
        """Close without touching the journal (interrupted and failed runs). A flush or close
        that fails too (a full disk) is ignored: the journal holds every completed sample, and
        the error that stopped the run is the one to report."""
        try:
            self.f.flush()
        except (OSError, RuntimeError):
            pass
        finally:
            try:
                self.f.close()
            except (OSError, RuntimeError):
                pass


def _journal_digest(jdir: Path, path: Path) -> tuple[str, int | None] | None:
    """The digest (and defaults version) a journal belongs to: ``run.json``, else (older
    versions) the run file's or the first readable entry's."""
    try:
        stamp = json.loads((jdir / "run.json").read_text())
        version = stamp.get("defaults_version")
        return str(stamp["config_digest"]), None if version is None else int(version)
    except (OSError, ValueError, KeyError):
        pass
    for p in [path, *sorted(jdir.glob("s*.h5"))]:
        try:
            with h5py.File(p, "r") as f:
                if "config_digest" in f.attrs:
                    return _stored_stamp(f.attrs)
        except OSError:
            continue
    return None


def _read_journal_entry(p: Path, layout: Layout) -> SampleResult | None:
    """A journalled sample, or None when the entry cannot be read (it is recomputed)."""
    try:
        with h5py.File(p, "r") as jf:
            if not layout.matches(*_stored_stamp(jf.attrs)):
                raise InputError(f"{p}: journal entry of a different configuration; move the "
                                 "journal away or use --overwrite")
            return _read_sample_file(jf)
    except (OSError, KeyError, ValueError):
        return None


def _init_file(f: h5py.File, layout: Layout, indices: list[int], n_targets: int,
               attrs: dict[str, Any]) -> None:
    f.attrs["format"] = FORMAT
    f.attrs["format_version"] = FORMAT_VERSION
    f.attrs["config"] = layout.config_text
    f.attrs.update(layout.stamp)
    f.attrs["control"] = layout.control
    for k, v in attrs.items():
        f.attrs[k] = json.dumps(v) if isinstance(v, dict | list) else v
    ns = len(indices)
    f.create_dataset("sample_index", data=np.asarray(indices, dtype=np.int64))
    f.create_dataset("complete", data=np.zeros(ns, dtype=np.uint8))
    axis_name = "depth" if layout.control == "depth" else "force_target"
    d = f.create_dataset(axis_name, data=np.asarray(layout.axis, dtype=float))
    d.attrs["unit"] = layout.axis_unit
    d.attrs["description"] = schema.AXES[axis_name]
    d.make_scale(axis_name)
    rows = f["sample_index"]
    rows.make_scale("sample_index")
    for name, text in schema.ROOT.items():
        f[name].attrs["description"] = text
    units = attrs.get("units", {})  # the unit of each dimension (roughslip.run.units)
    for col in layout.columns:
        ds = f.create_dataset(col.name, shape=(ns, n_targets), dtype="f8", fillvalue=np.nan)
        ds.attrs["description"] = col.description
        if col.dimension in units:
            ds.attrs["unit"] = units[col.dimension]
        ds.attrs["kind"] = col.kind
        ds.dims[0].attach_scale(rows)
        ds.dims[1].attach_scale(d)
        ds.dims[0].label = "sample"
        ds.dims[1].label = axis_name
    f.create_group("samples")


def _stored(dtype: np.dtype, values: np.ndarray) -> np.ndarray:
    """Scalars as the dataset stores them: float64 (NaN where not computed), or, in files of
    format 1 (integer counts and flags), 0 for NaN."""
    v = np.asarray(values, dtype=float)
    if np.issubdtype(dtype, np.integer):
        return np.nan_to_num(v, nan=0.0).astype(dtype)
    return v


def _write_array(g: h5py.Group, name: str, a: np.ndarray, comp: dict[str, Any]) -> None:
    a = np.asarray(a)
    if a.dtype == bool:
        a = a.astype(np.uint8)
    if a.ndim == 2 and a.size >= 64:
        chunks = (min(a.shape[0], 256), min(a.shape[1], 256))
        g.create_dataset(name, data=a, chunks=chunks, shuffle=bool(comp), **comp)
    else:
        g.create_dataset(name, data=a)


def _write_sample_group(g: h5py.Group, res: SampleResult, comp: dict[str, Any],
                        first_written: Callable[[], None] | None = None) -> None:
    for i, (name, a) in enumerate(res.surfaces.items()):
        _write_array(g, name, a, comp)
        if i == 0 and first_written is not None:
            first_written()
    for k, fields in enumerate(res.fields):
        d = g.create_group(f"d{k:03d}")
        for name, a in fields.items():
            _write_array(d, name, a, comp)
    if res.notes:
        g.attrs["notes"] = json.dumps(res.notes)
    if res.solvers:
        g.attrs["solvers"] = json.dumps(res.solvers)


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
    solvers = json.loads(jf.attrs["solvers"]) if "solvers" in jf.attrs else []
    return SampleResult(sample, scalars, fields, surfaces, notes, solvers,
                        digest=str(jf.attrs.get("config_digest", "")))
