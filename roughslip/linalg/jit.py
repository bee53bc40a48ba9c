"""The switch for the package's numba kernels: the squeeze's fused passes
(:mod:`roughslip.contact.pk_passes`), the gathers of the dense blocks
(:func:`roughslip.elastic.tables.gather_pairs`), the scans of the event tables
(:func:`roughslip.friction.events.event_table`), the candidate scans of the single-precision
pull (:mod:`roughslip.friction.breaking_single`), and the compactions and submatrix gathers
of an updated inverse (:mod:`roughslip.linalg.inverse`).

Each kernel has a numpy twin that performs the same operations, so both give bitwise the same
numbers (tested). The kernels are compiled at their first use, once per installation, then
loaded from numba's cache. ``ROUGHSLIP_FUSED=0`` in the environment selects the numpy twins.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable
from typing import Any

#: whether numba is installed (imported only when a kernel is first compiled)
HAVE_NUMBA = importlib.util.find_spec("numba") is not None
#: whether the kernels run compiled (numba installed and ``ROUGHSLIP_FUSED`` not ``0``)
ENABLED = HAVE_NUMBA and os.environ.get("ROUGHSLIP_FUSED", "1") != "0"


def njit() -> Callable[[Any], Any]:
    """numba's ``njit`` with the package's options: cached, no GIL, no fast-math (IEEE
    operations in source order), no bounds checks, and numpy's error model (a division by
    zero gives the IEEE infinity or NaN, as in the numpy twins, instead of raising)."""
    import numba

    return numba.njit(cache=True, nogil=True, fastmath=False, boundscheck=False,
                      error_model="numpy")
