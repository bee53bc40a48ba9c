"""Figures of a run file (``roughslip plot``); matplotlib is imported only here, lazily."""

from __future__ import annotations

import errno
import math
import os
from pathlib import Path

import numpy as np

from roughslip.analysis import model
from roughslip.analysis.fit import fit_power_law, pair, quantity
from roughslip.analysis.model import units
from roughslip.analysis.summary import axis_unit, mean_sem, pixel_size
from roughslip.errors import InputError, io_failure
from roughslip.friction.laws import LAWS
from roughslip.friction.pull import METHODS
from roughslip.run.store import read_run
from roughslip.run.units import Units


def pyplot():
    """matplotlib.pyplot with the non-interactive Agg backend, or a clear error."""
    try:
        import matplotlib
    except ImportError:
        raise InputError("plots need the plot extra: pip install 'roughslip[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(plt, fig, path: str | Path) -> Path:
    """Lay out, place the legends where they cover no data
    (:func:`roughslip.analysis.legends.place_legends`), write at 120 dpi and close a figure
    (:class:`OutputError` when it cannot be written)."""
    from roughslip.analysis.legends import place_legends

    engine = fig.get_layout_engine()
    if engine is None:
        fig.tight_layout()
    if any(ax.get_legend() is not None for ax in fig.axes):
        place_legends(fig, fig.tight_layout if engine is None else None)
    try:
        fig.savefig(path, dpi=120)
    except OSError as exc:
        raise io_failure(path, "cannot write the figure", exc) from exc
    finally:
        plt.close(fig)
    return Path(path)


def make_folder(folder: str | Path) -> Path:
    """Create ``folder`` (and its parents) for figures, or name the cause in one line
    (:class:`OutputError`). Commands call it before they compute what they will draw."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise io_failure(folder, "cannot make the folder for the figures", exc) from exc
    if not os.access(folder, os.W_OK):
        raise io_failure(folder, "cannot write figures into it",
                         PermissionError(errno.EACCES, os.strerror(errno.EACCES)))
    return folder


def log_ticks(axis, most: int = 6) -> None:
    """Labelled major ticks on a log axis, never closer than a fifth of its span: powers of ten
    first, then 2 and 5, then the other digits, so that a short axis still gets labels and
    labels never collide. Plain numbers from 0.01 to 9000, powers of ten beyond."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter

    ax = axis.axes
    if axis is ax.xaxis:  # freeze the autoscaled limits: the ticks are placed for them
        ax.set_xlim(*ax.get_xlim())
    else:
        ax.set_ylim(*ax.get_ylim())
    lo, hi = sorted(axis.get_view_interval())
    k0, k1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
    span = math.log10(hi / lo)
    gap = span / (most - 1)
    picked: list[float] = []
    for digits in ((1,), (2, 5), (3, 4, 6, 7, 8, 9)):
        for t in (m * 10.0**k for k in range(k0, k1 + 1) for m in digits):
            if not (lo <= t * (1 + 1e-9) and t <= hi * (1 + 1e-9)):
                continue
            if all(abs(math.log10(t / p)) >= gap * (1 - 1e-9) for p in picked):
                picked.append(t)
    if len(picked) > most:  # powers of ten alone, thinned to every n-th
        step = math.ceil(len(picked) / most)
        picked = [10.0**k for k in range(k0, k1 + 1) if k % step == 0 and lo <= 10.0**k <= hi]
    digits = 1
    if len(picked) < 2:  # a span too short for one-digit values: steps of 1, 2 or 5 in the
        # second digit (or further), at least two of them
        k = math.floor(math.log10(hi - lo))
        for step in (d * 10.0**e for e in range(k, k - 4, -1) for d in (5, 2, 1)):
            ticks = [n * step for n in range(math.ceil(lo / step - 1e-9),
                                            math.floor(hi / step + 1e-9) + 1)]
            if len(ticks) >= 2:
                picked = ticks[:: max(1, math.ceil(len(ticks) / most))]
                digits = max(2, math.floor(math.log10(max(picked))) - math.floor(
                    math.log10(step)) + 1)
                break

    def label(t: float, _pos: int) -> str:
        k = math.floor(math.log10(t) + 1e-9)
        m = round(t / 10.0**k, digits - 1)
        if -2 <= k <= 3:  # plain numbers where they are short: 0.05, 3, 200
            return f"{m * 10.0**k:.{max(0, digits - 1 - k)}f}"
        mantissa = f"{m:.{digits - 1}f}"
        return f"$10^{{{k}}}$" if m == 1 else f"${mantissa}\\times10^{{{k}}}$"

    axis.set_major_locator(FixedLocator(sorted(picked)))
    axis.set_major_formatter(FuncFormatter(label))
    axis.set_minor_formatter(NullFormatter())


def finish_axes(ax, xlabel: str, ylabel: str, fontsize: int = 8) -> None:
    """Labels, a grid at the major ticks and the legend."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=fontsize)


def quantity_label(run, name: str) -> str:
    """Axis label of a quantity of :func:`roughslip.analysis.fit.quantity`, with its unit
    (:meth:`roughslip.run.units.Units.label`): the run's named units (``um``, ``uN``, or
    ``E x um^2`` when only the length is named), "(dimensionless)" for a run without units."""
    u = units(run)
    if name == "depth" and run.axis_name == "depth" and run.axis_unit != "length":
        return f"penetration depth $D_z$ ({_axis_tex(run)})"
    return {"depth": f"penetration depth $D_z${u.label('length')}",
            "depth_length": f"penetration depth $D_z${u.label('length')}",
            "normal_force": f"normal force $F_n${u.label('force')}",
            "contact_area": "contact area (fraction of the nominal area)",
            "friction_force": f"static friction $F_{{friction}}${u.label('force')}",
            "friction_normal_force": "normal force of the pulled state"
                                     + u.label("force")}[name]


def _axis_tex(run) -> str:
    """The unit of the run's depths or loads for a figure (empty: none)."""
    if run.axis_unit in ("length", "force"):
        return units(run).tex(run.axis_unit)
    return {"rms": "rms", "range": "range", "pressure": "E*"}.get(run.axis_unit,
                                                                  run.axis_unit)


