"""Which configuration a run file belongs to, and what differs when it is not this one.

A run file (and its journal's ``run.json``) stores the digest of its configuration
(:mod:`roughslip.run.digest`) and the configuration itself. ``--resume`` refuses a
configuration whose digest differs; the refusal names the keys that differ, with the stored
value and the new one (:func:`config_changes`), so that the user sees at once whether the
file or the command line is wrong.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py

from roughslip.errors import ConfigError, InputError
from roughslip.run import schema
from roughslip.run.sections import defaults
from roughslip.run.tomlio import loads_toml, show

#: sections and keys that never change the numbers (not in the digest)
_IGNORED = ("execution", "title")
#: differences listed in a message before "and N more"
SHOWN = 6


def stored_stamp(attrs: Any) -> tuple[str, int | None]:
    """The digest and defaults version stored in ``attrs`` (None: written before versioned
    defaults)."""
    version = attrs.get("defaults_version")
    return str(attrs.get("config_digest", "")), None if version is None else int(version)


def _flat(d: Mapping[str, Any]) -> dict[str, Any]:
    """``{"section.key": value}`` of a resolved configuration, without what the digest leaves
    out."""
    out: dict[str, Any] = {}
    for section, table in d.items():
        if section in _IGNORED:
            continue
        if isinstance(table, Mapping):
            out.update({f"{section}.{k}": v for k, v in table.items()})
        else:
            out[section] = table
    return out


def config_changes(stored: str, now: str,
                   defaults: Mapping[tuple[str, str], Any] | None = None) -> list[str]:
    """The keys whose values differ between two resolved configurations (TOML texts, as run
    files store them), each as ``"key = stored value in the file, now value"``; the execution
    settings and the title are left out, as the digest leaves them out. A key one of them
    lacks counts as its default (``defaults``: ``(section, key) -> value``) when it has one.
    Empty when the texts cannot be read."""
    try:
        a, b = _flat(loads_toml(stored, "stored")), _flat(loads_toml(now, "now"))
    except (ConfigError, ValueError):
        return []
    defaults = defaults or {}
    missing = object()
    out = []
    for key in sorted(set(a) | set(b), key=lambda k: (k not in a or k not in b, k)):
        section, _, name = key.partition(".")
        default = defaults.get((section, name), missing)
        old, new = a.get(key, default), b.get(key, default)
        if old == new:
            continue
        shown = ["(not set)" if v is missing or v is None else show(v) for v in (old, new)]
        out.append(f"{key} = {shown[0]} in the file, {shown[1]} now")
    return out


def stored_config(journal: Path, path: Path) -> str | None:
    """The configuration (TOML) a journal belongs to: its ``run.json``'s, else the run file's
    (journals of earlier versions stored only the digest); None when neither has one."""
    try:
        text = json.loads((journal / "run.json").read_text()).get("config")
        if isinstance(text, str):
            return text
    except (OSError, ValueError, AttributeError):
        pass
    try:
        with h5py.File(path, "r") as f:
            text = f.attrs.get("config")
    except OSError:
        return None
    return text.decode() if isinstance(text, bytes) else text if isinstance(text, str) else None


def check_stamp(path: Path, stamp: tuple[str, int | None], layout: Any,
                stored: str | None = None) -> None:
    """Refuse a run whose stored digest is not this configuration's, naming the keys that
    differ (from the ``stored`` configuration, when there is one), and saying so plainly
    when it was made under defaults newer than this version knows.

    ``layout`` is the run's :class:`~roughslip.run.store.Layout`.
    """
    digest, version = stamp
    if version is not None and version > layout.defaults_version:
        raise InputError(f"{path}: written by a newer roughslip (configuration defaults "
                         f"version {version}; this one knows up to {layout.defaults_version})")
    if layout.matches(digest, version):
        return
    changes = config_changes(stored, layout.config_text, defaults()) if stored else []
    if changes:
        more = len(changes) - SHOWN
        what = "; ".join(changes[:SHOWN]) + (f"; and {more} more" if more > 0 else "")
        raise InputError(f"{path}: was made with a different configuration: {what}; "
                         "resume with the stored values, or use --overwrite to start anew")
    raise InputError(f"{path}: was made with a different configuration (stored digest "
                     f"{str(digest)[:12]}..., now {layout.digest[:12]}...); run "
                     "`roughslip inspect` to see the stored one, or use --overwrite")


def check_derived(path: Path, f: h5py.File, layout: Any) -> None:
    """A resumed run has the derived columns of the run that started it
    (:data:`~roughslip.run.schema.DERIVED`; ``layout``: the run's
    :class:`~roughslip.run.store.Layout`): else :class:`InputError`, before anything is
    written."""
    want = {c.name for c in layout.columns if c.derive is not None}
    stage = {c.name for c in schema.COLUMNS}
    shape = (*f["complete"].shape, len(layout.axis))
    have = {n for n, d in f.items() if isinstance(d, h5py.Dataset) and d.shape == shape
            and "description" in d.attrs and n not in stage}
    if want != have:
        now, then = sorted(want - have), sorted(have - want)
        raise InputError(
            f"{path}: cannot be resumed with other derived output columns than the run that "
            f"started it (registered now only: {', '.join(now) or 'none'}; in the file "
            f"only: {', '.join(then) or 'none'}); register the same ones, or use --overwrite")
