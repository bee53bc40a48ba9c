r"""Convolution operators :math:`u_a = \sum_b G_{ab} * f_b` on a pixel grid.

The boundary treatment (open: a finite patch on a half-space; periodic: a repeating grid) is a
:class:`~roughslip.elastic.boundaries.Boundary` object (docs/theory/boundaries.rst#boundaries);
grids and operators accept its name.

An operator computes the spectra of the components it is asked for, once, at construction;
nothing else. Applying it allocates nothing when an ``out`` array is given (pyfftw backend).
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.sparse.linalg import LinearOperator

from roughslip.elastic import green
from roughslip.elastic.boundaries import (
    BOUNDARIES,
    OPEN,
    PERIODIC_KERNELS,
    Boundary,
    check_periodic_kernel,
)
from roughslip.elastic.boundaries import boundary as as_boundary
from roughslip.elastic.fft import RealFFT2
from roughslip.elastic.green import CANONICAL as _CANONICAL
from roughslip.elastic.tables import KernelTables
from roughslip.errors import InputError

__all__ = ["BOUNDARIES", "PERIODIC_KERNELS", "Boundary", "ElasticOperator", "Grid", "Material",
           "padded_shape"]


@dataclass(frozen=True)
class Material:
    r"""Isotropic elastic half-space.

    Attributes
    ----------
    E : float
        Young's modulus (stress units).
    nu : float
        Poisson ratio, :math:`-1 < \nu \le 1/2`.
    """

    E: float = 1.0
    nu: float = 0.3

    def __post_init__(self) -> None:
        green.check_material(self.E, self.nu)

    @property
    def E_star(self) -> float:
        r"""Contact modulus :math:`E^* = E/(1-\nu^2)` (rigid indenter on the half-space)."""
        return self.E / (1.0 - self.nu * self.nu)

    @property
    def mu(self) -> float:
        r"""Shear modulus :math:`\mu = E/(2(1+\nu))`."""
        return self.E / (2.0 * (1.0 + self.nu))

    @property
    def coupled(self) -> bool:
        r"""True unless :math:`\nu = 1/2`, where :math:`G_{zx}` vanishes identically."""
        return self.nu != 0.5


@dataclass(frozen=True)
class Grid:
    """A pixel grid: shape ``(ny, nx)``, pixel side ``a`` and boundary treatment."""

    shape: tuple[int, int]
    a: float = 1.0
    boundary: Boundary = OPEN  # or its name
    periodic_kernel: str = "pixel"

    def __post_init__(self) -> None:
        object.__setattr__(self, "shape", _check_grid(tuple(self.shape), self.a))
        object.__setattr__(self, "boundary", as_boundary(self.boundary))
        check_periodic_kernel(self.periodic_kernel)

    @property
    def size(self) -> int:
        """Number of pixels."""
        return self.shape[0] * self.shape[1]

    @property
    def area(self) -> float:
        """Nominal area ``ny nx a²``."""
        return self.size * self.a * self.a

    def operator(self, material: Material, components: Iterable[str], fft: str = "auto",
                 threads: int = 1) -> ElasticOperator:
        """An :class:`ElasticOperator` on this grid for the given components."""
        return ElasticOperator(self.shape, a=self.a, material=material, boundary=self.boundary,
                               periodic_kernel=self.periodic_kernel, components=components,
                               fft=fft, threads=threads)


def padded_shape(shape: tuple[int, int], kind: str | Boundary) -> tuple[int, int]:
    """The FFT grid of an operator on a grid of ``shape`` (:meth:`Boundary.padded_shape`)."""
    return as_boundary(kind).padded_shape(shape)


def _check_grid(shape: tuple[int, int], a: float) -> tuple[int, int]:
    if len(shape) != 2:
        raise InputError(f"grid shape {shape!r}: must be (ny, nx)")
    ny, nx = (int(s) for s in shape)
    if ny < 1 or nx < 1 or ny != shape[0] or nx != shape[1]:
        raise InputError(f"grid shape {shape!r}: both lengths must be integers >= 1")
    if not (isinstance(a, int | float) and math.isfinite(a) and a > 0):
        raise InputError(f"pixel size a = {a!r}: must be a finite number > 0")
    return ny, nx


class ElasticOperator:
    r"""FFT convolution with the pixel Green functions of an elastic half-space.

    Parameters
    ----------
    shape : (ny, nx)
        Grid shape; fields are indexed ``[iy, ix]`` and x is the last axis.
    a : float
        Pixel side.
    material : Material
        Elastic constants.
    boundary : Boundary or {"open", "periodic"}
    periodic_kernel : {"pixel", "continuous"}
        Periodic symbol (ignored for open grids).
    components : iterable of str
        The components that will be applied, e.g. ``("zz",)`` for a squeeze, ``("xx",)`` for a
        pull, ``("zz", "zx", "xx")`` for the coupled block. Only these spectra are built.
    fft : {"auto", "pyfftw", "scipy"}
    threads : int
        FFT threads.

    Notes
    -----
    ``apply("zz", f)`` returns :math:`u_z(i) = \sum_j G_{zz}(i-j) f_z(j)`, exact linear (open)
    or circular (periodic) convolution; see docs/theory/boundaries.rst#boundaries.
    """

    def __init__(
        self,
        shape: tuple[int, int],
        *,
        a: float = 1.0,
        material: Material | None = None,
        boundary: str | Boundary = "open",
        periodic_kernel: str = "pixel",
        components: Iterable[str] = ("zz",),
        fft: str = "auto",
        threads: int = 1,
    ) -> None:
        self.shape = _check_grid(tuple(shape), a)
        self.a = float(a)
        self.material = material if material is not None else Material()
        self.boundary = as_boundary(boundary)
        self.periodic_kernel = check_periodic_kernel(periodic_kernel)
        self.padded_shape = self.boundary.padded_shape(self.shape)
        # open grids: only the first ny rows carry data in and out (pruned row transforms)
        self.fft = RealFFT2(self.padded_shape, backend=fft, threads=threads,
                            rows=self.boundary.data_rows(self.shape))
        self._kernel_fft = RealFFT2(self.padded_shape, backend=fft, threads=threads)
        self._in = self.fft.real_buffer()
        self._out = self.fft.real_buffer()
        self._spec = [self.fft.spectrum_buffer() for _ in range(2)]
        self._work = None
        self._full: list[np.ndarray] = []  # the spectra of :meth:`apply_full`, when used
        #: the :meth:`work_buffer` arrays by name, and the addresses of those that
        #: :meth:`apply` transforms directly
        self._work_buffers: dict[str, np.ndarray] = {}
        self._direct: set[int] = set()
        self._khat: dict[str, np.ndarray] = {}
        #: kernel tables in real space, built on demand (shared with thread views)
        self.tables = KernelTables(self)
        self.setup_seconds = 0.0
        requested = list(components)
        for c in requested:
            if c not in _CANONICAL:
                raise InputError(f"unknown component {c!r}; use one of {tuple(_CANONICAL)}")
        t0 = time.perf_counter()
        for c in dict.fromkeys(_CANONICAL[c][0] for c in requested):
            self._khat[c] = self._build_spectrum(c)
        self.setup_seconds = time.perf_counter() - t0
        #: seconds spent inside FFT calls by :meth:`apply` / :meth:`apply_block`
        self.fft_seconds = 0.0
        #: number of convolutions applied (one forward + one backward FFT each)
        self.applications = 0

    # -- memory -------------------------------------------------------------------------------
    @staticmethod
    def footprint(shape: tuple[int, int], boundary: str | Boundary = "open",
                  components: Iterable[str] = ("zz",)) -> int:
        """Bytes an operator on a grid of ``shape`` holds at most, before it is built.

        Three real arrays on the FFT grid (input, output, the kernels' transform), four half
        spectra (two work spectra, the kernels' transform, one temporary) and, per component,
        its half spectrum and both real-space tables (:attr:`tables`: the window table and the
        pair table, ``(2ny - 1)(2nx - 1)`` or ``4 ny nx`` doubles each, built on first use).
        :attr:`nbytes` counts what an operator holds; it never exceeds this bound (tested).
        """
        ny, nx = shape
        py, px = as_boundary(boundary).padded_shape((ny, nx))
        half = 16 * py * (px // 2 + 1)
        per_component = half + 2 * 8 * 4 * ny * nx
        return int(3 * 8 * py * px + 4 * half + len(tuple(components)) * per_component)

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays this operator holds now: buffers, spectra and the kernel tables
        built so far."""
        arrays = [self._in, self._out, *self._spec, *self._khat.values()]
        return sum(a.nbytes for a in arrays) + self.tables.nbytes

    # -- construction -------------------------------------------------------------------------
    @property
    def components(self) -> tuple[str, ...]:
        """The canonical components whose spectra exist."""
        return tuple(self._khat)

    def _build_spectrum(self, c: str) -> np.ndarray:
        def forward(K: np.ndarray) -> np.ndarray:
            buf = self._kernel_fft.real_buffer(zero=False)
            buf[...] = K
            spec = self._kernel_fft.spectrum_buffer()
            self._kernel_fft.forward(buf, spec)
            return spec

        return self.boundary.spectrum(c, self.shape, self.padded_shape, self.a,
                                      self.material.E, self.material.nu, self.periodic_kernel,
                                      forward)

    def real_kernel(self, component: str) -> np.ndarray:
        """A component's kernel in real space on the FFT grid: the inverse FFT of its stored
        spectrum (a new array)."""
        spec = self._kernel_fft.spectrum_buffer()
        np.copyto(spec, self.spectrum(component))
        K = self._kernel_fft.real_buffer(zero=False)
        self._kernel_fft.backward(spec, K)
        return K

    def spectrum(self, component: str) -> np.ndarray:
        """The (scaled) half-spectrum used for a component; raises if it was not built."""
        canon, sign = _CANONICAL[component]
        try:
            k = self._khat[canon]
        except KeyError:
            raise InputError(
                f"component {component!r} was not requested when this operator was built "
                f"(it has {self.components})"
            ) from None
        return k if sign > 0 else -k

    def require(self, components: Iterable[str]) -> ElasticOperator:
        """Build the spectra of ``components`` that this operator does not have yet.

        Lets one operator per grid serve every stage of a scene, each asking only for what it
        applies (the squeeze ``zz``, the pull ``xx``, the coupled model all three). Returns
        the operator itself.
        """
        t0 = time.perf_counter()
        for c in components:
            if c not in _CANONICAL:
                raise InputError(f"unknown component {c!r}; use one of {tuple(_CANONICAL)}")
            canon = _CANONICAL[c][0]
            if canon not in self._khat:
                self._khat[canon] = self._build_spectrum(canon)
        self.setup_seconds += time.perf_counter() - t0
        return self

    def with_threads(self, threads: int) -> ElasticOperator:
        """An operator sharing this one's spectra and kernel tables that applies with
        ``threads`` FFT threads, with its own transforms, buffers and counters.

        Used by the dense pull and coupled solvers: right after a threaded BLAS-3 call,
        OpenBLAS's spinning threads made a two-thread FFTW convolution about 40 times slower
        than a single-threaded one on two cores (a padded grid of 256 x 256). Views are cached per
        thread count; the operator itself is never modified, so views can be used side by side.
        """
        threads = int(threads)
        if threads == self.fft.threads:
            return self
        views = self.__dict__.setdefault("_views", {})
        view = views.get(threads)
        if view is None:
            view = copy.copy(self)  # shares _khat and the table caches (same dict objects)
            view.fft = RealFFT2(self.padded_shape, backend=self.fft.backend, threads=threads,
                                rows=self.fft.rows if self.fft.pruned else None)
            view._in = view.fft.real_buffer()
            view._out = view.fft.real_buffer()
            view._spec = [view.fft.spectrum_buffer() for _ in range(2)]
            view._work = None
            view._full = []
            view.fft_seconds = 0.0
            view.applications = 0
            view.__dict__["_views"] = {}
            views[threads] = view
        return view

    # -- application --------------------------------------------------------------------------
    def _check_field(self, f: np.ndarray, name: str = "f") -> None:
        if f.shape != self.shape:
            raise InputError(f"{name} has shape {f.shape}, operator grid is {self.shape}")

    def work_buffer(self, name: str) -> np.ndarray:
        """The operator's field ``name`` of the grid's shape, for repeated :meth:`apply` calls:
        created (zeroed) at the first request, the same array after that, also for every
        solver and thread view of this operator, so its user must set it before each use.

        On a grid that is its own transform grid (periodic) and with the pyfftw backend, it is
        aligned for the FFT, and :meth:`apply` transforms it directly, as input or as output,
        instead of copying it through the operator's buffers (one plan per buffer and
        direction, made once). The numbers are bitwise those of any other array (tested): the
        plans see the same sizes, strides and alignment. These fields are the solvers' work
        arrays: :attr:`nbytes` and :meth:`footprint` do not count them (a run's memory
        estimate counts them with the solver's).
        """
        buf = self._work_buffers.get(name)
        if buf is None:
            direct = self.padded_shape == self.shape and self.fft.backend == "pyfftw"
            buf = self.fft.real_buffer() if direct else np.zeros(self.shape)
            self._work_buffers[name] = buf
            if direct:
                self._direct.add(buf.ctypes.data)
        return buf

    def _transforms_directly(self, a: np.ndarray | None) -> bool:
        return (a is not None and a.ctypes.data in self._direct and a.flags.c_contiguous
                and a.dtype == np.float64)

    def _load(self, f: np.ndarray, spec: np.ndarray) -> None:
        ny, nx = self.shape
        self._in[:ny, :nx] = f
        t0 = time.perf_counter()
        self.fft.forward(self._in, spec)
        self.fft_seconds += time.perf_counter() - t0

    def _unload(self, spec: np.ndarray, out: np.ndarray | None) -> np.ndarray:
        ny, nx = self.shape
        t0 = time.perf_counter()
        self.fft.backward(spec, self._out)
        self.fft_seconds += time.perf_counter() - t0
        if out is None:
            return self._out[:ny, :nx].copy()
        np.copyto(out, self._out[:ny, :nx])
        return out

    def apply(self, component: str, f: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Displacement ``u_a = G_ab * f_b`` for ``component = "ab"``.

        Parameters
        ----------
        component : str
            e.g. ``"zz"``.
        f : ndarray, shape ``(ny, nx)``
            Pixel forces (traction times a²).
        out : ndarray, optional
            Result array; may be ``f`` itself (the input is copied into the FFT buffer first).
        """
        ks = self._khat_signed(component)
        self._check_field(f)
        spec = self._spec[0]
        self.applications += 1
        if self._transforms_directly(f) and self._transforms_directly(out):
            t0 = time.perf_counter()
            self.fft.forward(f, spec)
            t1 = time.perf_counter()
            self._multiply(spec, ks)
            t2 = time.perf_counter()
            self.fft.backward(spec, out)
            self.fft_seconds += (t1 - t0) + (time.perf_counter() - t2)
            return out
        self._load(f, spec)
        self._multiply(spec, ks)
        return self._unload(spec, out)

    def _khat_signed(self, component: str) -> tuple[np.ndarray, float]:
        canon, sign = _CANONICAL.get(component, (None, 0.0))
        if canon is None:
            raise InputError(f"unknown component {component!r}")
        if canon not in self._khat:
            self.spectrum(component)  # raises with a clear message
        return self._khat[canon], sign

    @staticmethod
    def _multiply(spec: np.ndarray, ks: tuple[np.ndarray, float]) -> None:
        k, sign = ks
        np.multiply(spec, k, out=spec)
        if sign < 0:
            np.negative(spec, out=spec)

    def apply_block(
        self,
        fz: np.ndarray,
        fx: np.ndarray,
        out_z: np.ndarray | None = None,
        out_x: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        r"""The coupled (z, x) block: :math:`u_z = G_{zz}f_z + G_{zx}f_x`,
        :math:`u_x = G_{xz}f_z + G_{xx}f_x` ([Report2003] eq. 3.5, corrected: erratum T14
        (docs/theory/errata.rst#erratum-t14)).

        Two forward and two backward FFTs; one forward FFT when one of the force fields is zero
        (the tangential forces of a frictionless state, the slip forces alone of the Coulomb
        law's correction): its spectrum is zero, and the terms it would add are exact zeros.
        """
        self._check_field(fz, "fz")
        self._check_field(fx, "fx")
        kzz = self._khat_signed("zz")[0]
        kzx = self._khat_signed("zx")[0]
        kxx = self._khat_signed("xx")[0]
        if self._work is None:
            self._work = (self.fft.spectrum_buffer(), self.fft.spectrum_buffer())
        sz, sx = self._spec
        w, w2 = self._work
        zero_z, zero_x = not fz.any(), not fx.any()
        if zero_z and not zero_x:  # u_z = kzx * sx, u_x = kxx * sx
            self._load(fx, sx)
            np.multiply(sx, kxx, out=w)
            np.multiply(sx, kzx, out=sz)
        elif zero_x and not zero_z:  # u_z = kzz * sz, u_x = -kzx * sz
            self._load(fz, sz)
            np.multiply(sz, kzx, out=w)
            np.negative(w, out=w)
            np.multiply(sz, kzz, out=sz)
        else:
            self._load(fz, sz)
            self._load(fx, sx)
            # u_x = -kzx * sz + kxx * sx into w; then u_z = kzz * sz + kzx * sx in place of sz.
            np.multiply(sx, kxx, out=w)
            np.multiply(sz, kzx, out=w2)
            np.subtract(w, w2, out=w)
            np.multiply(sx, kzx, out=sx)
            np.multiply(sz, kzz, out=sz)
            np.add(sz, sx, out=sz)
        self.applications += 2
        uz = self._unload(sz, out_z)
        ux = self._unload(w, out_x)
        return uz, ux

    def apply_tangential(self, fx: np.ndarray, fy: np.ndarray, out_x: np.ndarray,
                         out_y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""The tangential block: :math:`u_x = G_{xx}f_x + G_{xy}f_y`,
        :math:`u_y = G_{yx}f_x + G_{yy}f_y` (:math:`G_{yx} = G_{xy}`), the sums taken in
        Fourier space: two forward and two backward FFTs."""
        self._check_field(fx, "fx")
        self._check_field(fy, "fy")
        kxx, sxx = self._khat_signed("xx")
        kxy, sxy = self._khat_signed("xy")
        kyy, syy = self._khat_signed("yy")
        if self._work is None:
            self._work = (self.fft.spectrum_buffer(), self.fft.spectrum_buffer())
        sx, sy = self._spec
        w, w2 = self._work
        self._load(fx, sx)
        self._load(fy, sy)
        np.multiply(sx, kxx if sxx > 0 else -kxx, out=w)  # u_x
        np.multiply(sy, kxy if sxy > 0 else -kxy, out=w2)
        np.add(w, w2, out=w)
        np.multiply(sx, kxy if sxy > 0 else -kxy, out=sx)  # u_y
        np.multiply(sy, kyy if syy > 0 else -kyy, out=sy)
        np.add(sx, sy, out=sx)
        self.applications += 2
        return self._unload(w, out_x), self._unload(sx, out_y)

    def apply_full(self, F: np.ndarray, out: np.ndarray) -> np.ndarray:
        r"""All three displacement components of all three force components,
        :math:`u_a = \sum_b G_{ab} f_b` for ``F`` and ``out`` stacked as :math:`(z, x, y)`,
        shape ``(3, ny, nx)``, the sums taken in Fourier space: one forward FFT per nonzero
        force component and three backward ones. Needs the spectra of ``zz``, ``zx``, ``zy``,
        ``xx``, ``xy`` and ``yy``."""
        names = "zxy"
        if len(self._full) < 5:
            self._full = [self.fft.spectrum_buffer() for _ in range(5)]
        spec, acc, tmp = self._full[:3], self._full[3], self._full[4]
        loaded = []
        for b in range(3):
            self._check_field(F[b], "f" + names[b])
            if F[b].any():
                self._load(F[b], spec[b])
                loaded.append(b)
        for a in range(3):
            if not loaded:
                out[a] = 0.0
                continue
            for i, b in enumerate(loaded):
                k, sign = self._khat_signed(names[a] + names[b])
                target = acc if i == 0 else tmp
                np.multiply(spec[b], k, out=target)
                if i == 0:
                    if sign < 0:
                        np.negative(acc, out=acc)
                elif sign < 0:
                    np.subtract(acc, tmp, out=acc)
                else:
                    np.add(acc, tmp, out=acc)
            self._unload(acc, out[a])
        self.applications += 3
        return out

    def apply_stacked(self, v: np.ndarray, out: np.ndarray) -> np.ndarray:
        """:meth:`apply_block` on stacked fields ``v = [f_z, f_x]`` of shape ``(2, ny, nx)``."""
        self.apply_block(v[0], v[1], out[0], out[1])
        return out

    # -- adapters -----------------------------------------------------------------------------
    def as_linear_operator(self, component: str = "zz") -> LinearOperator:
        """A :class:`scipy.sparse.linalg.LinearOperator` on flattened fields (row-major)."""
        n = self.shape[0] * self.shape[1]
        transpose = {"zx": "xz", "xz": "zx", "zy": "yz", "yz": "zy"}.get(component, component)
        self._khat_signed(component)
        self._khat_signed(transpose)

        def mv(v: np.ndarray) -> np.ndarray:
            return self.apply(component, np.asarray(v, float).reshape(self.shape)).ravel()

        def rmv(v: np.ndarray) -> np.ndarray:
            return self.apply(transpose, np.asarray(v, float).reshape(self.shape)).ravel()

        return LinearOperator((n, n), matvec=mv, rmatvec=rmv, dtype=float)

    def block_linear_operator(self) -> LinearOperator:
        """The (z, x) block operator on ``concatenate([fz.ravel(), fx.ravel()])``."""
        n = self.shape[0] * self.shape[1]

        def mv(v: np.ndarray) -> np.ndarray:
            v = np.asarray(v, float).ravel()
            uz, ux = self.apply_block(v[:n].reshape(self.shape), v[n:].reshape(self.shape))
            return np.concatenate([uz.ravel(), ux.ravel()])

        return LinearOperator((2 * n, 2 * n), matvec=mv, rmatvec=mv, dtype=float)
