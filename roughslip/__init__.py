"""roughslip: static friction of rough elastic surfaces.

A rigid rough surface is squeezed into an elastic half-space (:func:`squeeze`), then pulled
sideways until its contact bonds break (:func:`pull`). See ``MODEL.md`` in the documentation
for the model and ``roughslip --help`` for the command line.
"""

from ._version import __version__
from .config import RunConfig, load_config
from .errors import (
    ConfigError,
    ConvergenceError,
    InputError,
    MemoryLimitError,
    NumericalError,
    OutputError,
    RoughslipError,
)
from .operators import ElasticOperator, Material

__all__ = [
    "ConfigError",
    "ConvergenceError",
    "ElasticOperator",
    "InputError",
    "Material",
    "MemoryLimitError",
    "NumericalError",
    "OutputError",
    "RoughslipError",
    "RunConfig",
    "__version__",
    "load_config",
]
