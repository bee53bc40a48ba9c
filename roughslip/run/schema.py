"""The output schema of a run: every per-(sample, depth) scalar and every per-depth field, named
and described once.

The writer creates exactly these datasets, the stages fill them by these names, and the readers,
``roughslip inspect`` and the documentation list them from here. A scalar a stage did not
compute stays NaN (the fill value), never 0: a coupled run has no squeeze iteration count, a
pull without ``pull.error_estimate`` has no error estimate.

Format versions
    1 stored counts as integers and flags as ``uint8`` with fill 0; 2 stores every scalar as
    ``float64`` with fill NaN (flags 1.0 / 0.0) and attaches ``/sample_index`` and ``/depth``
    (or ``/force_target``) as HDF5 dimension scales of the per-depth datasets. Readers accept
    both.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from roughslip.registry import Registry

FORMAT = "roughslip-run"
FORMAT_VERSION = 2

#: the stages a run can have, in the order a sample runs them
STAGES = ("squeeze", "pull", "coupled", "traction")


@dataclass(frozen=True)
class Column:
    """A per-(sample, depth) scalar dataset ``/name`` of shape ``(n_samples, n_depths)``.

    ``kind`` is ``"value"``, ``"count"`` (an integer, stored as float so that it can be NaN) or
    ``"flag"`` (1.0 yes, 0.0 no). ``dimension`` says which of the run's units it is in
    (``length``, ``force``, ``fraction``, ``seconds``; empty: a pure number), stored as the
    dataset's ``unit`` attribute (:meth:`roughslip.run.units.Units.of_dimension`).
    """

    name: str
    stage: str
    description: str
    kind: str = "value"
    dimension: str = ""
    #: a derived column (:data:`DERIVED`): its value from the other scalars of the same
    #: sample and target, ``derive(scalars) -> float``; None for a column a stage fills
    derive: Callable[[Mapping[str, float]], float] | None = None


COLUMNS: tuple[Column, ...] = (
    Column("depth_length", "squeeze", "penetration D_z in length units", dimension="length"),
    Column("normal_force", "squeeze", "total normal force F_n", dimension="force"),
    Column("contact_area", "squeeze", "contact area as a fraction of the grid",
           dimension="fraction"),
    Column("iterations", "squeeze", "squeeze solver iterations", "count"),
    Column("residual", "squeeze", "squeeze residual: worst gap error relative to the depth "
           "(coupled model: worst relative residual of the block solves, each certified "
           "against the FFT operator); a measure of convergence, not of the error of the "
           "forces, from which it is off by factors 0.26 to 10^4 on the verify squeezes (and "
           "by 10^5 in a coupled matrix-free solve whose release order had near-ties)"),
    Column("converged", "squeeze", "1 when the squeeze met its tolerance", "flag"),
    Column("seconds", "squeeze", "squeeze wall-clock time (a measurement, differs between "
           "runs; coupled model: the part of its solve before the pull starts)",
           dimension="seconds"),
    Column("friction_force", "pull", "static friction force: the peak of the pull curve",
           dimension="force"),
    Column("friction_normal_force", "pull", "normal force of the pulled state",
           dimension="force"),
    Column("pull_seconds", "pull", "pull wall-clock time (a measurement, differs between "
           "runs; coupled model: the rest of its solve)", dimension="seconds"),
    Column("pull_converged", "pull", "1 when every pull solve met its tolerance", "flag"),
    Column("pull_steps", "pull", "bonds broken (or sites slipped, the Coulomb cone's events, "
           "or coupled events) until the pull stopped", "count"),
    Column("pull_error_estimate", "pull", "with pull.error_estimate: estimate of the relative "
           "error of friction_force, the pull's own part (one refinement step on the peak "
           "state; 0 under the Coulomb law) plus the part of the squeeze's error in f_z "
           "(one refinement step on the contact set); within a factor 3.2 of the true error "
           "on the verify scenes; NaN when not estimated and for method 'batch', which has "
           "none"),
    Column("friction_force_x", "traction", "pull.components = 'xy': the x component of the "
           "peak's tangential force vector (friction_force is its component along the drive, "
           "pull.direction)", dimension="force"),
    Column("friction_force_y", "traction", "pull.components = 'xy': the y component of the "
           "peak's tangential force vector", dimension="force"),
    Column("released_bonds", "coupled", "coupled model: contact sites with no bond holding "
           "when the pull starts, at D_x = 0 (released, broken or slipping under the squeeze "
           "history, coupling.history)", "count"),
)
BY_NAME = {c.name: c for c in COLUMNS}

#: columns computed from the others of the same sample and target (:attr:`Column.derive`),
#: registered by name: the writer stores them beside the stage's own, and the readers,
#: ``roughslip inspect`` and the tables read them like any other. A derived column of a stage
#: a run does not have is not stored.
DERIVED: Registry[Column] = Registry("output column")


def register(column: Column) -> Column:
    """Register the derived ``column`` (one with :attr:`Column.derive`) under its name."""
    if column.derive is None:
        raise ValueError(f"output column {column.name!r}: a registered column is derived")
    if column.name in BY_NAME:
        raise ValueError(f"output column {column.name!r} is a column of the schema already")
    return DERIVED.register(column.name, column.description)(column)


def all_columns() -> tuple[Column, ...]:
    """Every column: the stages' own (``COLUMNS``), then the derived ones."""
    return COLUMNS + tuple(DERIVED.get(n) for n in DERIVED)

