"""Thread control for BLAS (numpy and scipy each load an OpenBLAS).

Everything in roughslip runs with an explicit thread count, by default one per worker: two
threads on a machine that is busy elsewhere can be far slower than one (a 128 x 128 Cholesky
was measured at 44 ms instead of 0.1 ms with the second core occupied).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from threadpoolctl import threadpool_limits


@contextlib.contextmanager
def blas_threads(n: int) -> Iterator[None]:
    """Limit BLAS/LAPACK to ``n`` threads inside the block."""
    with threadpool_limits(limits=max(1, int(n)), user_api="blas"):
        yield
