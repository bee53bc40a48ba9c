"""What a run was: its resolved model, its units, its configuration and its notes, read from
the run file (``roughslip inspect`` and the figures' titles and labels).

Names come from the registries: slip laws from :data:`roughslip.friction.laws.LAWS`, pull
methods from :data:`roughslip.friction.pull.METHODS`, squeeze histories from
:data:`roughslip.coupling.histories.HISTORIES`. The methods a run actually used (``auto``
chooses per contact) are stored per sample and depth (the ``solvers`` attribute of each
sample, :mod:`roughslip.run.store`) and counted here.
"""

from __future__ import annotations

import json
import re
import textwrap
from collections import Counter
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from roughslip.coupling.histories import HISTORIES
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import METHODS
from roughslip.run.reading import RunData
from roughslip.run.sections import QUANTITY_KEYS, SURFACE_KEYS, defaults
from roughslip.run.titles import render, show
from roughslip.run.units import Units

#: the width terminal output keeps to
WIDTH = 100

#: symbols of the slip laws' parameters (``pull`` keys): text and figure forms
SYMBOLS = {"lam": ("lambda", r"$\lambda$"), "lam_dynamic": ("lambda_d", r"$\lambda_d$"),
           "slip_distance": ("d_c", r"$d_c$")}


def config(run: RunData) -> dict[str, Any]:
    """The run's stored configuration, as a dict."""
    return run.config_dict()


def title(run: RunData) -> str | None:
    """The run's title with its placeholders filled (:mod:`roughslip.run.titles`)."""
    cfg = run.config_dict()
    return render(cfg.get("title"), cfg)


def units(run: RunData) -> Units:
    """The run's units (:class:`roughslip.run.units.Units`)."""
    return Units.of(run.config_dict())


def coupled(cfg: Mapping[str, Any]) -> bool:
    """Whether the coupled model ran (enabled, and nu < 1/2 where the coupling is nonzero)."""
    return bool(cfg.get("coupling", {}).get("enabled")) and \
        cfg.get("material", {}).get("nu") != 0.5


def law_parameters(cfg: Mapping[str, Any], tex: bool = False) -> str:
    """The slip law's coefficient and own parameters, ``lambda = 0.2, lambda_d = 0.1, d_c =
    0.5 um`` (``tex``: for figures, with symbols), lengths with the run's unit."""
    pull = cfg.get("pull", {})
    law = pull.get("slip_law", "break")
    keys = ["lam", *(LAWS.get(law).params if law in LAWS else ())]
    u = Units.of(cfg)
    parts = []
    for key in keys:
        if pull.get(key) is None:
            continue
        symbol = SYMBOLS.get(key, (key, key))[1 if tex else 0]
        dim = QUANTITY_KEYS["pull"].get(key, "")
        unit = (u.tex(dim) if tex else u.of_dimension(dim)) if dim else ""
        parts.append(f"{symbol} = {show(pull[key])}" + (f" {unit}" if unit else ""))
    return ", ".join(parts)


def law_label(cfg: Mapping[str, Any], tex: bool = False) -> str:
    """The slip law with its parameters, ``slip-weakening law: lambda = 0.3, ...``,
    ``(coupled)`` under the coupled model, and ``, traction (f_x, f_y) pulled at 30 deg``
    when the bonds carry the traction vector (``pull.components = "xy"``); empty without a
    pull."""
    pull = cfg.get("pull", {})
    if not pull.get("enabled"):
        return ""
    law = pull.get("slip_law", "break")
    vector = ""
    if pull.get("components", "x") != "x":
        f = r"$(f_x, f_y)$" if tex else "(f_x, f_y)"
        deg = r"$^\circ$" if tex else " deg"
        vector = f", traction {f} pulled at {show(pull.get('direction', 0.0))}{deg}"
    return (f"{law} law" + (" (coupled)" if coupled(cfg) else "") + ": "
            + law_parameters(cfg, tex) + vector)


