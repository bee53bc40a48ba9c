"""Thread control for BLAS (numpy and scipy each load an OpenBLAS).

Everything in roughslip runs with an explicit thread count, by default one per worker: two
threads on a machine that is busy elsewhere can be far slower than one (a 128 x 128 Cholesky
was measured several hundred times slower with the second core occupied).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from threadpoolctl import ThreadpoolController

#: the BLAS libraries of the process, found once (finding them reads the process's memory
#: map: about 2 ms, more than a product with a small inverse)
_controller: ThreadpoolController | None = None
#: the limit set by the innermost active :func:`blas_threads`, None outside any
_current: int | None = None


@contextlib.contextmanager
def blas_threads(n: int) -> Iterator[None]:
    """Limit BLAS/LAPACK to ``n`` threads inside the block (a no-op when the enclosing block
    already set ``n``)."""
    global _controller, _current
    n = max(1, int(n))
    if n == _current:
        yield
        return
    if _controller is None:
        _controller = ThreadpoolController()
    prev = _current
    with _controller.limit(limits=n, user_api="blas"):
        _current = n
        try:
            yield
        finally:
            _current = prev
