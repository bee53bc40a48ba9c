r"""What lies beyond the grid: the boundary treatments of an elastic operator.

A boundary decides how a convolution with the pixel Green functions wraps at the edges of the
``ny x nx`` grid (docs/theory/boundaries.rst#boundaries). Everything that differs between
treatments lives here, once: the FFT grid, the kernel spectrum, the layout of the kernel in
real space, the dense matrix and how deep a rigid surface can be pressed. Code above this
module asks the boundary object and never compares names.

:class:`Open`
    A finite patch on an infinite half-space. Linear convolution by zero padding to fast FFT
    lengths ``>= 2n - 1`` per axis (DC-FFT, docs/theory/boundaries.rst#open-boundary); exact to
    round-off.
:class:`Periodic`
    The grid repeats. Circular convolution with the symbol of
    :func:`~roughslip.elastic.green.periodic_symbol` (``"pixel"``: exact periodic images of
    the pixel kernel, or ``"continuous"``). The zero mode is zero: a uniform load produces no
    displacement (docs/theory/boundaries.rst#periodic-boundary).

A third treatment (e.g. periodic along one axis and open along the other) is a subclass that
implements the methods below, registered in :data:`BOUNDARIES` (:func:`register`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from roughslip.elastic import green
from roughslip.elastic.fft import fast_len
from roughslip.errors import InputError
from roughslip.registry import Registry

#: periodic symbols (``grid.periodic_kernel``)
PERIODIC_KERNELS = ("pixel", "continuous")


class Boundary:
    """A boundary treatment (abstract): subclasses give every method."""

    #: the name used in configurations and ``Grid(boundary=...)``
    name: str = ""
    #: one line for help texts (after its name)
    description: str = ""

    def __str__(self) -> str:
        return self.name

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self)

    def __hash__(self) -> int:
        return hash(type(self))

    def padded_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        """The FFT grid of an operator on a grid of ``shape``."""
        raise NotImplementedError

    def data_rows(self, shape: tuple[int, int]) -> int | None:
        """Rows of the FFT grid that carry data in and out (pruned transforms), or None for
        all."""
        raise NotImplementedError

    def spectrum(self, component: str, shape: tuple[int, int], padded: tuple[int, int],
                 a: float, E: float, nu: float, periodic_kernel: str,
                 forward: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Half spectrum of a canonical component on the FFT grid, scaled by ``1 / (my mx)``
        for an unnormalised backward transform; ``forward`` is the real FFT of the padded
        grid."""
        raise NotImplementedError

    def window_table(self, K: np.ndarray, shape: tuple[int, int],
                     padded: tuple[int, int]) -> np.ndarray:
        """The real-space kernel ``K`` (on the FFT grid) laid out so that every source has a
        contiguous ``ny x nx`` window (:meth:`window_origin`)."""
        raise NotImplementedError

    def window_origin(self, sy: np.ndarray, sx: np.ndarray,
                      shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Top-left corner in :meth:`window_table` of the window of sources at ``(sy, sx)``."""
        raise NotImplementedError

    def pair_table(self, component: str, shape: tuple[int, int], a: float, E: float,
                   nu: float, real_space: Callable[[str], np.ndarray]
                   ) -> tuple[np.ndarray, int, int]:
        """Flat table ``(T, w, off)`` of the kernel between any two sites: for offsets
        ``(dy, dx)`` between them, ``G = T[dy w + dx + off]``."""
        raise NotImplementedError

    def dense(self, component: str, shape: tuple[int, int], a: float, E: float, nu: float,
              spectrum: Callable[[], np.ndarray]) -> np.ndarray:
        """Dense matrix of a component without FFTs (small grids; the test reference);
        ``spectrum`` returns the component's stored half spectrum."""
        raise NotImplementedError

    def depth_limit(self, hmax: float, hmean: float) -> float:
        """The largest depth displacement control accepts for heights with this maximum and
        mean (infinite unless the force diverges at a finite depth)."""
        raise NotImplementedError

    def check_squeeze(self, shape: tuple[int, int]) -> None:
        """Raise :class:`InputError` for grids on which a squeeze is undefined."""


class Open(Boundary):
    """A finite patch on an infinite half-space (zero-padded linear convolution)."""

    name = "open"
    description = "finite patch on a half-space"

    def padded_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        ny, nx = shape
        return fast_len(2 * ny - 1), fast_len(2 * nx - 1)

    def data_rows(self, shape: tuple[int, int]) -> int | None:
        return shape[0]

    def spectrum(self, component, shape, padded, a, E, nu, periodic_kernel, forward):
        ny, nx = shape
        my, mx = padded
        odd = green.PARITY[component] in ((-1, 1), (1, -1))
        scale = 1.0 / (my * mx)  # the backward transform is unnormalised
        spec = forward(green.open_kernel_padded(component, nx, ny, mx, my, a=a, E=E, nu=nu))
        # Even (odd) padded kernels have purely real (imaginary) spectra
        # (docs/theory/boundaries.rst#open-boundary); drop the round-off in the other part.
        # Stored complex: numpy multiplies complex by complex ~2.7x faster than complex by
        # real (no casting loop).
        if component == "xy" or not odd:
            return (spec.real * scale).astype(complex)
        return (1j * spec.imag) * scale

    def window_table(self, K, shape, padded):
        ny, nx = shape
        my, mx = padded
        rows = np.r_[my - ny + 1 : my, 0:ny]
        cols = np.r_[mx - nx + 1 : mx, 0:nx]
        return np.ascontiguousarray(K[np.ix_(rows, cols)])

    def window_origin(self, sy, sx, shape):
        ny, nx = shape
        return ny - 1 - sy, nx - 1 - sx

    def pair_table(self, component, shape, a, E, nu, real_space):
        ny, nx = shape
        canon, sign = green.CANONICAL[component]
        T = sign * green.kernel_table(canon, nx, ny, a=a, E=E, nu=nu)
        w, oy, ox = 2 * nx - 1, ny - 1, nx - 1
        return np.ascontiguousarray(T).ravel(), w, oy * w + ox

    def dense(self, component, shape, a, E, nu, spectrum):
        l, m = _offsets(shape)
        return green.pixel_kernel(component, l, m, a=a, E=E, nu=nu)

    def depth_limit(self, hmax: float, hmean: float) -> float:
        return math.inf


class Periodic(Boundary):
    """The grid repeats (circular convolution with the periodic symbol)."""

    name = "periodic"
    description = "repeating grid"

    def padded_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        return int(shape[0]), int(shape[1])

    def data_rows(self, shape: tuple[int, int]) -> int | None:
        return None

    def spectrum(self, component, shape, padded, a, E, nu, periodic_kernel, forward):
        my, mx = padded
        sym = green.periodic_symbol(component, shape, a=a, E=E, nu=nu, kind=periodic_kernel)
        return (sym * (1.0 / (my * mx))).astype(complex)

    def window_table(self, K, shape, padded):
        return np.tile(K, (2, 2))

    def window_origin(self, sy, sx, shape):
        ny, nx = shape
        return ny - sy, nx - sx

    def pair_table(self, component, shape, a, E, nu, real_space):
        ny, nx = shape
        T = real_space(component)
        w, oy, ox = 2 * nx, ny, nx
        return np.ascontiguousarray(T).ravel(), w, oy * w + ox

    def dense(self, component, shape, a, E, nu, spectrum):
        ny, nx = shape
        l, m = _offsets(shape)
        k = spectrum() * (ny * nx)
        # Explicit inverse real DFT of the half spectrum (Hermitian completion along x).
        full = np.zeros((ny, nx), dtype=complex)
        full[:, : nx // 2 + 1] = k
        for kx in range(nx // 2 + 1, nx):
            full[:, kx] = np.conj(k[(-np.arange(ny)) % ny, nx - kx])
        ey = np.exp(2j * np.pi * np.outer(np.arange(ny), np.arange(ny)) / ny)
        ex = np.exp(2j * np.pi * np.outer(np.arange(nx), np.arange(nx)) / nx)
        kern = (ey @ full @ ex.T).real / (ny * nx)  # kern[m, l]
        return kern[m % ny, l % nx]

    def depth_limit(self, hmax: float, hmean: float) -> float:
        # the force diverges as the mean gap closes
        return hmax - hmean

    def check_squeeze(self, shape: tuple[int, int]) -> None:
        if shape[0] * shape[1] < 2:
            raise InputError("a periodic 1x1 grid has no non-uniform mode: use an open grid")


def _offsets(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    ny, nx = shape
    iy, ix = np.divmod(np.arange(ny * nx), nx)
    return ix[:, None] - ix[None, :], iy[:, None] - iy[None, :]


#: every boundary treatment, by name (the configuration's ``grid.boundary``); an entry is
#: registered under its :attr:`Boundary.name` with its :attr:`Boundary.description`
BOUNDARIES: Registry[Boundary] = Registry("boundary")


def register(b: Boundary) -> Boundary:
    """Register the boundary ``b`` under its name, with its description as the summary."""
    return BOUNDARIES.register(b.name, b.description)(b)


#: the default boundary
OPEN = register(Open())
register(Periodic())


def boundary(value: str | Boundary) -> Boundary:
    """The boundary named ``value`` (or ``value`` itself); the one place names are checked."""
    if isinstance(value, Boundary):
        return value
    if isinstance(value, str) and value in BOUNDARIES:
        return BOUNDARIES.get(value)
    raise InputError(f"boundary = {value!r}: must be one of "
                     f"{', '.join(map(repr, BOUNDARIES))}")


def check_periodic_kernel(kind: str) -> str:
    """``kind`` when it names a periodic symbol, else :class:`InputError`."""
    if kind not in PERIODIC_KERNELS:
        raise InputError(f"periodic_kernel = {kind!r}: must be 'pixel' or 'continuous'")
    return kind
