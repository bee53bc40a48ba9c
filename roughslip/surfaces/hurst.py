r"""The Hurst exponent of a topography, with an uncertainty that includes the fit's systematic
error.

The power spectrum of a self-affine surface is :math:`C(q) = C_0\,q^{-2(1+H)}`
([Jacobs2017], in docs/theory/references.rst), so :math:`H` follows from the slope of
:math:`\ln C` against :math:`\ln q`. Measured and synthetic surfaces are self-affine over a
limited range only: below a roll-off wavenumber the spectrum is flat (a plateau), and near
the pixel scale it bends, down where the instrument or the pixels average (a transfer
function), up where noise or aliasing adds power ([Jacobs2017]). A fit that takes in a
plateau or a bend is biased, and the spread of the same fit over synthetic surfaces (a
parametric bootstrap) says nothing about that bias. :func:`fit_hurst` therefore

1. computes the radially averaged PSD of the Hann-windowed heights (the window limits the
   leakage of a non-periodic scan, [Jacobs2017]) in logarithmic bins, 4 per octave, up
   to the Nyquist wavenumber :math:`\pi/a`;
2. starts from the range :math:`4 q_L \le q \le \pi/(2a)` (:math:`q_L = 2\pi/L`; below
   :math:`4 q_L` the window's leakage and the size of the patch bend the spectrum, above
   :math:`\pi/(2a)` the pixels do);
3. looks in that range for a break of the slope: a continuous two-slope line
   :math:`\ln C = b - s x - \Delta s\,\max(0, x - x_b)`, :math:`x = \ln q`, is fitted at
   every bin :math:`x_b` (weighted least squares, the weights below), and a break is taken
   when it lowers :math:`\chi^2` by more than :data:`BREAK_CHI2` (a likelihood-ratio test of
   one more parameter). Of its two sides the fit keeps the one whose exponent lies in
   (0, 1), or nearer to it (a plateau and a noise floor have slopes near 0, :math:`H`
   near -1), and when both do, the longer one. Kept above the break, the break is a
   roll-off and the range starts above it (by :data:`BREAK_MARGIN`, and by two widths of the
   window's main lobe, :math:`4 q_L`); kept below, it is a noise floor or a bend of the pixel
   scale and the range ends below it (by :data:`BREAK_MARGIN`). This repeats on the range
   that is left while it spans at least :data:`MIN_OCTAVES` octaves;
4. fits :math:`\ln C = b - 2(1+H)\ln q` over the range by weighted least squares. The
   weight of a bin is its number of Fourier modes :math:`n_i` over :data:`KAPPA`: for a
   Gaussian random surface :math:`|\hat h|^2` of a mode is exponentially distributed, so the
   log of a bin's mean power has a variance of about :math:`1/n_\mathrm{ind}`, and the
   independent modes are :math:`n_\mathrm{ind} = n_i / (2 \cdot 1.5^2)` (each mode appears
   at :math:`\pm q`; the Hann window's equivalent noise bandwidth is 1.5 bins per axis);
5. states one standard deviation

   .. math::

      \sigma_H^2 = \sigma_\mathrm{stat}^2 + \delta_\mathrm{low}^2 + \delta_\mathrm{high}^2

   with :math:`\sigma_\mathrm{stat}` the least-squares standard error (scaled up by
   :math:`\sqrt{\chi^2/\nu}` when the bins scatter more than a Gaussian surface's),
   :math:`\delta_\mathrm{low}` the change of :math:`H` when the low end of the range is
   moved up by an octave (by a third of the range when it spans less than 3 octaves), and
   :math:`\delta_\mathrm{high}` the larger of the change when the high end is moved down as
   much and the change when a term :math:`c\,(q/q_\mathrm{max})^2` is fitted as well (the
   leading order of any smooth transfer function at the pixel scale, e.g. the pixel
   average's :math:`\ln\mathrm{sinc}^2(qa/2) \approx -(qa)^2/12`). For a pure power law
   these terms are about as large as :math:`\sigma_\mathrm{stat}`; where the spectrum bends
   inside the range they grow with the bias.

``scripts/hurst_validation.py`` checks the statement on surfaces from generators other than
roughslip's (docs/guide/topographies.rst#hurst-validation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from roughslip.errors import InputError

#: logarithmic wavenumber bins per octave
PER_OCTAVE = 4

#: variance of the log of a bin's mean power times its number of modes, for a Gaussian
#: random surface under the Hann window: 2 (modes at :math:`\pm q`) times :math:`1.5^2` (the
#: window's equivalent noise bandwidth per axis, squared)
KAPPA = 2 * 1.5**2

#: the fewest octaves the fit range may be cut to by a detected break
MIN_OCTAVES = 2.0

#: decrease of :math:`\chi^2` that makes a break of the slope significant: for one more
#: parameter at one place the decrease is :math:`\chi^2` with one degree of freedom, and
#: :math:`P(\chi^2_1 > 25) = 6\cdot10^{-7}`, so about :math:`10^{-5}` over the 20 places a
#: 512 x 512 scan offers
BREAK_CHI2 = 25.0

#: the range keeps this factor away from a detected break (its knee is not sharp)
BREAK_MARGIN = math.sqrt(2.0)

#: highest wavenumber of the fit as a fraction of the Nyquist wavenumber pi/a: above it the
#: pixels bend the spectrum
HIGH_END = 0.5

#: lowest wavenumber of the fit in units of q_L = 2 pi / L: below it the Hann window's
#: leakage (main lobe +-2 q_L) and the patch size bend the spectrum
LOW_START = 4.0


@dataclass(frozen=True)
class HurstFit:
    """A Hurst exponent with its uncertainty and how it was found (:func:`fit_hurst`).

    ``std`` is one standard deviation including the systematic error of the fit:
    ``std**2 = std_statistical**2 + sys_low**2 + sys_high**2``. ``rolloff`` and ``bend`` are
    the wavenumbers of a detected roll-off and of a detected noise floor or pixel-scale bend
    (None when none was found); ``psd`` holds the binned spectrum ``(q, C, modes)``.
    """

    hurst: float
    std: float
    std_statistical: float
    sys_low: float
    sys_high: float
    qmin: float
    qmax: float
    bins: int
    rolloff: float | None = None
    bend: float | None = None
    psd: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(repr=False, default=None)


def spectrum_bins(h: np.ndarray, a: float = 1.0, per_octave: int = PER_OCTAVE
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""Radially averaged PSD of the Hann-windowed heights in logarithmic bins.

    .. math:: C(q_i) = \frac{a^2}{n_y n_x}\,\big\langle |\mathrm{DFT}(w\,(h - \bar h))|^2
              \big\rangle_{q \in \text{bin } i}

    with the 2-D Hann window :math:`w` scaled to :math:`\langle w^2\rangle = 1`
    ([Jacobs2017]). Bins are ``per_octave`` per factor 2 from
    :math:`q_L = 2\pi/(\max(n_y, n_x)\,a)` to :math:`\pi/a`; a bin's wavenumber is the
    geometric mean of its modes'.

    Parameters
    ----------
    h : ndarray, shape (ny, nx)
        Heights, every one finite.
    a : float
        Pixel size.
    per_octave : int
        Bins per octave.

    Returns
    -------
    q, C, modes : ndarray
        Wavenumbers (rad per length unit), mean powers and numbers of modes of the bins
        that hold a mode.
    """
    if not np.isfinite(h).all():
        raise InputError(f"{int((~np.isfinite(h)).sum())} missing (non-finite) height(s): "
                         "a spectrum needs every point; fill them first "
                         "(roughslip.surfaces.topography.harmonic_fill)")
    ny, nx = h.shape
    w = np.outer(np.hanning(ny), np.hanning(nx))
    hh = (h - h.mean()) * w / np.sqrt(np.mean(w**2))
    p = (np.abs(np.fft.fft2(hh)) ** 2 * a * a / (ny * nx)).ravel()
    qy = 2 * np.pi * np.fft.fftfreq(ny, d=a)[:, None]
    qx = 2 * np.pi * np.fft.fftfreq(nx, d=a)[None, :]
    q = np.hypot(qx, qy).ravel()
    q_low = 2 * np.pi / (max(ny, nx) * a)
    nb = max(1, math.ceil(per_octave * math.log2((np.pi / a) / q_low) - 1e-9))
    edges = q_low * 2.0 ** (np.arange(nb + 1) / per_octave)
    edges[0] *= 1 - 1e-9
    edges[-1] = np.pi / a * (1 + 1e-9)
    idx = np.digitize(q, edges) - 1
    ok = (q > 0) & (idx >= 0) & (idx < nb)
    modes = np.bincount(idx[ok], minlength=nb)
    power = np.bincount(idx[ok], weights=p[ok], minlength=nb)
    logq = np.bincount(idx[ok], weights=np.log(q[ok]), minlength=nb)
    m = modes > 0
    return np.exp(logq[m] / modes[m]), power[m] / modes[m], modes[m]


