"""Run configuration: TOML schema as frozen dataclasses, validation, ``--set`` overrides.

A configuration is a TOML file with the sections below (every key optional unless marked).
:func:`load_config` reads it, deep-merges ``--set key=value`` overrides (values parsed as inline
TOML; a bare word is taken as a string), rejects unknown sections and keys, checks every value
and returns a frozen :class:`RunConfig`. Every error is a :class:`~roughslip.errors.ConfigError`
whose message names the file, the dotted key, the value and the rule, e.g.::

    run.toml: material.nu = 0.7: must satisfy -1 < nu <= 0.5

The sections and their fields are in :mod:`roughslip.run.sections`, the rules of values in
:mod:`roughslip.run.rules`, digests in :mod:`roughslip.run.digest`; the names a caller needs
are importable from here.

Units: lengths (pixel size, heights, depths, radii, wavelengths) share one unit, and stresses
(``material.E``) another; ``[units]`` names them, and a value may carry its own unit
(``E = "70 GPa"``), converted when the file is read (:mod:`roughslip.run.units`). Forces are
stress x length². A title may quote keys, ``{surface.hurst}`` (:mod:`roughslip.run.titles`).
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import math
import re
import tomllib
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from roughslip.errors import ConfigError, echo, shorten
from roughslip.run import schema, titles
from roughslip.run.digest import RENAMED, RETIRED
from roughslip.run.machine import machine_file, read_machine
from roughslip.run.messages import Context, Errors
from roughslip.run.pull_rules import check_pull
from roughslip.run.sections import (
    FIELD_NAMES,
    LAW_PARAMS,
    QUANTITY_KEYS,
    SECTIONS,
    SURFACE_KEYS,
    SURFACE_KINDS,
    TOP_LEVEL_KEYS,
    CouplingConfig,
    EnsembleConfig,
    ExecutionConfig,
    GridConfig,
    MaterialConfig,
    OutputConfig,
    PullConfig,
    RunConfig,
    SqueezeConfig,
    SurfaceConfig,
    UnitsConfig,
    defaults,
)
from roughslip.run.tomlio import BARE_KEY, check_nesting, dumps_toml, loads_toml, too_deep
from roughslip.run.units import resolve as resolve_units

__all__ = ["FIELD_NAMES", "LAW_PARAMS", "SECTIONS", "SURFACE_KEYS", "SURFACE_KINDS",
           "TOP_LEVEL_KEYS", "CouplingConfig", "EnsembleConfig", "ExecutionConfig",
           "GridConfig", "MaterialConfig", "OutputConfig", "PullConfig", "RunConfig",
           "SqueezeConfig", "SurfaceConfig", "UnitsConfig", "dumps_toml", "load_config",
           "merge_overrides", "parse_override"]

def parse_override(text: str) -> tuple[list[str], Any]:
    """Parse ``key.path=value``; the value is inline TOML, or a bare word taken as a string."""
    where = f"--set {shorten(text)}"
    if "=" not in text:
        raise ConfigError(f"{where}: expected KEY=VALUE, e.g. surface.hurst=0.6")
    key, raw = text.split("=", 1)
    key = key.strip()
    raw = raw.strip()
    parts = key.split(".")
    if not key or any(not p or not BARE_KEY.match(p) for p in parts):
        raise ConfigError(f"{where}: {echo(key)} is not a dotted key like surface.hurst")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError as exc:
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.\-/]*", raw):
            value = raw
        else:
            raise ConfigError(f"{where}: value is not valid TOML ({exc})") from None
    except RecursionError:
        raise too_deep(where) from None
    # the value sits below the tables of its key: output.fields=[...] is an array at level 2
    check_nesting({parts[-1]: value}, where, len(parts) - 1, ".".join(parts[:-1]))
    return parts, value


def merge_overrides(data: dict[str, Any], overrides: Sequence[str]) -> dict[str, str]:
    """Deep-merge overrides into ``data`` in place; returns {dotted key: override text}."""
    origin: dict[str, str] = {}
    for text in overrides:
        parts, value = parse_override(text)
        node = data
        for i, p in enumerate(parts[:-1]):
            nxt = node.get(p)
            if nxt is None:
                nxt = node[p] = {}
            elif not isinstance(nxt, dict):
                raise ConfigError(f"--set {shorten(text)}: "
                                  f"{shorten('.'.join(parts[: i + 1]))} is a value, not a table")
            node = nxt
        if isinstance(value, dict) and isinstance(node.get(parts[-1]), dict) and \
                parts[-1] not in ("depths",):
            node[parts[-1]].update(value)
        else:
            node[parts[-1]] = value
        origin[".".join(parts)] = text
        if isinstance(value, dict):
            for k in value:
                origin[".".join([*parts, k])] = text
    return origin


def load_config(path: str | Path | None = None, overrides: Sequence[str] = (),
                data: Mapping[str, Any] | None = None, use_machine: bool = True) -> RunConfig:
    """Read, merge, validate.

    Parameters
    ----------
    path : path-like, optional
        TOML file. Relative ``surface.path`` values are resolved against its folder.
    overrides : sequence of str
        ``"key.path=value"`` strings, applied in order before validation.
    data : mapping, optional
        Use this dict instead of reading a file (``path`` then only names the source).
    use_machine : bool
        Read the per-machine execution settings (:mod:`roughslip.run.machine`) beneath the
        file's own.

    Raises
    ------
    ConfigError
        With file, dotted key, value and rule in the message.
    """
    source = Path(path).name if path is not None else "<config>"
    if data is None:
        if path is None:
            raise ConfigError("no configuration file given")
        p = Path(path)
        try:
            raw = p.read_bytes()
        except FileNotFoundError:
            raise ConfigError(f"{path}: no such configuration file") from None
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read ({exc.strerror})") from None
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise ConfigError(f"{source}: not UTF-8 text") from None
        data = loads_toml(text, source)
    else:
        check_nesting(data, source)
    data = _deepcopy(data)
    machine = machine_file() if use_machine else None
    if machine is not None:  # below the experiment's own [execution] (roughslip.run.machine)
        tables = read_machine(machine)
        for name, table in tables.items():
            _build_section(name, SECTIONS[name], table, Context(str(machine), {}))
            mine = data.get(name, {})
            if isinstance(mine, dict):  # else reported as not a table by the checks below
                data[name] = {**table, **mine}
    given = _deepcopy(data)
    origin = merge_overrides(data, overrides)
    ctx = Context(source, origin)
    base_dir = Path(path).resolve().parent if path is not None else Path.cwd()
    cfg = _build(data, ctx, base_dir)
    wrong = titles.check(cfg.title, given, cfg.to_dict(), origin, defaults())
    if wrong:  # a title that would mislabel the run (roughslip.run.titles)
        raise ConfigError(f"{ctx.where('title')}: {wrong}")
    return cfg if machine is None else dataclasses.replace(cfg, machine=str(machine))


def _deepcopy(d: Any) -> Any:
    if isinstance(d, Mapping):
        return {k: _deepcopy(v) for k, v in d.items()}
    if isinstance(d, list):
        return [_deepcopy(v) for v in d]
    return d


def _suggest(key: str, known: Sequence[str]) -> str:
    lower = {k.lower(): k for k in known}
    # difflib's ratio is at most 2 k / (len(key) + k) for known keys of length <= k: a key
    # over 2.5 k long cannot reach its cutoff 0.6, and comparing a huge one only costs time
    close = (difflib.get_close_matches(key.lower(), list(lower), n=1)
             if len(key) <= 2.5 * max(map(len, known)) else [])
    if close:
        return f" (did you mean {lower[close[0]]!r}?)"
    return f" (known: {', '.join(known)})"


def _build(data: dict[str, Any], ctx: Context, base_dir: Path) -> RunConfig:
    known = [*SECTIONS, *TOP_LEVEL_KEYS]
    errors = Errors(ctx)
    for k, v in data.items():
        if k not in known:
            errors.add(k, rule="unknown section or key" + _suggest(k, known))
        elif k in SECTIONS and not isinstance(v, dict):
            errors.add(k, v, "must be a table ([" + k + "])")
    title = data.get("title")
    if title is not None and not isinstance(title, str):
        errors.add("title", title, "must be a string")
    for required in ("surface",):
        if required not in data:
            errors.add(required, rule="missing section [" + required + "]")
    before = len(errors.found)
    quantities = resolve_units(data, QUANTITY_KEYS, ctx, errors)
    if len(errors.found) > before:  # else each would be reported again as not a number
        errors.raise_any()
    sections: dict[str, Any] = {}
    for name, cls in SECTIONS.items():
        if name in data and isinstance(data[name], dict):
            sections[name] = _build_section(name, cls, data[name], ctx, errors)
    errors.raise_any()
    sections.setdefault("grid", GridConfig())
    sections.setdefault("material", MaterialConfig())
    for name in ("pull", "coupling", "ensemble", "output", "execution"):
        sections.setdefault(name, SECTIONS[name]())
    for name in ("surface", "elastic_surface"):
        if name in sections:
            sections[name] = errors.check(_check_surface, name, sections[name], data[name], ctx,
                                          base_dir)
    sections["squeeze"] = errors.check(_check_squeeze, data.get("squeeze", {}),
                                       sections.get("squeeze"), ctx)
    errors.raise_any()
    given = frozenset(f"{sec}.{k}" for sec, t in data.items() if isinstance(t, dict)
                      for k in t)
    pull = sections["pull"]
    if pull.direction != 0 and "pull.components" not in given:  # a drive off x pulls the vector
        sections["pull"] = dataclasses.replace(pull, components="xy")
    cfg = RunConfig(title=title, source=ctx.source, given=given, retired=dict(ctx.retired),
                    quantities=quantities, **sections)
    _check_cross(cfg, ctx, errors)
    errors.raise_any()
    return cfg


def _type_name(tp: Any) -> str:
    return {float: "a number", int: "an integer", bool: "true or false", str: "a string"}.get(
        tp, str(tp))


def _coerce(value: Any, tp: Any, key: str, ctx: Context) -> Any:
    """Check ``value`` against a type hint; return it normalised (ints to floats where needed)."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        inner = [a for a in args if a is not type(None)]
        if len(inner) == 1:
            return _coerce(value, inner[0], key, ctx)
        raise TypeError(tp)
    if origin is list:
        (el,) = args
        if not isinstance(value, list):
            raise ctx.fail(key, value, f"must be a list of {_type_name(el).split(' ', 1)[1]}s")
        return [_coerce(v, el, key, ctx) for v in value]
    if tp is bool:
        if not isinstance(value, bool):
            raise ctx.fail(key, value, "must be true or false")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ctx.fail(key, value, "must be an integer")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ctx.fail(key, value, "must be a number")
        if not math.isfinite(value):
            raise ctx.fail(key, value, "must be finite")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ctx.fail(key, value, "must be a string")
        return value
    raise TypeError(tp)


