"""A scene: what one run simulates, resolved from a configuration.

A :class:`Scene` knows the grid, the material, the surfaces of every sample, the depths (or
forces) in absolute units, and which stages and kernels the run needs: the squeeze always
needs ``G_zz``; the pull adds ``G_xx``; only the coupled model builds ``G_zx``, and not at
``nu = 0.5`` where it vanishes. Fixed shapes (sphere, punch, sinusoid, plane, file) run one
sample whatever ``ensemble.samples`` says.

Measured topographies (``kind = "file"``) are read and prepared by
:mod:`roughslip.surfaces.topography`: units, pixel size, missing points, crop,
down-sampling, detrending and tiles; with tiles, sample ``i`` is tile ``i``. Missing points
kept as voids are NaN in the stored surfaces; the solvers see them far below every other
point (so they never touch, and a solve in which one did is an error).

Randomness: sample ``i`` of a run with seed ``s`` draws its rigid surface from
``SeedSequence(s, spawn_key=(i,))`` (child ``i`` of ``SeedSequence(s).spawn``) and the elastic
body's own roughness from ``SeedSequence(s, spawn_key=(i, 1))``: the same numbers whatever the
number of workers.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from roughslip.coupling.coupled import COUPLED_TOL
from roughslip.elastic.operators import Grid, Material
from roughslip.errors import InputError, MemoryLimitError
from roughslip.run import schema
from roughslip.run.digest import DEFAULTS_VERSION
from roughslip.run.sections import RunConfig, SurfaceConfig
from roughslip.run.store import Layout
from roughslip.surfaces import synthetic as S
from roughslip.surfaces.topography import Preparation


@dataclass(frozen=True)
class SampleSurfaces:
    """The topographies of one sample."""

    rigid: np.ndarray  # NaN at voids
    elastic: np.ndarray | None
    # rigid + elastic: what the contact problem sees (docs/theory/squeeze.rst#squeeze-problem),
    # voids filled with a depth no contact reaches
    composite: np.ndarray
    valid: np.ndarray | None = None  # False at voids; None: no voids


@dataclass(frozen=True)
class Scene:
    """Everything a run needs to know about what it simulates (see module docstring)."""

    config: RunConfig
    grid: Grid
    material: Material
    fixed: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    notes: tuple[str, ...] = ()
    tiles: dict[str, list[np.ndarray]] = field(default_factory=dict, repr=False)
    #: what was read and done per file surface (stored in the run file's provenance)
    topography: dict[str, dict] = field(default_factory=dict)

    @classmethod
    def from_config(cls, cfg: RunConfig) -> Scene:
        """Resolve a configuration: load topography files, fix the grid shape, collect notes.

        Raises :class:`InputError` naming the file for unreadable or invalid topographies, and
        for grid shapes that disagree between the config and the files.
        """
        from roughslip.surfaces.topography import prepare, read_raw

        fixed: dict[str, np.ndarray] = {}
        tiles: dict[str, list[np.ndarray]] = {}
        provenance: dict[str, dict] = {}
        file_notes: list[str] = []
        shape = cfg.shape
        a = cfg.grid.pixel_size
        a_given = "grid.pixel_size" in cfg.given
        a_from: str | None = None
        for role in ("surface", "elastic_surface"):
            sc: SurfaceConfig | None = getattr(cfg, role)
            if sc is None or sc.kind != "file":
                continue
            prep = prepare(read_raw(sc.path, sc.key), _preparation(sc, role, cfg, a_given))
            h = prep.tiles[0]
            if shape is not None and h.shape != shape:
                what = "tiles have" if len(prep.tiles) > 1 else "heights have"
                raise InputError(
                    f"{sc.path}: {what} shape {list(h.shape)} but the grid is "
                    f"{list(shape)} (set grid.shape to match, or leave grid.n/grid.shape out)"
                )
            shape = h.shape
            if a_from is not None and not np.isclose(prep.pixel_size, a, rtol=1e-9):
                raise InputError(f"{sc.path}: pixel size {prep.pixel_size:.10g} differs "
                                 f"from that of {a_from} ({a:.10g})")
            a, a_from = prep.pixel_size, sc.path
            tiles[role] = prep.tiles
            fixed[role] = prep.tiles[0]
            provenance[role] = prep.provenance
            file_notes += prep.notes
        assert shape is not None  # guaranteed by config validation
        g = cfg.grid
        grid = Grid(shape, a, g.boundary, g.periodic_kernel)
        material = Material(cfg.material.E, cfg.material.nu)
        for role in ("surface", "elastic_surface"):
            sc = getattr(cfg, role)
            if sc is not None and not sc.is_random and role not in fixed:
                fixed[role] = _analytic(sc, grid, f"[{role}]")
        notes = list(file_notes)
        n_tiles = max((len(t) for t in tiles.values()), default=1)
        if n_tiles > 1:
            notes.append(f"tiles: running {n_tiles} samples, sample i is tile i "
                         "(ensemble.samples is not used)")
        elif cfg.n_samples == 1 and cfg.ensemble.samples > 1:
            notes.append(
                f"fixed shapes only: running 1 sample (ensemble.samples = "
                f"{cfg.ensemble.samples} would repeat identical work)"
            )
        if cfg.coupling.enabled and material.nu == 0.5:
            notes.append("nu = 0.5: the normal-tangential coupling G_zx vanishes; using the "
                         "decoupled model")
        elif cfg.coupling.enabled:
            notes += _unused_under_coupling(cfg)
        return cls(cfg, grid, material, fixed, tuple(notes), tiles, provenance)

    # -- what the run needs ---------------------------------------------------------------------
    @property
    def n_samples(self) -> int:
        """Samples to run (1 for scenes without randomness)."""
        return self.config.n_samples

    @property
    def sample_indices(self) -> list[int]:
        """Global sample indices: ``first_sample .. first_sample + n_samples - 1``."""
        first = self.config.ensemble.first_sample
        return list(range(first, first + self.n_samples))

    @property
    def pull(self) -> bool:
        """Whether the pull stage runs."""
        return self.config.pull.enabled

    @property
    def coupled(self) -> bool:
        """Whether the coupled model runs (enabled, and nu < 0.5 where G_zx is nonzero)."""
        return self.config.coupling.enabled and self.material.coupled

    @property
    def stages(self) -> tuple[str, ...]:
        """The stages whose columns the run stores (:func:`roughslip.run.schema.stages`): the
        coupled model's column whenever it is asked for, also at nu = 1/2."""
        return schema.stages(self.pull, self.config.coupling.enabled,
                             self.config.pull.components != "x")

    @property
    def columns(self) -> tuple[schema.Column, ...]:
        """The scalar columns of the run."""
        return schema.columns(self.stages)

    @property
    def n_targets(self) -> int:
        """Depths or loads per sample."""
        return len(self.config.targets)

    def layout(self) -> Layout:
        """What the run file's writer needs (:class:`roughslip.run.store.Layout`)."""
        cfg = self.config
        out = cfg.output
        comp = {"none": {}, "lzf": {"compression": "lzf"},
                "gzip": {"compression": "gzip", "compression_opts": out.compression_level}
                }[out.compression]
        return Layout(config_text=cfg.to_toml(), digest=cfg.digest(),
                      defaults_version=DEFAULTS_VERSION, matches=cfg.matches,
                      control=cfg.control, axis=np.asarray(cfg.targets, dtype=float),
                      axis_unit=(cfg.squeeze.depth_unit if cfg.control == "depth"
                                 else cfg.squeeze.force_unit),
                      columns=self.columns, compression=comp)

    @property
    def components(self) -> tuple[str, ...]:
        """Green function components the run builds, with those of both tangential directions
        for the traction vector (``pull.components = "xy"``) at nu > 0."""
        if self.coupled:
            return (("zz", "zx", "xx") if self.config.pull.components == "x"
                    else ("zz", "zx", "zy", "xx", "xy", "yy"))
        if self.pull and self.config.pull.components != "x" and self.material.nu != 0:
            return ("zz", "xx", "xy", "yy")
        return ("zz", "xx") if self.pull else ("zz",)

    # -- per sample -----------------------------------------------------------------------------
    def surfaces(self, sample: int) -> SampleSurfaces:
        """The rigid surface, the elastic body's roughness and their composite for a sample."""
        cfg = self.config
        rigid = self._one(cfg.surface, "surface", sample, (sample,))
        elastic = None
        if cfg.elastic_surface is not None:
            elastic = self._one(cfg.elastic_surface, "elastic_surface", sample, (sample, 1))
        composite = rigid if elastic is None else rigid + elastic
        valid = np.isfinite(composite)
        if valid.all():
            return SampleSurfaces(rigid, elastic, composite)
        # voids: far below anything a contact at these depths (or loads) can reach
        ok = composite[valid]
        span = float(ok.max() - ok.min())
        reach = span
        if self.config.control == "depth":
            reach += float(self.targets(composite, valid).max())
        filled = np.where(valid, composite, float(ok.min()) - 100.0 * reach - 1.0)
        return SampleSurfaces(rigid, elastic, filled, valid)

    def _one(self, sc: SurfaceConfig, role: str, sample: int, key: tuple[int, ...]
             ) -> np.ndarray:
        if role in self.tiles:
            tiles = self.tiles[role]
            if len(tiles) == 1:
                return tiles[0]
            if not 0 <= sample < len(tiles):
                raise InputError(f"sample {sample}: there are {len(tiles)} tiles (0.."
                                 f"{len(tiles) - 1})")
            return tiles[sample]
        if role in self.fixed:
            return self.fixed[role]
        rng = np.random.default_rng(np.random.SeedSequence(self.config.ensemble.seed,
                                                           spawn_key=key))
        return S.self_affine(
            self.grid.shape, hurst=sc.hurst, rng=rng, a=self.grid.a, rms_height=sc.rms_height,
            rms_slope=sc.rms_slope, rolloff_wavelength=sc.rolloff_wavelength,
            cutoff_wavelength=sc.cutoff_wavelength, oversample=sc.oversample,
            anisotropy=sc.anisotropy,
        )

    def targets(self, composite: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
        """Depths (length) or total forces of a sample, in increasing order.

        ``depth_unit = "rms"`` multiplies by the composite rms height, ``"range"`` by its
        peak-to-valley (both over the ``valid`` points: voids excluded); ``force_unit =
        "pressure"`` multiplies by ``E*`` times the nominal area.
        """
        if valid is not None:
            composite = composite[valid]
        sq = self.config.squeeze
        vals = np.asarray(self.config.targets, dtype=float)
        if self.config.control == "force":
            if sq.force_unit == "pressure":
                vals = vals * self.material.E_star * self.grid.area
            return vals
        if sq.depth_unit == "rms":
            vals = vals * S.rms_height_of(composite)
        elif sq.depth_unit == "range":
            vals = vals * float(composite.max() - composite.min())
        return vals


def _preparation(sc: SurfaceConfig, role: str, cfg: RunConfig, pixel_given: bool
                 ) -> Preparation:
    """The preparation of a file surface, its parameters named by their configuration keys."""
    keys = ("unit", "scale", "override_pixel_size", "missing", "detrend", "crop", "downsample",
            "tiles")
    names = {k: f"{role}.{k}" for k in keys}
    names.update(run_unit="units.length", pixel_size="grid.pixel_size")
    return Preparation(**{k: getattr(sc, k) for k in keys}, run_unit=cfg.length_unit,
                       pixel_size=cfg.grid.pixel_size, pixel_given=pixel_given, names=names)


def _analytic(sc: SurfaceConfig, grid: Grid, where: str) -> np.ndarray:
    shape, a = grid.shape, grid.a
    try:
        if sc.kind == "sphere":
            return S.sphere(shape, radius=sc.radius, a=a, center=sc.center)
        if sc.kind == "punch":
            return S.punch(shape, radius=sc.radius, a=a, center=sc.center, step=sc.step)
        if sc.kind == "sinusoid":
            return S.sinusoid(shape, amplitude=sc.amplitude, wavelength=sc.wavelength, a=a,
                              direction=sc.direction, phase=sc.phase)
        if sc.kind == "plane":
            return S.plane(shape, a=a, slope=sc.slope or (0.0, 0.0))
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    except MemoryError:  # a grid far too large, e.g. for a cluster run checked on its nodes
        raise MemoryLimitError(f"{where}: a {shape[0]} x {shape[1]} {sc.kind} "
                               f"({8 * grid.size / 2**30:.3g} GiB of heights) does not fit in "
                               "this machine's memory (grid.n or grid.shape)") from None
    raise InputError(f"{where}: kind {sc.kind!r} is not an analytic shape")


#: keys the coupled model does not read: it solves the squeeze and the pull with its own block
#: solver and event tracking (docs/theory/coupled.rst), from a Polonsky-Keer contact at 1e-8
_COUPLED_IGNORES = {"squeeze": ("tol", "max_iter", "warm_start"),
                    "pull": ("method", "batch_size", "error_estimate", "early_stop")}

def _unused_under_coupling(cfg: RunConfig) -> list[str]:
    """One note per configured key that the coupled model does not honour (a key left at its
    default says nothing)."""
    notes = []
    for section, keys in _COUPLED_IGNORES.items():
        sec = getattr(cfg, section)
        defaults = {f.name: f.default for f in fields(sec)}
        for key in keys:
            value = getattr(sec, key)
            if value != defaults[key]:
                notes.append(f"coupling: {section}.{key} = {value!r} is not used by the coupled "
                             "model (it solves the squeeze and the pull with its own block "
                             "solver)")
    if cfg.pull.tol > COUPLED_TOL:
        notes.append(f"coupling: pull.tol = {cfg.pull.tol!r} is tightened to {COUPLED_TOL:g}, "
                     "the coupled model's largest tolerance")
    return notes
