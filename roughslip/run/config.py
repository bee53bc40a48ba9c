"""Run configuration: TOML schema as frozen dataclasses, validation, ``--set`` overrides.

A configuration is a TOML file with the sections below (every key optional unless marked).
:func:`load_config` reads it, deep-merges ``--set key=value`` overrides (values parsed as inline
TOML; a bare word is taken as a string), rejects unknown sections and keys, checks every value
and returns a frozen :class:`RunConfig`. Every error is a :class:`~roughslip.errors.ConfigError`
whose message names the file, the dotted key, the value and the rule, e.g.::

    run.toml: material.nu = 0.7: must satisfy -1 < nu <= 0.5

Units: lengths (pixel size, heights, depths, radii, wavelengths) share one unit of your choice;
``material.E`` sets the stress unit; forces are stress x length².
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import itertools
import math
import re
import tomllib
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from roughslip.contact.histories import HISTORIES
from roughslip.contact.laws import LAWS, LawParameterError
from roughslip.contact.pull import METHODS as PULL_METHODS
from roughslip.contact.pull import methods_for
from roughslip.contact.squeeze import METHODS as SQUEEZE_METHODS
from roughslip.errors import ConfigError
from roughslip.run import schema
from roughslip.surfaces.topography import LENGTH_UNITS

# --------------------------------------------------------------------------------------------
# Field helpers
# --------------------------------------------------------------------------------------------

Check = Callable[[Any], str | None]


def _f(default: Any = None, doc: str = "", check: Check | None = None, choices=None, **kw):
    meta = {"doc": doc, "check": check, "choices": tuple(choices) if choices else None}
    if isinstance(default, list | dict):
        return field(default_factory=lambda d=default: type(d)(d), metadata=meta, **kw)
    return field(default=default, metadata=meta, **kw)


def _ruled(text: str, check: Check) -> Check:
    """Attach the rule's wording (shown in the configuration reference) to a check."""
    check.rule = text  # type: ignore[attr-defined]
    return check


def _positive(v):
    return None if v > 0 else "must be > 0"


def _nonnegative(v):
    return None if v >= 0 else "must be >= 0"


def _at_least(n):
    return _ruled(f">= {n}", lambda v: None if v >= n else f"must be >= {n}")


def _nu_rule(v):
    return None if -1.0 < v <= 0.5 else "must satisfy -1 < nu <= 0.5"


def _hurst_rule(v):
    return None if 0.0 < v < 1.0 else "must be in (0, 1)"


def _tol_rule(v):
    return None if 0.0 < v < 1.0 else "must satisfy 0 < tol < 1"


def _pair(v):
    return None if len(v) == 2 else "must be a list of two numbers"


def _crop_rule(v):
    if len(v) != 4:
        return "must be [y0, y1, x0, x1]"
    y0, y1, x0, x1 = v
    if min(v) < 0 or not (y0 < y1 and x0 < x1):
        return "must satisfy 0 <= y0 < y1 and 0 <= x0 < x1"
    return None


for _check, _text in ((_positive, "> 0"), (_nonnegative, ">= 0"), (_nu_rule, "-1 < nu <= 0.5"),
                     (_hurst_rule, "0 < H < 1"), (_tol_rule, "0 < tol < 1"),
                     (_pair, "two values"), (_crop_rule, "0 <= y0 < y1, 0 <= x0 < x1")):
    _ruled(_text, _check)



# --------------------------------------------------------------------------------------------
# Sections
# --------------------------------------------------------------------------------------------

SURFACE_KINDS = ("self-affine", "sphere", "punch", "sinusoid", "plane", "file")

#: keys allowed (and, in the second set, required) for each surface kind
SURFACE_KEYS: dict[str, tuple[set[str], set[str]]] = {
    "self-affine": (
        {"hurst", "rms_height", "rms_slope", "rolloff_wavelength", "cutoff_wavelength",
         "oversample"},
        {"hurst"},
    ),
    "sphere": ({"radius", "center"}, {"radius"}),
    "punch": ({"radius", "center", "step"}, {"radius"}),
    "sinusoid": ({"amplitude", "wavelength", "direction", "phase"}, {"amplitude", "wavelength"}),
    "plane": ({"slope"}, set()),
    "file": ({"path", "key", "scale", "unit", "override_pixel_size", "missing", "detrend",
              "crop", "downsample", "tiles"}, {"path"}),
}

