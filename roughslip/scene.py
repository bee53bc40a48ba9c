"""A scene: what one run simulates, resolved from a configuration.

A :class:`Scene` knows the grid, the material, the surfaces of every sample, the depths (or
forces) in absolute units, and which stages and kernels the run needs: the squeeze always
needs ``G_zz``; the pull adds ``G_xx``; only the coupled model builds ``G_zx``, and not at
``nu = 0.5`` where it vanishes. Fixed shapes (sphere, punch, sinusoid, plane, file) run one
sample whatever ``ensemble.samples`` says.

Randomness: sample ``i`` of a run with seed ``s`` draws its rigid surface from
``SeedSequence(s, spawn_key=(i,))`` (child ``i`` of ``SeedSequence(s).spawn``) and the elastic
body's own roughness from ``SeedSequence(s, spawn_key=(i, 1))``: the same numbers whatever the
number of workers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import surfaces as S
from .config import RunConfig, SurfaceConfig
from .errors import InputError
from .operators import Grid, Material


@dataclass(frozen=True)
class SampleSurfaces:
    """The topographies of one sample."""

    rigid: np.ndarray
    elastic: np.ndarray | None
    composite: np.ndarray  # rigid + elastic: what the contact problem sees (MODEL §1)


@dataclass(frozen=True)
class Scene:
    """Everything a run needs to know about what it simulates (see module docstring)."""

    config: RunConfig
    grid: Grid
    material: Material
    fixed: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    notes: tuple[str, ...] = ()

    @classmethod
    def from_config(cls, cfg: RunConfig) -> Scene:
        """Resolve a configuration: load topography files, fix the grid shape, collect notes.

        Raises :class:`InputError` naming the file for unreadable or invalid topographies, and
        for grid shapes that disagree between the config and the files.
        """
        fixed: dict[str, np.ndarray] = {}
        shape = cfg.shape
        for role in ("surface", "elastic_surface"):
            sc: SurfaceConfig | None = getattr(cfg, role)
            if sc is None or sc.kind != "file":
                continue
            h = S.load_topography(sc.path, sc.key, sc.scale)
            if shape is not None and h.shape != shape:
                raise InputError(
                    f"{sc.path}: heights have shape {list(h.shape)} but the grid is "
                    f"{list(shape)} (set grid.shape to match, or leave grid.n/grid.shape out)"
                )
            shape = h.shape
            fixed[role] = h
        assert shape is not None  # guaranteed by config validation
        g = cfg.grid
        grid = Grid(shape, g.pixel_size, g.boundary, g.periodic_kernel)
        material = Material(cfg.material.E, cfg.material.nu)
        for role in ("surface", "elastic_surface"):
            sc = getattr(cfg, role)
            if sc is not None and not sc.is_random and role not in fixed:
                fixed[role] = _analytic(sc, grid, f"[{role}]")
        notes = []
        if cfg.n_samples == 1 and cfg.ensemble.samples > 1:
            notes.append(
                f"fixed shapes only: running 1 sample (ensemble.samples = "
                f"{cfg.ensemble.samples} would repeat identical work)"
            )
        if cfg.coupling.enabled and material.nu == 0.5:
            notes.append("nu = 0.5: the normal-tangential coupling G_zx vanishes; using the "
                         "decoupled model")
        return cls(cfg, grid, material, fixed, tuple(notes))

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
    def components(self) -> tuple[str, ...]:
        """Green function components the run builds."""
        if self.coupled:
            return ("zz", "zx", "xx")
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
        return SampleSurfaces(rigid, elastic, composite)

    def _one(self, sc: SurfaceConfig, role: str, sample: int, key: tuple[int, ...]
             ) -> np.ndarray:
        if role in self.fixed:
            return self.fixed[role]
        rng = np.random.default_rng(np.random.SeedSequence(self.config.ensemble.seed,
                                                           spawn_key=key))
        return S.self_affine(
            self.grid.shape, hurst=sc.hurst, rng=rng, a=self.grid.a, rms_height=sc.rms_height,
            rms_slope=sc.rms_slope, rolloff_wavelength=sc.rolloff_wavelength,
            cutoff_wavelength=sc.cutoff_wavelength, oversample=sc.oversample,
        )

    def targets(self, composite: np.ndarray) -> np.ndarray:
        """Depths (length) or total forces of a sample, in increasing order.

        ``depth_unit = "rms"`` multiplies by the composite rms height, ``"range"`` by its
        peak-to-valley; ``force_unit = "pressure"`` multiplies by ``E*`` times the nominal area.
        """
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
    raise InputError(f"{where}: kind {sc.kind!r} is not an analytic shape")
