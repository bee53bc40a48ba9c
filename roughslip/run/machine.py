"""The per-machine layer of execution settings.

How a run is executed (workers, threads, FFT backend, memory budget, Dask scheduler) belongs
to the machine, not to the experiment, and never changes the numbers. A machine file holds
those settings once for every experiment run on that machine::

    # ~/.config/roughslip/machine.toml
    [execution]
    workers = 8
    threads = 2
    memory_limit_gb = 48

Where it is read from: the file named by the environment variable ``ROUGHSLIP_MACHINE``
(empty: no machine file), else ``$XDG_CONFIG_HOME/roughslip/machine.toml`` (by default
``~/.config/roughslip/machine.toml``) when it exists.

Precedence, lowest first: the built-in defaults, the machine file, the experiment file's
``[execution]``, ``--set execution.KEY=VALUE``, and the command-line options (``--workers``,
``--scheduler``). The run file stores the settings that were used (``config`` attribute).
The environment variable ``ROUGHSLIP_MEMORY_LIMIT_GB`` caps the memory budget below all of
these (:mod:`roughslip.linalg.memory`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from roughslip.errors import ConfigError, echo, shorten
from roughslip.run.tomlio import loads_toml

#: the environment variable that names the machine file ("" turns the layer off)
MACHINE_ENV = "ROUGHSLIP_MACHINE"
#: the sections a machine file may hold
SECTIONS = ("execution",)


def machine_file() -> Path | None:
    """The machine file in force, or None."""
    named = os.environ.get(MACHINE_ENV)
    if named is not None:
        if not named.strip():
            return None
        p = Path(named).expanduser()
        if not p.is_file():
            raise ConfigError(f"{MACHINE_ENV}={named}: no such machine file")
        return p
    base = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    p = base / "roughslip" / "machine.toml"
    return p if p.is_file() else None


def read_machine(path: Path) -> dict[str, Any]:
    """The tables of a machine file; only :data:`SECTIONS` are allowed (their keys are
    checked by the loader, with the file named in its errors)."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the machine file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: invalid TOML: {exc}") from None
    data = loads_toml(text, str(path))
    for k, v in data.items():
        if k not in SECTIONS:
            raise ConfigError(f"{path}: {shorten(k)}: a machine file holds only "
                              f"{', '.join(f'[{s}]' for s in SECTIONS)} (settings that never "
                              "change the numbers)")
        if not isinstance(v, dict):
            raise ConfigError(f"{path}: {k} = {echo(v)}: must be a table ([{k}])")
    return data