#: ``output.fields`` names: the grid fields of the schema, and "pull_curve" for the curve arrays
FIELD_NAMES = (*(f.name for f in schema.FIELDS if f.grid), *schema.FIELD_GROUPS)


@dataclass(frozen=True)
class GridConfig:
    """``[grid]``: the pixel grid (x, the pull direction, is the last array axis)."""

    n: int | None = _f(None, "grid side for a square n x n grid", _at_least(1))
    shape: list[int] | None = _f(
        None, "[ny, nx] for a rectangular grid",
        _ruled("two integers >= 1", lambda v: _pair(v) or
               (None if min(v) >= 1 else "both lengths must be >= 1")))
    pixel_size: float = _f(1.0, "pixel side a (length)", _positive)
    boundary: str = _f("open", "open: finite patch on a half-space; periodic: repeating grid",
                       choices=("open", "periodic"))
    periodic_kernel: str = _f("pixel", "periodic symbol: exact pixel images or continuous",
                              choices=("pixel", "continuous"))

    @property
    def resolved_shape(self) -> tuple[int, int] | None:
        """``(ny, nx)`` or None when the grid comes from a topography file."""
        if self.shape is not None:
            return int(self.shape[0]), int(self.shape[1])
        if self.n is not None:
            return int(self.n), int(self.n)
        return None


@dataclass(frozen=True)
class MaterialConfig:
    """``[material]``: the elastic half-space."""

    E: float = _f(1.0, "Young's modulus (stress unit)", _positive)
    nu: float = _f(0.3, "Poisson ratio", _nu_rule)


@dataclass(frozen=True)
class SurfaceConfig:
    """``[surface]`` / ``[elastic_surface]``: a topography.

    Heights protrude toward the other body: the rigid surface's toward the elastic body, the
    elastic body's own roughness toward the rigid surface (docs/theory/squeeze.rst#squeeze-problem).
    """

    kind: str = _f(None, "shape", choices=SURFACE_KINDS)
    # self-affine
    hurst: float | None = _f(None, "Hurst exponent H", _hurst_rule)
    rms_height: float | None = _f(None, "rms height (length)", _positive)
    rms_slope: float | None = _f(None, "rms slope", _positive)
    rolloff_wavelength: float | None = _f(None, "long-wavelength roll-off (length)", _positive)
    cutoff_wavelength: float | None = _f(None, "short-wavelength cut-off (length)", _positive)
    oversample: int = _f(1, "generate on an oversample-times larger periodic grid and crop",
                         _at_least(1))
    # sphere / punch
    radius: float | None = _f(None, "sphere or punch radius (length)", _positive)
    center: list[float] | None = _f(None, "[x, y] of the apex (length; default grid centre)",
                                    _pair)
    step: float | None = _f(None, "punch: height of the step at its edge (default grid size)",
                            _positive)
    # sinusoid
    amplitude: float | None = _f(None, "sinusoid amplitude (length)", _positive)
    wavelength: float | None = _f(None, "sinusoid wavelength (length)", _positive)
    direction: str = _f("x", "sinusoid varies along x or y", choices=("x", "y"))
    phase: float = _f(0.0, "sinusoid phase (radians); 0 puts a crest at x = 0")
    # plane
    slope: list[float] | None = _f(None, "[dh/dx, dh/dy]", _pair)
    # file
    path: str | None = _f(None, "topography file: .npy, .npz, .txt/.csv/.dat/.asc, .h5/.hdf5, "
                          "or an instrument format (with the topography extra)")
    key: str | None = _f(None, "array name in .npz, dataset path in HDF5, or channel name in "
                         "an instrument file (default: its only or default channel)")
    scale: float = _f(1.0, "factor applied to the heights read from the file", _positive)
    unit: str | None = _f(None, "length unit of a file that carries none (heights and pixel "
                          "size); a file with units is converted to units.length",
                          choices=LENGTH_UNITS)
    override_pixel_size: bool = _f(False, "use grid.pixel_size even where the file gives "
                                   "another pixel size")
    missing: str = _f("error", "missing (NaN or masked) points: error, interpolate (from the "
                      "neighbours) or void (a deep valley that never touches)",
                      choices=("error", "interpolate", "void"))
    detrend: str = _f("none", "remove the mean, a tilt (plane) or a curvature (quadric) fitted "
                      "to the heights, per tile", choices=("none", "mean", "tilt", "curvature"))
    crop: list[int] | None = _f(None, "[y0, y1, x0, x1]: keep rows y0..y1-1 and columns "
                                "x0..x1-1 of the file's grid", _crop_rule)
    downsample: int = _f(1, "average blocks of k x k pixels (after cropping)", _at_least(1))
    tiles: list[int] | None = _f(None, "[ny, nx]: cut the (cropped) scan into ny x nx tiles, "
                                 "one sample each (sample i is tile i, row-major)",
                                 _ruled("two integers >= 1", lambda v: _pair(v) or (
                                     None if min(v) >= 1 else "both counts must be >= 1")))

    @property
    def is_random(self) -> bool:
        """True for kinds that differ from sample to sample."""
        return self.kind == "self-affine"

    @property
    def n_tiles(self) -> int:
        """Samples a tiled file gives (1 without tiles)."""
        return self.tiles[0] * self.tiles[1] if self.tiles else 1