#: the axes: the configured targets of displacement or load control
AXES = {
    "depth": "configured depths, in squeeze.depth_unit",
    "force_target": "configured normal loads, in squeeze.force_unit",
}
ROOT = {
    "sample_index": "global sample numbers (ensemble.first_sample + row)",
    "complete": "1 once the sample is fully written; entries of other rows are fill values",
}


@dataclass(frozen=True)
class Field:
    """A per-(sample, depth) array in ``/samples/sNNNNNN/dKKK/name``, computed by ``stage``
    (``"squeeze"`` or ``"pull"``: a pull field needs the pull)."""

    name: str
    description: str
    grid: bool = True  # (ny, nx) on the grid, else a curve (one entry per event)
    boolean: bool = False
    stage: str = "squeeze"


FIELDS: tuple[Field, ...] = (
    Field("fz", "normal pixel forces after the squeeze"),
    Field("uz", "normal surface displacement after the squeeze"),
    Field("gap", "gap u_z - overlap (0 in contact)"),
    Field("contact", "contact sites", boolean=True),
    Field("fx", "tangential pixel forces at the friction peak (x component)", stage="pull"),
    Field("fy", "tangential pixel forces at the friction peak, y component "
          "(pull.components = 'xy')", stage="pull"),
    Field("ux", "tangential surface displacement at the friction peak", stage="pull"),
    Field("stick", "bonded (stick) sites at the friction peak", boolean=True, stage="pull"),
    Field("dx_lim", "pull curve: displacement of each event", grid=False, stage="pull"),
    Field("fx_lim", "pull curve: pull force of each event", grid=False, stage="pull"),
    Field("fz_lim", "pull curve (coupled model): normal force of each event", grid=False,
          stage="pull"),
    Field("dz_lim", "pull curve (coupled model): depth D_z of each event (it moves when the "
          "pull holds the force)", grid=False, stage="pull"),
    Field("broken_site", "pull curve: flat index iy * nx + ix of each event's site",
          grid=False, stage="pull"),
)
FIELD_BY_NAME = {f.name: f for f in FIELDS}
BOOL_FIELDS = tuple(f.name for f in FIELDS if f.boolean)
#: ``output.fields`` entries that stand for several arrays
FIELD_GROUPS = {"pull_curve": ("dx_lim", "fx_lim", "fz_lim", "dz_lim", "broken_site")}


def needs_pull(name: str) -> bool:
    """Whether the ``output.fields`` entry ``name`` (a field or a group) needs the pull."""
    return any(FIELD_BY_NAME[n].stage == "pull" for n in FIELD_GROUPS.get(name, (name,)))


def stages(pull: bool, coupled: bool, traction: bool = False) -> tuple[str, ...]:
    """The stages whose columns a run stores: the squeeze always, the pull when it runs, the
    coupled model's own column when the coupled model is asked for (at nu = 1/2 it is the
    decoupled model, which releases no bond before the pull: the column then holds 0), and
    the force vector's components when the pull carries the traction vector
    (``traction``, ``pull.components = "xy"``)."""
    return ("squeeze", *(("pull",) if pull else ()), *(("coupled",) if coupled else ()),
            *(("traction",) if pull and traction else ()))


def columns(have: Iterable[str]) -> tuple[Column, ...]:
    """The scalar columns of a run with the stages ``have``."""
    have = tuple(have)
    return tuple(c for c in all_columns() if c.stage in have)


def derived(cols: Iterable[Column], rows: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The rows of one sample (one array per column, an entry per target) with the derived
    columns among ``cols`` computed from the others, target by target. The writer calls it,
    so a column registered in the process that writes is stored whichever process computed
    the sample (a worker process that never imported it included)."""
    cols = tuple(cols)
    base = {c.name: rows[c.name] for c in cols if c.derive is None and c.name in rows}
    out = dict(rows)
    n = len(next(iter(rows.values()))) if rows else 0
    for c in cols:
        if c.derive is not None:
            out[c.name] = np.array([float(c.derive({k: float(v[t]) for k, v in base.items()}))
                                    for t in range(n)])
    return out


def empty(cols: Iterable[Column], n_targets: int) -> dict[str, np.ndarray]:
    """NaN-filled rows of one sample, one array of ``n_targets`` per column."""
    return {c.name: np.full(n_targets, np.nan) for c in cols}


def put(rows: dict[str, np.ndarray], k: int, values: dict[str, float]) -> None:
    """Store a stage's scalars at target index ``k``; a name outside the schema is an error."""
    for name, v in values.items():
        if name not in rows:
            raise KeyError(f"output schema: {name!r} is not a column of this run "
                           f"(columns: {', '.join(rows)})")
        rows[name][k] = float(v)
