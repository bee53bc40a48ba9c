"""The exception hierarchy of roughslip.

Every error a user can provoke is a :class:`RoughslipError`. The command line maps each
class to one line on stderr and an exit code (see :data:`EXIT_CODES`):

=====================  ====  ==========================================================
class                  code  meaning
=====================  ====  ==========================================================
ConfigError            2     a configuration file or ``--set`` override breaks a rule
InputError             2     bad input data (topography file, parameter, HDF5 file)
OutputError            1     an output file cannot be written or read back
ConvergenceError       3     a solver missed its tolerance and strict mode is on
NumericalError         1     a NaN or inf appeared inside a computation
MemoryLimitError       2     the estimated peak memory exceeds what is available
SizeLimitError         2     a problem too large for a library's index range (32-bit LAPACK)
WorkerError            1     a worker process died (killed, out of memory)
VerificationError      1     ``verify``: an estimate broke the relation it claims
=====================  ====  ==========================================================
"""

from __future__ import annotations


class RoughslipError(Exception):
    """Base class of every error roughslip raises on purpose."""

    exit_code: int = 1


class ConfigError(RoughslipError):
    """A configuration value breaks a rule; the message names file, key, value and rule."""

    exit_code = 2


class InputError(RoughslipError):
    """Input data or a function argument is invalid (named in the message)."""

    exit_code = 2


class OutputError(RoughslipError):
    """An output file cannot be written, or an existing file cannot be read back."""

    exit_code = 1


class ConvergenceError(RoughslipError):
    """A solver did not reach its tolerance (raised only in strict mode)."""

    exit_code = 3


class NumericalError(RoughslipError):
    """A non-finite value (NaN or inf) appeared where none may appear."""

    exit_code = 1


class MemoryLimitError(RoughslipError):
    """The estimated peak memory of a computation exceeds the memory available."""

    exit_code = 2


class SizeLimitError(RoughslipError):
    """A problem exceeds what a library can index (a dense matrix beyond 32-bit LAPACK), however
    much memory there is."""

    exit_code = 2


class WorkerError(RoughslipError):
    """A worker process died; completed samples are kept."""

    exit_code = 1


class VerificationError(RoughslipError):
    """``roughslip verify`` found an error estimate that breaks the relation it claims, or a
    tight reference that did not converge."""

    exit_code = 1


EXIT_CODES = {
    "ok": 0,
    "failure": 1,
    "usage": 2,
    "nonconvergence": 3,
}
