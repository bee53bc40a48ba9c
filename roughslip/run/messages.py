"""The errors of a configuration: each names where its value came from (the file, or the
``--set`` that gave it), the dotted key, the value and the rule, and the checks that do not
depend on each other are collected so that one message lists every error they found."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from roughslip.errors import ConfigError, shorten
from roughslip.run.tomlio import show


class Context:
    """Where the values of a configuration came from: its file, and the ``--set`` overrides
    that replaced some of them."""

    def __init__(self, source: str, overridden: dict[str, str]):
        self.source = source
        self.overridden = overridden
        #: retired keys given, with their values (dotted key -> value)
        self.retired: dict[str, Any] = {}

    def where(self, key: str) -> str:
        """The source of ``key``'s value: the file, and the ``--set`` that gave it if one
        did."""
        hit = self.overridden.get(key) or next(
            (t for k, t in self.overridden.items() if k.startswith(key + ".")), None)
        return self.source if hit is None else f"{self.source} (--set {shorten(hit)})"

    def fail(self, key: str, value: Any = dataclasses.MISSING, rule: str = "") -> ConfigError:
        """The error (returned, not raised) of ``key``, with its value when given, the rule it
        breaks and where it came from; the key, the value and the ``--set`` text each at most
        about :data:`~roughslip.errors.ECHO_LIMIT` characters."""
        where = self.where(key)
        key = shorten(key)
        if value is dataclasses.MISSING:
            return ConfigError(f"{where}: {key}: {rule}")
        return ConfigError(f"{where}: {key} = {show(value)}: {rule}")


class Errors:
    """The errors of the checks that do not depend on each other, collected so that one
    message lists them all (:meth:`check` runs one check, :meth:`raise_any` reports)."""

    def __init__(self, ctx: Context) -> None:
        self.ctx = ctx
        self.found: list[ConfigError] = []

    def check(self, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)``, or None with its :class:`ConfigError` kept."""
        try:
            return fn(*args)
        except ConfigError as exc:
            self.found.append(exc)
            return None

    def add(self, key: str, value: Any = dataclasses.MISSING, rule: str = "") -> None:
        """Keep the error of ``key`` (:meth:`Context.fail`)."""
        self.found.append(self.ctx.fail(key, value, rule))

    def raise_any(self) -> None:
        """Raise the one error found as it is, several as one error with a line each."""
        if len(self.found) == 1:
            raise self.found[0]
        if self.found:
            lines = "\n".join(f"  {e}" for e in self.found)
            raise ConfigError(f"{self.ctx.source}: {len(self.found)} errors:\n{lines}")