def nondefault(cfg: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The keys of a resolved configuration that differ from today's defaults, by section
    (the title apart); a surface's keys always (its kind's parameters have no default)."""
    d = defaults()
    missing = object()
    out: dict[str, dict[str, Any]] = {}
    for section, table in cfg.items():
        if not isinstance(table, Mapping):
            continue
        keep = {k: v for k, v in table.items() if d.get((section, k), missing) != v}
        if keep:
            out[section] = keep
    return out


def _short(value: Any) -> str:
    """A configuration value for one line: long lists cut to their ends with their length."""
    if isinstance(value, list) and len(value) > 5:
        ends = [_num(v) for v in (value[0], value[1], value[-1])]
        return f"[{ends[0]}, {ends[1]}, ..., {ends[2]}] ({len(value)} values)"
    if isinstance(value, list):
        return "[" + ", ".join(_num(v) for v in value) + "]"
    return _num(value)


def _num(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v)


def wrap(head: str, text: str | list[str], indent: int = 4, width: int = WIDTH,
         cut: bool = False) -> list[str]:
    """``head`` then ``text``, wrapped to ``width`` with continuation lines indented under
    the text; a list of items is joined by commas and broken between items only. ``cut``:
    a word longer than a line (a path) is cut, so that no line is wider than ``width``."""
    first = " " * indent + head
    keep = "\u00a0"  # a space that does not break
    if isinstance(text, list):
        text = ", ".join(t.replace(" ", keep) for t in text)
    lines = textwrap.wrap(text, width=width, initial_indent=first,
                          subsequent_indent=" " * len(first), break_on_hyphens=False,
                          break_long_words=cut) or [first.rstrip()]
    return [line.replace(keep, " ") for line in lines]


def _counted(values: Iterable[str], total: int) -> str:
    c = Counter(values)
    if not c:
        return ""
    if len(c) == 1:
        (name, n), = c.items()
        return name + (f" (at {n} of {total} states)" if n != total else "")
    return ", ".join(f"{name} at {n}" for name, n in c.most_common()) + f" of {total} states"


def solvers_used(run: RunData) -> dict[str, str]:
    """What solved the complete samples' states: ``{role: "inverse"}`` or ``{role: "literal
    at 3, inverse at 93 of 96 states"}`` for each role stored (``pull_method``,
    ``precision``, ``coupled_solver``); empty for files of earlier versions."""
    per = run.sample_attribute("solvers")
    states = [d for rows in per.values() for d in rows if isinstance(d, dict)]
    roles = sorted({k for d in states for k in d})
    return {r: _counted([d[r] for d in states if r in d], sum(r in d for d in states))
            for r in roles}


def completed(cfg: Mapping[str, Any]) -> dict[str, Any]:
    """A stored configuration with the keys it lacks (files of earlier versions, written
    before the keys existed) at today's defaults, which reproduce what those versions did
    (:data:`roughslip.run.digest.ADDED`)."""
    out: dict[str, Any] = {k: (dict(v) if isinstance(v, Mapping) else v)
                           for k, v in cfg.items()}
    for (section, key), value in defaults().items():
        if isinstance(out.get(section), dict) and value is not None:
            out[section].setdefault(key, value)
    return out


def _summary(registry: Any, name: Any) -> str:
    """A registry's one-line summary of ``name`` (the name alone if it has none)."""
    return registry.summary(name) if name in registry else str(name)