_SPECIAL = {("squeeze", "depths"), ("squeeze", "forces")}

def _build_section(name: str, cls: type, table: dict[str, Any], ctx: Context,
                   errors: Errors | None = None) -> Any:
    """The section's dataclass from its table. Every key is checked; with ``errors`` their
    errors are collected there (and None returned if there were any), else raised."""
    found = errors if errors is not None else Errors(ctx)
    before = len(found.found)
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {}
    for k, v in table.items():
        k = RENAMED.get((name, k), k)
        if k in kwargs:
            found.add(f"{name}.{k}", rule="given twice (once under its former name)")
            continue
        found.check(_build_key, name, k, v, hints, fields, kwargs, ctx)
    if errors is None:
        found.raise_any()
    elif len(found.found) > before:
        return None
    return cls(**kwargs)


def _build_key(name: str, k: str, v: Any, hints: dict[str, Any],
               fields: dict[str, dataclasses.Field], kwargs: dict[str, Any], ctx: Context) -> None:
    """Check key ``k`` of section ``name`` and add its value to ``kwargs``."""
    key = f"{name}.{k}"
    if (name, k) in RETIRED:
        if isinstance(v, bool) or not isinstance(v, int) or v < 2:
            raise ctx.fail(key, v, "must be an integer >= 2 (the key has no effect: "
                           f"{RETIRED[(name, k)][2]})")
        ctx.retired[key] = v
        return
    if k not in fields:
        raise ctx.fail(key, rule="unknown key" + _suggest(k, list(fields)))
    if (name, k) in _SPECIAL:
        kwargs[k] = v
        return
    val = _coerce(v, hints[k], key, ctx)
    meta = fields[k].metadata
    if meta.get("choices") and val not in meta["choices"]:
        raise ctx.fail(key, v, "must be one of " + ", ".join(map(repr, meta["choices"])))
    check = meta.get("check")
    if check is not None:
        msg = check(val)
        if msg:
            raise ctx.fail(key, v, msg)
    kwargs[k] = val


