r"""The pull as an experiment sees it: the curve under monotone :math:`D_x`, and its bursts.

The break law's pull (:mod:`roughslip.friction.pull`) yields the break sequence
:math:`(D_{x,{\rm lim},i}, F_{x,{\rm lim},i})`, :math:`i = 0, 1, \dots`: break :math:`i` would
happen at :math:`D_{x,{\rm lim},i}` with the stick set :math:`S_i` it finds, whose stiffness is
:math:`K_i = \mathbf 1^T G_{xx}[S_i,S_i]^{-1}\mathbf 1 = F_{x,{\rm lim},i}/D_{x,{\rm lim},i}`
(the pull force is :math:`F_x = K_i D_x` while :math:`S_i` holds).

Under displacement control :math:`D_x` never decreases. A break whose :math:`D_{x,{\rm lim}}`
exceeds every earlier one is a *record*: the load rises to it along :math:`F = K_i D_x`. A break
whose :math:`D_{x,{\rm lim}}` lies at or below the current :math:`D_x` happens at once, at that
same :math:`D_x`: it belongs to the *burst* (avalanche) the last record started. During a burst
the force drops at constant :math:`D_x`, from :math:`F_{x,{\rm lim}}` of its record to
:math:`K_j D_x` with :math:`j` the next record (or 0 once no bond is left). The curve is a
sawtooth: rising segments between records, vertical drops in bursts.

Its maximum is the static friction force :math:`\max_i F_{x,{\rm lim},i}`, exactly: removing a
bond lowers the stiffness (:math:`\mathbf 1^T A^{-1}\mathbf 1 = \max_x (2\,\mathbf 1^T x -
x^TAx)` over :math:`x` supported on the stick set, a maximum over fewer variables when a site
leaves it), so a break inside a burst has :math:`F_i = K_i D_i \le K_r D_r = F_r` for the
burst's record :math:`r`; the largest :math:`F_i` is a record's.

Bursts are derived from the stored pull curve on reading (``dx_lim``, ``fx_lim``; the file
format is unchanged). A burst's *size* is its number of breaks, its *drop* the force it
releases. The last burst of a sequence cut by the exact early stop (``pull.early_stop``) has
no known end: it is left out, and so is every burst of a pull with one break or fewer. Use
``pull.early_stop = false`` to record every break after the peak.

Power laws are fitted by maximum likelihood with the lower bound of the fit range chosen by the
Kolmogorov-Smirnov distance (Clauset, Shalizi & Newman, SIAM Review 51, 661 (2009),
doi:10.1137/070710111): discrete for sizes, continuous for drops.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from roughslip.errors import InputError
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import METHODS
from roughslip.run.units import Units

PHASES = ("all", "before", "after")


@dataclass(frozen=True)
class PullCurve:
    """The pull curve under monotone :math:`D_x` and its bursts.

    Attributes
    ----------
    dx, fx : ndarray
        Vertices of the curve from :math:`(0, 0)`: each record is reached by a rising segment,
        each break of a burst adds a point at the same :math:`D_x` with the force after it.
    peak : float
        Its maximum: the static friction force.
    peak_break : int
        Index in the break sequence of the first break at the peak.
    burst_start : ndarray of int
        Index (in the break sequence) of the record that starts each burst.
    burst_size : ndarray of int
        Breaks in each burst (the record included).
    burst_drop : ndarray
        Force released by each burst; NaN for a burst whose end is unknown.
    burst_dx : ndarray
        :math:`D_x` at which each burst happens.
    complete : ndarray of bool
        Whether the end of each burst is known (all but the last of an early-stopped pull).
    """

    dx: np.ndarray
    fx: np.ndarray
    peak: float
    peak_break: int
    burst_start: np.ndarray
    burst_size: np.ndarray
    burst_drop: np.ndarray
    burst_dx: np.ndarray
    complete: np.ndarray


def pull_curve(dx_lim: np.ndarray, fx_lim: np.ndarray, *, exhausted: bool = False
               ) -> PullCurve:
    r"""The curve under monotone :math:`D_x` from a break sequence (module docstring).

    Parameters
    ----------
    dx_lim, fx_lim : ndarray
        The break sequence, in order (``PullResult.curve.dx[1:]``, ``curve.fx[1:]``, or the stored
        ``dx_lim``/``fx_lim`` of a run).
    exhausted : bool
        The sequence ran until no bond was left (``method="literal"``, or no early stop that
        cut it): the force after the last burst is 0 and that burst is complete.
    """
    d = np.asarray(dx_lim, dtype=float)
    f = np.asarray(fx_lim, dtype=float)
    if d.shape != f.shape or d.ndim != 1:
        raise InputError("pull curve: dx_lim and fx_lim must be 1-d arrays of equal length")
    if d.size and not (np.all(np.isfinite(d)) and np.all(d > 0) and np.all(np.isfinite(f))):
        raise InputError("pull curve: dx_lim must be finite and > 0, fx_lim finite")
    n = d.size
    if n == 0:
        z = np.zeros(0)
        return PullCurve(np.zeros(1), np.zeros(1), 0.0, -1, z.astype(np.int64),
                         z.astype(np.int64), z, z, z.astype(bool))
    k = f / d  # stiffness of the stick set each break finds
    record = np.empty(n, dtype=bool)
    record[0] = True
    record[1:] = d[1:] > np.maximum.accumulate(d)[:-1]
    starts = np.flatnonzero(record)
    ends = np.append(starts[1:], n)  # a burst runs to the next record
    cur = np.maximum.accumulate(d)
    k_next = np.append(k[1:], 0.0)  # stiffness after each break (0: nothing left)
    after = cur * k_next  # force at constant D_x after each break
    # vertices: rise to each record, then one point per break of its burst
    xs, ys = [0.0], [0.0]
    for s, e in zip(starts, ends, strict=True):
        xs.append(d[s])
        ys.append(f[s])
        xs.extend(cur[s:e])
        ys.extend(after[s:e])
    complete = np.ones(starts.size, dtype=bool)
    if not exhausted:
        complete[-1] = False
        xs, ys = xs[:-(ends[-1] - starts[-1])], ys[:-(ends[-1] - starts[-1])]
    drop = f[starts] - after[ends - 1]
    drop[~complete] = np.nan
    xs_a, ys_a = np.asarray(xs), np.asarray(ys)
    peak = float(ys_a.max())
    return PullCurve(xs_a, ys_a, peak, int(np.flatnonzero(f == peak)[0]), starts,
                     (ends - starts).astype(np.int64), drop, d[starts], complete)


def landing_curve(dx_lim: np.ndarray, fx_lim: np.ndarray, site: np.ndarray) -> PullCurve:
    r"""The curve under monotone :math:`D_x` of a pull that records where its bursts land
    (slip-weakening, docs/theory/pull.rst#slip-weakening).

    Its events are the stable path's, the failures inside each burst and the state each burst
    lands in (site ``-1``), both at the drive that set the burst off (states recorded below
    the drive, at their own limits, are passed over). The curve joins the events not below the
    drive: between them every force is affine in :math:`D_x`, and a burst is a drop at
    constant :math:`D_x`. A burst runs from the first event at its drive to its landing; its
    size is the number of events in between, that one included (a failure of the stable path
    at exactly that drive counts in it), and its drop the force it releases.
    """
    d = np.asarray(dx_lim, dtype=float)
    f = np.asarray(fx_lim, dtype=float)
    site = np.asarray(site)
    if not (d.shape == f.shape == site.shape and d.ndim == 1):
        raise InputError("pull curve: dx_lim, fx_lim and broken_site must be 1-d arrays of "
                         "equal length")
    top = np.maximum.accumulate(np.r_[0.0, d])[:-1]  # the drive before each event
    on = d >= top  # the stable path and the landings
    starts, sizes, drops, where = [], [], [], []
    last = -1  # the previous landing
    for j in np.flatnonzero(site < 0):
        prev, last = last, int(j)
        here = np.arange(prev + 1, j)
        here = here[on[here] & (site[here] >= 0)]
        before = here[d[here] == d[j]]
        if before.size == 0:
            continue
        r = int(before[0])  # the first event at the landing's drive since the last landing
        starts.append(r)
        sizes.append(j - r)
        drops.append(f[r] - f[j])
        where.append(d[j])
    xs, ys = np.r_[0.0, d[on]], np.r_[0.0, f[on]]
    peak = float(ys.max())
    hit = np.flatnonzero(on & (f == peak))
    n = len(starts)
    return PullCurve(xs, ys, peak, int(hit[0]) if hit.size else -1,
                     np.array(starts, dtype=np.int64), np.array(sizes, dtype=np.int64),
                     np.array(drops), np.array(where), np.ones(n, dtype=bool))


# ----------------------------------------------------------------------------------------------
# Power laws
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PowerLawFit:
    r"""A power law :math:`p(x) \propto x^{-\alpha}` for :math:`x \ge x_{\min}`."""

    alpha: float
    sigma: float  # standard error from the likelihood's curvature
    xmin: float
    xmax: float
    n_tail: int  # points in [xmin, xmax]
    n: int  # points in all
    ks: float  # Kolmogorov-Smirnov distance of the tail to the fit
    discrete: bool

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _discrete_alpha(x: np.ndarray, xmin: float) -> tuple[float, float]:
    """MLE of the discrete power law on ``x >= xmin`` (Hurwitz zeta normalisation)."""
    from scipy.optimize import minimize_scalar
    from scipy.special import zeta

    n, slog = x.size, float(np.log(x).sum())

    def nll(a: float) -> float:
        return n * math.log(zeta(a, xmin)) + a * slog

    res = minimize_scalar(nll, bounds=(1.0 + 1e-6, 8.0), method="bounded",
                          options={"xatol": 1e-10})
    a = float(res.x)
    h = 1e-4
    curv = (nll(a + h) - 2 * nll(a) + nll(a - h)) / h**2
    return a, (1.0 / math.sqrt(curv) if curv > 0 else math.inf)


def _discrete_ks(x: np.ndarray, xmin: float, a: float) -> float:
    from scipy.special import zeta

    vals, counts = np.unique(x, return_counts=True)
    emp = 1.0 - np.concatenate([[0.0], np.cumsum(counts)[:-1]]) / x.size  # P(X >= v)
    model = zeta(a, vals) / zeta(a, xmin)
    return float(np.max(np.abs(emp - model)))


def _continuous_alpha(x: np.ndarray, xmin: float) -> tuple[float, float]:
    a = 1.0 + x.size / float(np.log(x / xmin).sum())
    return a, (a - 1.0) / math.sqrt(x.size)


def _continuous_ks(x: np.ndarray, xmin: float, a: float) -> float:
    xs = np.sort(x)
    n = xs.size
    model = 1.0 - (xs / xmin) ** (1.0 - a)
    return float(max(np.max(np.arange(1, n + 1) / n - model),
                     np.max(model - np.arange(n) / n)))


def fit_power_law(values: np.ndarray, *, discrete: bool, xmin: float | None = None,
                  min_tail: int = 50) -> PowerLawFit:
    r"""Maximum-likelihood power law with :math:`x_{\min}` by the KS distance (Clauset et al.
    2009, doi:10.1137/070710111).

    Discrete: :math:`p(x) = x^{-\alpha}/\zeta(\alpha, x_{\min})`, :math:`\hat\alpha` maximises
    the likelihood numerically. Continuous: :math:`\hat\alpha = 1 + n/\sum\ln(x_i/x_{\min})`.
    :math:`x_{\min}` (unless given) is the candidate that minimises the KS distance between the
    tail and the fit, among those that keep at least ``min_tail`` points. ``sigma`` is the
    standard error from the curvature of the log-likelihood (discrete) or
    :math:`(\hat\alpha-1)/\sqrt n` (continuous).
    """
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x) & (x > 0)]
    if x.size < min_tail:
        raise InputError(f"power-law fit: {x.size} positive values; at least {min_tail} needed")
    if discrete:
        x = np.round(x)
    if xmin is not None:
        cands = np.array([float(xmin)])
    else:
        u = np.unique(x)
        tail_sizes = x.size - np.searchsorted(np.sort(x), u)
        cands = u[tail_sizes >= min_tail]
        if not discrete and cands.size > 200:  # continuous data: quantiles suffice
            cands = np.unique(np.quantile(x[x <= cands[-1]], np.linspace(0, 1, 200)))
    best = None
    for xm in cands:
        tail = x[x >= xm]
        if tail.size < min(min_tail, x.size) or np.all(tail == xm):
            continue
        if discrete:
            a, s = _discrete_alpha(tail, xm)
            ks = _discrete_ks(tail, xm, a)
        else:
            a, s = _continuous_alpha(tail, xm)
            ks = _continuous_ks(tail, xm, a)
        if best is None or ks < best.ks:
            best = PowerLawFit(a, s, float(xm), float(tail.max()), int(tail.size),
                               int(x.size), ks, discrete)
    if best is None:
        raise InputError("power-law fit: no fit range with enough distinct values")
    return best


def log_binned(values: np.ndarray, bins_per_decade: int = 5, discrete: bool = False
               ) -> tuple[np.ndarray, np.ndarray]:
    """Probability density on logarithmic bins: (geometric bin centres, density).

    Discrete values are binned on integer edges, each bin's count divided by the number of
    integers it holds."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x) & (x > 0)]
    if x.size == 0:
        return np.zeros(0), np.zeros(0)
    lo, hi = x.min(), x.max()
    nb = max(1, math.ceil(bins_per_decade * math.log10(hi / lo + 1e-300)) + 1)
    edges = np.geomspace(lo, hi * (1 + 1e-12), nb + 1)
    if discrete:
        edges = np.unique(np.ceil(edges - 1e-9))
        edges[-1] = max(edges[-1], hi + 1)
        counts, _ = np.histogram(x, edges)
        width = np.diff(edges)  # integers per bin
        centres = np.sqrt(edges[:-1] * (edges[1:] - 1))
    else:
        counts, _ = np.histogram(x, edges)
        width = np.diff(edges)
        centres = np.sqrt(edges[:-1] * edges[1:])
    dens = counts / (width * x.size)
    keep = counts > 0
    return centres[keep], dens[keep]


# ----------------------------------------------------------------------------------------------
# Bursts of run files
# ----------------------------------------------------------------------------------------------


@dataclass
class BurstSample:
    """Bursts pooled over files, samples and depths, by phase relative to the peak."""

    sizes: dict[str, list[int]]
    drops: dict[str, list[float]]
    pulls: int
    files: list[str]
    #: the length unit of the first run (``units.length``), None for bare numbers
    length_unit: str | None = None
    #: the units of the first run (:class:`roughslip.run.units.Units`)
    units: Units | None = None
    #: pulls left out because they did not converge (their curves stop short)
    left_out: int = 0


def collect_bursts(paths: list[str | Path]) -> BurstSample:
    """Every complete burst of every complete sample and depth of the run files.

    ``before``: bursts whose record comes before the peak break; ``after``: the burst at the
    peak and those that follow. Needs runs of the decoupled break law with ``pull_curve`` in
    ``output.fields``. A pull that did not converge is left out (:attr:`BurstSample.left_out`).
    """
    from roughslip.analysis.fit import unconverged_pulls
    from roughslip.analysis.summary import length_unit
    from roughslip.run.store import open_file, read_run

    out = BurstSample({p: [] for p in PHASES}, {p: [] for p in PHASES}, 0,
                      [str(p) for p in paths])
    for path in paths:
        run = read_run(path)
        cfg = run.config_dict()
        if path == paths[0]:
            out.length_unit = length_unit(run)
            out.units = Units.of(cfg)
        pull = cfg.get("pull", {})
        if not pull.get("enabled", False):
            raise InputError(f"{path}: has no pull (pull.enabled = false)")
        law = pull.get("slip_law", "break")
        lands = law in LAWS and LAWS.get(law).lands
        sequence = law in LAWS and LAWS.get(law).sequence
        if not (sequence or lands) or cfg.get("coupling", {}).get("enabled"):
            raise InputError(f"{path}: bursts need the decoupled break sequence or a law whose "
                             f"pull records where its bursts land (this run has slip_law = "
                             f"{law!r} or coupling.enabled)")
        if "pull_curve" not in cfg.get("output", {}).get("fields", []):
            raise InputError(f"{path}: no pull curves stored; run with 'pull_curve' in "
                             "output.fields")
        method = METHODS.get(pull.get("method", "auto"))
        if not method.exact:
            raise InputError(f"{path}: bursts need an exact pull method (this run has "
                             f"pull.method = {method.name!r}, which breaks several bonds per "
                             "step)")
        exhausted = not method.early_stop or not pull.get("early_stop", True)
        bad = unconverged_pulls(run)
        with open_file(path) as f:
            for row, s in enumerate(run.sample_index[run.complete]):
                for k in range(len(run.axis)):
                    if bad[row, k]:
                        out.left_out += 1
                        continue
                    g = f[f"samples/s{int(s):06d}/d{k:03d}"]
                    c = (landing_curve(g["dx_lim"][()], g["fx_lim"][()],
                                       g["broken_site"][()]) if lands else
                         pull_curve(g["dx_lim"][()], g["fx_lim"][()], exhausted=exhausted))
                    out.pulls += 1
                    for b in np.flatnonzero(c.complete):
                        phase = "before" if c.burst_start[b] < c.peak_break else "after"
                        for p in ("all", phase):
                            out.sizes[p].append(int(c.burst_size[b]))
                            out.drops[p].append(float(c.burst_drop[b]))
    return out


@dataclass(frozen=True)
class BurstFit:
    """Power-law fits of one phase's burst sizes and force drops (None: too few bursts)."""

    phase: str
    bursts: int
    size: PowerLawFit | None
    drop: PowerLawFit | None
    note: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"phase": self.phase, "bursts": self.bursts, "note": self.note,
                "size": None if self.size is None else self.size.as_dict(),
                "drop": None if self.drop is None else self.drop.as_dict()}


