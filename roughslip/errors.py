"""The exception hierarchy of roughslip.

Every error a user can provoke is a :class:`RoughslipError`. The command line maps each
class to one line on stderr and an exit code (see :data:`EXIT_CODES`; a run stopped by
SIGINT, SIGTERM or SIGHUP exits with 128 + the signal's number: 130, 143, 129):

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
OutputBusyError        2     another run is writing the output file (it holds its lock)
VerificationError      1     ``verify``: an estimate broke the relation it claims
=====================  ====  ==========================================================
"""

from __future__ import annotations

import errno as _errno
import os
import re


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


class OutputBusyError(RoughslipError):
    """Another run holds the lock of the output file (:mod:`roughslip.run.lock`); the message
    names the file and the holder's PID and host."""

    exit_code = 2


class VerificationError(RoughslipError):
    """``roughslip verify`` found an error estimate that breaks the relation it claims, or a
    tight reference that did not converge."""

    exit_code = 1


#: the longest value (or key) an error message repeats, in characters: about a terminal line.
#: A message stays one readable line however large the value that broke a rule (a 10 MB
#: string in a configuration is echoed as its first 80 characters and its length).
ECHO_LIMIT = 80


def shorten(text: str, *, length: int | None = None) -> str:
    """``text`` for an error message: whole when it has at most :data:`ECHO_LIMIT` characters,
    else its first :data:`ECHO_LIMIT`, ``...`` and how long it was.

    Parameters
    ----------
    text : str
        What the message would show.
    length : int, optional
        The length to report when ``text`` renders only the start of a longer value (then the
        ellipsis and the length are always added).

    Returns
    -------
    str
        E.g. ``"xxxx"... (10000000 characters)``.
    """
    if length is None:
        if len(text) <= ECHO_LIMIT:
            return text
        length = len(text)
    return f"{text[:ECHO_LIMIT]}... ({length} characters)"


def echo(value: object) -> str:
    """``repr(value)`` for an error message, at most about :data:`ECHO_LIMIT` characters
    (:func:`shorten`); a long string is not rendered whole first.

    Parameters
    ----------
    value : object
        A value from a file, a configuration or the command line.

    Returns
    -------
    str
    """
    if isinstance(value, str) and len(value) > ECHO_LIMIT:
        return shorten(repr(value[:ECHO_LIMIT]), length=len(value))
    return shorten(repr(value))


EXIT_CODES = {
    "ok": 0,
    "failure": 1,
    "usage": 2,
    "nonconvergence": 3,
    # a run stopped by a signal: 128 + its number (roughslip.run.signals)
    "interrupted": 130,  # SIGINT, Ctrl-C
    "hangup": 129,  # SIGHUP
    "terminated": 143,  # SIGTERM
}


#: h5py reports the operating system's error inside a long message: "... errno = 28, ..."
_H5_ERRNO = re.compile(r"errno = (\d+)")

#: what a run can do after a failed write, by the operating system's error number
_KEPT = "the samples completed before are kept: {}, then run again with --resume"
_REMEDY = {_errno.ENOSPC: _KEPT.format("free some space"),
           _errno.EDQUOT: _KEPT.format("free some space"),
           _errno.EACCES: _KEPT.format("make the file and its folder writable"),
           _errno.EPERM: _KEPT.format("make the file and its folder writable"),
           _errno.EROFS: _KEPT.format("make the file system writable"),
           _errno.ENOENT: "the folder was removed, and the samples written into it with it: "
                          "run again (restore the folder, or choose another with -o)"}


def _errno_of(exc: BaseException) -> int | None:
    if isinstance(exc, OSError) and exc.errno:
        return exc.errno
    m = _H5_ERRNO.search(str(exc))
    return int(m.group(1)) if m else None


def io_cause(exc: BaseException) -> str:
    """The cause of a failed file operation in a few words ("No space left on device"),
    from an ``OSError`` or from h5py's long error text; its first line when it names none.

    The whole text, with the library's detail, stays on the exception that
    :func:`io_failure` chains (``roughslip --verbose`` prints it).
    """
    code = _errno_of(exc)
    if isinstance(exc, OSError) and code is not None and exc.strerror \
            and exc.strerror.startswith(os.strerror(code)):
        return exc.strerror  # the system's words, with what roughslip added to them
    if code is not None:
        return os.strerror(code)
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text if len(text) <= 120 else text[:117] + "..."


def io_failure(path: object, what: str, exc: BaseException, *, resume: bool = False
               ) -> OutputError:
    """One line for a failed write: the file, what failed, the cause and, for a run, what to
    do and that the completed samples are kept (``--resume``). Raise it ``from exc``."""
    code = _errno_of(exc)
    line = f"{path}: {what}: {io_cause(exc)}"
    folder = os.path.dirname(os.path.abspath(str(path)))
    if code == _errno.ENOENT and not os.path.isdir(folder):
        line += f" (the folder {folder} is gone)"
    if resume:
        line += "; " + _REMEDY.get(code or -1, _KEPT.format("remove the cause"))
    return OutputError(line)
