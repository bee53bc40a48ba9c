"""Dask: samples computed on a cluster and streamed back to the single writer."""

from __future__ import annotations

from roughslip.errors import InputError
from roughslip.run.config import RunConfig
from roughslip.run.sample import Progress, run_sample
from roughslip.run.store import RunWriter


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
        client = Client(address, timeout="20s")
    except OSError as exc:
        raise InputError(f"--scheduler {address}: cannot connect ({exc})") from None
    with client:
        futures = [client.submit(run_sample, config, s, pure=False, key=f"roughslip-{s}")
                   for s in pending]
        nd = len(config.targets)
        try:
            for fut in as_completed(futures):
                res = fut.result()
                writer.write_sample(res)
                for k in range(nd):
                    emit({"kind": "depth", "sample": res.sample, "depth_index": k})
                emit({"kind": "sample", "sample": res.sample})
        except BaseException:
            client.cancel(futures)
            raise