def _line(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[float, float, float]:
    """Weighted least-squares line: slope, its standard error and chi^2 (weights 1/var)."""
    sw = w.sum()
    xm, ym = (w * x).sum() / sw, (w * y).sum() / sw
    sxx = (w * (x - xm) ** 2).sum()
    slope = (w * (x - xm) * (y - ym)).sum() / sxx
    chi2 = float((w * (y - ym - slope * (x - xm)) ** 2).sum())
    return float(slope), float(1 / math.sqrt(sxx)), chi2


def _break(x: np.ndarray, y: np.ndarray, w: np.ndarray
           ) -> tuple[float, float, float, float]:
    """The bin where a continuous two-slope line lowers chi^2 most against one line:
    ``(decrease, x_b, slope below, slope above)``; a decrease of 0 for fewer than 6 bins."""
    nan = math.nan
    if x.size < 6:
        return 0.0, nan, nan, nan
    base = _line(x, y, w)[2]
    sw = np.sqrt(w)
    best = (0.0, nan, nan, nan)
    for xb in x[2:-2]:
        A = np.stack([np.ones_like(x), x, np.maximum(0.0, x - xb)], axis=1) * sw[:, None]
        coef, *_ = np.linalg.lstsq(A, y * sw, rcond=None)
        r = y * sw - A @ coef
        d = base - float(r @ r)
        if d > best[0]:
            best = (d, float(xb), float(coef[1]), float(coef[1] + coef[2]))
    return best


def _outside(hurst: float) -> float:
    """How far an exponent lies outside the self-affine interval (0, 1)."""
    return max(0.0, -hurst, hurst - 1.0)


def _hurst(q: np.ndarray, c: np.ndarray, n: np.ndarray, lo: float, hi: float,
           curvature: bool = False) -> tuple[float, float, int]:
    """H and its statistical standard error over ``lo <= q <= hi`` (with a ``(q/hi)^2`` term
    when ``curvature``), and the number of bins."""
    sel = (q >= lo * (1 - 1e-9)) & (q <= hi * (1 + 1e-9))
    k = int(sel.sum())
    if k < (4 if curvature else 3):
        return math.nan, math.nan, k
    x, y, w = np.log(q[sel]), np.log(c[sel]), n[sel] / KAPPA
    if not curvature:
        slope, se, chi2 = _line(x, y, w)
    else:
        sw = np.sqrt(w)
        A = np.stack([np.ones_like(x), x, (q[sel] / hi) ** 2], axis=1) * sw[:, None]
        coef, *_ = np.linalg.lstsq(A, y * sw, rcond=None)
        r = y * sw - A @ coef
        chi2 = float(r @ r)
        slope, se = float(coef[1]), float(math.sqrt(np.linalg.inv(A.T @ A)[1, 1]))
    dof = k - (3 if curvature else 2)
    scale = max(1.0, math.sqrt(chi2 / dof)) if dof > 0 else 1.0
    return -slope / 2 - 1, se * scale / 2, k


def _shift(hurst: float, stat: float, other: tuple[float, float, int]) -> float:
    """How far H moves from ``hurst`` (standard error ``stat``) when the same spectrum is
    fitted over a shorter range or with one more term (``other``): the whole change, its
    statistical part included (where the range is short, that part is large and so is the
    uncertainty of the range's choice)."""
    h2 = other[0]
    return abs(h2 - hurst) if math.isfinite(h2) else stat


def fit_hurst(h: np.ndarray, a: float = 1.0) -> HurstFit:
    r"""Hurst exponent of a topography, its fit range chosen from the spectrum, and one
    standard deviation that includes the fit's systematic error (module docstring).

    Parameters
    ----------
    h : ndarray, shape (ny, nx)
        Heights, every one finite (fill missing points first,
        :func:`roughslip.surfaces.topography.harmonic_fill`).
    a : float
        Pixel size.

    Returns
    -------
    HurstFit

    Raises
    ------
    InputError
        A missing point, or fewer than 3 wavenumber bins in the range.

    Notes
    -----
    :math:`C(q) \propto q^{-2(1+H)}` ([Jacobs2017]) is fitted in log-log;
    :math:`\sigma_H^2 = \sigma_\mathrm{stat}^2 + \delta_\mathrm{low}^2 +
    \delta_\mathrm{high}^2` (module docstring).
    """
    ny, nx = h.shape
    q, c, n = spectrum_bins(h, a)
    q_low = 2 * np.pi / (max(ny, nx) * a)
    lo, hi = LOW_START * q_low, HIGH_END * np.pi / a
    rolloff = bend = None
    while math.log2(hi / lo) >= MIN_OCTAVES:
        sel = (q >= lo) & (q <= hi) & (c > 0)
        d, xb, below, above = _break(np.log(q[sel]), np.log(c[sel]), n[sel] / KAPPA)
        if not d > BREAK_CHI2:
            break
        qb = math.exp(xb)
        # keep the side whose exponent is self-affine (a plateau or a noise floor has a
        # slope near 0, H near -1); when both are, the longer one
        out_below, out_above = _outside(-below / 2 - 1), _outside(-above / 2 - 1)
        if out_below != out_above:
            keep_above = out_above < out_below
        else:
            keep_above = math.log(hi / qb) > math.log(qb / lo)
        if keep_above:  # a roll-off
            rolloff = qb
            lo = max(qb * BREAK_MARGIN, qb + LOW_START * q_low)
        else:  # a noise floor, or the pixel scale
            bend = qb
            hi = qb / BREAK_MARGIN
    hurst, stat, bins = _hurst(q, c, n, lo, hi)
    if not math.isfinite(hurst):
        raise InputError("too few wavenumbers in the fitting range to estimate H")
    octaves = math.log2(hi / lo)
    cut = 2.0 if octaves >= 3 else 2 ** (octaves / 3)
    sys_low = _shift(hurst, stat, _hurst(q, c, n, lo * cut, hi))
    sys_high = max(_shift(hurst, stat, _hurst(q, c, n, lo, hi / cut)),
                   _shift(hurst, stat, _hurst(q, c, n, lo, hi, curvature=True)))
    std = math.sqrt(stat**2 + sys_low**2 + sys_high**2)
    return HurstFit(hurst, std, stat, sys_low, sys_high, lo, hi, bins, rolloff, bend, (q, c, n))
