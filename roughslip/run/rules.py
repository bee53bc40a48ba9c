"""The rules of configuration values: a field helper that attaches a description, a check and
choices to a section's dataclass field, and the checks themselves.

A check takes a value already converted to the field's type and returns None when the value
is valid, else the rule it breaks ("must be > 0"); its ``rule`` attribute words the rule for
the configuration reference.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import field
from typing import Any

from roughslip.registry import Registry

Check = Callable[[Any], str | None]


def option(default: Any = None, doc: str = "", check: Check | None = None, choices=None,
           dimension: str = "", **kw):
    """A section's field: its default, its description, its check, its choices (a
    :class:`~roughslip.registry.Registry`, read live, or any iterable of the allowed values)
    and its dimension (``length``, ``stress`` or ``force``: the value may be a quantity with
    a unit, :mod:`roughslip.run.units`)."""
    live = isinstance(choices, Registry)
    meta = {"doc": doc, "check": check,
            "choices": choices if live else tuple(choices) if choices else None,
            "dimension": dimension}
    if isinstance(default, list | dict):
        return field(default_factory=lambda d=default: type(d)(d), metadata=meta, **kw)
    return field(default=default, metadata=meta, **kw)


def ruled(text: str, check: Check) -> Check:
    """Attach the rule's wording (shown in the configuration reference) to a check."""
    check.rule = text  # type: ignore[attr-defined]
    return check


def positive(v):
    return None if v > 0 else "must be > 0"


def nonnegative(v):
    return None if v >= 0 else "must be >= 0"


def at_least(n):
    return ruled(f">= {n}", lambda v: None if v >= n else f"must be >= {n}")


def nu_rule(v):
    return None if -1.0 < v <= 0.5 else "must satisfy -1 < nu <= 0.5"


def hurst_rule(v):
    return None if 0.0 < v < 1.0 else "must be in (0, 1)"


def tol_rule(v):
    return None if 0.0 < v < 1.0 else "must satisfy 0 < tol < 1"


def pair(v):
    return None if len(v) == 2 else "must be a list of two numbers"


def crop_rule(v):
    if len(v) != 4:
        return "must be [y0, y1, x0, x1]"
    y0, y1, x0, x1 = v
    if min(v) < 0 or not (y0 < y1 and x0 < x1):
        return "must satisfy 0 <= y0 < y1 and 0 <= x0 < x1"
    return None


for _check, _text in ((positive, "> 0"), (nonnegative, ">= 0"), (nu_rule, "-1 < nu <= 0.5"),
                     (hurst_rule, "0 < H < 1"), (tol_rule, "0 < tol < 1"),
                     (pair, "two values"), (crop_rule, "0 <= y0 < y1, 0 <= x0 < x1")):
    ruled(_text, _check)
