"""Time one operator application against a bare rfft2 + irfft2 pair of the same padded size.

    python scripts/bench_operator.py [--sizes 256 512 1024] [--repeat 7] [--threads 1]

For each grid size, boundary (open: zero-padded to fast lengths >= 2N-1; periodic: N) and FFT
backend it prints the median time of ``ElasticOperator.apply("zz", f)`` and of the bare FFT
pair on an array of the padded shape, and their ratio (the overhead of the operator: copying
in and out of the padded buffer and one complex multiply). Medians of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import os

import numpy as np
import scipy.fft
from benchlib import median_times

from roughslip.elastic.operators import ElasticOperator


def bare_pair(shape, backend: str, threads: int):
    """A function running one bare rfft2 + irfft2 pair of ``shape`` on ``backend``."""
    x = np.random.default_rng(0).standard_normal(shape)
    if backend == "pyfftw":
        import pyfftw

        a = pyfftw.empty_aligned(shape, dtype="float64")
        b = pyfftw.empty_aligned((shape[0], shape[1] // 2 + 1), dtype="complex128")
        c = pyfftw.empty_aligned(shape, dtype="float64")
        a[...] = x
        fwd = pyfftw.FFTW(a, b, axes=(0, 1), flags=("FFTW_ESTIMATE",), threads=threads)
        bwd = pyfftw.FFTW(b, c, axes=(0, 1), direction="FFTW_BACKWARD",
                          flags=("FFTW_ESTIMATE", "FFTW_DESTROY_INPUT"), threads=threads)

        def run():
            fwd.execute()
            bwd.execute()

        return run

    def run():
        scipy.fft.irfftn(scipy.fft.rfftn(x, axes=(0, 1), workers=threads), s=shape,
                         axes=(0, 1), workers=threads)

    return run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    ap.add_argument("--repeat", type=int, default=11)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    print(f"# cores: {os.cpu_count()}, FFT threads: {args.threads}, medians of {args.repeat}")
    print(f"{'N':>6} {'boundary':>9} {'backend':>8} {'padded':>11} {'apply ms':>9} "
          f"{'bare ms':>8} {'ratio':>6}")
    rng = np.random.default_rng(1)
    for n in args.sizes:
        f = rng.standard_normal((n, n))
        for boundary in ("open", "periodic"):
            for backend in ("pyfftw", "scipy"):
                op = ElasticOperator((n, n), boundary=boundary, components=("zz",),
                                     fft=backend, threads=args.threads)
                out = np.empty((n, n))
                t_op, t_bare = median_times(
                    [lambda op=op, out=out, f=f: op.apply("zz", f, out=out),
                     bare_pair(op.padded_shape, backend, args.threads)],
                    args.repeat,
                )
                shape = f"{op.padded_shape[0]}x{op.padded_shape[1]}"
                print(f"{n:>6} {boundary:>9} {backend:>8} {shape:>11} {1e3 * t_op:>9.2f} "
                      f"{1e3 * t_bare:>8.2f} {t_op / t_bare:>6.2f}", flush=True)


if __name__ == "__main__":
    main()