def model_lines(run: RunData) -> list[str]:
    """The resolved model, a line per part (surface, material, squeeze, pull, coupling,
    units), each within :data:`WIDTH` columns."""
    cfg = completed(run.config_dict())
    u = Units.of(cfg)
    a = run.attrs
    lines: list[str] = []
    for role in ("surface", "elastic_surface"):
        s = cfg.get(role)
        if not s:
            continue
        kind = s.get("kind")
        allowed = SURFACE_KEYS.get(kind, (set(), set()))[0]
        parts = []
        d = defaults()
        for k in (k for k in s if k in allowed and s[k] != d.get(("surface", k))):
            v = s[k]
            if k == "path":
                v = Path(str(v)).name
            dim = QUANTITY_KEYS["surface"].get(k, "")
            unit = u.of_dimension(dim) if dim else ""
            parts.append(f"{k} = {_short(v)}" + (f" {unit}" if unit else ""))
        lines += wrap(f"{role:<12}", [f"{kind}" + (": " + parts[0] if parts else ""),
                                      *parts[1:]])
    for role, read in _topography(a).items():
        lines += wrap(f"{'read':<12}", [f"{role}: {read.get('format')} "
                                        f"{show(read.get('file_shape'))}"]
                      + [f"{k.replace('_', ' ')} {show(read[k])}"
                         for k in ("file_unit", "file_pixel_size", "missing_points", "missing",
                                   "crop", "downsample", "tiles", "detrend")
                         if read.get(k) is not None])
    g = cfg.get("grid", {})
    shape = g.get("shape") or [g.get("n"), g.get("n")]
    if run.n_complete:  # file surfaces set the grid; the stored surface has its shape
        shape = list(run.surface(int(run.sample_index[run.complete][0])).shape)
    pixel = float(a.get("pixel_size", g.get("pixel_size", 1.0)))
    area = shape[0] * shape[1] * pixel**2 if shape[0] else float("nan")
    lu = u.of_dimension("length")
    lines += wrap(f"{'grid':<12}", f"{shape[0]} x {shape[1]} pixels of a = {pixel:g}"
                  + (f" {lu}" if lu else "") + f", {g.get('boundary')}; nominal area "
                  f"{area:.6g}" + (f" {u.of_dimension('area')}" if lu else ""))
    m = cfg.get("material", {})
    su = u.of_dimension("stress")
    lines += wrap(f"{'material':<12}", f"E = {_num(m.get('E'))}"
                  + (f" {su}" if su else " (sets the stress unit)") + f", nu = {m.get('nu')}")
    sq = cfg.get("squeeze", {})
    control = ("depths" if sq.get("depths") is not None else "loads")
    targets = sq.get("depths") if sq.get("depths") is not None else sq.get("forces", [])
    lines += wrap(f"{'squeeze':<12}", f"{sq.get('method')}, {len(targets)} {control} "
                  f"{_num(min(targets))} to {_num(max(targets))} {_axis_words(run)}, tol "
                  f"{_num(sq.get('tol'))}")
    used = solvers_used(run)
    pull = cfg.get("pull", {})
    if not pull.get("enabled"):
        lines += wrap(f"{'pull':<12}", "none (pull.enabled = false)")
    elif coupled(cfg):
        c = cfg.get("coupling", {})
        lines += wrap(f"{'pull':<12}", law_label(cfg) + f"; {_summary(LAWS, pull['slip_law'])}")
        lines += wrap(f"{'coupling':<12}", f"history {c.get('history')} ("
                      f"{_summary(HISTORIES, c.get('history'))}); the pull holds the "
                      f"{c.get('pull_control')}; sites that touch during the pull enter "
                      f"{c.get('gained')}; block solver "
                      + (used.get("coupled_solver") or "(not recorded)")
                      + " in double precision")
    else:
        method = pull.get("method", "auto")
        how = used.get("pull_method")
        lines += wrap(f"{'pull':<12}", law_label(cfg) + f"; {_summary(LAWS, pull['slip_law'])}")
        text = (f"{method}" + (f" -> {how}" if how and how != method else "")
                + f" ({_summary(METHODS, how if how in METHODS else method)})"
                + ("" if how else "; the method used is not recorded in this file"))
        # only the break law's inverse records its precision: every other solve is double
        text += (f"; {used.get('precision') or 'double'} precision (pull.precision = "
                 f"{pull.get('precision', 'auto')})" + ("" if how else " as asked"))
        lines += wrap(f"{'method':<12}", text)
        if cfg.get("coupling", {}).get("enabled"):
            lines += wrap(f"{'coupling':<12}", "asked for, but nu = 0.5: the coupling vanishes "
                          "and the decoupled model ran")
    lines += wrap(f"{'units':<12}", u.describe())
    return lines


