"""TOML text of a configuration: the reader, with its limit on nesting; tomli-w for the text
people read; and a frozen writer of single values for error messages and digests
(:mod:`roughslip.run.digest`)."""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from typing import Any

from roughslip.errors import ECHO_LIMIT, ConfigError, shorten

#: The deepest nesting of tables, inline tables and arrays a configuration may have (a
#: section is level 1; ``squeeze.depths = {start = ...}`` or any list in a section is level
#: 2, the most a configuration uses). 32 is far above any real configuration and far below
#: the depth at which reading fails without it: Python's TOML parser recurses once per level
#: and stops with a ``RecursionError`` near 330 nested inline tables (500 arrays), and so do
#: the recursive copies and writers of the loader.
MAX_NESTING = 32

#: the rule a configuration nested too deep breaks
_NESTING_RULE = (f"tables, inline tables and arrays may nest at most {MAX_NESTING} levels")

BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def loads_toml(text: str, where: str) -> dict[str, Any]:
    """Parse TOML text whose tables, inline tables and arrays nest at most
    :data:`MAX_NESTING` levels.

    Parameters
    ----------
    text : str
        The document.
    where : str
        How errors name it (a file name, or ``--set KEY=VALUE``).

    Returns
    -------
    dict
        The parsed document.

    Raises
    ------
    ConfigError
        One line naming ``where``: invalid TOML, or nesting deeper than :data:`MAX_NESTING`
        (also when it is too deep for the parser itself).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: invalid TOML: {exc}") from None
    except RecursionError:
        raise too_deep(where) from None
    check_nesting(data, where)
    return data


def too_deep(where: str) -> ConfigError:
    """The error (returned, not raised) of TOML text nested too deep for the parser itself
    (it raised ``RecursionError``).

    Parameters
    ----------
    where : str
        How the error names the source.

    Returns
    -------
    ConfigError
    """
    return ConfigError(f"{where}: nested too deep to read: {_NESTING_RULE}")


def check_nesting(data: Any, where: str, level: int = 0, prefix: str = "") -> None:
    """Refuse tables, inline tables and arrays nested deeper than :data:`MAX_NESTING` levels.

    The walk is iterative and stops at the first level too deep, so neither the depth nor a
    mapping that contains itself can exhaust the stack.

    Parameters
    ----------
    data : mapping, list or scalar
        A parsed document, or a value.
    where : str
        How the error names the source (a file name, or ``--set KEY=VALUE``).
    level : int
        The level of ``data`` itself: 0 for a document, the number of tables above a value
        that ``--set`` places (``output.fields=[...]``: 1, the array then being level 2).
    prefix : str
        The dotted key of ``data`` (for the message).

    Raises
    ------
    ConfigError
        ``FILE: KEY: nested more than 32 levels deep: ...``, the key cut to
        :data:`~roughslip.errors.ECHO_LIMIT` characters.
    """
    if level > MAX_NESTING:  # the tables of a --set key alone are too many
        raise ConfigError(f"{where}: {_spell(prefix, None)}: nested more than {MAX_NESTING} "
                          f"levels deep: {_NESTING_RULE}")
    # each entry keeps its key and a link to its parent's: the path is spelled out only for
    # the message (building every path would copy long keys once per descendant)
    stack: list[tuple[Any, int, Any]] = [(data, level, None)]
    while stack:
        node, depth, chain = stack.pop()
        if isinstance(node, Mapping):
            items: Any = node.items()
        elif isinstance(node, list | tuple):
            items = enumerate(node)
        else:
            continue
        for key, value in items:
            if not isinstance(value, Mapping | list | tuple):
                continue
            if depth + 1 > MAX_NESTING:
                raise ConfigError(f"{where}: {_spell(prefix, (chain, key))}: nested more than "
                                  f"{MAX_NESTING} levels deep: {_NESTING_RULE}")
            stack.append((value, depth + 1, (chain, key)))


def _spell(prefix: str, chain: Any) -> str:
    """The dotted key (``a.b[0]``) of a link chain of :func:`check_nesting`, at most
    :data:`~roughslip.errors.ECHO_LIMIT` characters of it (:func:`~roughslip.errors.shorten`)."""
    keys = []
    while chain is not None:
        chain, key = chain
        keys.append(key)
    parts = [prefix] if prefix else []
    for key in reversed(keys):
        parts.append(f"[{key}]" if isinstance(key, int) else f".{key}" if parts else str(key))
    length = sum(map(len, parts))
    text = ""
    for part in parts:  # never more than the limit: a key may be megabytes long
        text += part[:ECHO_LIMIT + 1 - len(text)]
        if len(text) > ECHO_LIMIT:
            break
    return shorten(text, length=length) if length > ECHO_LIMIT else text


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