def _check_surface(name: str, s: SurfaceConfig, table: dict[str, Any], ctx: Context,
                   base_dir: Path) -> SurfaceConfig:
    if s.kind is None:
        raise ctx.fail(f"{name}.kind", rule="missing; choose one of " + ", ".join(SURFACE_KINDS))
    allowed, required = SURFACE_KEYS[s.kind]
    for k in table:
        if k != "kind" and k not in allowed:
            raise ctx.fail(
                f"{name}.{k}",
                table[k],
                f"not a parameter of kind {s.kind!r} "
                f"(its parameters: {', '.join(sorted(allowed))})",
            )
    for k in sorted(required):
        if getattr(s, k) is None:
            raise ctx.fail(f"{name}.{k}", rule=f"missing; required for kind {s.kind!r}")
    if s.kind == "self-affine":
        if (s.rms_height is None) == (s.rms_slope is None):
            raise ctx.fail(f"{name}.rms_height",
                           rule="give exactly one of rms_height and rms_slope")
        if (s.rolloff_wavelength is not None and s.cutoff_wavelength is not None
                and not s.cutoff_wavelength < s.rolloff_wavelength):
            raise ctx.fail(f"{name}.cutoff_wavelength", s.cutoff_wavelength,
                           "must be smaller than rolloff_wavelength")
    if s.kind == "file":
        p = Path(s.path).expanduser()
        if not p.is_absolute():
            p = (base_dir / p).resolve()
        if p.is_dir():
            raise ctx.fail(f"{name}.path", s.path, f"is a directory, not a file ({p})")
        if not p.is_file():
            raise ctx.fail(f"{name}.path", s.path, f"no such file ({p})")
        s = dataclasses.replace(s, path=str(p))
    return s