def target_label(run, k: int) -> str:
    """The depth (or load) of target index ``k``, as a value with its unit (none for a
    dimensionless run)."""
    name = "$D_z$" if run.axis_name == "depth" else "$F_n$"
    unit = _axis_tex(run)
    if run.axis_unit == "pressure":
        name, unit = "$p$", "$E^*$"
    return f"{name} = {run.axis[k]:.3g} {unit}".rstrip()


def run_title(run, what: str, law: bool = True) -> str:
    """A figure title: ``what``, the slip law with its parameters when the run pulls (and
    ``law``), and the run's title (filled from its configuration) on a line of its own."""
    cfg = run.config_dict()
    law = model.law_label(cfg, tex=True) if law else ""
    head = f"{what}, {law}" if law and what else what or law
    name = model.title(run)
    return f"{name}\n{head}" if name else head


def _loglog_png(plt, stem: Path, suffix: str, x, y, xlabel: str, ylabel: str,
                label: str, exact: tuple[str, np.ndarray] | None = None) -> Path:
    """One log-log figure with its fitted power law (and the closed form ``exact``, a name
    and the exact ``y`` per sample and depth), written to ``<stem>_<suffix>.png``."""
    fig, ax = plt.subplots(figsize=(5.4, 4.4))
    _loglog_with_fit(ax, x, y, xlabel, ylabel, label, exact)
    return save(plt, fig, stem.parent / f"{stem.name}_{suffix}.png")


#: the closed forms of :func:`roughslip.analysis.summary.closed_form`, as figures write them
CLOSED_FORMS = {"Hertz": r"Hertz, $F_n = \frac{4}{3}E^*R^{1/2}(D_z - h_{max})^{3/2}$",
                "flat punch": r"Boussinesq, $F_n = 2aE^*D_z$"}


