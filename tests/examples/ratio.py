"""An output column computed from others (the recipe "an output column" of
docs/extending.md): one :class:`~roughslip.run.schema.Column` with a ``derive`` function and
one entry of :data:`~roughslip.run.schema.DERIVED`. It is the ratio of the friction force to
the normal force of the pulled state, per sample and target, a pure number. The writer stores
it in every run with a pull, and the reader and the tables give it like any other column. A
column changes every run file written while it is registered, so the tests register it only
where they check it (the ``derived_column`` fixture of ``tests/conftest.py``), against the two
columns it comes from."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from contextlib import contextmanager

from roughslip.run.schema import DERIVED, Column, register


def friction_ratio(scalars: Mapping[str, float]) -> float:
    """:math:`F_{\\rm friction}/F_z` at the peak; NaN without a normal force."""
    fz = scalars["friction_normal_force"]
    return scalars["friction_force"] / fz if fz > 0 else math.nan


COLUMN = Column("friction_ratio", "pull", "friction_force / friction_normal_force: the "
                "friction coefficient of the sample at this target (a test-only column)",
                derive=friction_ratio)


@contextmanager
def registered() -> Iterator[Column]:
    """The column registered for the duration of the block."""
    register(COLUMN)
    try:
        yield COLUMN
    finally:
        DERIVED.remove(COLUMN.name)
