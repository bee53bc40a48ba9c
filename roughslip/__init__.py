"""roughslip: static friction of rough elastic surfaces.

A rigid rough surface is squeezed into an elastic half-space (:func:`squeeze`), then pulled
sideways until its contact bonds break (:func:`pull`). The documentation in ``docs/``
(``make docs``) derives the model; ``roughslip --help`` lists the commands.
"""

from roughslip._version import __version__
from roughslip.contact.problem import Problem
from roughslip.contact.squeeze import NormalResult, NormalSolver, squeeze
from roughslip.coupling.coupled import (
    IndentResult,
    couple,
    indent,
    squeeze_pull_coupled,
)
from roughslip.elastic.operators import ElasticOperator, Grid, Material
from roughslip.errors import (
    ConfigError,
    ConvergenceError,
    InputError,
    MemoryLimitError,
    NumericalError,
    OutputError,
    RoughslipError,
    SizeLimitError,
)
from roughslip.friction.pull import pull
from roughslip.friction.result import PullResult, renamed
from roughslip.run.config import RunConfig, load_config

__all__ = [
    "ConfigError",
    "ConvergenceError",
    "ElasticOperator",
    "Grid",
    "IndentResult",
    "InputError",
    "Material",
    "MemoryLimitError",
    "NormalResult",
    "NormalSolver",
    "NumericalError",
    "OutputError",
    "Problem",
    "PullResult",
    "RoughslipError",
    "RunConfig",
    "SizeLimitError",
    "__version__",
    "couple",
    "indent",
    "load_config",
    "pull",
    "squeeze",
    "squeeze_pull_coupled",
]


def __getattr__(name: str) -> type:
    """``SlipResult`` and ``CoupledResult``, the result types of earlier versions
    (deprecated: both are :class:`PullResult`)."""
    if name in ("SlipResult", "CoupledResult"):
        return renamed(__name__, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
