r"""The contact problem: a rigid rough surface against an elastic half-space on a pixel grid.

A :class:`Problem` holds what every solver needs and nothing a solver decides: the grid and its
boundary, the material, the heights of the rigid (composite) surface, the overlap at a depth,
and a cache of the convolution operator, whose kernel spectra are built when a solver first
asks for them. The squeeze needs only :math:`G_{zz}`, the decoupled pull :math:`G_{xx}`, the
coupled model :math:`G_{zz}, G_{zx}, G_{xx}`: a scene computes the kernels it uses and no
other.

Problems of an ensemble share one operator: :meth:`Problem.with_heights` makes the problem of
another surface on the same grid and material, reusing the kernels already built.

Conventions: arrays are indexed ``[iy, ix]`` (x the last axis); heights are positive toward the
elastic body; the depth :math:`D_z` is measured from the first touch of the highest point, so
the imposed overlap is

.. math:: \bar u_i(D_z) = D_z - (\max_j h_j - h_i).
"""

from __future__ import annotations

import math

import numpy as np

from roughslip.elastic.operators import ElasticOperator, Grid, Material
from roughslip.errors import InputError
from roughslip.linalg.restricted import Restricted


def check_heights(heights: np.ndarray, name: str = "heights") -> np.ndarray:
    """Return ``heights`` as a C-contiguous float64 2-D array, or raise :class:`InputError`."""
    h = np.asarray(heights)
    if h.ndim != 2:
        raise InputError(f"{name}: must be a 2-D array, got {h.ndim} dimension(s)")
    if h.size == 0:
        raise InputError(f"{name}: is empty")
    if not np.issubdtype(h.dtype, np.number) or np.iscomplexobj(h):
        raise InputError(f"{name}: must be real numbers, got dtype {h.dtype}")
    h = np.ascontiguousarray(h, dtype=float)
    if not np.all(np.isfinite(h)):
        bad = np.argwhere(~np.isfinite(h))[0]
        raise InputError(f"{name}: non-finite value at [iy, ix] = {bad.tolist()}")
    return h


def finite(value: object, name: str) -> float:
    """``value`` as a finite float, or :class:`InputError` naming ``name``."""
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name} = {value!r}: must be a number") from None
    if not math.isfinite(x):
        raise InputError(f"{name} = {value!r}: must be finite")
    return x


class _Kernels:
    """The operator of one grid and material, shared by the problems built on it."""

    def __init__(self, grid: Grid, material: Material, fft: str, threads: int) -> None:
        self.grid, self.material, self.fft, self.threads = grid, material, fft, int(threads)
        self.op: ElasticOperator | None = None

    def operator(self, components: tuple[str, ...]) -> ElasticOperator:
        if self.op is None:
            self.op = self.grid.operator(self.material, components, fft=self.fft,
                                         threads=self.threads)
        return self.op.require(components)


