r"""Physical units of a run: quantities with units in a configuration, and the named units of
its results.

A run computes in two units of its own: a length unit (``units.length``: grid.pixel_size,
heights, depths, displacements) and a stress unit (``units.stress``: material.E and pressures).
Forces are stress x length² and get a named unit when both are named (MPa x um² = uN); areas
are length². A run without units is dimensionless: its lengths are in whatever unit its inputs
share and its stresses in that of E, and the results say so rather than invent a unit.

Configuration values that carry a dimension (:data:`DIMENSIONS` of the fields in
:mod:`roughslip.run.sections`) may be written as quantities, ``E = "70 GPa"``,
``pixel_size = "0.5 um"``: the loader converts them to the run's units, which a quantity
also sets when ``[units]`` does not (:func:`resolve`). Units are powers of ten of the SI units,
so conversions are exact decimal shifts, rounded once to a float: ``"2.3 um"`` in metres is
2.3e-06, the float of the number typed, not the 2.2999999999999996e-06 of a float product. A
configuration without quantities is untouched, number for number.

No units library is used: the units are two dimensions (length and stress) with SI prefixes,
and a table of exponents does the parsing, the exact conversion and the naming.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from typing import Any

#: length units, as powers of ten of the metre (the keys are ``units.length``'s choices)
LENGTH = {"m": 0, "mm": -3, "um": -6, "nm": -9, "pm": -12}
#: stress units, as powers of ten of the pascal (the keys are ``units.stress``'s choices)
STRESS = {"Pa": 0, "kPa": 3, "MPa": 6, "GPa": 9}
#: other spellings accepted in quantities
ALIASES = {"µm": "um", "μm": "um", "micron": "um", "N/m^2": "Pa", "N/mm^2": "MPa",
           "N/mm2": "MPa"}
#: SI prefixes by power of ten (ASCII: ``u`` for micro)
PREFIXES = {12: "T", 9: "G", 6: "M", 3: "k", 0: "", -3: "m", -6: "u", -9: "n", -12: "p",
            -15: "f", -18: "a", -21: "z", -24: "y", -27: "r", -30: "q"}
#: the dimensions a configuration value can have
DIMENSIONS = ("length", "stress", "force")

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_QUANTITY = re.compile(rf"^\s*({_NUMBER})\s*([^\s\d.+\-][^\s]*)\s*$")


class UnitError(ValueError):
    """A quantity that cannot be read or converted; the message is the rule it breaks."""


@dataclass(frozen=True)
class Quantity:
    """A number with a unit, as written (``Decimal``: exact)."""

    value: Decimal
    unit: str
    dimension: str
    exponent: int  # power of ten of the SI unit


def unit_exponent(unit: str, dimension: str) -> int:
    """The power of ten of the SI unit (m, Pa or N) that ``unit`` is; :class:`UnitError` for a
    unit of another dimension or none."""
    unit = ALIASES.get(unit, unit)
    if dimension == "length" and unit in LENGTH:
        return LENGTH[unit]
    if dimension == "stress" and unit in STRESS:
        return STRESS[unit]
    if dimension == "force" and unit.endswith("N"):
        prefix = unit[:-1]
        for k, p in PREFIXES.items():
            if p == prefix or (prefix in ("µ", "μ") and p == "u"):
                return k
    known = {"length": ", ".join(LENGTH), "stress": ", ".join(STRESS),
             "force": "N with an SI prefix (mN, uN, nN, ...)"}[dimension]
    raise UnitError(f"{unit!r} is not a {dimension} unit (known: {known})")


def parse(text: str, dimension: str) -> Quantity:
    """Read ``"0.5 um"`` as a :class:`Quantity` of ``dimension``; :class:`UnitError` says
    what is wrong."""
    m = _QUANTITY.match(text)
    if m is None:
        raise UnitError(f"must be a number or a quantity like {example(dimension)!r}")
    try:
        value = Decimal(m.group(1))
    except InvalidOperation:  # pragma: no cover - the pattern admits only numbers
        raise UnitError(f"must be a number or a quantity like {example(dimension)!r}") from None
    unit = ALIASES.get(m.group(2), m.group(2))
    return Quantity(value, unit, dimension, unit_exponent(unit, dimension))


def example(dimension: str) -> str:
    """An example quantity of ``dimension``, for messages."""
    return {"length": "0.5 um", "stress": "70 GPa", "force": "2 mN"}[dimension]


def convert(q: Quantity, exponent: int) -> float:
    """``q`` in the unit ``10^exponent`` of its SI unit: an exact decimal shift, rounded once."""
    return float(q.value.scaleb(q.exponent - exponent))


def force_exponent(length: str, stress: str) -> int:
    """The power of ten of the newton that stress x length² is."""
    return STRESS[stress] + 2 * LENGTH[length]


def si_name(exponent: int, symbol: str) -> str:
    """The SI-prefixed name of ``10^exponent symbol`` (``-6, "N"`` -> ``"uN"``), or
    ``1e-5 N`` when no prefix is that power."""
    prefix = PREFIXES.get(exponent)
    return f"{prefix}{symbol}" if prefix is not None else f"1e{exponent} {symbol}"


@dataclass(frozen=True)
class Units:
    """The units of a run: its length and stress units (None: not named), and the names of
    the derived units of its results.

    Text forms are ASCII (``um``, ``uN``, ``um^2``), as stored in run files and printed by the
    command line; :meth:`tex` gives the forms for figures.
    """

    length: str | None = None
    stress: str | None = None

    @classmethod
    def of(cls, config: Mapping[str, Any]) -> Units:
        """The units of a resolved configuration (as a dict: a run file's stored one)."""
        u = config.get("units") or {}
        return cls(u.get("length"), u.get("stress"))

    @property
    def dimensionless(self) -> bool:
        """Neither a length nor a stress unit is named."""
        return self.length is None and self.stress is None

    @property
    def force(self) -> str | None:
        """The named force unit (``"uN"``), when both units are named."""
        if self.length is None or self.stress is None:
            return None
        return si_name(force_exponent(self.length, self.stress), "N")

    def of_dimension(self, dimension: str) -> str:
        """The unit of a result of ``dimension`` (``length``, ``stress``, ``force``, ``area``,
        ``fraction``, ``seconds``, ``count`` or ``""``) as text; empty when it has no named
        unit (the run is dimensionless there)."""
        if dimension == "length":
            return self.length or ""
        if dimension == "area":
            return f"{self.length}^2" if self.length else ""
        if dimension == "stress":
            return self.stress or ""
        if dimension == "force":
            if self.force:
                return self.force
            if self.length:
                return f"E x {self.length}^2"
            if self.stress:
                return f"{self.stress} x length^2"
            return ""
        return {"seconds": "s", "fraction": "1"}.get(dimension, "")

    def tex(self, dimension: str) -> str:
        """:meth:`of_dimension` for figures: ``µm``, ``µm$^2$``, ``E $\\times$ µm$^2$``."""
        text = self.of_dimension(dimension)
        if dimension == "fraction":
            return ""
        text = re.sub(r"\bu(?=[mN]\b)", "µ", text)
        text = text.replace(" x ", r" $\times$ ")
        return re.sub(r"\^(\d)", r"$^\1$", text)

    def label(self, dimension: str) -> str:
        """``" (um)"`` for a figure's axis label: the unit in brackets, ``" (dimensionless)"``
        for a dimensionless run, or nothing for a quantity without a unit."""
        if dimension in ("fraction", "count", ""):
            return ""
        text = self.tex(dimension)
        return f" ({text})" if text else " (dimensionless)"

    def attributes(self) -> dict[str, str]:
        """The ``units`` root attribute of a run file: the unit of every kind of result."""
        free = "dimensionless: " if self.dimensionless else "not named: "
        return {
            "length": self.length or free + "the unit of grid.pixel_size (heights, depths, "
                                            "displacements)",
            "stress": self.stress or free + "the unit of material.E",
            "force": self.of_dimension("force") or free + "stress x length^2",
            "pressure": self.stress or free + "the unit of material.E",
            "area": self.of_dimension("area") or free + "length^2",
            "fraction": "1",
            "seconds": "s",
            "contact_area": "fraction of the nominal area",
        }

    def describe(self) -> str:
        """One line for ``roughslip inspect``."""
        if self.dimensionless:
            return ("dimensionless (no [units]): lengths in the unit of grid.pixel_size, "
                    "stresses in that of E, forces in E x length^2")
        parts = [f"length {self.length}" if self.length else "length: dimensionless",
                 f"stress {self.stress}" if self.stress else "stress: the unit of E",
                 f"force {self.of_dimension('force')}", "area "
                 + (self.of_dimension("area") or "length^2")]
        return ", ".join(parts)


def resolve(data: dict[str, Any], fields: Mapping[str, Mapping[str, str]], context: Any,
            errors: Any) -> dict[str, str]:
    """Convert the quantities of a configuration's tables ``data`` to the run's units, in
    place, and set ``data["units"]`` to the units they imply.

    Parameters
    ----------
    data : dict
        The configuration's tables (sections as dicts), before their values are checked.
    fields : mapping
        ``{section: {key: dimension}}``: the keys that may carry units.
    context : roughslip.run.messages.Context
        Where the values came from (for messages).
    errors : roughslip.run.messages.Errors
        Where a quantity that cannot be read or converted is reported.

    Returns
    -------
    dict
        ``{dotted key: the text given}`` of every value converted.

    Notes
    -----
    ``units.length`` and ``units.stress`` name the run's units; a length (a stress) given as a
    quantity sets ``units.length`` (``units.stress``) when it is not given: the unit of
    grid.pixel_size (material.E) if it carries one, else that of the first in section order.
    Depths are lengths only with ``squeeze.depth_unit = "length"``, and loads forces only with
    ``squeeze.force_unit = "force"``; a force needs both units.
    """
    found: list[tuple[str, str, Any, list, str]] = []  # (section, key, value, quantities, dim)
    for section, keys in fields.items():
        table = data.get(section)
        if not isinstance(table, dict):
            continue
        for key, dimension in keys.items():
            if key not in table:
                continue
            value = table[key]
            dim = _dimension_of(section, key, dimension, table)
            before = len(errors.found)
            qs = _quantities(value, dim, f"{section}.{key}", errors)
            if qs and len(errors.found) == before:
                found.append((section, key, value, qs, dim))
    if not found:
        return {}
    units = data.get("units") if isinstance(data.get("units"), dict) else {}
    chosen = dict(units)
    for dim, first in (("length", ("grid", "pixel_size")), ("stress", ("material", "E"))):
        if chosen.get(dim) is not None:
            continue
        given = [(s, k, qs) for s, k, _, qs, d in found if d == dim]
        if given:
            pick = next((g for g in given if (g[0], g[1]) == first), given[0])
            chosen[dim] = _flat(pick[2])[0].unit
    converted: dict[str, str] = {}
    for section, key, value, qs, dim in found:
        dotted = f"{section}.{key}"
        try:
            target = _target_exponent(dim, chosen)
        except UnitError as exc:
            errors.add(dotted, value, str(exc))
            continue
        data[section][key] = _replace(value, qs, target)
        converted[dotted] = _text(value)
    if any(chosen.get(d) != units.get(d) for d in ("length", "stress")):
        data["units"] = {**units, **{d: chosen[d] for d in ("length", "stress")
                                      if chosen.get(d) is not None}}
    return converted


def _dimension_of(section: str, key: str, dimension: str, table: Mapping[str, Any]) -> str:
    """The dimension of a value: depths are lengths only in length units, loads forces only as
    totals ("" otherwise: a quantity there is an error)."""
    if (section, key) == ("squeeze", "depths"):
        return dimension if table.get("depth_unit", "length") == "length" else ""
    if (section, key) == ("squeeze", "forces"):
        return dimension if table.get("force_unit", "force") == "force" else ""
    return dimension


def _quantities(value: Any, dimension: str, key: str, errors: Any) -> Any:
    """The quantities in ``value`` (a string, a list of them, or a {start, stop} table),
    mirrored: a :class:`Quantity` where a string was, None elsewhere; None when there is
    none. Strings that are not quantities are reported in ``errors``."""
    if isinstance(value, str):
        if not dimension:
            errors.add(key, value, "must be a number (a unit applies only to depths in length "
                       "units, squeeze.depth_unit = 'length', and loads in force units, "
                       "squeeze.force_unit = 'force')")
            return [None]
        try:
            return [parse(value, dimension)]
        except UnitError as exc:
            errors.add(key, value, str(exc))
            return [None]
    if isinstance(value, list) and any(isinstance(v, str) for v in value):
        out = [_quantities(v, dimension, key, errors) if isinstance(v, str) else None
               for v in value]
        return [o[0] if isinstance(o, list) else o for o in out]
    if isinstance(value, dict) and any(isinstance(value.get(k), str) for k in ("start", "stop")):
        return [_quantities(value.get(k), dimension, f"{key}.{k}", errors)[0]
                if isinstance(value.get(k), str) else None for k in ("start", "stop")]
    return None


def _flat(qs: list) -> list:
    return [q for q in qs if q is not None]


def _target_exponent(dimension: str, units: Mapping[str, Any]) -> int:
    length, stress = units.get("length"), units.get("stress")
    if dimension == "length":
        if length not in LENGTH:
            raise UnitError(f"units.length = {length!r} is not a length unit")
        return LENGTH[length]
    if dimension == "stress":
        if stress not in STRESS:
            raise UnitError(f"units.stress = {stress!r} is not a stress unit")
        return STRESS[stress]
    if length is None or stress is None:
        raise UnitError("a force with a unit needs the run's length and stress units "
                        "(units.length and units.stress, or a pixel size and E with units)")
    if length not in LENGTH or stress not in STRESS:
        raise UnitError("units.length and units.stress must be known units")
    return force_exponent(length, stress)


def _replace(value: Any, qs: list, exponent: int) -> Any:
    """``value`` with its quantities converted to floats in the unit ``10^exponent``."""
    conv = [convert(q, exponent) if isinstance(q, Quantity) else None for q in qs]
    if isinstance(value, str):
        return conv[0]
    if isinstance(value, list):
        return [c if c is not None else v for v, c in zip(value, conv, strict=True)]
    out = dict(value)
    for k, c in zip(("start", "stop"), conv, strict=True):
        if c is not None:
            out[k] = c
    return out


def _text(value: Any) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, list):
        return "[" + ", ".join(repr(v) if isinstance(v, str) else str(v) for v in value) + "]"
    return "{" + ", ".join(f"{k} = {v!r}" for k, v in value.items()) + "}"
