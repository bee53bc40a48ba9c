r"""Power-law fits :math:`y = c\,x^\alpha` over ensemble means (docs/guide/quickstart.rst).

The means over samples at each depth are fitted in log-log by least squares. A pull that did
not converge is left out of the means (:func:`pair`): its friction force, and the other
quantity at the same sample and depth, are not a result (docs/methods.rst#unconverged).
Two uncertainties are reported: the regression standard error of :math:`\alpha` (scatter of the
means about the line) and the standard deviation of :math:`\alpha` over bootstrap resamples of
the samples (sampling error of the ensemble), with a 95 % percentile interval. The bootstrap is
seeded, so a fit is reproducible.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from roughslip.errors import InputError, echo
from roughslip.run.store import RunData, read_run

QUANTITIES = ("depth", "depth_length", "normal_force", "contact_area", "friction_force",
              "friction_normal_force")
#: the quantities a pull computes: not a result where the pull did not converge
PULLED = ("friction_force", "friction_normal_force")


@dataclass(frozen=True)
class PowerLawFit:
    """Result of :func:`fit_power_law`."""

    alpha: float
    prefactor: float
    alpha_stderr: float  # regression standard error (nan with 2 points)
    alpha_bootstrap_std: float  # over resamples of the samples (nan with 1 sample)
    alpha_ci95: tuple[float, float]
    r2: float
    n_points: int
    n_samples: int
    x_range: tuple[float, float]
    #: entries (sample, depth) left out of the means: pulls that did not converge
    excluded: int = 0

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in d.items()}


def _ols(lx: np.ndarray, ly: np.ndarray) -> tuple[float, float, float, float]:
    """Slope, intercept, slope standard error and R² of y on x."""
    n = lx.size
    xm, ym = lx.mean(), ly.mean()
    sxx = float(((lx - xm) ** 2).sum())
    if sxx == 0:
        raise InputError("all x values are equal: no power law can be fitted")
    slope = float(((lx - xm) * (ly - ym)).sum() / sxx)
    icpt = float(ym - slope * xm)
    resid = ly - (icpt + slope * lx)
    ss_res = float((resid**2).sum())
    ss_tot = float(((ly - ym) ** 2).sum())
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else 1.0
    se = math.sqrt(ss_res / (n - 2) / sxx) if n > 2 else math.nan
    return slope, icpt, se, r2


def fit_power_law(x: np.ndarray, y: np.ndarray, *, xmin: float | None = None,
                  xmax: float | None = None, n_boot: int = 2000, seed: int = 0,
                  names: tuple[str, str] = ("x", "y")) -> PowerLawFit:
    """Fit :math:`\\bar y = c\\,\\bar x^\\alpha` to ensemble means.

    Parameters
    ----------
    x, y : array_like, shape (n_samples, n_points)
        Per-sample values at each depth (or 1-D: one sample). NaN marks an entry left out
        (:func:`pair`), in both arrays; the means at a depth are over the others.
    xmin, xmax : float, optional
        Use only depths whose mean ``x`` lies in this range.
    n_boot : int
        Bootstrap resamples of the samples.
    names : (str, str)
        Names used in error messages.

    Raises
    ------
    InputError
        For non-finite input, mismatched shapes, or fewer than two usable points (means must be
        positive to take logarithms).
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    y = np.atleast_2d(np.asarray(y, dtype=float))
    if x.shape != y.shape:
        raise InputError(f"{names[0]} and {names[1]} have different shapes {x.shape}, {y.shape}")
    for arr, nm in ((x, names[0]), (y, names[1])):
        if np.any(np.isinf(arr)):
            raise InputError(f"{nm} contains inf")
    out = np.isnan(x) | np.isnan(y)
    if out.any():
        x, y = np.where(out, np.nan, x), np.where(out, np.nan, y)
    ns, nd = x.shape
    if ns == 0 or nd == 0:
        raise InputError("no data to fit")
    xm, ym = means(x), means(y)
    use = (xm > 0) & (ym > 0)
    if xmin is not None:
        use &= xm >= xmin
    if xmax is not None:
        use &= xm <= xmax
    if use.sum() < 2:
        why = []
        if nd < 2:
            why.append(f"only {nd} depth(s)")
        if np.any((xm <= 0) | (ym <= 0)):
            why.append(f"{int(((xm <= 0) | (ym <= 0)).sum())} point(s) with zero or negative "
                       f"mean {names[0]} or {names[1]}")
        if xmin is not None or xmax is not None:
            why.append(f"range [{xmin}, {xmax}]")
        if out.any():
            k = int(out.sum())
            why.append(f"{k} {'entry' if k == 1 else 'entries'} left out (unconverged pulls)")
        raise InputError(f"fewer than 2 usable points for a power law of {names[1]} on "
                         f"{names[0]} ({'; '.join(why) or 'no positive means'})")
    lx, ly = np.log(xm[use]), np.log(ym[use])
    alpha, icpt, se, r2 = _ols(lx, ly)
    boot = []
    if ns > 1 and n_boot > 0:
        rng = np.random.default_rng(seed)
        for _ in range(n_boot):
            idx = rng.integers(0, ns, ns)
            bx, by = means(x[idx])[use], means(y[idx])[use]
            if np.all(bx > 0) and np.all(by > 0) and np.ptp(np.log(bx)) > 0:
                boot.append(_ols(np.log(bx), np.log(by))[0])
    if boot:
        b = np.array(boot)
        bstd = float(b.std(ddof=1)) if b.size > 1 else math.nan
        ci = (float(np.percentile(b, 2.5)), float(np.percentile(b, 97.5)))
    else:
        bstd, ci = math.nan, (math.nan, math.nan)
    return PowerLawFit(alpha=alpha, prefactor=math.exp(icpt), alpha_stderr=se,
                       alpha_bootstrap_std=bstd, alpha_ci95=ci, r2=r2,
                       n_points=int(use.sum()), n_samples=ns,
                       x_range=(float(xm[use].min()), float(xm[use].max())),
                       excluded=int(out.sum()))


