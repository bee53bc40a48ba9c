"""Dask: samples computed on a cluster and streamed back to the single writer.

Several runs can share one scheduler: the task keys name the configuration and the output
(:func:`task_prefix`), and the writer checks the configuration digest of every sample it
receives (:meth:`roughslip.run.store.RunWriter.write_sample`).
"""

from __future__ import annotations

import hashlib
import secrets
import socket
from pathlib import Path

from threadpoolctl import ThreadpoolController

from roughslip.errors import InputError
from roughslip.run.config import RunConfig
from roughslip.run.sample import Progress, run_sample
from roughslip.run.store import RunWriter, SampleResult


def output_identity(path: str | Path) -> str:
    """A short hash (16 hex digits) of where a run file is written: this host's name and the
    file's resolved path.

    Parameters
    ----------
    path : path
        The run file.

    Returns
    -------
    str
    """
    where = f"{socket.gethostname()}:{Path(path).resolve()}"
    return hashlib.sha256(where.encode()).hexdigest()[:16]


def task_prefix(config: RunConfig, out: str | Path) -> str:
    """The prefix of this run's Dask task keys: sample ``s`` is ``f"{prefix}-{s}"``.

    A scheduler treats a submitted key that it already holds as the same task, so keys that
    are only the sample number let two runs sharing a scheduler receive each other's samples.
    The prefix holds the configuration digest (its first 16 hex digits) and the output's
    identity (:func:`output_identity`), so that tasks of different configurations or of
    different files never meet, and a token of this invocation, so that a resumed run does not
    meet the tasks of the run it continues while the scheduler may still be cancelling them.

    Parameters
    ----------
    config : RunConfig
    out : path
        The run file.

    Returns
    -------
    str
        ``"roughslip-<digest>-<output>-<token>"``.
    """
    return (f"roughslip-{config.digest()[:16]}-{output_identity(out)}-"
            f"{secrets.token_hex(4)}")


def _task(config: RunConfig, sample: int) -> SampleResult:
    """One sample on a Dask worker, whose BLAS is first set to ``execution.threads`` threads
    for good.

    A worker runs tasks in several threads of one process, and BLAS's thread count belongs to
    the process: a solver that limits it for a block restores the count it found on leaving,
    under the feet of a thread still inside its own block. With the count at the configured
    value from the start, every restore gives that value back, and the numbers are those of a
    run in one process, bitwise.
    """
    global _controller
    if _controller is None:
        _controller = ThreadpoolController()
    _controller.limit(limits=max(1, config.execution.threads), user_api="blas")
    return run_sample(config, sample)


#: the BLAS libraries of a Dask worker process, found once
_controller: ThreadpoolController | None = None


def run_dask(config: RunConfig, pending: list[int], writer: RunWriter, emit: Progress,
             address: str) -> None:
    """Compute ``pending`` samples on the Dask scheduler at ``address``; write each as it
    arrives.

    Parameters
    ----------
    config : RunConfig
    pending : list of int
        The global numbers of the samples to compute.
    writer : RunWriter
        The run file's single writer (in this process).
    emit : callable
        Receives the progress events (:data:`roughslip.run.sample.Progress`).
    address : str
        The scheduler, e.g. ``tcp://10.0.0.5:8786``.

    Raises
    ------
    InputError
        When the dask extra is missing or the scheduler cannot be reached.
    """
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError("--scheduler needs the dask extra: pip install 'roughslip[dask]'"
                         ) from None
    try:
        # not the default client: a process-wide Dask setting would outlive this run and,
        # with two runs in one process, be restored out of order
        client = Client(address, timeout="20s", set_as_default=False)
    except OSError as exc:
        raise InputError(f"--scheduler {address}: cannot connect ({exc})") from None
    with client:
        prefix = task_prefix(config, writer.path)
        futures = [client.submit(_task, config, s, pure=False, key=f"{prefix}-{s}")
                   for s in pending]
        nd = len(config.targets)
        try:
            for fut in as_completed(futures, loop=client.loop):
                res = fut.result()
                writer.write_sample(res)
                for k in range(nd):
                    emit({"kind": "depth", "sample": res.sample, "depth_index": k})
                emit({"kind": "sample", "sample": res.sample})
        except BaseException:
            client.cancel(futures)
            raise

