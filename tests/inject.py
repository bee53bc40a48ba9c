"""Fault injection for the kill tests: stop a run at a named checkpoint of its writer.

    python tests/inject.py [--signal NAME] CHECKPOINT COUNT roughslip-args...

listens to the writer's checkpoints (:mod:`roughslip.run.checkpoints`), runs the ``roughslip``
command line given after COUNT, and sends itself SIGKILL (or the named signal, e.g. ``INT``
for a Ctrl-C) the COUNT-th time the run reaches CHECKPOINT.
"""

from __future__ import annotations

import os
import signal
import sys

from roughslip.run import checkpoints


def arm(point: str, count: int = 1, sig: int = signal.SIGKILL) -> None:
    """Make this process send itself ``sig`` the ``count``-th time the writer reaches
    checkpoint ``point``."""
    if point not in checkpoints.CHECKPOINTS:
        raise ValueError(f"unknown checkpoint {point!r}; choose from "
                         f"{sorted(checkpoints.CHECKPOINTS)}")
    hits = {"n": 0}

    def listener(name: str) -> None:
        if name == point:
            hits["n"] += 1
            if hits["n"] == count:
                os.kill(os.getpid(), sig)

    checkpoints.listen(listener)


def main(argv: list[str]) -> None:
    sig = signal.SIGKILL
    if argv[:1] == ["--signal"] and len(argv) > 1:
        sig = getattr(signal, "SIG" + argv[1].upper())
        argv = argv[2:]
    if len(argv) < 3:
        sys.exit("usage: python tests/inject.py [--signal NAME] CHECKPOINT COUNT "
                 "roughslip-args...")
    arm(argv[0], int(argv[1]), sig)
    from roughslip.cli import cli

    cli.main(argv[2:], prog_name="roughslip")


if __name__ == "__main__":
    main(sys.argv[1:])