def fit_bursts(sample: BurstSample, min_tail: int = 50) -> list[BurstFit]:
    """Fit sizes (discrete) and drops (continuous) in each phase."""
    fits = []
    for phase in PHASES:
        sizes, drops = sample.sizes[phase], sample.drops[phase]
        notes, res = [], {}
        for name, vals, discrete in (("size", sizes, True), ("drop", drops, False)):
            try:
                res[name] = fit_power_law(np.asarray(vals), discrete=discrete,
                                          min_tail=min_tail)
            except InputError as exc:
                res[name] = None
                notes.append(f"{name}: {exc}")
        fits.append(BurstFit(phase, len(sizes), res["size"], res["drop"], "; ".join(notes)))
    return fits


def format_table(sample: BurstSample, fits: list[BurstFit]) -> str:
    """A plain-text table of the fits."""
    left = (f" ({sample.left_out} unconverged pull(s) left out)" if sample.left_out else "")
    lines = [f"# {sample.pulls} pulls from {len(sample.files)} file(s){left}; power laws "
             "p(x) ~ x^-alpha by maximum likelihood, x_min by KS distance (Clauset et al. 2009)",
             f"{'phase':>7} {'bursts':>7} {'quantity':>8} {'alpha':>7} {'+-':>6} "
             f"{'x_min':>10} {'x_max':>10} {'n_tail':>7} {'KS':>6}"]
    for bf in fits:
        for name, fit in (("size", bf.size), ("drop", bf.drop)):
            if fit is None:
                lines.append(f"{bf.phase:>7} {bf.bursts:>7} {name:>8}  too few bursts")
                continue
            lines.append(f"{bf.phase:>7} {bf.bursts:>7} {name:>8} {fit.alpha:7.3f} "
                         f"{fit.sigma:6.3f} {fit.xmin:10.4g} {fit.xmax:10.4g} "
                         f"{fit.n_tail:7d} {fit.ks:6.3f}")
    return "\n".join(lines)


def burst_report(paths: list[str | Path], min_tail: int = 50
                 ) -> tuple[BurstSample, list[BurstFit]]:
    """Collect and fit the bursts of run files (``roughslip bursts``)."""
    sample = collect_bursts(paths)
    if not sample.sizes["all"]:
        raise InputError("no complete bursts in the given run files")
    return sample, fit_bursts(sample, min_tail)