def _expand_range(table: dict[str, Any], key: str, ctx: Context) -> list[float]:
    allowed = {"start", "stop", "num", "spacing"}
    for k in table:
        if k not in allowed:
            raise ctx.fail(f"{key}.{k}", rule="unknown key" + _suggest(k, sorted(allowed)))
    for k in ("start", "stop", "num"):
        if k not in table:
            raise ctx.fail(f"{key}.{k}", rule="missing (a range needs start, stop and num)")
    start = _coerce(table["start"], float, f"{key}.start", ctx)
    stop = _coerce(table["stop"], float, f"{key}.stop", ctx)
    num = _coerce(table["num"], int, f"{key}.num", ctx)
    spacing = table.get("spacing", "linear")
    if spacing not in ("linear", "log"):
        raise ctx.fail(f"{key}.spacing", spacing, "must be 'linear' or 'log'")
    if num < 1:
        raise ctx.fail(f"{key}.num", num, "must be >= 1")
    if not stop >= start:
        raise ctx.fail(f"{key}.stop", stop, "must be >= start")
    if spacing == "log":
        if not start > 0:
            raise ctx.fail(f"{key}.start", start, "must be > 0 for log spacing")
        if num == 1:
            return [start]
        r = math.log(stop / start)
        vals = [start * math.exp(r * i / (num - 1)) for i in range(num)]
    elif num == 1:
        return [start]
    else:
        vals = [start + (stop - start) * i / (num - 1) for i in range(num)]
    vals[-1] = stop
    return vals


