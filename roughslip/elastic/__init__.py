"""The elastic half-space: pixel Green functions (:mod:`.green`), FFT plans (:mod:`.fft`) and the
convolution operators that tie pixel forces to surface displacements (:mod:`.operators`)."""
