"""Real-space tables of an operator's kernels: windows for direct sums of a few point
sources, a pair table for assembling dense blocks between any sites, and dense matrices (the
test reference). Built from the operator's spectra (or, on open grids, the closed-form pixel
kernels) on first use, and cached."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from roughslip.elastic.boundaries import Boundary
from roughslip.errors import InputError


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

        One convolution costs ~``M log2 M`` for ``M`` padded points, one source ~``N`` for
        ``N`` grid points; on this hardware class the measured cost ratio is ~0.7 of
        ``M log2 M / N`` (N = 256..1024, open and periodic). The limit is a deterministic
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
