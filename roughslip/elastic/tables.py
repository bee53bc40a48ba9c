"""Real-space tables of an operator's kernels: windows for direct sums of a few point
sources, a pair table for assembling dense blocks between any sites, and dense matrices (the
test reference). Built from the operator's spectra (or, on open grids, the closed-form pixel
kernels) on first use, and cached."""

from __future__ import annotations

import functools
import math
from typing import Protocol

import numpy as np

from roughslip.elastic.boundaries import Boundary
from roughslip.errors import InputError
from roughslip.linalg import jit


class _Elastic(Protocol):
    E: float
    nu: float


class KernelSource(Protocol):
    """What the tables read from an operator
    (:class:`~roughslip.elastic.operators.ElasticOperator` is one)."""

    shape: tuple[int, int]
    padded_shape: tuple[int, int]
    a: float
    boundary: Boundary

    @property
    def material(self) -> _Elastic: ...

    def spectrum(self, component: str) -> np.ndarray: ...

    def real_kernel(self, component: str) -> np.ndarray: ...


class KernelTables:
    """The real-space side of an :class:`~roughslip.elastic.operators.ElasticOperator`
    (``op.tables``)."""

    def __init__(self, op: KernelSource) -> None:
        self.op = op
        self._real: dict[str, np.ndarray] = {}
        self._pairs: dict[str, tuple[np.ndarray, int, int]] = {}

    @property
    def nbytes(self) -> int:
        """Bytes of the tables built so far (a pair table that is a view of a window table,
        as on periodic grids, is counted once)."""
        owners = {id(a if a.base is None else a.base): (a if a.base is None else a.base)
                  for a in [*self._real.values(), *(t[0] for t in self._pairs.values())]}
        return sum(a.nbytes for a in owners.values())

    def real_space(self, component: str) -> np.ndarray:
        """The kernel in real space, laid out so that every source has a contiguous window.

        Open grids: ``T[m + ny - 1, l + nx - 1] = G(l, m)``, shape ``(2ny - 1, 2nx - 1)``.
        Periodic grids: the periodic kernel tiled twice per axis, shape ``(2ny, 2nx)``.
        Recovered from the stored spectrum by one inverse FFT and cached.
        """
        cache = self._real
        if component in cache:
            return cache[component]
        op = self.op
        T = op.boundary.window_table(op.real_kernel(component), op.shape, op.padded_shape)
        cache[component] = T
        return T

    def pair(self, component: str) -> tuple[np.ndarray, int, int]:
        """Flat lookup table for the kernel between any two sites of the grid.

        Returns ``(T, w, off)`` such that for flat site indices ``i = iy nx + ix`` and ``j``,
        ``G(i - j) = T[(iy_i - iy_j) w + (ix_i - ix_j) + off]``. Open grids use the closed-form
        pixel kernel (no FFT round-off); periodic grids the periodic kernel.
        """
        cache = self._pairs
        if component in cache:
            return cache[component]
        op = self.op
        out = op.boundary.pair_table(component, op.shape, op.a, op.material.E, op.material.nu,
                                     self.real_space)
        cache[component] = out
        return out

    def add_sources(self, component: str, out: np.ndarray, sites: np.ndarray,
                    values: np.ndarray) -> np.ndarray:
        """``out += G * f`` for forces ``values`` at flat indices ``sites``, by direct sums.

        Costs one pass over the grid per site: cheaper than a convolution for a handful of
        sites (see :attr:`direct_sum_limit`).
        """
        T = self.real_space(component)
        ny, nx = self.op.shape
        sy, sx = np.divmod(np.asarray(sites), nx)
        oy, ox = self.op.boundary.window_origin(sy, sx, self.op.shape)
        for y0, x0, v in zip(oy, ox, values, strict=True):
            out += v * T[y0 : y0 + ny, x0 : x0 + nx]
        return out

    @property
    def direct_sum_limit(self) -> int:
        """Number of point sources below which :meth:`add_sources` beats a convolution.

        One convolution costs about ``M log2 M`` for ``M`` padded points, one source about
        ``N`` for ``N`` grid points; on this hardware class the measured cost ratio is about
        0.7 of ``M log2 M / N`` (N = 256..1024, open and periodic). The limit is a deterministic
        function of the grid, so the iteration path does not depend on timing.
        """
        m = self.op.padded_shape[0] * self.op.padded_shape[1]
        n = self.op.shape[0] * self.op.shape[1]
        return max(1, int(0.6 * m * math.log2(max(m, 2)) / n))

    def dense(self, component: str = "zz") -> np.ndarray:
        """Dense ``(ny nx) x (ny nx)`` matrix of a component, without FFTs (small grids only).

        Open grids: the closed-form pixel kernel at every offset. Periodic grids: the circulant
        of the symbol, inverted by an explicit DFT.
        """
        ny, nx = self.op.shape
        n = ny * nx
        if n > 4096:
            raise InputError(f"dense matrix of a {self.op.shape} grid is too large "
                             f"(n = {n} > 4096)")
        op = self.op
        return op.boundary.dense(component, op.shape, op.a, op.material.E, op.material.nu,
                                 lambda: op.spectrum(component))


def gather_pairs(T: np.ndarray, li: np.ndarray, lj: np.ndarray, off: int, out: np.ndarray,
                 rows: np.ndarray | None = None, cols: np.ndarray | None = None,
                 compiled: bool | None = None) -> np.ndarray:
    r"""Write a block of a pair table (:meth:`KernelTables.pair`) into ``out``:

    .. math:: \mathrm{out}[r_a, c_b] = T[l^i_a - l^j_b + \mathrm{off}],

    the kernel between the sites of table indices ``li`` (rows) and ``lj`` (columns), at the
    rows ``rows`` and columns ``cols`` of ``out`` (all of them by default). ``T`` has the dtype
    of ``out`` (a float32 block gathers from the table rounded once). The entries are copied,
    so the compiled kernel and numpy give the same block bit for bit; the kernel writes
    ``out`` in its memory order, numpy a column at a time (``compiled``: default
    :data:`roughslip.linalg.jit.ENABLED`). Returns ``out``.
    """
    li = np.asarray(li, dtype=np.int64)
    lj = np.asarray(lj, dtype=np.int64)
    if li.size == 0 or lj.size == 0:
        return out
    rows = np.arange(li.size) if rows is None else np.asarray(rows, dtype=np.int64)
    cols = np.arange(lj.size) if cols is None else np.asarray(cols, dtype=np.int64)
    if compiled is None:
        compiled = jit.ENABLED
    if compiled:
        _gather_kernel()(T, li, lj, int(off), out, rows, cols, bool(out.flags.c_contiguous))
    else:
        for b in range(lj.size):
            out[rows, cols[b]] = T[li + (off - lj[b])]
    return out


@functools.cache
def _gather_kernel():
    """The compiled gather (defined and compiled, or loaded from numba's cache, at first use):
    by columns into a Fortran-ordered block, by rows into a C-ordered one."""
    @jit.njit()
    def gather(T, li, lj, off, out, rows, cols, by_rows):
        if by_rows:
            for a in range(li.size):
                r = rows[a]
                base = li[a] + off
                for b in range(lj.size):
                    out[r, cols[b]] = T[base - lj[b]]
        else:
            for b in range(lj.size):
                c = cols[b]
                base = off - lj[b]
                for a in range(li.size):
                    out[rows[a], c] = T[li[a] + base]

    return gather