@dataclass(frozen=True)
class SqueezeConfig:
    """``[squeeze]``: the vertical squeeze (docs/theory/squeeze.rst#squeeze-problem)."""

    depths: list[float] | None = _f(
        None, "penetration depths D_z measured from first touch, or a table "
        "{start, stop, num, spacing = 'linear'|'log'}")
    forces: list[float] | None = _f(None, "total normal forces F_n (load control)")
    depth_unit: str = _f("length", "depths in length units, in multiples of the composite rms "
                         "height ('rms'), or as fractions of its peak-to-valley ('range')",
                         choices=("length", "rms", "range"))
    force_unit: str = _f("force", "forces as totals or as mean pressures in units of E*",
                         choices=("force", "pressure"))
    method: str = _f("pk", SQUEEZE_METHODS.describe(), choices=SQUEEZE_METHODS.names())
    tol: float = _f(1e-10, "dimensionless residual tolerance", _tol_rule)
    max_iter: int = _f(20000, "iteration limit", _at_least(1))
    warm_start: bool = _f(True, "start each depth from the previous depth's forces")


#: the slip laws' own parameters, each a key of ``[pull]``
LAW_PARAMS = tuple(sorted({k for name in LAWS for k in LAWS.get(name).params}))


@dataclass(frozen=True)
class PullConfig:
    """``[pull]``: horizontal pull and slip (docs/theory/pull.rst#break-law)."""

    enabled: bool = _f(False, "run the pull stage")
    lam: float = _f(0.2, "local friction coefficient lambda", _positive)
    slip_law: str = _f("break", LAWS.describe(), choices=LAWS.names())
    lam_dynamic: float | None = _f(None, "slip_law = 'slip-weakening': the residual "
                                   "coefficient lambda_d, 0 <= lam_dynamic <= lam", _nonnegative)
    slip_distance: float | None = _f(None, "slip_law = 'slip-weakening': the slip d_c "
                                     "(length) over which the strength falls from lam f_z "
                                     "to lam_dynamic f_z", _positive)
    method: str = _f("auto", PULL_METHODS.describe(), choices=PULL_METHODS.names())
    tol: float = _f(1e-10, "relative tolerance of the tangential solves", _tol_rule)
    batch_size: int = _f(16, "sites broken per solve by method = 'batch'", _at_least(1))
    error_estimate: bool = _f(False, "store pull_error_estimate, the estimated error of the "
                              "friction force: the pull's solves and the squeeze's normal "
                              "forces, each by one refinement step ('batch' has none); also "
                              "runs the Lanczos condition estimate of G_xx on the bonds")
    early_stop: bool = _f(True, "stop the break sequence once no later break can exceed the "
                          "peak (exact for the friction force); false records every break, "
                          "for the bursts after the peak")