def _loglog_with_fit(ax, x, y, xlabel, ylabel, title, exact=None):
    """Per-sample points, ensemble means with their standard errors, the power-law fit and
    the closed form ``exact`` where there is one; NaN entries (pulls that did not converge)
    are left out, and the legend says how many."""
    xm, _ = mean_sem(x)
    ym, ye = mean_sem(y)
    if exact is not None:
        ex, _ = mean_sem(exact[1])
        ok = np.isfinite(ex) & (ex > 0) & (xm > 0)
        if ok.sum() > 1:
            ax.loglog(xm[ok], ex[ok], "-", color="0.55", lw=5, alpha=0.55, zorder=1,
                      solid_capstyle="round", label=CLOSED_FORMS.get(exact[0], exact[0]))
    left = int(np.isnan(x).sum())
    ok = (xm > 0) & (ym > 0)
    for row_x, row_y in zip(x, y, strict=True):
        sel = (row_x > 0) & (row_y > 0)
        ax.loglog(row_x[sel], row_y[sel], ".", color="0.75", ms=3)
    ax.errorbar(xm[ok], ym[ok], yerr=ye[ok], fmt="o", color="C0", ms=4, capsize=2,
                label=("ensemble mean" if x.shape[0] > 1 else "one sample")
                + (f" ({left} unconverged pull{'s' if left != 1 else ''} left out)"
                   if left else ""))
    try:
        f = fit_power_law(x, y)
        xx = np.geomspace(xm[ok].min(), xm[ok].max(), 50)
        err = f.alpha_bootstrap_std if np.isfinite(f.alpha_bootstrap_std) else f.alpha_stderr
        ax.loglog(xx, f.prefactor * xx**f.alpha, "-", color="C3",
                  label=f"fit: exponent {f.alpha:.3f} ± {err:.3f}")
    except InputError:
        pass
    log_ticks(ax.xaxis)
    log_ticks(ax.yaxis)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)


