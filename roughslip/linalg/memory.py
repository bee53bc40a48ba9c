"""Memory budget: what is available, and estimates of what a computation needs.

The budget is the smallest of ``MemAvailable`` (Linux ``/proc/meminfo``; otherwise physical
memory from ``sysconf``), the ``ROUGHSLIP_MEMORY_LIMIT_GB`` environment variable and a limit set
with :func:`set_limit` (``execution.memory_limit_gb`` in a config).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

_LIMIT: int | None = None


def set_limit(gigabytes: float | None) -> None:
    """Cap the budget for this process (None removes the cap)."""
    global _LIMIT
    _LIMIT = None if gigabytes is None else int(gigabytes * 2**30)


@contextlib.contextmanager
def limited(gigabytes: float | None) -> Iterator[None]:
    """Cap the budget inside the block (None: leave it as it is), restoring it after."""
    global _LIMIT
    old = _LIMIT
    if gigabytes is not None:
        set_limit(gigabytes)
    try:
        yield
    finally:
        _LIMIT = old


def system_available_bytes() -> int:
    """Memory the operating system reports as available to new allocations."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 8 * 2**30


def available_bytes() -> int:
    """The memory budget in bytes (see module docstring)."""
    vals = [system_available_bytes()]
    env = os.environ.get("ROUGHSLIP_MEMORY_LIMIT_GB")
    if env:
        try:
            vals.append(int(float(env) * 2**30))
        except ValueError:
            pass
    if _LIMIT is not None:
        vals.append(_LIMIT)
    return min(vals)