@dataclass(frozen=True)
class CouplingConfig:
    """``[coupling]``: the coupled normal-tangential model (docs/theory/coupled.rst#coupled)."""

    enabled: bool = _f(False, "solve squeeze and pull with the full (z, x) block operator")
    pull_control: str = _f("depth", "what the pull holds: depth (D_z fixed, the report's "
                           "pull) or force (the normal force after the squeeze, as a dead "
                           "weight; D_z follows)", choices=("depth", "force"))
    gained: str = _f("unbonded", "how a site that comes into contact during the pull enters: "
                     "unbonded (the report's model: the bonds are the squeeze's contacts) or "
                     "bonded (a new bond, formed where the surfaces meet)",
                     choices=("unbonded", "bonded"))
    history: str = _f("bonded", "how the contacts come to carry their bonds before the pull: "
                      + HISTORIES.describe(), choices=HISTORIES.names())


@dataclass(frozen=True)
class EnsembleConfig:
    """``[ensemble]``: random samples."""

    samples: int = _f(1, "number of samples", _at_least(1))
    seed: int = _f(0, "root seed of numpy.random.SeedSequence", _nonnegative)
    first_sample: int = _f(0, "index of the first sample (to extend an ensemble)", _nonnegative)


@dataclass(frozen=True)
class OutputConfig:
    """``[output]``: what is stored per sample and depth."""

    fields: list[str] = _f(["contact", "fz"], f"per-depth fields to store, from {FIELD_NAMES}",
                           _ruled("names from the list, each once",
                                  lambda v: _fields_rule(v)))
    compression: str = _f("gzip", "HDF5 compression of fields", choices=("gzip", "lzf", "none"))
    compression_level: int = _f(4, "gzip level", _ruled("0..9", lambda v: None if 0 <= v <= 9
                                                         else "must be in 0..9"))


@dataclass(frozen=True)
class ExecutionConfig:
    """``[execution]``: how the work is run (never changes the numbers)."""

    workers: int = _f(1, "worker processes", _at_least(1))
    fft: str = _f("auto", "FFT backend", choices=("auto", "pyfftw", "scipy"))
    threads: int = _f(1, "FFT and BLAS threads per worker", _at_least(1))
    scheduler: str | None = _f(None, "Dask scheduler address (tcp://host:port)")
    strict: bool = _f(False, "a solve that misses its tolerance stops the run")
    memory_limit_gb: float | None = _f(None, "memory budget (default: available memory)",
                                       _positive)


@dataclass(frozen=True)
class UnitsConfig:
    """``[units]``: the run's length unit (stored in the provenance, used in labels)."""

    length: str | None = _f(None, "the length unit of the run: grid.pixel_size, heights, "
                            "depths and displacements are in it; files with units are "
                            "converted to it", choices=LENGTH_UNITS)


def _fields_rule(v: Sequence[str]) -> str | None:
    bad = [x for x in v if x not in FIELD_NAMES]
    if bad:
        return f"unknown field(s) {bad}; choose from {list(FIELD_NAMES)}"
    if len(set(v)) != len(v):
        return "lists a field twice"
    return None


SECTIONS: dict[str, type] = {
    "grid": GridConfig,
    "material": MaterialConfig,
    "surface": SurfaceConfig,
    "elastic_surface": SurfaceConfig,
    "squeeze": SqueezeConfig,
    "pull": PullConfig,
    "coupling": CouplingConfig,
    "ensemble": EnsembleConfig,
    "output": OutputConfig,
    "execution": ExecutionConfig,
    "units": UnitsConfig,
}
TOP_LEVEL_KEYS = ("title",)