def plot_solves(run, stem: Path) -> Path:
    """The run's own error against run time, per depth: residual and errors (left),
    iterations (middle), seconds (right); every sample as a point, the worst or median as a
    line. Written to ``<stem>_solves.png``."""
    from roughslip.analysis.summary import closed_form, solves_table

    plt = pyplot()
    exact = closed_form(run)
    rows = solves_table(run, exact)
    x = np.asarray(run.axis, dtype=float)
    sel = run.complete
    au = axis_unit(run)
    xlabel = run.axis_name.replace("_", " ") + (f" ({au})" if au else "")
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))

    def scatter(ax, name, color):
        if name in run.scalars:
            v = np.asarray(run.scalars[name][sel], dtype=float)
            for row in v:
                ok = np.isfinite(row) & (row > 0)
                ax.plot(x[ok], row[ok], ".", color=color, alpha=0.35, ms=3)

    def line(ax, key, style, color, label):
        y = np.array([r[key] for r in rows])
        ok = np.isfinite(y) & (y > 0)
        if ok.any():
            ax.plot(x[ok], y[ok], style, color=color, label=label, ms=4)

    ax = axes[0]
    scatter(ax, "residual", "C0")
    line(ax, "residual", "o-", "C0", "squeeze residual (worst)")
    scatter(ax, "pull_error_estimate", "C1")
    line(ax, "pull_error_estimate", "s-", "C1", "pull: estimated error (worst)")
    if exact is not None:
        line(ax, "normal_force_error", "D-", "C3", f"$F_n$ against {exact[0]} (worst)")
    ax.set_yscale("log")
    ax.set_ylabel("relative residual or error")
    ax.set_title("residual and error", fontsize=9)
    ax = axes[1]
    scatter(ax, "iterations", "C0")
    line(ax, "iterations", "o-", "C0", "squeeze (mean)")
    ax.set_ylabel("iterations")
    ax.set_title("squeeze iterations", fontsize=9)
    ax = axes[2]
    scatter(ax, "seconds", "C0")
    line(ax, "seconds", "o-", "C0", "squeeze (median)")
    scatter(ax, "pull_seconds", "C1")
    line(ax, "pull_seconds", "s-", "C1", "pull (median)")
    ax.set_yscale("log")
    ax.set_ylabel("wall-clock seconds")
    ax.set_title("run time (a measurement: differs between runs)", fontsize=9)
    for ax in axes:
        if np.all(x > 0):
            ax.set_xscale("log")
            log_ticks(ax.xaxis)
        if ax.get_yscale() == "log":
            log_ticks(ax.yaxis)
        ax.set_xlabel(xlabel)
        ax.grid(True, which="major", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    title = model.title(run) or run.path.name
    n = run.n_complete
    fig.suptitle(f"{title}: the solves of {n} sample{'s' if n != 1 else ''}"
                 + (" (points: each sample)" if n > 1 else ""), fontsize=10)
    return save(plt, fig, stem.parent / f"{stem.name}_solves.png")


def plot_run(path: str | Path, out: str | Path | None = None, sample: int | None = None,
             depth_index: int | None = None, solves: bool = False) -> list[Path]:
    """Write the friction law, F_n(D_z), contact/stick maps and a pull curve as PNGs.

    The maps and the pull curve show ``depth_index`` (default: the deepest state, which has
    the most contact). Files are named ``<out>_friction.png``, ``_normal.png``, ``_maps.png``,
    ``_pull.png`` and, with ``solves``, ``_solves.png`` (:func:`plot_solves`); ``out``
    defaults to the run file without its suffix. Returns the paths written.
    """
    plt = pyplot()
    run = read_run(path)
    if run.n_complete == 0:
        raise InputError(f"{run.path}: has no complete samples to plot")
    stem = Path(out) if out else Path(path).with_suffix("")
    make_folder(stem.parent)
    written = []
    from roughslip.analysis.summary import closed_form

    fn = quantity(run, "normal_force")
    depth = quantity(run, "depth_length")
    cfg = run.config_dict()
    squeeze = ("coupled squeeze, history " + model.completed(cfg)["coupling"]["history"]
               if model.coupled(cfg) else "")
    written.append(_loglog_png(plt, stem, "normal", depth, fn,
                               quantity_label(run, "depth_length"),
                               quantity_label(run, "normal_force"),
                               run_title(run, "$F_n \\propto D_z^{\\beta}$"
                                         + (f", {squeeze}" if squeeze else ""), law=False),
                               closed_form(run)))
    has_pull = "friction_force" in run.scalars
    if has_pull:
        fn_pulled, ff, _ = pair(run, "normal_force", "friction_force")
        written.append(_loglog_png(plt, stem, "friction", fn_pulled, ff,
                                   quantity_label(run, "normal_force"),
                                   quantity_label(run, "friction_force"),
                                   run_title(run, "$F_{friction} \\propto F_n^{\\alpha}$")))
    s = int(run.sample_index[run.complete][0]) if sample is None else int(sample)
    if s not in set(run.sample_index[run.complete].tolist()):
        raise InputError(f"{run.path}: sample {s} is not complete")
    # the deepest state by default: the most contact to see
    k = len(run.axis) - 1 if depth_index is None else int(depth_index)
    if not 0 <= k < len(run.axis):
        raise InputError(f"depth index {k}: must be in 0..{len(run.axis) - 1}")
    where = f"sample {s}, {target_label(run, k)}"
    panels = []
    for name, title in (("contact", "contact"), ("stick", "stick at the friction peak"),
                        ("fz", "normal force $f_z$"), ("fx", "tangential force $f_x$ at peak"),
                        ("fy", "tangential force $f_y$ at peak")):
        try:
            panels.append((name, title, run.field(s, k, name)))
        except InputError:
            continue
    if panels:
        written.append(_maps_figure(plt, stem, run, panels, where))
    if has_pull:
        try:
            dx, fx = run.field(s, k, "dx_lim"), run.field(s, k, "fx_lim")
            site = run.field(s, k, "broken_site")
        except InputError:
            dx = fx = None
        if dx is not None and dx.size:
            written.append(_pull_figure(plt, stem, cfg, dx, fx, where, units(run), site))
    if solves:
        written.append(plot_solves(run, stem))
    return written


def _maps_figure(plt, stem: Path, run, panels: list, where: str) -> Path:
    """Contact, stick and force maps in length units, each with its key (a two-colour key
    for the sets), all panels of one size, two to a row."""
    from matplotlib.colors import ListedColormap

    u = units(run)
    pixel = pixel_size(run)
    drive = run.config_dict().get("pull", {})
    xlabel = "x, pull direction" if drive.get("components", "x") == "x" else "x"
    # at most two panels a row: four in a row shrink to unreadable text on a page or screen
    ncols = min(2, len(panels))
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.9 * ncols, 3.7 * nrows),
                             squeeze=False, layout="constrained")
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    for ax, (name, title, a) in zip(axes.flat, panels, strict=False):
        ny, nx = a.shape
        extent = (0.0, nx * pixel, 0.0, ny * pixel)
        if a.dtype == bool:
            im = ax.imshow(a.astype(int), origin="lower", interpolation="nearest",
                           extent=extent, cmap=ListedColormap(["white", "0.15"]), vmin=0,
                           vmax=1)
            cb = fig.colorbar(im, ax=ax, fraction=0.046, ticks=[0.25, 0.75])
            yes = {"contact": "in contact", "stick": "stuck"}.get(name, "yes")
            cb.ax.set_yticklabels(["no", yes], fontsize=8)
            title = f"{title}: {int(a.sum())} sites"
        else:
            im = ax.imshow(a, origin="lower", interpolation="nearest", extent=extent,
                           **field_colours(name, a))
            cb = fig.colorbar(im, ax=ax, fraction=0.046)
            cb.set_label("pixel force" + u.label("force"), fontsize=8)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(xlabel + u.label("length"))
        ax.set_ylabel("y" + u.label("length"))
    fig.suptitle(run_title(run, where), fontsize=10)
    return save(plt, fig, stem.parent / f"{stem.name}_maps.png")