def _check_squeeze(table: dict[str, Any], s: SqueezeConfig | None, ctx: Context) -> SqueezeConfig:
    s = s or SqueezeConfig()
    has_d = "depths" in table
    has_f = "forces" in table
    if has_d == has_f:
        raise ctx.fail("squeeze.depths", rule="give exactly one of squeeze.depths (displacement "
                       "control) and squeeze.forces (load control)")
    key = "squeeze.depths" if has_d else "squeeze.forces"
    raw = table["depths" if has_d else "forces"]
    if isinstance(raw, dict):
        vals = _expand_range(raw, key, ctx)
    elif isinstance(raw, list):
        vals = _coerce(raw, list[float], key, ctx)
    elif isinstance(raw, int | float) and not isinstance(raw, bool):
        vals = [_coerce(raw, float, key, ctx)]
    else:
        raise ctx.fail(key, raw, "must be a list of numbers or a table {start, stop, num}")
    if not vals:
        raise ctx.fail(key, raw, "must not be empty")
    if any(v < 0 for v in vals):
        raise ctx.fail(key, raw, "must be >= 0")
    if any(b <= a for a, b in itertools.pairwise(vals)):
        raise ctx.fail(key, raw, "must be strictly increasing (warm starts go upward)")
    return dataclasses.replace(s, depths=vals if has_d else None, forces=None if has_d else vals)


def _check_cross(cfg: RunConfig, ctx: Context, errors: Errors) -> None:
    """The rules across sections, each error collected in ``errors``."""
    g = cfg.grid
    if g.n is not None and g.shape is not None:
        errors.add("grid.shape", g.shape, "give grid.n or grid.shape, not both")
    file_surface = cfg.surface.kind == "file" or (
        cfg.elastic_surface is not None and cfg.elastic_surface.kind == "file")
    if g.resolved_shape is None and not file_surface:
        errors.add("grid.n", rule="missing (give grid.n or grid.shape)")
    if cfg.squeeze.forces is not None and cfg.squeeze.depth_unit != "length":
        errors.add("squeeze.depth_unit", cfg.squeeze.depth_unit,
                   "applies to depths only; use squeeze.force_unit with forces")
    if cfg.coupling.enabled and not cfg.pull.enabled:
        errors.add("coupling.enabled", True, "needs pull.enabled = true")
    flat = (cfg.surface.kind == "plane" and not any(cfg.surface.slope or (0.0, 0.0))
            and (cfg.elastic_surface is None or (cfg.elastic_surface.kind == "plane"
                 and not any(cfg.elastic_surface.slope or (0.0, 0.0)))))
    if flat and cfg.squeeze.forces is None and cfg.squeeze.depth_unit in ("rms", "range"):
        errors.add("squeeze.depth_unit", cfg.squeeze.depth_unit,
                   "needs a surface with relief; a plane with no slope is flat (its rms "
                   "height and range are 0, so every depth would be 0): give surface.slope, "
                   "or depths in length units (squeeze.depth_unit = \"length\")")
    check_pull(cfg, errors)
    es = cfg.elastic_surface
    tiled = [r for r in ("surface", "elastic_surface") if getattr(cfg, r) is not None
             and getattr(cfg, r).kind == "file" and getattr(cfg, r).tiles]
    if tiled and cfg.ensemble.first_sample != 0:
        errors.add("ensemble.first_sample", cfg.ensemble.first_sample,
                   f"must be 0 with {tiled[0]}.tiles (sample i is tile i)")
    if (es is not None and cfg.surface.tiles and es.tiles
            and cfg.surface.n_tiles != es.n_tiles):
        errors.add("elastic_surface.tiles", es.tiles, f"must give as many tiles as "
                   f"surface.tiles ({cfg.surface.tiles})")
    pull_fields = {n for n in cfg.output.fields if schema.needs_pull(n)}
    if pull_fields and not cfg.pull.enabled:
        errors.add("output.fields", cfg.output.fields,
                   f"{sorted(pull_fields)} need pull.enabled = true")
