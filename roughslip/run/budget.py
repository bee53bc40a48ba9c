"""The memory budget of a run, checked before anything is built: what one worker needs, which
key sets the grid's size, and what would fit.

:func:`check_budget` refuses a run whose estimated peak memory
(:func:`estimate_memory`, per worker) times the number of workers
exceeds the budget (:func:`roughslip.linalg.memory.available_bytes` under
``execution.memory_limit_gb``). Its one line names the key that sets the size (``grid.n``,
``grid.shape``, or the topography file and ``surface.downsample``) and gives a hint that
holds: fewer workers only when one worker fits, else the largest size that fits, and the
memory budget's own setting when that, not the machine, is the limit. The command line checks
a grid the configuration sets before any file is read or surface is made (a 100000 x 100000
surface alone is 75 GiB).
"""

from __future__ import annotations

import os
from collections.abc import Callable

from roughslip.elastic.operators import ElasticOperator, Grid, Material
from roughslip.errors import MemoryLimitError
from roughslip.linalg import memory
from roughslip.run.scene import Scene
from roughslip.run.sections import RunConfig
from roughslip.surfaces.limits import MIN_SCAN_SIDE

#: the environment variable that caps the memory budget (:mod:`roughslip.linalg.memory`)
MEMORY_ENV = "ROUGHSLIP_MEMORY_LIMIT_GB"


def _gib(n: float) -> str:
    v = n / 2**30
    return f"{v:.0f} GiB" if v >= 100 else f"{v:.3g} GiB"


def _per_worker(config: RunConfig) -> Callable[[tuple[int, int]], int]:
    """Bytes one worker of ``config`` needs on a grid of a given shape."""
    material = Material(config.material.E, config.material.nu)

    def need(shape: tuple[int, int]) -> int:
        grid = Grid(shape, config.grid.pixel_size, config.grid.boundary,
                    config.grid.periodic_kernel)
        return estimate_memory(Scene(config, grid, material))

    return need


def estimate_memory(scene: Scene) -> int:
    """Bytes one worker needs: its operator (:meth:`ElasticOperator.footprint`), the solver's
    work arrays and one sample's fields.

    The pull's own memory is checked when it starts (it depends on the bond count); each
    worker gets ``budget / workers`` so parallel pulls cannot overcommit together.
    """
    ny, nx = scene.grid.shape
    n = ny * nx
    ops = ElasticOperator.footprint(scene.grid.shape, scene.grid.boundary, scene.components)
    work = 8 * n * 16
    nfields = max(1, len(scene.config.output.fields))
    stored = 8 * n * nfields * scene.n_targets + 8 * n * 3
    return int(ops + work + stored)


def _largest(fits: Callable[[int], bool], below: int) -> int:
    """The largest ``k < below`` with ``fits(k)`` (0 if none), by bisection: the estimate
    grows with the grid (up to the FFT lengths' steps, which the last check absorbs)."""
    lo, hi = 0, below  # fits(lo) or lo == 0; not fits(hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if fits(mid):
            lo = mid
        else:
            hi = mid
    while lo > 0 and not fits(lo):
        lo -= 1
    return lo


def _budget_key(config: RunConfig, have: int) -> tuple[str, str]:
    """The setting that sets the budget, when the user can raise it: ``(its name, its name
    and value)``; empty strings when the machine's available memory is the limit."""
    limit = config.execution.memory_limit_gb
    if limit is not None and int(limit * 2**30) == have:
        return "execution.memory_limit_gb", f"execution.memory_limit_gb = {limit:g}"
    env = os.environ.get(MEMORY_ENV, "")
    try:
        if env and int(float(env) * 2**30) == have:
            return MEMORY_ENV, f"{MEMORY_ENV}={env}"
    except ValueError:
        pass
    return "", ""


def check_budget(config: RunConfig, workers: int, scene: Scene | None = None) -> None:
    """Refuse a run that does not fit in the memory budget, before anything is built.

    Parameters
    ----------
    config : RunConfig
    workers : int
        Worker processes (each needs the estimate).
    scene : Scene, optional
        The resolved scene, whose grid may come from a topography file. Without it the grid
        is the configuration's own (``grid.n`` or ``grid.shape``); a grid that a file sets is
        then not checked here (the run checks it once the file is read).

    Raises
    ------
    MemoryLimitError
        One line: the source, the key that sets the size with its value, what one worker and
        all workers need, the budget, and a hint that holds, e.g. ``run.toml: grid.n = 100000:
        a 100000 x 100000 grid needs ~4545 GiB per worker (even one worker), more than the
        22.9 GiB available; grid.n = 6993 is the largest that fits``.
    """
    with memory.limited(config.execution.memory_limit_gb):
        have = memory.available_bytes()
    need = _per_worker(config)
    if scene is not None:
        shape = scene.grid.shape
    elif config.shape is not None:
        shape = config.shape
    else:
        return  # the file sets the grid: checked once it is read
    per = need(shape)
    workers = max(1, int(workers))
    if per * workers <= have:
        return
    g = config.grid
    if scene is not None and config.shape is None:  # a topography file sets the size
        files = [getattr(config, r) for r in ("surface", "elastic_surface")]
        sc = next(s for s in files if s is not None and s.kind == "file")
        key = f"surface.path = {os.path.basename(sc.path)!r}"
        size = f"its {shape[0]} x {shape[1]} grid"
    elif g.n is not None:
        key, size = f"grid.n = {g.n}", f"a {shape[0]} x {shape[1]} grid"
    else:
        key, size = f"grid.shape = {list(shape)}", f"a {shape[0]} x {shape[1]} grid"
    where = f"{config.source}: {key}: {size}"
    name, setting = _budget_key(config, have)
    budget = f"the {_gib(have)} available" + (f" ({setting})" if setting else "")
    if per <= have:  # one worker fits: fewer workers is the hint that holds
        fewer = have // per
        raise MemoryLimitError(
            f"{where} needs ~{_gib(per)} per worker; {workers} workers need "
            f"~{_gib(per * workers)}, more than {budget}; use --workers {fewer}")
    hint = _smaller(config, scene, shape, have, need)
    raise MemoryLimitError(
        f"{where} needs ~{_gib(per)} per worker (even one worker), more than {budget}; "
        f"{hint}{f', or raise {name}' if name else ''}")


def _smaller(config: RunConfig, scene: Scene | None, shape: tuple[int, int], have: int,
             need: Callable[[tuple[int, int]], int]) -> str:
    """The largest size one worker can run in ``have`` bytes, as the key that sets it."""
    ny, nx = shape
    if scene is not None and config.shape is None:  # the file's grid: down-sample it
        files = [getattr(config, r) for r in ("surface", "elastic_surface")]
        sc = next(s for s in files if s is not None and s.kind == "file")
        d = sc.downsample
        for k in range(d + 1, d * max(ny, nx) + 1):
            small = (ny * d // k, nx * d // k)
            if min(small) < MIN_SCAN_SIDE:
                break
            if need(small) <= have:
                return f"surface.downsample = {k} fits ({small[0]} x {small[1]})"
        return "no down-sampling of the file fits"
    if config.grid.n is not None:
        n = _largest(lambda m: need((m, m)) <= have, ny)
        return f"grid.n = {n} is the largest that fits" if n else "no grid fits"
    def scaled(m: int) -> tuple[int, int]:  # ny -> m rows, the same aspect
        return m, max(1, nx * m // ny)

    m = _largest(lambda m: need(scaled(m)) <= have, ny)
    return (f"grid.shape = {list(scaled(m))} (the same aspect) is the largest that fits" if m
            else "no grid fits")