def _topography(attrs: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """What was read and done for each file surface (the ``topography`` attribute)."""
    try:
        read = json.loads(attrs.get("topography") or "{}")
    except (ValueError, TypeError):
        return {}
    return {k: v for k, v in read.items() if isinstance(v, dict)} if isinstance(read, dict) \
        else {}


def _axis_words(run: RunData) -> str:
    """The unit of the run's depths or loads, in words."""
    unit = run.axis_unit
    u = units(run)
    return {"rms": "x the rms height", "range": "x the peak-to-valley height",
            "pressure": "x E* (mean pressure)"}.get(
        unit, u.of_dimension("length" if unit == "length" else "force")
        or "(dimensionless)")


def config_lines(run: RunData) -> list[str]:
    """Every key of the stored configuration that differs from the defaults, by section."""
    lines = []
    for section, table in nondefault(run.config_dict()).items():
        lines += wrap(f"[{section}] ", [f"{k} = {_short(v)}" for k, v in table.items()])
    return lines


_DEPTH = re.compile(r"^depth index (\d+): (.*)$", re.S)
_NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w.])")


def _ranges(values: Iterable[int]) -> str:
    """``0-3, 7`` of a set of integers."""
    v = sorted(set(values))
    out, i = [], 0
    while i < len(v):
        j = i
        while j + 1 < len(v) and v[j + 1] == v[j] + 1:
            j += 1
        out.append(str(v[i]) if i == j else f"{v[i]}-{v[j]}")
        i = j + 1
    return ", ".join(out)


def _fill(template: str, values: list[str]) -> str:
    """``template`` with its ``#`` replaced by ``values`` in order."""
    it = iter(values)
    return re.sub("#", lambda _m: next(it), template)


def notes(run: RunData) -> list[str]:
    """The run's notes: those of the run (stored at the root), then those of its samples, the
    same note at several samples and depths once, with where it was said and the range of
    its numbers where they differ ("0-12 bond(s) released at D_x = 0 (8 states: sample 0,
    depth indices 0-7)")."""
    try:
        root = [str(n) for n in json.loads(run.attrs.get("notes", "[]"))]
    except (ValueError, TypeError):
        root = []
    groups: dict[str, list[tuple[int, int | None, str]]] = {}
    for sample, said in sorted(run.sample_attribute("notes").items()):
        for n in said:
            if n in root:  # the run's notes are repeated in every sample
                continue
            m = _DEPTH.match(n)
            depth, text = (int(m.group(1)), m.group(2)) if m else (None, n)
            groups.setdefault(_NUMBER.sub("#", text), []).append((sample, depth, text))
    out = list(root)
    for template, items in groups.items():
        texts = [t for _, _, t in items]
        if len(set(texts)) == 1:
            text = texts[0]
        else:
            nums = [[float(x) for x in _NUMBER.findall(t)] for t in texts]
            spans = []
            for col in zip(*nums, strict=True):
                lo, hi = min(col), max(col)
                spans.append(f"{lo:g}" if lo == hi else f"{lo:g}-{hi:g}")
            text = _fill(template, spans)
        samples = {s for s, _, _ in items}
        depths = {d for _, d, _ in items if d is not None}
        where = (f"sample{'s' if len(samples) > 1 else ''} {_ranges(samples)}"
                 + (f", depth ind{'ices' if len(depths) > 1 else 'ex'} {_ranges(depths)}"
                    if depths else ""))
        out.append(f"{text} ({len(items)} state{'s' if len(items) > 1 else ''}: {where})"
                   if depths else f"{text} ({where})")
    return out