#: fields with a sign (a direction): drawn on a diverging colour map centred on zero
SIGNED = ("fx", "fy", "ux")


def field_colours(name: str, a: np.ndarray) -> dict:
    """``imshow`` colours of a stored field: a diverging map centred on zero (symmetric
    limits) for the signed fields (:data:`SIGNED`), the sequential viridis for the others."""
    if name in SIGNED:
        top = float(np.nanmax(np.abs(a))) if a.size and np.isfinite(a).any() else 0.0
        top = top or 1.0
        return {"cmap": "RdBu_r", "vmin": -top, "vmax": top}
    return {"cmap": "viridis"}


def _pull_figure(plt, stem: Path, cfg: dict, dx: np.ndarray, fx: np.ndarray,
                 where: str, u: Units | None = None, site: np.ndarray | None = None) -> Path:
    """The pull curve under monotone D_x (a sawtooth for the break law, with its bursts; the
    stable path and the landings of its bursts for slip-weakening), over the events; titled
    with the slip law and its parameters."""
    from roughslip.analysis.bursts import landing_curve, pull_curve

    u = u or Units.of(cfg)
    pull = cfg.get("pull", {})
    coupled = bool(cfg.get("coupling", {}).get("enabled"))
    law = "coupled" if coupled else pull.get("slip_law", "break")
    fig, ax = plt.subplots(figsize=(6, 4.2))
    what = LAWS.get(law).curve if law in LAWS else "events"
    # along the drive: x in the report's model, pull.direction with the traction vector
    a = "x" if pull.get("components", "x") == "x" else r"\parallel"
    ax.plot(dx, fx, ".", color="0.6", ms=2.5, label=f"{what} $(D_{{{a},lim}}, F_{{{a},lim}})$")
    i = int(np.argmax(fx))
    method = METHODS.get(pull.get("method", "auto"))
    if law in LAWS and LAWS.get(law).sequence and method.exact:
        exhausted = not method.early_stop or not pull.get("early_stop", True)
        c = pull_curve(dx, fx, exhausted=exhausted)
        ax.plot(c.dx, c.fx, "-", color="C0", lw=0.8, label=f"pull curve, monotone $D_{a}$")
        big = c.complete & (c.burst_size > 1)
        if np.any(big):
            ax.plot(c.burst_dx[big], fx[c.burst_start[big]], "v", color="C1", ms=3,
                    label=f"bursts of 2+ breaks ({int(big.sum())})")
    elif law in LAWS and LAWS.get(law).lands and site is not None:
        c = landing_curve(dx, fx, site)
        i = c.peak_break  # the peak of the stable path (a state inside a burst never is)
        ax.plot(c.dx, c.fx, "-", color="C0", lw=0.8, label=f"pull curve, monotone $D_{a}$")
        if c.burst_dx.size:
            ax.plot(c.burst_dx, fx[c.burst_start], "v", color="C1", ms=3,
                    label=f"bursts ({c.burst_dx.size})")
    else:
        # Coulomb law (affine between slip events, no drops) and the coupled model's events
        order = np.argsort(dx, kind="stable")
        ax.plot(np.r_[0.0, dx[order]], np.r_[0.0, fx[order]], "-", color="C0", lw=0.8,
                label="pull curve between events")
    force = u.of_dimension("force")
    ax.plot(dx[i], fx[i], "o", color="C3", label=f"$F_{{friction}}$ = {fx[i]:.4g}"
            + (f" {u.tex('force')}" if force else ""))
    ax.set_xlabel(f"pull displacement $D_{a}$" + u.label("length"))
    ax.set_ylabel(f"pull force $F_{a}$" + u.label("force"))
    ax.set_title(f"pull curve, {model.law_label(cfg, tex=True)}\n{where}", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    return save(plt, fig, stem.parent / f"{stem.name}_pull.png")


def plot_bursts(sample, fits, out: str | Path) -> Path:
    """Burst-size and force-drop distributions (log bins) with their power-law fits, per
    phase; titled with the slip law and its parameters when the files share them."""
    from roughslip.analysis.bursts import log_binned

    plt = pyplot()
    force = (sample.units or Units(sample.length_unit)).label("force")  # of the pull force
    fig, axes = plt.subplots(1, 2, figsize=(7.5, 3.6))
    for ax, name, data, discrete in ((axes[0], "size", sample.sizes, True),
                                     (axes[1], "drop", sample.drops, False)):
        handles, labels = [], []
        for j, bf in enumerate(fits):
            vals = np.asarray(data[bf.phase], dtype=float)
            x, dens = log_binned(vals, discrete=discrete)
            if not x.size:
                continue
            points = ax.loglog(x, dens, "o", color=f"C{j}", ms=4)[0]
            label = f"{bf.phase} ({vals.size})"
            fit = getattr(bf, name)
            if fit is not None:
                xx = np.geomspace(fit.xmin, fit.xmax, 50)
                frac = fit.n_tail / fit.n
                if discrete:
                    from scipy.special import zeta

                    yy = frac * xx ** -fit.alpha / zeta(fit.alpha, fit.xmin)
                else:
                    yy = frac * (fit.alpha - 1) / fit.xmin * (xx / fit.xmin) ** -fit.alpha
                line = ax.loglog(xx, yy, "-", color=f"C{j}")[0]
                handles.append((points, line))  # one entry: the points and their fit
                labels.append(f"{label}: $\\alpha$ = {fit.alpha:.2f} ± {fit.sigma:.2f}")
            else:
                handles.append(points)
                labels.append(label)
        ref = {"size": "burst size (breaks)", "drop": f"force drop $\\Delta F_x${force}"}[name]
        ax.set_xlabel(ref)
        ax.set_ylabel("probability density")
        ax.grid(True, which="major", alpha=0.3)
        if handles:
            lo, hi = ax.get_ylim()
            ax.set_ylim(lo, hi * (hi / lo) ** 0.3)  # room above the data for the legend
            ax.legend(handles, labels, fontsize=8)
        ax.set_title({"size": "burst sizes", "drop": "force drops"}[name], fontsize=9)
    laws = {model.law_label(read_run(p).config_dict(), tex=True) for p in sample.files}
    law = laws.pop() if len(laws) == 1 else ""
    fig.suptitle(f"bursts of {sample.pulls} pulls, log bins, fits from $x_{{min}}$"
                 + (f"\n{law}" if law else ""), fontsize=10)
    return save(plt, fig, out)


#: the symbol of the exponent of each law the documentation names (:doc:`/results`):
#: :math:`F_{\\rm friction} \\propto F_n^\\alpha`, :math:`F_n \\propto D_z^\\beta`,
#: :math:`A \\propto F_n^\\gamma`
EXPONENTS = {("normal_force", "friction_force"): "\\alpha",
             ("friction_normal_force", "friction_force"): "\\alpha",
             ("depth", "normal_force"): "\\beta", ("depth_length", "normal_force"): "\\beta",
             ("normal_force", "contact_area"): "\\gamma"}


def plot_fits(paths: list[str], fits, x: str, y: str, out: str | Path) -> Path:
    """One log-log panel with every file's ensemble means (error bars: the standard error
    over samples; open markers: points outside the fitted range) and its fit, labelled with
    its exponent (:data:`EXPONENTS`: :math:`\\alpha`, :math:`\\beta`, :math:`\\gamma`) and
    :math:`\\sigma` (bootstrap over samples, or the regression's standard error with one
    sample)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.4))
    excluded = False
    symbol = EXPONENTS.get((x, y))
    exponent = f"${symbol}$" if symbol else "exponent"
    for i, (p, f) in enumerate(zip(paths, fits, strict=True)):
        run = read_run(p)
        xv, yv, _ = pair(run, x, y)
        xm, _ = mean_sem(xv)
        ym, ye = mean_sem(yv)
        n = xv.shape[0]
        ok = (xm > 0) & (ym > 0)
        lo, hi = f.fit.x_range
        inside = ok & (xm >= lo * (1 - 1e-12)) & (xm <= hi * (1 + 1e-12))
        out_ = ok & ~inside
        excluded |= bool(out_.any())
        name = ", ".join(f"{k.split('.')[-1]} = {v}" for k, v in f.varied.items()) \
            or Path(p).name
        ax.errorbar(xm[inside], ym[inside], yerr=ye[inside], fmt="o", color=f"C{i}", ms=4,
                    capsize=2)
        if out_.any():
            ax.errorbar(xm[out_], ym[out_], yerr=ye[out_], fmt="o", color=f"C{i}", ms=4,
                        mfc="none", capsize=2)
        sigma = f.fit.alpha_bootstrap_std
        if not np.isfinite(sigma):
            sigma = f.fit.alpha_stderr
        err = f" ± {sigma:.3f}" if np.isfinite(sigma) else ""
        xx = np.geomspace(lo, hi, 50)
        ax.loglog(xx, f.fit.prefactor * xx**f.fit.alpha, "-", color=f"C{i}",
                  label=f"{name}: {exponent} = {f.fit.alpha:.3f}{err} ({n} sample"
                        f"{'s' if n != 1 else ''})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    log_ticks(ax.xaxis)
    log_ticks(ax.yaxis)
    run0 = read_run(paths[0])
    ax.set_xlabel(quantity_label(run0, x))
    ax.set_ylabel(quantity_label(run0, y))
    ax.grid(True, which="major", alpha=0.3)
    if excluded:
        ax.plot([], [], "o", mfc="none", color="0.3", label="not fitted (outside --range)")
    ax.legend(fontsize=8)
    laws = {model.law_label(read_run(p).config_dict(), tex=True) for p in paths}
    law = laws.pop() if len(laws) == 1 else ""
    what = {"\\alpha": "friction law", "\\beta": "load law", "\\gamma": "area law"}.get(
        symbol, "power law")
    ax.set_title(f"{what}: ensemble means ± standard error, with the fits"
                 + (f"\n{law}" if law and y in ("friction_force",) else ""), fontsize=10)
    return save(plt, fig, out)
