"""Named checkpoints in the life of a run file's writer.

The writer (:mod:`roughslip.run.store`) calls :func:`reached` with a name from
:data:`CHECKPOINTS` at each moment after which a crash leaves a distinct state on disk. In a
run nothing listens, and a checkpoint costs one dictionary lookup. A test installs a listener
(:func:`listen`) to stop the process at a chosen checkpoint, which reaches every state a kill
can leave at a fixed, reproducible moment, whatever the machine's speed.

Names are checked: :func:`reached` with a name that is not in :data:`CHECKPOINTS` is an
error, and the fault-injection tests check that every checkpoint they name is listed here and
reached by a run, so that renaming or moving one cannot silently disarm a test.
"""

from __future__ import annotations

from collections.abc import Callable

#: checkpoint name -> the state of the run file and journal when it is reached
CHECKPOINTS: dict[str, str] = {
    "start": "before anything is written: no run file, no journal",
    "creating": "the new run file written to OUT.h5.creating, not yet renamed",
    "journal-entry": "a sample's journal entry written to a temporary file, not yet renamed",
    "main-write": "a sample journalled and half-written into OUT.h5 (open for writing)",
    "sample-done": "a sample fully written, OUT.h5 open for writing",
    "depth-entry": "a finished depth of an unfinished sample journalled to a temporary file, "
                   "not yet renamed",
    "finish": "every sample done, the journal renamed .journal.done but not removed",
    "rebuild": "during a resume: a journal entry read while OUT.h5 is rebuilt from the journal",
}

Listener = Callable[[str], None]

_listener: Listener | None = None


def reached(name: str) -> None:
    """The writer reached checkpoint ``name``: tell the listener, if any."""
    if name not in CHECKPOINTS:
        raise KeyError(f"unknown checkpoint {name!r}; known: {', '.join(CHECKPOINTS)}")
    if _listener is not None:
        _listener(name)


def listen(listener: Listener | None) -> Listener | None:
    """Install ``listener`` (called with each checkpoint's name; None removes it); returns
    the previous one."""
    global _listener
    previous, _listener = _listener, listener
    return previous
