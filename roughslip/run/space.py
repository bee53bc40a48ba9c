"""Free space before a sample is written: HDF5 does not recover from a write that fails
half-way, and a run file it was writing into can be left unusable, so a full disk is found
before anything is written."""

from __future__ import annotations

import errno
import os
import shutil
from collections.abc import Iterable
from pathlib import Path

import numpy as np

#: room for HDF5's metadata beside a sample's arrays (object headers, chunk indices)
MARGIN = 1 << 18


def check_space(path: Path, arrays: Iterable[np.ndarray]) -> None:
    """Raise ``OSError(ENOSPC)`` when the file system of ``path`` has less room than two
    copies of a sample (its journal entry and its group in the run file) and :data:`MARGIN`
    take.

    Parameters
    ----------
    path : Path
        The run file.
    arrays : iterable of arrays
        The sample's arrays; their bytes, uncompressed, bound what one copy of the sample
        adds before metadata.
    """
    need = 2 * sum(np.asarray(a).nbytes for a in arrays) + MARGIN
    free = shutil.disk_usage(path.parent).free
    if free < need:
        raise OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)} (this sample needs up to "
                      f"{need / 2**20:.1f} MiB, {free / 2**20:.1f} MiB are free)")