def means(v: np.ndarray) -> np.ndarray:
    """The mean over samples (axis 0) at each depth, of the entries that are not NaN (NaN
    where none is)."""
    if not np.isnan(v).any():
        return v.mean(axis=0)
    n = (~np.isnan(v)).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.nansum(v, axis=0) / n, np.nan)


def unconverged_pulls(run: RunData) -> np.ndarray:
    """The (complete sample, depth) entries whose pull did not converge (all False for a run
    without a pull, or for a file that does not record it)."""
    sel = run.complete
    shape = (int(sel.sum()), len(run.axis))
    if "pull_converged" not in run.scalars:
        return np.zeros(shape, bool)
    return np.asarray(run.scalars["pull_converged"][sel], dtype=float) == 0


def pair(run: RunData, x: str, y: str) -> tuple[np.ndarray, np.ndarray, int]:
    """The per-sample values of ``x`` and ``y`` (:func:`quantity`), NaN in both where a pull
    that did not converge would enter either (a quantity of :data:`PULLED`), and how many
    entries that leaves out."""
    xv = np.asarray(quantity(run, x), dtype=float)
    yv = np.asarray(quantity(run, y), dtype=float)
    if x not in PULLED and y not in PULLED:
        return xv, yv, 0
    out = unconverged_pulls(run)
    if not out.any():
        return xv, yv, 0
    return np.where(out, np.nan, xv), np.where(out, np.nan, yv), int(out.sum())


def quantity(run: RunData, name: str) -> np.ndarray:
    """Per-sample values (complete samples) of a named quantity of a run file."""
    if name not in QUANTITIES:
        raise InputError(f"unknown quantity {echo(name)}; choose from {', '.join(QUANTITIES)}")
    sel = run.complete
    if name == "depth":
        if run.axis_name != "depth":
            return run.scalars["depth_length"][sel]
        return np.broadcast_to(run.axis, (int(sel.sum()), run.axis.size)).copy()
    if name not in run.scalars:
        raise InputError(f"{run.path}: has no {echo(name)} (was the pull enabled?)")
    return run.scalars[name][sel]