@dataclass(frozen=True)
class RunConfig:
    """A validated run configuration (all sections resolved, defaults filled)."""

    grid: GridConfig
    material: MaterialConfig
    surface: SurfaceConfig
    squeeze: SqueezeConfig
    pull: PullConfig = field(default_factory=PullConfig)
    coupling: CouplingConfig = field(default_factory=CouplingConfig)
    ensemble: EnsembleConfig = field(default_factory=EnsembleConfig)
    output: OutputConfig = field(default_factory=OutputConfig)
    execution: ExecutionConfig = field(default_factory=ExecutionConfig)
    elastic_surface: SurfaceConfig | None = None
    units: UnitsConfig | None = None
    title: str | None = None
    source: str = field(default="<config>", compare=False)
    #: dotted keys the user gave (file and overrides), as opposed to defaults
    given: frozenset[str] = field(default=frozenset(), compare=False)
    #: retired keys the user gave (:data:`_RETIRED`): no effect, but part of older digests
    retired: dict[str, Any] = field(default_factory=dict, compare=False)

    @property
    def length_unit(self) -> str | None:
        """``units.length``, or None for bare numbers."""
        return None if self.units is None else self.units.length

    def to_dict(self) -> dict[str, Any]:
        """Nested plain dict of all set values (None values omitted), in section order."""
        out: dict[str, Any] = {}
        if self.title is not None:
            out["title"] = self.title
        for name in SECTIONS:
            sec = getattr(self, name)
            if sec is None:
                continue
            out[name] = {
                f.name: _plain(getattr(sec, f.name))
                for f in dataclasses.fields(sec)
                if getattr(sec, f.name) is not None and _relevant(name, sec, f.name)
            }
        return out

    def to_toml(self) -> str:
        """The resolved configuration as TOML text (round-trips through :func:`load_config`)."""
        return dumps_toml(self.to_dict())

    def digest(self, *, generation: int | None = None) -> str:
        """SHA-256 of everything that determines the numbers (execution settings excluded).

        ``generation``: the digest the same configuration had in an earlier version, so that
        runs started then can be resumed. Generation g lacks the keys added after it
        (:data:`_ADDED`, when at their default); 1 and 0: also before keys were retired
        (:data:`_RETIRED`, at their default or given value); 0: also before keys were renamed
        (:data:`_RENAMED`). The serialisation (:func:`_canonical`) is frozen:
        a digest must not change when a TOML writer's formatting does.
        """
        d = self.to_dict()
        d.pop("execution", None)
        d.pop("title", None)
        if generation is not None and generation <= 1:
            for (section, key), (default, before, _) in _RETIRED.items():
                if section in d:
                    value = self.retired.get(f"{section}.{key}", default)
                    items = list(d[section].items())
                    at = next((i for i, (k, _) in enumerate(items) if k == before), len(items))
                    items.insert(at, (key, value))
                    d[section] = dict(items)
        if generation is not None:
            for (section, key), (default, since) in _ADDED.items():
                if since > generation and d.get(section, {}).get(key, default) == default:
                    d.get(section, {}).pop(key, None)
        if generation is not None and generation <= 0:
            for (section, old), new in _RENAMED.items():
                if section in d and new in d[section]:
                    d[section] = {old if k == new else k: v for k, v in d[section].items()}
        return hashlib.sha256(_canonical(d).encode()).hexdigest()

    def matches(self, digest: str) -> bool:
        """Whether a stored digest is this configuration's (now or in an earlier version)."""
        return digest == self.digest() or any(digest == self.digest(generation=g)
                                              for g in _GENERATIONS)

    @property
    def shape(self) -> tuple[int, int] | None:
        """Grid shape ``(ny, nx)``, or None for a file surface that sets it."""
        return self.grid.resolved_shape

    @property
    def n_samples(self) -> int:
        """Samples actually run: one for a scene without randomness."""
        random = self.surface.is_random or (
            self.elastic_surface is not None and self.elastic_surface.is_random
        )
        tiles = max(self.surface.n_tiles, self.elastic_surface.n_tiles
                    if self.elastic_surface is not None else 1)
        if tiles > 1:
            return tiles
        return self.ensemble.samples if random else 1

    @property
    def control(self) -> str:
        """``"depth"`` (displacement control) or ``"force"`` (load control)."""
        return "force" if self.squeeze.forces is not None else "depth"

    @property
    def targets(self) -> tuple[float, ...]:
        """Depths or forces in increasing order, in the configured unit."""
        vals = self.squeeze.forces if self.control == "force" else self.squeeze.depths
        return tuple(float(v) for v in vals)


def _relevant(section: str, sec: Any, key: str) -> bool:
    """Hide surface keys that do not belong to the surface's kind."""
    if isinstance(sec, SurfaceConfig) and key != "kind":
        return key in SURFACE_KEYS[sec.kind][0]
    return True


