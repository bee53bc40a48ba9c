"""Surfaces: synthetic topographies and their statistics (:mod:`.synthetic`), and measured
topographies read from instrument files (:mod:`.topography`)."""

from roughslip.surfaces.synthetic import (
    hurst_estimate,
    load_topography,
    plane,
    punch,
    radial_psd,
    rms_height_of,
    rms_slope_of,
    sample_rng,
    self_affine,
    sinusoid,
    sphere,
)

__all__ = ["hurst_estimate", "load_topography", "plane", "punch", "radial_psd",
           "rms_height_of", "rms_slope_of", "sample_rng", "self_affine", "sinusoid", "sphere"]
