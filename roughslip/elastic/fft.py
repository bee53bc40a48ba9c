"""Real 2-D FFTs behind one door: pyfftw (planned once) or scipy.fft.

A :class:`RealFFT2` owns the buffers of one transform shape. ``forward(src, dst)`` computes the
unnormalised ``rfft2`` and ``backward(src, dst)`` the unnormalised inverse (callers fold the
``1/(m0 m1)`` into their kernels, which saves a pass over the data). With pyfftw the plans are
made once per buffer pair with ``FFTW_ESTIMATE`` (bitwise reproducible across processes) and an
explicit thread count; with scipy every call allocates its result, which is then copied.

The backend is chosen by name: ``"pyfftw"``, ``"scipy"`` or ``"auto"`` (pyfftw when it imports,
else scipy with one warning).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import scipy.fft

from roughslip.errors import InputError

_PYFFTW: Any = None
_PYFFTW_ERROR: str | None = None
_WARNED = False

BACKENDS = ("auto", "pyfftw", "scipy")
#: plans remembered by the identity of their arrays (beyond, the memo starts afresh: views
#: made anew for every call would only pile up)
MEMO_LIMIT = 64


def _import_pyfftw():
    global _PYFFTW, _PYFFTW_ERROR
    if _PYFFTW is None and _PYFFTW_ERROR is None:
        try:
            import pyfftw

            _PYFFTW = pyfftw
        except Exception as exc:  # ImportError, or a broken shared library
            _PYFFTW_ERROR = f"{type(exc).__name__}: {exc}"
    return _PYFFTW


def resolve_backend(name: str) -> str:
    """Return the concrete backend (``"pyfftw"`` or ``"scipy"``) for a requested name.

    ``"auto"`` falls back to scipy with a single :class:`RuntimeWarning` per process when pyfftw
    cannot be imported; an explicit ``"pyfftw"`` that cannot be imported is an error.
    """
    global _WARNED
    if name not in BACKENDS:
        raise InputError(f"fft = {name!r}: must be one of {', '.join(BACKENDS)}")
    if name == "scipy":
        return "scipy"
    if _import_pyfftw() is not None:
        return "pyfftw"
    if name == "pyfftw":
        raise InputError(f"fft = 'pyfftw' but pyfftw cannot be imported ({_PYFFTW_ERROR})")
    if not _WARNED:
        warnings.warn(
            f"pyfftw unavailable ({_PYFFTW_ERROR}); using scipy.fft, which is slower",
            RuntimeWarning,
            stacklevel=2,
        )
        _WARNED = True
    return "scipy"


def fast_len(n: int) -> int:
    """Smallest fast real-FFT length >= n (5-smooth), as :func:`scipy.fft.next_fast_len`."""
    return int(scipy.fft.next_fast_len(int(n), real=True))


def library_versions() -> dict[str, str]:
    """Versions of the FFT libraries, for provenance."""
    out = {"scipy": scipy.__version__, "numpy": np.__version__}
    if _import_pyfftw() is not None:
        out["pyfftw"] = getattr(_PYFFTW, "__version__", "unknown")
    return out


class RealFFT2:
    """Planned real-to-complex 2-D FFT pair of a fixed real shape ``(m0, m1)``.

    Parameters
    ----------
    shape : (m0, m1)
        Real-space shape; the half spectrum has shape ``(m0, m1 // 2 + 1)``.
    backend : {"auto", "pyfftw", "scipy"}
    threads : int
        FFT threads (default 1: FFT and BLAS thread pools competing for the same cores
        were measured up to 60x slower; see :mod:`roughslip.linalg.threads`).
    rows : int, optional
        Pruning for zero-padded data: inputs are zero beyond row ``rows`` and only the first
        ``rows`` output rows are wanted. The transforms along axis 1 then run on ``rows`` rows
        instead of ``m0`` (exactly the same result on those rows; about 25 % fewer operations
        when ``m0 = 2 rows``). Rows ``>= rows`` of a backward output are left undefined.
    """

    def __init__(self, shape: tuple[int, int], backend: str = "auto", threads: int = 1,
                 rows: int | None = None) -> None:
        if len(shape) != 2 or min(shape) < 1:
            raise InputError(f"FFT shape {shape!r}: must be two positive lengths")
        if int(threads) < 1:
            raise InputError(f"fft threads = {threads!r}: must be >= 1")
        self.shape = (int(shape[0]), int(shape[1]))
        self.spectrum_shape = (self.shape[0], self.shape[1] // 2 + 1)
        self.size = self.shape[0] * self.shape[1]
        self.backend = resolve_backend(backend)
        self.threads = int(threads)
        self.rows = self.shape[0] if rows is None else int(rows)
        if not 1 <= self.rows <= self.shape[0]:
            raise InputError(f"rows = {rows!r}: must be in 1..{self.shape[0]}")
        self.pruned = self.rows < self.shape[0]
        self._plans: dict[tuple[str, int, int], Any] = {}
        #: the plans by the identity of the arrays (holding them, so that no other object
        #: takes their ids while the entry lives)
        self._memo: dict[tuple[str, int, int], tuple[Any, np.ndarray, np.ndarray]] = {}
        #: Number of forward and backward transforms executed (for profiling).
        self.count = 0

    # -- buffers ------------------------------------------------------------------------------
    def real_buffer(self, zero: bool = True) -> np.ndarray:
        """A new (aligned) real array of the transform shape."""
        if self.backend == "pyfftw":
            buf = _PYFFTW.empty_aligned(self.shape, dtype="float64")
        else:
            buf = np.empty(self.shape)
        if zero:
            buf[...] = 0.0
        return buf

    def spectrum_buffer(self) -> np.ndarray:
        """A new (aligned) complex half-spectrum array."""
        if self.backend == "pyfftw":
            buf = _PYFFTW.empty_aligned(self.spectrum_shape, dtype="complex128")
        else:
            buf = np.empty(self.spectrum_shape, dtype=complex)
        buf[...] = 0.0
        return buf

    # -- transforms ---------------------------------------------------------------------------
    def _plan(self, kind: str, src: np.ndarray, dst: np.ndarray):
        # the plan of the same array objects as last time, without reading their addresses
        memo = self._memo.get((kind, id(src), id(dst)))
        if memo is not None and memo[1] is src and memo[2] is dst:
            return memo[0]
        key = (kind, src.ctypes.data, dst.ctypes.data)
        plan = self._plans.get(key)
        if plan is None:
            k = self.rows
            est = ("FFTW_ESTIMATE",)
            direction = "FFTW_FORWARD" if kind in ("f", "fr", "fc") else "FFTW_BACKWARD"
            destroy = ("FFTW_DESTROY_INPUT",) if kind in ("b", "br") else ()
            if kind in ("f", "b"):  # full 2-D transform
                a, b, axes = src, dst, (0, 1)
            elif kind == "fr":  # rows: real -> half spectrum, first k rows only
                a, b, axes = src[:k], dst[:k], (1,)
            elif kind in ("fc", "bc"):  # columns, in place on the spectrum
                a, b, axes = dst, dst, (0,)
            else:  # "br": half spectrum -> real, first k rows only
                a, b, axes = src[:k], dst[:k], (1,)
            fftw = _PYFFTW.FFTW(a, b, axes=axes, direction=direction, flags=est + destroy,
                                threads=self.threads)
            # keep the arrays alive with the plan so that their addresses are not reused
            plan = self._plans[key] = (fftw, src, dst)
        if len(self._memo) >= MEMO_LIMIT:
            self._memo.clear()
        self._memo[(kind, id(src), id(dst))] = (plan[0], src, dst)
        return plan[0]

    def forward(self, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        """Unnormalised ``rfft2`` of ``src`` (real, transform shape) into ``dst``."""
        self.count += 1
        k = self.rows
        if self.backend == "pyfftw":
            if self.pruned:
                self._plan("fr", src, dst).execute()
                dst[k:] = 0.0
                self._plan("fc", dst, dst).execute()
            else:
                self._plan("f", src, dst).execute()
        elif self.pruned:
            half = scipy.fft.rfft(src[:k], axis=1, workers=self.threads)
            np.copyto(dst, scipy.fft.fft(half, n=self.shape[0], axis=0, workers=self.threads))
        else:
            np.copyto(dst, scipy.fft.rfftn(src, axes=(0, 1), workers=self.threads))
        return dst

    def backward(self, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
        """Unnormalised inverse of :meth:`forward`; ``src`` is destroyed.

        With pruning only the first ``rows`` rows of ``dst`` are written.
        """
        self.count += 1
        k = self.rows
        if self.backend == "pyfftw":
            if self.pruned:
                self._plan("bc", src, src).execute()
                self._plan("br", src, dst).execute()
            else:
                self._plan("b", src, dst).execute()
        elif self.pruned:
            cols = scipy.fft.ifft(src, axis=0, workers=self.threads, norm="forward",
                                  overwrite_x=True)
            dst[:k] = scipy.fft.irfft(cols[:k], n=self.shape[1], axis=1, workers=self.threads,
                                      norm="forward")
        else:
            np.copyto(
                dst,
                scipy.fft.irfftn(
                    src, s=self.shape, axes=(0, 1), workers=self.threads, norm="forward",
                    overwrite_x=True,
                ),
            )
        return dst
