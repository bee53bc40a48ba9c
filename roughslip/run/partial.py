"""The finished depths of a sample that is not finished yet: one journal entry per depth.

A sample runs its depths (or loads) in order, each warm-started from the one before, and the
run file takes it whole (:mod:`roughslip.run.store`). A run of one large sample (a measured
scan) can take hours; an interruption then would lose every depth it finished. So a run that
computes its samples in its own process journals each finished depth of the sample it is
computing, in ``OUT.h5.journal/depths/``: the depth's record (scalars, fields, notes, the
methods that solved it) and what the next depth starts from (the squeeze's warm start). A
``--resume`` takes the finished depths of the unfinished sample back and computes only the
rest; the sample's numbers are bitwise those of an uninterrupted run, because the next depth
starts from exactly what it would have started from. The entries of a sample are removed once
the sample is written whole.

Each entry is written to a temporary file and renamed, so it is either whole or absent; an
entry that cannot be read, or that belongs to another configuration, ends the sequence there
(the depths from it on are computed again). Samples sent to a process pool or a Dask cluster
are not journalled by depth: their results come back whole.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from roughslip.run.checkpoints import reached
from roughslip.run.reading import group_name

#: the folder of the depth entries, inside the run's journal
DEPTHS = "depths"


@dataclass
class DepthRecord:
    """One finished depth of a sample, as journalled: what the run file will hold for it,
    and what the next depth starts from (``carry``, the stage's warm start)."""

    index: int
    scalars: dict[str, float]
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    solvers: dict[str, str] = field(default_factory=dict)
    carry: dict[str, np.ndarray] = field(default_factory=dict)


def _name(sample: int, index: int) -> str:
    return f"{group_name(sample)}.d{index:03d}.h5"


def write_depth(journal: Path, sample: int, rec: DepthRecord, digest: str) -> None:
    """Journal the finished depth ``rec.index`` of ``sample`` (atomically: a temporary file,
    flushed, then renamed)."""
    folder = journal / DEPTHS
    journal.mkdir(exist_ok=True)  # never the run's folder: a vanished folder is an error
    folder.mkdir(exist_ok=True)
    final = folder / _name(sample, rec.index)
    tmp = final.with_suffix(".tmp")
    with h5py.File(tmp, "w", libver="earliest") as f:
        f.attrs["config_digest"] = digest
        f.attrs["sample"] = sample
        f.attrs["index"] = rec.index
        f.attrs["notes"] = json.dumps(rec.notes)
        f.attrs["solvers"] = json.dumps(rec.solvers)
        for group, values in (("scalars", rec.scalars), ("fields", rec.fields),
                              ("carry", rec.carry)):
            g = f.create_group(group)
            for k, v in values.items():
                g.create_dataset(k, data=v)
    with open(tmp, "rb") as fh:
        os.fsync(fh.fileno())
    reached("depth-entry")
    os.replace(tmp, final)


def read_depths(journal: Path, sample: int, digest: str) -> list[DepthRecord]:
    """The journalled finished depths of ``sample``, from the first on, up to the first that
    is missing, unreadable or of another configuration."""
    out: list[DepthRecord] = []
    folder = journal / DEPTHS
    while True:
        p = folder / _name(sample, len(out))
        try:
            with h5py.File(p, "r") as f:
                if str(f.attrs["config_digest"]) != digest:
                    return out
                out.append(DepthRecord(
                    index=int(f.attrs["index"]),
                    scalars={k: f["scalars"][k][()] for k in f["scalars"]},
                    fields={k: f["fields"][k][()] for k in f["fields"]},
                    notes=list(json.loads(f.attrs["notes"])),
                    solvers=dict(json.loads(f.attrs["solvers"])),
                    carry={k: f["carry"][k][()] for k in f["carry"]},
                ))
        except (OSError, KeyError, ValueError):
            return out


def kept_text(out: str | Path) -> str:
    """What an interrupted run keeps, as the line that says so words it: ``completed
    samples``, and the finished depths journalled of each sample not yet complete (read from
    the journal, which is the truth whenever the interruption came)."""
    out = Path(out)
    journal = out.with_name(out.name + ".journal")
    parts = []
    for p in sorted((journal / DEPTHS).glob("s*.d000.h5")):
        sample = int(p.name[1:7])
        if (journal / f"{group_name(sample)}.h5").exists():
            continue  # complete: its depth entries are left over from the instant before
        n = 1
        while (journal / DEPTHS / _name(sample, n)).exists():
            n += 1
        parts.append(f"{n} finished depth(s) of sample {sample}")
    return "completed samples" + (f" and {', '.join(parts)}" if parts else "")


def drop_depths(journal: Path, sample: int) -> None:
    """Remove the depth entries of ``sample`` (it is written whole)."""
    folder = journal / DEPTHS
    for p in folder.glob(f"{group_name(sample)}.d*"):
        p.unlink(missing_ok=True)
    if folder.is_dir() and not any(folder.iterdir()):
        shutil.rmtree(folder, ignore_errors=True)
