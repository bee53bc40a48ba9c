"""A boundary whose FFT lengths are powers of two (the recipe "a boundary" of
docs/extending.md): one subclass of :class:`~roughslip.elastic.boundaries.Boundary` and one
entry of :data:`~roughslip.elastic.boundaries.BOUNDARIES`. It is the open boundary, a finite
patch on a half-space, zero-padded to the smallest power of two of at least ``2n - 1`` per
axis instead of the smallest length with small prime factors: what a user whose FFT library
is fast only on powers of two would add. Its kernel spectrum, its real-space tables and its
dense reference are the open boundary's, laid out on its own FFT grid, so the shared suite
checks it against the dense matrix and against the open boundary to round-off."""

from __future__ import annotations

from roughslip.elastic.boundaries import Open, register


class OpenPow2(Open):
    """A finite patch on a half-space, on power-of-two FFT grids."""

    name = "open-pow2"
    description = "finite patch on a half-space, FFT lengths powers of two"

    def padded_shape(self, shape: tuple[int, int]) -> tuple[int, int]:
        ny, nx = shape
        return 1 << (2 * ny - 2).bit_length(), 1 << (2 * nx - 2).bit_length()


register(OpenPow2())