def _plain(v: Any) -> Any:
    if isinstance(v, tuple):
        return list(v)
    return v


# --------------------------------------------------------------------------------------------
# TOML writing: tomli-w for text people read; a frozen canonical form for digests
# --------------------------------------------------------------------------------------------

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def dumps_toml(d: Mapping[str, Any]) -> str:
    """Write a configuration mapping as TOML (tomli-w)."""
    import tomli_w

    def plain(v: Any) -> Any:
        if isinstance(v, tuple):
            return [plain(x) for x in v]
        if isinstance(v, list):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        return v

    return tomli_w.dumps(plain(dict(d)))


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _toml_str(k)


def _toml_str(s: str) -> str:
    out = s.replace("\\", "\\\\").replace('"', '\\"')
    out = "".join(c if c.isprintable() else f"\\u{ord(c):04x}" for c in out)
    return f'"{out}"'


def _toml_value(v: Any) -> str:
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
        return _toml_str(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _canonical(d: Mapping[str, Any]) -> str:
    """The text a configuration digest hashes. Frozen: stored digests of every earlier run
    file were made with exactly this form, so it must not follow any library's formatting."""
    lines = [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in d.items() if not isinstance(v, dict)]
    for k, v in d.items():
        if isinstance(v, dict):
            if lines:
                lines.append("")
            lines.append(f"[{_toml_key(k)}]")
            lines.extend(f"{_toml_key(kk)} = {_toml_value(vv)}" for kk, vv in v.items())
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------------


class _Ctx:
    """Where values came from, for error messages."""

    def __init__(self, source: str, overridden: dict[str, str]):
        self.source = source
        self.overridden = overridden
        #: retired keys given, with their values (dotted key -> value)
        self.retired: dict[str, Any] = {}

    def fail(self, key: str, value: Any = dataclasses.MISSING, rule: str = "") -> ConfigError:
        where = self.source
        hit = self.overridden.get(key) or next(
            (t for k, t in self.overridden.items() if k.startswith(key + ".")), None)
        if hit is not None:
            where = f"{self.source} (--set {hit})"
        if value is dataclasses.MISSING:
            return ConfigError(f"{where}: {key}: {rule}")
        return ConfigError(f"{where}: {key} = {_show(value)}: {rule}")


def _show(v: Any) -> str:
    try:
        return _toml_value(v)
    except TypeError:
        return repr(v)


def parse_override(text: str) -> tuple[list[str], Any]:
    """Parse ``key.path=value``; the value is inline TOML, or a bare word taken as a string."""
    if "=" not in text:
        raise ConfigError(f"--set {text}: expected KEY=VALUE, e.g. surface.hurst=0.6")
    key, raw = text.split("=", 1)
    key = key.strip()
    raw = raw.strip()
    parts = key.split(".")
    if not key or any(not p or not _BARE_KEY.match(p) for p in parts):
        raise ConfigError(f"--set {text}: {key!r} is not a dotted key like surface.hurst")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError as exc:
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.\-/]*", raw):
            value = raw
        else:
            raise ConfigError(f"--set {text}: value is not valid TOML ({exc})") from None
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
                raise ConfigError(
                    f"--set {text}: {'.'.join(parts[: i + 1])} is a value, not a table"
                )
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
                data: Mapping[str, Any] | None = None) -> RunConfig:
    """Read, merge, validate.

    Parameters
    ----------
    path : path-like, optional
        TOML file. Relative ``surface.path`` values are resolved against its folder.
    overrides : sequence of str
        ``"key.path=value"`` strings, applied in order before validation.
    data : mapping, optional
        Use this dict instead of reading a file (``path`` then only names the source).

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
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{source}: invalid TOML: {exc}") from None
    data = _deepcopy(data)
    origin = merge_overrides(data, overrides)
    ctx = _Ctx(source, origin)
    base_dir = Path(path).resolve().parent if path is not None else Path.cwd()
    return _build(data, ctx, base_dir)


def _deepcopy(d: Any) -> Any:
    if isinstance(d, Mapping):
        return {k: _deepcopy(v) for k, v in d.items()}
    if isinstance(d, list):
        return [_deepcopy(v) for v in d]
    return d


def _suggest(key: str, known: Sequence[str]) -> str:
    lower = {k.lower(): k for k in known}
    close = difflib.get_close_matches(key.lower(), list(lower), n=1)
    if close:
        return f" (did you mean {lower[close[0]]!r}?)"
    return f" (known: {', '.join(known)})"


def _build(data: dict[str, Any], ctx: _Ctx, base_dir: Path) -> RunConfig:
    known = [*SECTIONS, *TOP_LEVEL_KEYS]
    for k, v in data.items():
        if k not in known:
            raise ctx.fail(k, rule="unknown section or key" + _suggest(k, known))
        if k in SECTIONS and not isinstance(v, dict):
            raise ctx.fail(k, v, "must be a table ([" + k + "])")
    title = data.get("title")
    if title is not None and not isinstance(title, str):
        raise ctx.fail("title", title, "must be a string")
    for required in ("surface",):
        if required not in data:
            raise ctx.fail(required, rule="missing section [" + required + "]")
    sections: dict[str, Any] = {}
    for name, cls in SECTIONS.items():
        if name not in data:
            continue
        sections[name] = _build_section(name, cls, data[name], ctx)
    sections.setdefault("grid", GridConfig())
    sections.setdefault("material", MaterialConfig())
    for name in ("pull", "coupling", "ensemble", "output", "execution"):
        sections.setdefault(name, SECTIONS[name]())
    for name in ("surface", "elastic_surface"):
        if name in sections:
            sections[name] = _check_surface(name, sections[name], data[name], ctx, base_dir)
    sections["squeeze"] = _check_squeeze(data.get("squeeze", {}), sections.get("squeeze"), ctx)
    given = frozenset(f"{sec}.{k}" for sec, t in data.items() if isinstance(t, dict)
                      for k in t)
    cfg = RunConfig(title=title, source=ctx.source, given=given, retired=dict(ctx.retired),
                    **sections)
    _check_cross(cfg, data, ctx)
    return cfg


def _type_name(tp: Any) -> str:
    return {float: "a number", int: "an integer", bool: "true or false", str: "a string"}.get(
        tp, str(tp))


def _coerce(value: Any, tp: Any, key: str, ctx: _Ctx) -> Any:
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

#: keys renamed since they were introduced: old (section, key) -> new key. The old spelling
#: is still read, so configs and run files written with it keep working.
_RENAMED = {("pull", "error_bound"): "error_estimate"}
#: keys added since the first run-file format: (section, key) -> (the default that reproduces
#: the former behaviour, the first digest generation that has the key). A configuration at
#: that default has the digest it had in earlier generations.
_ADDED = {("pull", "early_stop"): (True, 1),
          **{(role, k): (v, 1) for role in ("surface", "elastic_surface")
             for k, v in (("unit", None), ("override_pixel_size", False), ("missing", "error"),
                          ("detrend", "none"), ("crop", None), ("downsample", 1),
                          ("tiles", None))},
          ("coupling", "pull_control"): ("depth", 2), ("coupling", "gained"): ("unbonded", 2),
          ("coupling", "history"): ("bonded", 3)}
#: the digest generations a stored run may carry: 0 up to the newest key's (:meth:`matches`)
_GENERATIONS = range(max(since for _, since in _ADDED.values()) - 1, -1, -1)


#: keys that no longer do anything: (section, key) -> (default, the key before which it stood
#: in the resolved configuration, why). They are still accepted (and checked), so older
#: configurations load, and they enter the digest of the version that had them.
_RETIRED = {("pull", "coulomb_steps"): (32, "early_stop", "the Coulomb pull curve is exact, "
                                        "event by event")}


def _build_section(name: str, cls: type, table: dict[str, Any], ctx: _Ctx) -> Any:
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {}
    for k, v in table.items():
        k = _RENAMED.get((name, k), k)
        key = f"{name}.{k}"
        if (name, k) in _RETIRED:
            if isinstance(v, bool) or not isinstance(v, int) or v < 2:
                raise ctx.fail(key, v, "must be an integer >= 2 (the key has no effect: "
                               f"{_RETIRED[(name, k)][2]})")
            ctx.retired[key] = v
            continue
        if k in kwargs:
            raise ctx.fail(key, rule="given twice (once under its former name)")
        if k not in fields:
            raise ctx.fail(key, rule="unknown key" + _suggest(k, list(fields)))
        if (name, k) in _SPECIAL:
            kwargs[k] = v
            continue
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
    return cls(**kwargs)


def _check_surface(name: str, s: SurfaceConfig, table: dict[str, Any], ctx: _Ctx,
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
        if not p.is_file():
            raise ctx.fail(f"{name}.path", s.path, f"no such file ({p})")
        s = dataclasses.replace(s, path=str(p))
    return s


def _expand_range(table: dict[str, Any], key: str, ctx: _Ctx) -> list[float]:
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


def _check_squeeze(table: dict[str, Any], s: SqueezeConfig | None, ctx: _Ctx) -> SqueezeConfig:
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


def _check_cross(cfg: RunConfig, data: dict[str, Any], ctx: _Ctx) -> None:
    g = cfg.grid
    if g.n is not None and g.shape is not None:
        raise ctx.fail("grid.shape", g.shape, "give grid.n or grid.shape, not both")
    file_surface = cfg.surface.kind == "file" or (
        cfg.elastic_surface is not None and cfg.elastic_surface.kind == "file")
    if g.resolved_shape is None and not file_surface:
        raise ctx.fail("grid.n", rule="missing (give grid.n or grid.shape)")
    if cfg.squeeze.forces is not None and cfg.squeeze.depth_unit != "length":
        raise ctx.fail("squeeze.depth_unit", cfg.squeeze.depth_unit,
                       "applies to depths only; use squeeze.force_unit with forces")
    if cfg.coupling.enabled and not cfg.pull.enabled:
        raise ctx.fail("coupling.enabled", True, "needs pull.enabled = true")
    law = LAWS.get(cfg.pull.slip_law)
    if cfg.pull.enabled:  # the slip law's own parameters ([pull] keys named as the law's)
        given = {k: getattr(cfg.pull, k) for k in LAW_PARAMS}
        try:
            law.bind(cfg.pull.lam, **given)
        except LawParameterError as exc:
            key = f"pull.{exc.key}"
            raise (ctx.fail(key, rule=exc.rule) if exc.value is None
                   else ctx.fail(key, exc.value, exc.rule)) from None
    if cfg.coupling.enabled and not law.couples:
        raise ctx.fail("pull.slip_law", cfg.pull.slip_law,
                       "has no exact coupled model (its strength and f_z both vary, a "
                       "bilinear constraint); needs coupling.enabled = false")
    if cfg.pull.enabled and not cfg.coupling.enabled:
        if not LAWS.get(cfg.pull.slip_law).pull_runs:
            raise ctx.fail("pull.slip_law", cfg.pull.slip_law,
                           "has no decoupled pull method; needs coupling.enabled = true")
        laws = methods_for(cfg.pull.slip_law)
        if cfg.pull.method not in laws:
            raise ctx.fail("pull.method", cfg.pull.method,
                           f"slip_law = {cfg.pull.slip_law!r} needs one of {', '.join(laws)}")
    es = cfg.elastic_surface
    tiled = [r for r in ("surface", "elastic_surface") if getattr(cfg, r) is not None
             and getattr(cfg, r).kind == "file" and getattr(cfg, r).tiles]
    if tiled and cfg.ensemble.first_sample != 0:
        raise ctx.fail("ensemble.first_sample", cfg.ensemble.first_sample,
                       f"must be 0 with {tiled[0]}.tiles (sample i is tile i)")
    if (es is not None and cfg.surface.tiles and es.tiles
            and cfg.surface.n_tiles != es.n_tiles):
        raise ctx.fail("elastic_surface.tiles", es.tiles, f"must give as many tiles as "
                       f"surface.tiles ({cfg.surface.tiles})")
    pull_fields = {"fx", "ux", "stick", "pull_curve"} & set(cfg.output.fields)
    if pull_fields and not cfg.pull.enabled:
        raise ctx.fail("output.fields", cfg.output.fields,
                       f"{sorted(pull_fields)} need pull.enabled = true")
