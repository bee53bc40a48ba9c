"""Shared fixtures, and what makes the suite independent of order and chance.

* Hypothesis runs derandomized (examples are a function of the test) and keeps no example
  database, so a run does not depend on earlier runs.
* The process-wide memory cap is restored after every test, and the BLAS thread counts after
  the tests that run a Dask worker in this process (``blas_restored``).
* No machine file (per-machine execution settings) is read: ``ROUGHSLIP_MACHINE`` is empty
  for the suite and the runs it starts.
* Test order is shuffled by pytest-randomly (``-p no:randomly`` turns it off; the seed is
  printed in the header, and ``--randomly-seed=N`` replays an order).
* The test-only extensions of ``tests/examples`` (a pull method whose solver recomputes its
  inverse at every change, a coupled block solver that solves every state afresh, an open
  boundary on power-of-two FFT grids) are registered before the tests are collected, so the
  suites that run over the registries run them too. The derived output column of
  ``tests/examples/ratio.py`` changes every run file, so it is registered only by the tests
  that ask for it (``derived_column``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from hypothesis import settings

from roughslip.linalg import memory
from tests.examples import direct, pow2, ratio, recomputed  # noqa: F401  (register them)

DATA = Path(__file__).parent / "data"

os.environ["ROUGHSLIP_MACHINE"] = ""

settings.register_profile("roughslip", derandomize=True, database=None)
settings.load_profile("roughslip")


@pytest.fixture(autouse=True)
def _restore_memory_cap():
    old = memory._LIMIT
    yield
    memory._LIMIT = old


@pytest.fixture
def derived_column():
    """The test-only derived output column, registered for the test."""
    with ratio.registered() as column:
        yield column


@pytest.fixture
def blas_restored():
    """The BLAS thread counts of the test process, restored after the test: a Dask worker
    inside this process sets them for good (:mod:`roughslip.run.cluster`)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=None, user_api="blas"):
        yield


@pytest.fixture(scope="session")
def green_values() -> dict:
    """The verified kernel test vectors (docs/theory/halfspace.rst#kernel-verification)."""
    return json.loads((DATA / "green_values.json").read_text())
