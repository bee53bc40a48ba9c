"""TOML text of a configuration: tomli-w for the text people read, and a frozen writer of
single values for error messages and digests (:mod:`roughslip.run.digest`)."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

from roughslip.errors import ECHO_LIMIT, shorten

BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def dumps_toml(d: Mapping[str, Any]) -> str:
    """Write a configuration mapping as TOML (tomli-w)."""
    import tomli_w

    def plain(v: Any) -> Any:
        if isinstance(v, tuple | list):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        return v

    return tomli_w.dumps(plain(dict(d)))


def toml_key(k: str) -> str:
    """A key, bare when it can be."""
    return k if BARE_KEY.match(k) else toml_str(k)


def toml_str(s: str) -> str:
    """A basic string with escapes."""
    out = s.replace("\\", "\\\\").replace('"', '\\"')
    out = "".join(c if c.isprintable() else f"\\u{ord(c):04x}" for c in out)
    return f'"{out}"'


def toml_value(v: Any) -> str:
    """One value as inline TOML. Frozen: configuration digests hash this text."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return toml_str(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def show(v: Any) -> str:
    """A value for an error message: inline TOML, or its repr, at most about
    :data:`~roughslip.errors.ECHO_LIMIT` characters (a longer one is cut, with its length:
    :func:`~roughslip.errors.shorten`)."""
    if isinstance(v, str) and len(v) > ECHO_LIMIT:
        return shorten(toml_str(v[:ECHO_LIMIT]), length=len(v))
    try:
        return shorten(toml_value(v))
    except TypeError:
        return shorten(repr(v))
