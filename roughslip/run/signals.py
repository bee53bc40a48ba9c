"""Stopping a run by a signal: what is kept, what is said, and the exit code.

A run stops the same way on SIGINT (Ctrl-C), SIGTERM (what cluster schedulers send at the
wall time, and ``kill``'s default) and SIGHUP (a closed terminal or SSH session): the workers
are ended, every completed sample is kept (journalled and in the run file), the lock of the
output is released, and one line gives the command that continues the run. The exit code is
``128 + the signal's number``, the shells' convention for a process ended by a signal: 130
for SIGINT, 143 for SIGTERM, 129 for SIGHUP (:func:`exit_code`).

Worker processes ignore the three signals: a terminal's Ctrl-C and a scheduler's SIGTERM reach
every process of the job, and only the main process acts on them (it ends its workers itself,
so that none dies in the middle of a result and none outlives it).
"""

from __future__ import annotations

import contextlib
import shlex
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from typing import Any

#: the signals that stop a run and keep what it completed
STOP_SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class Interrupted(KeyboardInterrupt):
    """A run stopped by the signal ``signum`` (a ``KeyboardInterrupt``, so that every clean-up
    written for Ctrl-C runs for the others too)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


def exit_code(signum: int) -> int:
    """The exit code of a run stopped by the signal ``signum``: ``128 + signum`` (130 for
    SIGINT, 143 for SIGTERM, 129 for SIGHUP).

    Parameters
    ----------
    signum : int

    Returns
    -------
    int
    """
    return 128 + int(signum)


def signal_of(exc: BaseException) -> int:
    """The signal that interrupted a run: that of an :class:`Interrupted`, SIGINT for a bare
    ``KeyboardInterrupt`` (Python's own Ctrl-C).

    Parameters
    ----------
    exc : BaseException

    Returns
    -------
    int
    """
    return getattr(exc, "signum", int(signal.SIGINT))


@contextlib.contextmanager
def interruptible(progress: Callable[[dict[str, Any]], None]
                  ) -> Iterator[Callable[[dict[str, Any]], None]]:
    """Stop the run inside the block on any of :data:`STOP_SIGNALS`, by raising
    :class:`Interrupted` in the main thread.

    The first signal raises; a second one while the run cleans up is noted but does not cut
    the clean-up short (it ends the workers and closes the file, in bounded time). The handler
    also sets a flag, which the returned progress callback (called after every depth, and
    every 0.25 s while workers compute) turns into :class:`Interrupted` if Python swallowed the
    first one (e.g. inside a weakref callback). An error that ends the run after a signal (a
    worker that the signal ended first) is reported as the interruption it follows from.
    Must be entered in the main thread.

    Parameters
    ----------
    progress : callable
        The run's progress callback.

    Yields
    ------
    callable
        The progress callback to give the run.
    """
    caught: list[int] = []

    def handler(signum: int, frame: Any) -> None:
        caught.append(signum)
        if len(caught) == 1:
            raise Interrupted(signum)

    def emit(event: dict[str, Any]) -> None:
        progress(event)
        if caught:
            raise Interrupted(caught[0])

    default_hook = sys.unraisablehook

    def hook(unraisable: Any) -> None:
        if not issubclass(unraisable.exc_type, KeyboardInterrupt):
            default_hook(unraisable)

    old = {s: signal.signal(s, handler) for s in STOP_SIGNALS}
    sys.unraisablehook = hook
    try:
        yield emit
    except Exception as exc:
        if caught:
            raise Interrupted(caught[0]) from exc
        raise
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        sys.unraisablehook = default_hook


def resume_command(config: str, out: str, overrides: Sequence[str] = (), *,
                   workers: int | None = None, scheduler: str | None = None,
                   strict: bool = False, quiet: bool = False) -> str:
    """The ``roughslip run ... --resume`` command that continues a run, as one shell line.

    Parameters
    ----------
    config : str
        The configuration file, as given.
    out : str
        The run file.
    overrides : sequence of str
        The ``--set`` values, in order.
    workers, scheduler, strict, quiet
        The options given (None or False: not given).

    Returns
    -------
    str
    """
    words = ["roughslip", "run", config, "-o", out]
    for text in overrides:
        words += ["--set", text]
    if workers is not None:
        words += ["--workers", str(workers)]
    if scheduler:
        words += ["--scheduler", scheduler]
    if strict:
        words.append("--strict")
    if quiet:
        words.append("--quiet")
    return shlex.join([*words, "--resume"])
