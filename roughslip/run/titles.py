"""Run titles filled from the resolved configuration, and titles that would lie.

A title may quote configuration keys as placeholders, ``title = "rough surface, H =
{surface.hurst}"``: :func:`render` fills them from the resolved configuration, so that a
``--set surface.hurst=0.6`` retitles the run ("rough surface, H = 0.6"). A format follows a
colon, ``{pull.lam:.2f}``; ``{{`` and ``}}`` are literal braces. The file keeps the title as
written (the stored configuration runs again with other ``--set`` values), and the figures
and ``roughslip inspect`` show it filled.

A ``--set`` that changes a key whose old value a title quotes literally ("H = 0.8" under
``--set surface.hurst=0.6``) would mislabel the run: :func:`contradiction` finds it, and the
configuration is refused with the placeholder that fixes it.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping
from typing import Any

from roughslip.run.tomlio import show as toml_show

_KEY = r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)+"
PLACEHOLDER = re.compile(r"\{\{|\}\}|\{(" + _KEY + r")(?::([^{}]*))?\}")
_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")


def placeholders(title: str) -> list[str]:
    """The dotted keys a title quotes as placeholders, in order."""
    return [m.group(1) for m in PLACEHOLDER.finditer(title) if m.group(1)]


def lookup(config: Mapping[str, Any], key: str) -> Any:
    """The value of a dotted key in a configuration dict (None when it has none)."""
    node: Any = config
    for part in key.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def show(value: Any, spec: str = "") -> str:
    """A configuration value as a title shows it: numbers as written (``0.8``, ``1e-10``) or
    by ``spec``, integer lists as a shape (``2 x 2``), other lists separated by commas."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        if spec:
            return format(value, spec)
        if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
            return str(int(value)) if math.isfinite(value) else str(value)
        return f"{value:g}" if isinstance(value, float) else str(value)
    if isinstance(value, list):
        sep = " x " if value and all(isinstance(v, int) and not isinstance(v, bool)
                                     for v in value) else ", "
        return sep.join(show(v, spec) for v in value)
    return format(str(value), spec) if spec else str(value)


def render(title: str | None, config: Mapping[str, Any]) -> str | None:
    """The title with its placeholders filled from ``config`` (a resolved configuration as a
    dict, e.g. a run file's stored one); a placeholder of a key that has no value stays as
    written."""
    if title is None:
        return None

    def fill(m: re.Match) -> str:
        if m.group(0) in ("{{", "}}"):
            return m.group(0)[0]
        value = lookup(config, m.group(1))
        if value is None or isinstance(value, Mapping):
            return m.group(0)
        try:
            return show(value, m.group(2) or "")
        except (ValueError, TypeError):
            return m.group(0)

    return PLACEHOLDER.sub(fill, title)


def unknown(title: str, config: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(key, why)`` of each placeholder that cannot be filled: no such key, a key without a
    value, or a format that does not suit the value."""
    out = []
    for m in PLACEHOLDER.finditer(title):
        key = m.group(1)
        if not key:
            continue
        value = lookup(config, key)
        if value is None or isinstance(value, Mapping):
            keys = [f"{s}.{k}" for s, t in config.items() if isinstance(t, Mapping) for k in t]
            close = difflib.get_close_matches(key, keys, n=1)
            out.append((key, "names no key with a value in the resolved configuration"
                        + (f" (did you mean {{{close[0]}}}?)" if close else "")))
            continue
        try:
            show(value, m.group(2) or "")
        except (ValueError, TypeError):
            out.append((key, f"its format {m.group(2)!r} does not suit {value!r}"))
    return out


def _literal(title: str) -> str:
    """The title without its placeholders (what it says of itself)."""
    return PLACEHOLDER.sub(lambda m: " " if m.group(1) else m.group(0)[0], title)


def _quoted(title: str, value: Any) -> re.Match | None:
    """Where the literal part of ``title`` quotes ``value``: a number equal to it, or the
    words of a string (three characters or more) or of a list as a title shows it."""
    text = _literal(title)
    if isinstance(value, bool) or value is None:
        return None
    if isinstance(value, int | float):
        for m in _NUMBER.finditer(text):
            try:
                if float(m.group(0)) == float(value):
                    return m
            except ValueError:  # pragma: no cover - the pattern admits only numbers
                continue
        return None
    shown = [str(value)] if isinstance(value, str) else (
        [show(value), ", ".join(map(str, value))] if isinstance(value, list) else [])
    for s in shown:
        if len(s) >= 3:
            m = re.search(r"(?<!\w)" + re.escape(s) + r"(?!\w)", text, re.IGNORECASE)
            if m:
                return m
    return None


def contradiction(title: str | None, before: Mapping[str, Any], after: Mapping[str, Any],
                  changed: Mapping[str, str]) -> str | None:
    """The rule a literal title breaks, or None.

    Parameters
    ----------
    title : str or None
        The title as written.
    before, after : mapping
        The configuration without and with the ``--set`` overrides (``before`` may lack keys
        left at their defaults: pass the defaults in it).
    changed : mapping
        ``{dotted key: the --set text}`` of the overrides.
    """
    if not title or "title" in changed:
        return None
    for key, text in changed.items():
        old, new = lookup(before, key), lookup(after, key)
        if old is None or old == new or isinstance(old, Mapping) or key in placeholders(title):
            continue
        m = _quoted(title, old)
        if m is None:
            continue
        fixed = _literal(title)[:m.start()] + "{" + key + "}" + _literal(title)[m.end():]
        if placeholders(title):  # the suggestion keeps the placeholders as they were
            fixed = title.replace(m.group(0), "{" + key + "}", 1)
        return (f"title = {toml_show(title)} quotes {key} = {toml_show(old)}, which --set "
                f"{text} changes to {toml_show(new)}; quote it as a placeholder, title = "
                f"{toml_show(fixed)}, or set the title too (--set 'title=\"...\"')")
    return None


def check(title: str | None, given: Mapping[str, Any], resolved: Mapping[str, Any],
          changed: Mapping[str, str], defaults: Mapping[tuple[str, str], Any]) -> str | None:
    """What is wrong with a configuration's title, or None: a placeholder that cannot be
    filled (:func:`unknown`), or a literal quote of a value a ``--set`` changes
    (:func:`contradiction`).

    ``given`` is the configuration as written, before the overrides ``changed``; ``resolved``
    the validated one, as a dict; ``defaults`` the ``(section, key) -> default`` of today.
    """
    if title is None:
        return None
    for key, why in unknown(title, resolved):
        return f"title = {toml_show(title)}: {{{key}}} {why}"
    before: dict[str, Any] = {}
    for (section, key), value in defaults.items():
        before.setdefault(section, {})[key] = value
    for section, table in given.items():
        before[section] = {**before.get(section, {}), **table} if isinstance(table, dict) \
            else table
    return contradiction(title, before, resolved, changed)
