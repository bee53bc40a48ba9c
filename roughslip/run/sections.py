"""The sections of a run configuration as frozen dataclasses, and :class:`RunConfig`, the
validated whole.

Each field carries its description, its check and its choices (:func:`~roughslip.run.rules.option`);
the loader (:mod:`roughslip.run.config`) checks values against them, and the configuration
reference in the documentation is generated from them. A key added to a section with a default
needs nothing else: configurations that leave it at the default keep their digest
(:mod:`roughslip.run.digest`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from roughslip.contact.squeeze import METHODS as SQUEEZE_METHODS
from roughslip.coupling.histories import HISTORIES
from roughslip.elastic.boundaries import BOUNDARIES
from roughslip.friction.bonds import TANGENTIAL_MODELS
from roughslip.friction.cone import FACETS, MAX_FACETS, MIN_FACETS
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import METHODS as PULL_METHODS
from roughslip.friction.pull import PRECISIONS as PULL_PRECISIONS
from roughslip.run import digest as digests
from roughslip.run import schema
from roughslip.run.rules import (
    at_least,
    crop_rule,
    hurst_rule,
    nonnegative,
    nu_rule,
    option,
    pair,
    positive,
    ruled,
    tol_rule,
)
from roughslip.run.tomlio import dumps_toml
from roughslip.run.units import STRESS
from roughslip.surfaces.topography import LENGTH_UNITS


def _finite(v: float) -> str | None:
    return None if math.isfinite(v) else "must be finite"


def _facets(v: int) -> str | None:
    if MIN_FACETS <= v <= MAX_FACETS:
        return None
    return f"must be an integer from {MIN_FACETS} to {MAX_FACETS}"


def _finite_positive(v: float) -> str | None:
    return None if math.isfinite(v) and v > 0 else "must be a finite number > 0"


SURFACE_KINDS = ("self-affine", "sphere", "punch", "sinusoid", "plane", "file")

#: keys allowed (and, in the second set, required) for each surface kind
SURFACE_KEYS: dict[str, tuple[set[str], set[str]]] = {
    "self-affine": (
        {"hurst", "rms_height", "rms_slope", "rolloff_wavelength", "cutoff_wavelength",
         "oversample", "anisotropy"},
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

    n: int | None = option(None, "grid side for a square n x n grid", at_least(1))
    shape: list[int] | None = option(
        None, "[ny, nx] for a rectangular grid",
        ruled("two integers >= 1", lambda v: pair(v) or
               (None if min(v) >= 1 else "both lengths must be >= 1")))
    pixel_size: float = option(1.0, "pixel side a (length)", positive, dimension="length")
    boundary: str = option("open", BOUNDARIES.describe(),
                       choices=BOUNDARIES)
    periodic_kernel: str = option("pixel", "periodic symbol: exact pixel images or continuous",
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

    E: float = option(1.0, "Young's modulus (in units.stress; without it, E sets the stress "
                       "unit)", positive, dimension="stress")
    nu: float = option(0.3, "Poisson ratio", nu_rule)


@dataclass(frozen=True)
class SurfaceConfig:
    """``[surface]`` / ``[elastic_surface]``: a topography.

    Heights protrude toward the other body: the rigid surface's toward the elastic body, the
    elastic body's own roughness toward the rigid surface (docs/theory/squeeze.rst#squeeze-problem).
    """

    kind: str = option(None, "shape", choices=SURFACE_KINDS)
    # self-affine
    hurst: float | None = option(None, "Hurst exponent H", hurst_rule)
    rms_height: float | None = option(None, "rms height (length)", positive, dimension="length")
    rms_slope: float | None = option(None, "rms slope", positive)
    rolloff_wavelength: float | None = option(None, "long-wavelength roll-off (length)", positive,
                                              dimension="length")
    cutoff_wavelength: float | None = option(None, "short-wavelength cut-off (length)", positive,
                                             dimension="length")
    oversample: int = option(1, "generate on an oversample-times larger periodic grid and crop",
                         at_least(1))
    anisotropy: float = option(1.0, "xi_y / xi_x, the ratio of the correlation lengths along y "
                               "and x: the isotropic surface stretched by it along y (ridges "
                               "along y when > 1); 1: isotropic",
                               ruled("a finite number > 0", _finite_positive))
    # sphere / punch
    radius: float | None = option(None, "sphere or punch radius (length)", positive,
                                  dimension="length")
    center: list[float] | None = option(None, "[x, y] of the apex (length; default grid centre)",
                                    pair, dimension="length")
    step: float | None = option(None, "punch: height of the step at its edge (default grid size)",
                            positive, dimension="length")
    # sinusoid
    amplitude: float | None = option(None, "sinusoid amplitude (length)", positive,
                                     dimension="length")
    wavelength: float | None = option(None, "sinusoid wavelength (length)", positive,
                                      dimension="length")
    direction: str = option("x", "sinusoid varies along x or y", choices=("x", "y"))
    phase: float = option(0.0, "sinusoid phase (radians); 0 puts a crest at x = 0")
    # plane
    slope: list[float] | None = option(None, "[dh/dx, dh/dy]", pair)
    # file
    path: str | None = option(None, "topography file: .npy, .npz, .txt/.csv/.dat/.asc, "
                          ".h5/.hdf5/.hdf, .x3p (ISO 25178-72, both revisions), or an "
                          "instrument format (with the topography extra)")
    key: str | None = option(None, "array name in .npz, dataset path in HDF5, layer number in "
                         ".x3p, or channel name in an instrument file (default: its only or "
                         "default channel, or layer 0)")
    scale: float = option(1.0, "factor applied to the heights read from the file", positive)
    unit: str | None = option(None, "length unit of a file that carries none (heights and pixel "
                          "size); a file with units is converted to units.length",
                          choices=LENGTH_UNITS)
    override_pixel_size: bool = option(False, "use grid.pixel_size even where the file gives "
                                   "another pixel size")
    missing: str = option("error", "missing (NaN or masked) points: error, interpolate (from the "
                      "neighbours) or void (a deep valley that never touches)",
                      choices=("error", "interpolate", "void"))
    detrend: str = option("none", "remove the mean, a tilt (plane) or a curvature (quadric) fitted "
                      "to the heights, per tile", choices=("none", "mean", "tilt", "curvature"))
    crop: list[int] | None = option(None, "[y0, y1, x0, x1]: keep rows y0..y1-1 and columns "
                                "x0..x1-1 of the file's grid", crop_rule)
    downsample: int = option(1, "average blocks of k x k pixels (after cropping)", at_least(1))
    tiles: list[int] | None = option(None, "[ny, nx]: cut the (cropped) scan into ny x nx tiles, "
                                 "one sample each (sample i is tile i, row-major)",
                                 ruled("two integers >= 1", lambda v: pair(v) or (
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

    depths: list[float] | None = option(
        None, "penetration depths D_z measured from first touch, or a table "
        "{start, stop, num, spacing = 'linear'|'log'}", dimension="length")
    forces: list[float] | None = option(None, "total normal forces F_n (load control)",
                                        dimension="force")
    depth_unit: str = option("length", "depths in length units, in multiples of the composite rms "
                         "height ('rms'), or as fractions of its peak-to-valley ('range')",
                         choices=("length", "rms", "range"))
    force_unit: str = option("force", "forces as totals or as mean pressures in units of E*",
                         choices=("force", "pressure"))
    method: str = option("pk", SQUEEZE_METHODS.describe(), choices=SQUEEZE_METHODS)
    tol: float = option(1e-10, "dimensionless residual tolerance", tol_rule)
    max_iter: int = option(20000, "iteration limit", at_least(1))
    warm_start: bool = option(True, "start each depth from the previous depth's forces")


#: the slip laws' own parameters, each a key of ``[pull]``
LAW_PARAMS = tuple(sorted({k for name in LAWS for k in LAWS.get(name).params}))


@dataclass(frozen=True)
class PullConfig:
    """``[pull]``: horizontal pull and slip (docs/theory/pull.rst#break-law)."""

    enabled: bool = option(False, "run the pull stage")
    lam: float = option(0.2, "local friction coefficient lambda", positive)
    slip_law: str = option("break", LAWS.describe(), choices=LAWS)
    lam_dynamic: float | None = option(None, "slip_law = 'slip-weakening': the residual "
                                   "coefficient lambda_d, 0 <= lam_dynamic <= lam", nonnegative)
    slip_distance: float | None = option(None, "slip_law = 'slip-weakening': the slip d_c "
                                     "(length) over which the strength falls from lam f_z "
                                     "to lam_dynamic f_z", positive, dimension="length")
    method: str = option("auto", PULL_METHODS.describe(), choices=PULL_METHODS)
    tol: float = option(1e-10, "relative tolerance of the tangential solves", tol_rule)
    batch_size: int = option(16, "sites broken per solve by method = 'batch'", at_least(1))
    error_estimate: bool = option(False, "store pull_error_estimate, the estimated error of the "
                              "friction force: the pull's solves and the squeeze's normal "
                              "forces, each by one refinement step ('batch' has none); also "
                              "runs the Lanczos condition estimate of G_xx on the bonds")
    early_stop: bool = option(True, "stop the pull once no later state can exceed the peak "
                          "(the break law and slip-weakening; exact for the friction "
                          "force); false records every event, for the bursts after the "
                          "peak")
    precision: str = option("auto", "the precision of the stored matrix of the inverse and "
                            "hierarchical methods: double, single (the break law; the Coulomb "
                            "law with components = 'x'. Half the memory, the same events and "
                            "friction force by certified decisions, the other curve points "
                            "within the bound the message reports) or auto (double when it "
                            "fits in memory, else single)", choices=PULL_PRECISIONS)
    components: str = option("x", "the tangential model: x (the report's: f_x alone, u_y free; "
                             "xy when pull.direction is set and this is not) or xy (the "
                             "traction vector (f_x, f_y), sticking both ways, pulled at "
                             "pull.direction; decoupled: every law at nu = 0, the break law on "
                             "methods inverse and hierarchical and the Coulomb cone on method "
                             "inverse at nu > 0; coupled: the Coulomb cone, history indent)",
                             choices=tuple(TANGENTIAL_MODELS))
    direction: float = option(0.0, "the drive's angle in the surface plane, degrees from x "
                              "toward y; 0 with components = 'x', which pulls along x alone",
                              ruled("a finite angle in degrees", _finite))
    facets: int = option(FACETS, "slip_law = 'coulomb' with components = 'xy' at nu > 0: the "
                         "facets of the polygon inscribed in the cone |f_t| <= lam f_z, a "
                         "vertex on the drive; its strength is the cone's within "
                         "1 - cos(pi/facets) in every direction",
                         ruled(f"an integer from {MIN_FACETS} to {MAX_FACETS}", _facets))


@dataclass(frozen=True)
class CouplingConfig:
    """``[coupling]``: the coupled normal-tangential model (docs/theory/coupled.rst#coupled)."""

    enabled: bool = option(False, "solve squeeze and pull with the full (z, x) block operator")
    pull_control: str = option("depth", "what the pull holds: depth (D_z fixed, the report's "
                           "pull) or force (the normal force after the squeeze, as a dead "
                           "weight; D_z follows)", choices=("depth", "force"))
    gained: str = option("unbonded", "how a site that comes into contact during the pull enters: "
                     "unbonded (the report's model: the bonds are the squeeze's contacts) or "
                     "bonded (a new bond, formed where the surfaces meet)",
                     choices=("unbonded", "bonded"))
    history: str = option("bonded", "how the contacts come to carry their bonds before the pull: "
                      + HISTORIES.describe(), choices=HISTORIES)


@dataclass(frozen=True)
class EnsembleConfig:
    """``[ensemble]``: random samples."""

    samples: int = option(1, "number of samples", at_least(1))
    seed: int = option(0, "root seed of numpy.random.SeedSequence", nonnegative)
    first_sample: int = option(0, "index of the first sample (to extend an ensemble)", nonnegative)


@dataclass(frozen=True)
class OutputConfig:
    """``[output]``: what is stored per sample and depth."""

    fields: list[str] = option(["contact", "fz"], f"per-depth fields to store, from {FIELD_NAMES}",
                           ruled("names from the list, each once",
                                  lambda v: _fields_rule(v)))
    compression: str = option("gzip", "HDF5 compression of fields", choices=("gzip", "lzf", "none"))
    compression_level: int = option(4, "gzip level", ruled("0..9", lambda v: None if 0 <= v <= 9
                                                         else "must be in 0..9"))


@dataclass(frozen=True)
class ExecutionConfig:
    """``[execution]``: how the work is run (never changes the numbers)."""

    workers: int = option(1, "worker processes", at_least(1))
    fft: str = option("auto", "FFT backend", choices=("auto", "pyfftw", "scipy"))
    threads: int = option(1, "FFT and BLAS threads per worker", at_least(1))
    scheduler: str | None = option(None, "Dask scheduler address (tcp://host:port)")
    strict: bool = option(False, "a solve that misses its tolerance stops the run")
    memory_limit_gb: float | None = option(None, "memory budget (default: available memory)",
                                       positive)


@dataclass(frozen=True)
class UnitsConfig:
    """``[units]``: the run's length and stress units (stored, named in every result)."""

    length: str | None = option(None, "the length unit of the run: grid.pixel_size, heights, "
                            "depths and displacements are in it; files with units are "
                            "converted to it. Set by the first length given with a unit "
                            "(pixel_size = '0.5 um') when not given", choices=LENGTH_UNITS)
    stress: str | None = option(None, "the stress unit of the run: material.E is in it, and "
                                "forces are in stress x length^2 (MPa x um^2 = uN). Set by E "
                                "given with a unit (E = '70 GPa') when not given",
                                choices=STRESS)


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

#: the keys that may be quantities with units: ``{section: {key: dimension}}``
QUANTITY_KEYS: dict[str, dict[str, str]] = {
    name: {f.name: f.metadata["dimension"] for f in dataclasses.fields(cls)
           if f.metadata.get("dimension")} for name, cls in SECTIONS.items()}


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
    #: retired keys the user gave (:data:`roughslip.run.digest.RETIRED`): no effect, but
    #: part of older digests
    retired: dict[str, Any] = field(default_factory=dict, compare=False)
    #: the machine file whose execution settings lie beneath the file's (None: none)
    machine: str | None = field(default=None, compare=False)
    #: the values given as quantities with units, converted: dotted key -> the text given
    quantities: dict[str, str] = field(default_factory=dict, compare=False)

    @property
    def length_unit(self) -> str | None:
        """``units.length``, or None for bare numbers."""
        return None if self.units is None else self.units.length

    @property
    def stress_unit(self) -> str | None:
        """``units.stress``, or None when E sets the stress unit."""
        return None if self.units is None else self.units.stress

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
        """The resolved configuration as TOML text (round-trips through
        :func:`~roughslip.run.config.load_config`)."""
        return dumps_toml(self.to_dict())

    def _digest_input(self) -> dict[str, Any]:
        d = self.to_dict()
        d.pop("execution", None)
        d.pop("title", None)
        return d

    @functools.cached_property
    def _digest(self) -> str:
        return digests.digest(self._digest_input(), defaults())

    def digest(self) -> str:
        """SHA-256 of everything that determines the numbers (execution settings and title
        excluded): of the values that differ from the defaults of this version
        (:mod:`roughslip.run.digest`). Computed once."""
        return self._digest

    @functools.cached_property
    def _legacy(self) -> tuple[str, ...]:
        return digests.legacy_digests(self._digest_input(), defaults(), self.retired)

    def matches(self, digest: str, defaults_version: int | None = None) -> bool:
        """Whether a stored digest is this configuration's.

        ``defaults_version``: the version of the defaults the digest was made under (stored
        with it); None for files written before versioned defaults, whose digests are those
        of the legacy generations (:func:`roughslip.run.digest.legacy_digests`).
        """
        if defaults_version is None:
            return digest in self._legacy
        if defaults_version == digests.DEFAULTS_VERSION:
            return digest == self._digest
        if not 1 <= defaults_version < digests.DEFAULTS_VERSION:
            return False  # written by a newer version
        return digest == digests.digest(self._digest_input(), defaults(), defaults_version)

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


def _default(f: dataclasses.Field) -> Any:
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return f.default


def defaults() -> dict[tuple[str, str], Any]:
    """Today's defaults, read from the sections: ``(section, key) -> default``."""
    return {(name, f.name): _default(f) for name, cls in SECTIONS.items()
            for f in dataclasses.fields(cls)}
