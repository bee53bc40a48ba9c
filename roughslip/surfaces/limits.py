r"""What a scan must hold.

A scan that was read must be at least :data:`MIN_SCAN_SIDE` pixels along each axis, hold at
least one valid point, and not be flat: its rms height above :data:`FLAT_RELIEF` times its
largest absolute height (:func:`check_scan`). The same rules apply to what the preparation of
a run leaves (crop, down-sampling, tiles, detrending; :mod:`roughslip.surfaces.topography`).
"""

from __future__ import annotations

import numpy as np

from roughslip.errors import InputError

#: The smallest scan side, in pixels, along each axis. Every statistic ``roughslip
#: topography`` prints and every preparation step is defined from 4 on: the rms slope needs 2
#: points per axis (differences), the rms curvature 3 (a central second difference), the
#: ``curvature`` detrend 3 distinct coordinates per axis (a quadric), and the Hann window of
#: the power spectrum is zero on the edge rows and columns, so it keeps two rows and columns
#: of a 4-pixel side (one of a 3-pixel side, nothing of a 2-pixel side, where the windowed
#: spectrum is 0 / 0). A Hurst exponent needs far more (about 32 per side for three
#: wavenumber bins in its fit); without them it is reported as not estimated, not refused.
MIN_SCAN_SIDE = 4

#: the rule of :data:`MIN_SCAN_SIDE`, as messages state it
SIDE_RULE = f"a scan must be at least {MIN_SCAN_SIDE} x {MIN_SCAN_SIDE} pixels"

#: A scan whose rms height is at most this fraction of its largest absolute height is flat:
#: a constant, or a constant plus rounding. Float64 heights resolve 2.2e-16 of their
#: magnitude, so at 1e-12 the variation spans only about 4,500 rounding steps of the offset
#: it sits on, fewer than four significant digits once the mean is removed; measured
#: roughness is many orders of magnitude above that. Depths in rms units (``depth_unit =
#: "rms"``) would all be 0 on such a surface, and in length units every point touches at once.
FLAT_RELIEF = 1e-12


def check_scan(h: np.ndarray, where: str, *, scale: float | None = None) -> None:
    """Refuse a height map that is too small, wholly missing or flat.

    Parameters
    ----------
    h : ndarray
        Heights ``[iy, ix]``, NaN at missing points.
    where : str
        What the messages name first: the file, or the configuration key (and the file) of
        the preparation step that made ``h``.
    scale : float, optional
        The largest absolute height of the file the flatness is measured against (default:
        that of ``h``); a tile is measured against its file's, so that a trend removed down
        to rounding leaves a flat tile.

    Raises
    ------
    InputError
        One line: ``scan.npy: 1 x 64 pixels (ny x nx): a scan must be at least 4 x 4
        pixels``, ``... every point is missing``, or ``... the heights are constant (rms
        height 0, largest |height| 5): a topography needs an rms height above 1e-12 x its
        largest |height|``.
    """
    ny, nx = h.shape
    if min(ny, nx) < MIN_SCAN_SIDE:
        raise InputError(f"{where}: {ny} x {nx} pixels (ny x nx): {SIDE_RULE}")
    finite = h[np.isfinite(h)]
    if finite.size == 0:
        raise InputError(f"{where}: every point is missing (NaN or masked)")
    rms = float(np.sqrt(np.mean((finite - finite.mean()) ** 2)))
    top = float(np.max(np.abs(finite))) if scale is None else float(scale)
    if not rms > FLAT_RELIEF * top:
        of = "" if scale is None else " of the file"
        raise InputError(f"{where}: the heights are constant (rms height {rms:.3g}, largest "
                         f"|height|{of} {top:.3g}): a topography needs an rms height above "
                         f"{FLAT_RELIEF:g} x its largest |height|")