class Problem:
    """A rigid rough surface, an elastic half-space and the grid they are discretised on.

    Parameters
    ----------
    heights : ndarray, shape (ny, nx)
        Heights of the rigid (composite) surface, positive toward the elastic body.
    grid : Grid, optional
        Pixel size and boundary (default: unit pixels, open boundary).
    material : Material, optional
        Elastic constants (default ``E = 1``, ``nu = 0.3``).
    fft : {"auto", "pyfftw", "scipy"}
        FFT backend of the operator.
    threads : int
        FFT (and BLAS, for the dense solvers) threads.

    Examples
    --------
    >>> import numpy as np
    >>> from roughslip.contact.problem import Problem
    >>> p = Problem(np.zeros((4, 4)))
    >>> float(p.overlap(0.5).max()), p.operator("zz").components
    (0.5, ('zz',))
    """

    def __init__(self, heights: np.ndarray, grid: Grid | None = None,
                 material: Material | None = None, *, fft: str = "auto",
                 threads: int = 1) -> None:
        h = check_heights(heights)
        grid = Grid(h.shape) if grid is None else grid
        if h.shape != grid.shape:
            raise InputError(f"heights shape {h.shape} != grid shape {grid.shape}")
        if int(threads) < 1:
            raise InputError(f"threads = {threads!r}: must be >= 1")
        self._set(h, _Kernels(grid, material or Material(), fft, int(threads)))

    def _set(self, h: np.ndarray, kernels: _Kernels) -> None:
        self.heights = h
        self._kernels = kernels
        self.hmax = float(h.max())
        self.hmean = float(h.mean())
        #: overlap at first touch, :math:`h - \max h`; the overlap at D is ``D + base``
        self.base = h - self.hmax

    @classmethod
    def from_arrays(cls, heights: np.ndarray, *, a: float = 1.0, E: float = 1.0,
                    nu: float = 0.3, boundary: str = "open", periodic_kernel: str = "pixel",
                    fft: str = "auto", threads: int = 1) -> Problem:
        """A problem from plain numbers (what :func:`roughslip.squeeze` takes)."""
        h = check_heights(heights)
        return cls(h, Grid(h.shape, a, boundary, periodic_kernel), Material(E, nu), fft=fft,
                   threads=threads)

    def with_heights(self, heights: np.ndarray) -> Problem:
        """The problem of another surface on the same grid and material, sharing the
        operator (and the kernels already built)."""
        h = check_heights(heights)
        if h.shape != self.grid.shape:
            raise InputError(f"heights shape {h.shape} != grid shape {self.grid.shape}")
        p = object.__new__(Problem)
        p._set(h, self._kernels)
        return p

    # -- what the problem is ---------------------------------------------------------------
    @property
    def grid(self) -> Grid:
        return self._kernels.grid

    @property
    def material(self) -> Material:
        return self._kernels.material

    @property
    def shape(self) -> tuple[int, int]:
        return self.grid.shape

    @property
    def fft(self) -> str:
        return self._kernels.fft

    @property
    def threads(self) -> int:
        return self._kernels.threads

    def overlap(self, depth: float) -> np.ndarray:
        r"""The imposed overlap :math:`\bar u = D_z - (\max h - h)` at depth ``depth``."""
        return self.base + float(depth)

    def depth_limit(self) -> float:
        r"""The largest depth displacement control accepts: :math:`\max h - \bar h` on
        periodic grids (the force diverges as the mean gap closes), infinite on open ones."""
        return self.grid.boundary.depth_limit(self.hmax, self.hmean)

    def check_depth(self, depth: float) -> float:
        """``depth`` as a float, checked: finite, and below :meth:`depth_limit`."""
        depth = finite(depth, "depth")
        if depth >= self.depth_limit():
            raise InputError(
                f"depth = {depth:g}: on a {self.grid.boundary} grid displacement control needs "
                f"depth < max(h) - mean(h) = {self.depth_limit():g} (the force diverges "
                "as the mean gap closes); use load control (force=...) instead"
            )
        return depth

    # -- operators ---------------------------------------------------------------------------
    def operator(self, *components: str) -> ElasticOperator:
        """The convolution operator, with the spectra of ``components`` built (once)."""
        return self._kernels.operator(tuple(components) or ("zz",))

    def restricted(self, component: str, mask: np.ndarray) -> Restricted:
        r""":math:`G_{cc}[K, K]` for a diagonal component (``"zz"``, ``"xx"``, ``"yy"``) and a
        mask :math:`K`, as a linear operator (:class:`~roughslip.linalg.restricted.Restricted`).
        """
        if component not in ("zz", "xx", "yy"):
            raise InputError(f"restricted({component!r}): a principal sub-block needs a "
                             "diagonal component (zz, xx or yy)")
        op = self.operator(component)
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != self.shape:
            raise InputError(f"mask shape {mask.shape} != grid shape {self.shape}")
        return Restricted(lambda v, out: op.apply(component, v, out=out), mask)

    def restricted_block(self, contact: np.ndarray, stick: np.ndarray,
                         threads: int | None = None) -> Restricted:
        r"""The coupled block on the contact set :math:`C` (normal unknowns) and the stick set
        :math:`S` (tangential unknowns), acting on stacked fields ``[f_z, f_x]``:

        .. math::

            \begin{bmatrix} G_{zz}(C,C) & G_{zx}(C,S) \\ G_{xz}(S,C) & G_{xx}(S,S)
            \end{bmatrix}.
        """
        op = self.operator("zz", "zx", "xx")
        if threads is not None:
            op = op.with_threads(threads)
        mask = np.stack([np.asarray(contact, bool), np.asarray(stick, bool)])
        if mask.shape[1:] != self.shape:
            raise InputError(f"mask shape {mask.shape[1:]} != grid shape {self.shape}")
        return Restricted(op.apply_stacked, mask)

    def __repr__(self) -> str:
        g, m = self.grid, self.material
        return (f"Problem({g.shape[0]}x{g.shape[1]}, a={g.a:g}, {g.boundary}, E={m.E:g}, "
                f"nu={m.nu:g})")