def flatten(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """A nested configuration as one level of dotted keys (``{"pull": {"lam": 0.2}}`` gives
    ``{"pull.lam": 0.2}``)."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


@dataclass(frozen=True)
class FileFit:
    """One run file's fit with the configuration keys that distinguish it from the others."""

    path: str
    fit: PowerLawFit
    varied: dict[str, Any]


_IGNORED = ("execution.", "title", "output.")


def fit_files(paths: list[str | Path], x: str = "normal_force", y: str = "friction_force", *,
              xmin: float | None = None, xmax: float | None = None, n_boot: int = 2000
              ) -> list[FileFit]:
    """Fit each run file; report the keys of the stored configurations that differ.

    The surface's Hurst exponent is always reported when present.
    """
    if not paths:
        raise InputError("no run files given")
    runs = [read_run(p) for p in paths]
    flats = [flatten(r.config_dict()) for r in runs]
    keys = sorted(set().union(*flats))
    varied_keys = [k for k in keys if not k.startswith(_IGNORED)
                   and len({repr(f.get(k)) for f in flats}) > 1]
    out = []
    for r, flat in zip(runs, flats, strict=True):
        if r.n_complete == 0:
            raise InputError(f"{r.path}: has no complete samples")
        try:
            xv, yv, _ = pair(r, x, y)
            res = fit_power_law(xv, yv, xmin=xmin, xmax=xmax, n_boot=n_boot, names=(x, y))
        except InputError as exc:
            raise InputError(f"{r.path}: {exc}") from None
        varied = {k: flat.get(k) for k in varied_keys}
        if "surface.hurst" in flat:
            varied = {"surface.hurst": flat["surface.hurst"], **varied}
        out.append(FileFit(str(r.path), res, varied))
    return out


def format_table(fits: list[FileFit], x: str, y: str, width: int = 100) -> str:
    """Text table, one row per file, within ``width`` columns: the configuration keys that
    differ between the files are columns while they fit, else a block of their own above the
    fits, a line per file (wrapped between keys)."""
    keys: list[str] = []
    for f in fits:
        keys += [k for k in f.varied if k not in keys]
    left = any(f.fit.excluded for f in fits)  # a column only when a pull is left out
    fit_head = ["alpha", "+-boot", "+-reg", "95% CI", "R2", "points", "samples",
                *(["left out"] if left else [])]
    names, values, fit_rows = [], [], []
    for f in fits:
        p = f.fit

        def num(v: float) -> str:
            return f"{v:.4f}" if math.isfinite(v) else "n/a"

        ci = (f"[{p.alpha_ci95[0]:.3f}, {p.alpha_ci95[1]:.3f}]"
              if math.isfinite(p.alpha_ci95[0]) else "n/a")
        names.append(Path(f.path).name)
        values.append(["-" if f.varied.get(k) is None else str(f.varied[k]) for k in keys])
        fit_rows.append([num(p.alpha), num(p.alpha_bootstrap_std), num(p.alpha_stderr), ci,
                         f"{p.r2:.4f}", str(p.n_points), str(p.n_samples),
                         *([str(p.excluded)] if left else [])])

    def table(head: list[str], rows: list[list[str]]) -> list[str]:
        widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
        return ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True))
                for r in [head, *rows]]

    lines = table(["file", *keys, *fit_head],
                  [[n, *v, *r] for n, v, r in zip(names, values, fit_rows, strict=True)])
    block: list[str] = []
    if max(map(len, lines)) > width and keys:
        import textwrap

        w = max(map(len, names))
        block = ["# the files differ in:"]
        for n, v in zip(names, values, strict=True):
            items = [f"{k} = {val}".replace(" ", "\u00a0") for k, val in zip(keys, v,
                                                                                strict=True)]
            block += [line.replace("\u00a0", " ") for line in textwrap.wrap(
                ", ".join(items), width=width, initial_indent=f"{n.rjust(w)}  ",
                subsequent_indent=" " * (w + 2), break_on_hyphens=False,
                break_long_words=False)]
        lines = table(["file", *fit_head], [[n, *r] for n, r in zip(names, fit_rows,
                                                                    strict=True)])
    note = ("\n# left out: (sample, depth) entries whose pull did not converge; the means at "
            "those depths are over the other samples") if left else ""
    return f"# {y} = c {x}^alpha\n" + "\n".join([*block, *lines]) + note
