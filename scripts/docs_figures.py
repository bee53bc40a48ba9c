"""The figures and console output of the documentation, made from scratch.

    python scripts/docs_figures.py OUT_DIR

``make docs`` runs this at build time (about 20 s on 2 cores); the pages include what it
writes into ``OUT_DIR``:

* ``quickstart_*.txt``: the console output of the quickstart's commands, run on a smaller
  demo (``configs/demo.toml`` with 64 x 64 pixels and 8 samples) exactly as a user types them,
  and of ``roughslip show-config``;
* ``demo_friction.png``, ``demo_normal.png``, ``demo_maps.png``, ``demo_pull.png``:
  ``roughslip plot`` of that run;
* ``fit_friction.png``, ``fit_area.png``: ``roughslip fit --plot`` of the friction law
  F_friction(F_n) and the area law A(F_n);
* ``bursts.png``, ``quickstart_bursts.txt``: ``roughslip bursts --plot``;
* ``hurst_loop.txt``, ``hurst_fit.png``: the loop over Hurst exponents of the guide
  (``configs/rough_h08.toml`` at 48 x 48 pixels, 6 samples, H = 0.5, 0.7, 0.9) and the fit
  of the friction law of each;
* ``hertz_resolution.png``, ``hertz_resolution.txt``: one Hertz contact (R = 1, depth 0.01,
  contact radius a = 0.1, E = 1, nu = 0.25, lambda = 0.2) at a/h = 4 ... 32: the frictionless
  force against Hertz's, and the friction coefficient of the break law, decoupled and
  coupled, against the pixel size.

* ``topography_scan.txt``, ``topography_scan.png``: ``roughslip topography --plot`` on the
  shipped example scan ``configs/data/scan.x3p`` (``scripts/make_example_scan.py``), as the
  topographies guide shows it, and ``topography_formats.txt``: ``roughslip topography
  --formats``;
* ``weakening_resolution.png``, ``weakening_resolution.txt``: the same Hertz problem at
  nu = 0.3 under the break law and under slip-weakening (lambda_s = 0.2, lambda_d = 0.1 and
  0, d_c = 5e-4) at a/h = 4 ... 32, and the three pull curves at a/h = 16.

* ``index_pull.png``: the picture of the index page, from the quickstart's run: one sample's
  surface with its contact and stick sets at the friction peak, and its pull curve.
* ``coupled_events.png``: the coupled theory page's event path and stick/slip maps, from two
  coupled pulls of one 24 x 24 rough surface (H = 0.8, seed 7, depth 1.6 rms, lambda = 0.2,
  nu = 0.25 and 0.45, the ``bonded`` history) computed here (about a second).
* ``coulomb_cone.png``: the partial-slip state of a Hertz contact under the Coulomb cone with
  the traction vector (nu = 0.5, Q = 0.5 lambda P, a/h = 12, 64 facets): its traction along
  and across the drive, the stick zone and Mindlin's circle, computed here (about a second).
* ``spence_sphere.png``: Spence's frictional sphere at nu = 0: the stick fraction against the
  friction, the ring-element solution (computed here) and the pixel model from the results
  page's table, and one indentation's stick zone and tractions at a/h = 8 (computed here,
  about 10 s in all).
* ``histories.png``, ``histories_weakening.png``, ``hertz_exponents.png``, ``rough_exponents.png``,
  ``coupled_finite_size.png``, ``indentation.png``, ``traction_direction.png``,
  ``weakening_rough.png``, ``burst_exponents.png``: the studies of ``docs/results.md`` (the
  squeeze histories, the Hertz and the rough-surface exponents against N, the coupled
  finite-size study, the frictional indentation, the friction against the drive's angle,
  slip-weakening on rough surfaces, the burst exponents), drawn from
  the page's own tables (:func:`results_figures`; recorded numbers: the studies take minutes
  to hours).
* ``bench_scaling.png``: time against size with fitted slopes, and against the peer codes,
  drawn from the tables of ``docs/benchmarks.md`` (recorded numbers, not measured here).
* ``python_<cell>.py``, ``python_<cell>.txt``, ``python_*.png``: the Python tutorial
  ``docs/guide/python_tutorial.py``, run cell by cell (its ``# %%`` lines): the code of each
  cell, what it prints, and the figures it saves.

Every command runs in a scratch folder laid out like a checkout (``configs/``, ``runs/``),
so the output shows the paths the quickstart uses.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import re
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import roughslip

ROOT = Path(__file__).resolve().parents[1]

#: the quickstart's commands, in order, with the file their console output goes to
QUICKSTART = (
    ("run", "roughslip run configs/demo.toml -o runs/demo.h5 --set grid.n=64 "
            "--set ensemble.samples=8"),
    ("inspect", "roughslip inspect runs/demo.h5"),
    ("fit", "roughslip fit runs/demo.h5 --plot runs/fit_friction.png"),
    ("fit_area", "roughslip fit runs/demo.h5 --x normal_force --y contact_area "
                 "--plot runs/fit_area.png"),
    ("plot", "roughslip plot runs/demo.h5 -o runs/demo"),
    ("bursts", "roughslip bursts runs/demo.h5 --min-tail 20 --plot runs/bursts.png"),
    ("show_config", "roughslip show-config configs/demo.toml --set surface.hurst=0.6"),
)
#: the Hurst loop's runs (one per exponent) and its joint fit
HURST = (0.5, 0.7, 0.9)
HURST_RUN = ("roughslip run configs/rough_h08.toml --set surface.hurst={H} --set grid.n=48 "
             "--set ensemble.samples=6 -o runs/H{H}.h5 --quiet")
HURST_FIT = ("roughslip fit " + " ".join(f"runs/H{h}.h5" for h in HURST)
             + " --plot runs/hurst_fit.png")
FIGURES = ("demo_friction.png", "demo_normal.png", "demo_maps.png", "demo_pull.png",
           "fit_friction.png", "fit_area.png", "bursts.png")


def _roughslip(command: str, cwd: Path) -> str:
    """Run one ``roughslip ...`` command line in ``cwd``; its output, or an error with it."""
    import shlex

    args = shlex.split(command)
    argv = [sys.executable, "-m", "roughslip", *args[1:]]
    out = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"{command!r} failed ({out.returncode}): {out.stderr.strip()}")
    # what the terminal shows (progress goes to stderr), with the paths as typed: the
    # provenance line names the program, not this interpreter's module path
    main = str(Path(roughslip.__file__).with_name("__main__.py"))
    text = out.stdout + out.stderr
    return text.replace(main, "roughslip").replace(f"{cwd.resolve()}/", "")


@contextlib.contextmanager
def _checkout(config: str):
    """A scratch folder laid out like a checkout: ``configs/<config>`` and an empty
    ``runs/``; removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="roughslip-docs-") as tmp:
        work = Path(tmp)
        (work / "configs").mkdir()
        (work / "runs").mkdir()
        shutil.copy(ROOT / "configs" / config, work / "configs" / config)
        yield work


def quickstart(out: Path) -> None:
    """The quickstart's commands on a scratch checkout; their output and figures to ``out``."""
    with _checkout("demo.toml") as work:
        for name, command in QUICKSTART:
            text = _roughslip(command, work)
            (out / f"quickstart_{name}.txt").write_text(f"$ {command}\n{text}")
        for name in FIGURES:
            shutil.copy(work / "runs" / name, out / name)
        index_picture(work / "runs" / "demo.h5", out)


def index_picture(path: Path, out: Path) -> None:
    """The index page's picture: the first sample of the quickstart's run at its deepest
    state, its surface with the contact sites that stick at the friction peak and those whose
    bonds broke before it, and its pull curve with the peak."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from roughslip.analysis.bursts import pull_curve
    from roughslip.analysis.model import law_label, units
    from roughslip.analysis.plotting import pyplot, save
    from roughslip.run.reading import read_run

    run = read_run(path)
    u = units(run)  # the run's units: "(dimensionless)" without [units], as `plot` says
    s, k = int(run.sample_index[run.complete][0]), len(run.axis) - 1
    h = run.surface(s)
    contact, stick = run.field(s, k, "contact"), run.field(s, k, "stick")
    c = pull_curve(run.field(s, k, "dx_lim"), run.field(s, k, "fx_lim"))
    cfg = run.config_dict()
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(7.5, 3.3),
                                      gridspec_kw={"width_ratios": [1, 1.25]},
                                      layout="constrained")
    ny, nx = h.shape
    extent = (0, nx, 0, ny)
    left.imshow(h, origin="lower", cmap="Greys_r", extent=extent, interpolation="nearest",
                alpha=0.55)
    sets = np.where(stick, 2, np.where(contact, 1, 0)).astype(float)
    sets[sets == 0] = np.nan
    left.imshow(sets, origin="lower", extent=extent, interpolation="nearest",
                cmap=ListedColormap(["C1", "C0"]), vmin=1, vmax=2)
    left.set_title(f"{nx} x {ny} rough surface (H = {cfg['surface']['hurst']})", fontsize=9)
    left.set_xlabel("x, pull direction (pixels)", fontsize=8)
    left.set_ylabel("y (pixels)", fontsize=8)
    left.tick_params(labelsize=8)
    left.legend(handles=[Patch(color="C0", label=f"stuck at the peak ({int(stick.sum())})"),
                         Patch(color="C1", label="contact, bond broken "
                                                 f"({int((contact & ~stick).sum())})")],
                loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize=8, ncol=1,
                frameon=False)
    right.plot(c.dx, c.fx, "-", color="C0", lw=0.9)
    i = int(np.argmax(c.fx))
    right.plot(c.dx[i], c.fx[i], "o", color="C3", ms=6)
    right.annotate(f"static friction force $F_x$ = {c.fx[i]:.3g}", (c.dx[i], c.fx[i]),
                   xytext=(-8, 8), textcoords="offset points", ha="right", fontsize=8)
    right.set_ylim(0, 1.15 * c.fx[i])  # room for the label above the curve
    right.set_xlabel("pull displacement $D_x$" + u.label("length"), fontsize=8)
    right.set_ylabel("pull force $F_x$" + u.label("force"), fontsize=8)
    right.set_title(f"its pull curve, {law_label(cfg, tex=True)}:\nbonds break, in bursts, "
                    "until the peak", fontsize=9)
    right.tick_params(labelsize=8)
    right.grid(True, alpha=0.3)
    save(plt, fig, out / "index_pull.png")


#: the topographies guide's command, on the shipped example scan
TOPOGRAPHY = "roughslip topography configs/data/scan.x3p --plot runs/scan.png"
#: the list of the formats read (with the topography extra: SurfaceTopography's too)
FORMATS = "roughslip topography --formats"


def topography(out: Path) -> None:
    """``roughslip topography --plot`` on the shipped scan: its report and its figure."""
    with _checkout("demo.toml") as work:
        (work / "configs" / "data").mkdir()
        shutil.copy(ROOT / "configs" / "data" / "scan.x3p", work / "configs" / "data")
        text = _roughslip(TOPOGRAPHY, work)
        (out / "topography_scan.txt").write_text(f"$ {TOPOGRAPHY}\n{text}")
        text = _roughslip(FORMATS, work)
        (out / "topography_formats.txt").write_text(f"$ {FORMATS}\n{text}")
        shutil.copy(work / "runs" / "scan.png", out / "topography_scan.png")


def _continued(command: str, first: str, rest: str, width: int = 84) -> str:
    """``command`` as typed over lines of at most ``width`` characters, each continued by a
    backslash, broken before an option (a word starting with ``-``)."""
    lines, line = [], first
    for word in command.split():
        if word.startswith("-") and line.strip(" >$") and len(line) + len(word) + 3 > width:
            lines.append(line + " \\")
            line = rest
        line += ("" if line in (first, rest) else " ") + word
    return "\n".join([*lines, line])


def hurst_loop(out: Path) -> None:
    """The Hurst loop of the guide: one run per exponent, then one fit of all of them."""
    with _checkout("rough_h08.toml") as work:
        for h in HURST:
            _roughslip(HURST_RUN.format(H=h), work)
        # the loop as typed over several lines, so that it fits the page's column
        run = _continued(HURST_RUN.replace("{H}", "$H"), ">   ", ">     ")
        loop = f"$ for H in {' '.join(map(str, HURST))}; do\n{run}\n> done"
        text = _roughslip(HURST_FIT, work)
        (out / "hurst_loop.txt").write_text(f"{loop}\n$ {HURST_FIT}\n{text}")
        shutil.copy(work / "runs" / "hurst_fit.png", out / "hurst_fit.png")


def hertz_resolution(out: Path, ratios=(4, 8, 16, 32), coupled_max: int = 16,
                     nu: float = 0.25, lam: float = 0.2) -> None:
    """One Hertz problem at ever finer pixels: the squeeze converges, the break law does not.

    The sphere R = 1 is pressed to d = 0.01 (Hertz contact radius a = sqrt(R d) = 0.1) into a
    half-space with E = 1 on an open grid of side 4a, h = a / ratio.
    """
    from roughslip import couple, pull
    from roughslip.analysis.plotting import log_ticks, pyplot, save
    from roughslip.contact.analytic import hertz
    from roughslip.contact.problem import Problem
    from roughslip.contact.squeeze import NormalSolver
    from roughslip.elastic.operators import Grid, Material
    from roughslip.surfaces import sphere

    R, d = 1.0, 0.01
    a = np.sqrt(R * d)
    rows = []
    for ratio in ratios:
        h, n = a / ratio, 4 * ratio
        problem = Problem(sphere((n, n), radius=R, a=h), Grid((n, n), h), Material(1.0, nu))
        normal = NormalSolver(problem, tol=1e-12).solve(depth=d)
        t0 = time.perf_counter()
        dec = pull(normal, lam=lam)
        t_dec = time.perf_counter() - t0
        fc, t_c, released = np.nan, np.nan, np.nan
        if ratio <= coupled_max:
            t0 = time.perf_counter()
            c = couple(problem, depth=d, lam=lam)
            t_c = time.perf_counter() - t0
            fc = c.friction_force / (lam * c.normal_force_at_peak)
            released = c.details.released / max(int(c.start.contact.sum()), 1)
        rows.append((ratio, n, normal.normal_force / hertz(R=R, d=d, E=1.0, nu=nu).force - 1,
                     dec.friction_force / (lam * normal.normal_force), fc, released,
                     t_dec, t_c))
    r = np.array(rows, dtype=float)
    lines = [f"# Hertz R = {R}, d = {d}, a = {a:.3g}, E = 1, nu = {nu}, lambda = {lam}",
             "# open grid of side 4a",
             f"{'a/h':>4} {'N':>4} {'F_n/Hertz-1':>12} {'F_f/(lam F_n)':>14} "
             f"{'coupled':>8} {'released':>8} {'s (dec)':>8} {'s (coup)':>8}"]
    for row in rows:
        coupled = (f"{row[4]:8.4f} {row[5]:8.2f}" if np.isfinite(row[4])
                   else f"{'-':>8} {'-':>8}")
        t_c = f"{row[7]:8.2f}" if np.isfinite(row[7]) else f"{'-':>8}"
        lines.append(f"{row[0]:4d} {row[1]:4d} {row[2]:12.3e} {row[3]:14.4f} {coupled} "
                     f"{row[6]:8.2f} {t_c}")
    (out / "hertz_resolution.txt").write_text("\n".join(lines) + "\n")

    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(7.5, 3.5), layout="constrained")
    x = r[:, 0]
    left.loglog(x, np.abs(r[:, 2]), "o-", color="C0", label="$|F_n / F_{Hertz} - 1|$")
    left.loglog(x, np.abs(r[0, 2]) * (x / x[0]) ** -2.0, "--", color="0.5",
                label="slope $-2$ ($\\propto h^2$)")
    left.set_title("squeeze: converges", fontsize=9)
    left.set_ylabel("relative error of the normal force", fontsize=8)
    right.loglog(x, r[:, 3], "o-", color="C0", label="break law, decoupled")
    ok = np.isfinite(r[:, 4])
    right.loglog(x[ok], r[ok, 4], "s-", color="C1", label=f"break law, coupled ($\\nu$ = {nu})")
    right.loglog(x, r[0, 3] * (x / x[0]) ** -0.5, "--", color="0.5",
                 label="slope $-1/2$ ($\\propto (h/a)^{1/2}$)")
    right.set_title("pull: falls with the pixel size", fontsize=9)
    right.set_ylabel("friction coefficient $F_f / (\\lambda F_n)$", fontsize=8)
    right.set_ylim(top=1.5)  # room for the legend above the curves
    for ax in (left, right):
        ax.set_xlabel("contact radius over pixel size, $a/h$", fontsize=8)
        log_ticks(ax.xaxis)
        log_ticks(ax.yaxis)
        ax.tick_params(labelsize=8)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"one Hertz contact (R = {R:g}, a = {a:.3g}, $\\nu$ = {nu}), break law, "
                 f"$\\lambda$ = {lam}, at ever finer pixels", fontsize=10)
    save(plt, fig, out / "hertz_resolution.png")


def weakening_resolution(out: Path, ratios=(4, 8, 16, 32), nu: float = 0.3,
                         lam: float = 0.2, slip_distance: float = 5e-4) -> None:
    """The Hertz problem of :func:`hertz_resolution` under slip-weakening: the friction
    coefficient converges once d_c is resolved, where the break law's falls."""
    from roughslip import pull
    from roughslip.analysis.bursts import landing_curve, pull_curve
    from roughslip.analysis.plotting import pyplot, save
    from roughslip.contact.problem import Problem
    from roughslip.contact.squeeze import NormalSolver
    from roughslip.elastic.operators import Grid, Material
    from roughslip.surfaces import sphere

    R, d = 1.0, 0.01
    a = np.sqrt(R * d)
    laws = [("break law", None), ("slip-weakening, $\\lambda_d$ = 0.1", 0.1),
            ("slip-weakening, $\\lambda_d$ = 0", 0.0)]
    mu = np.zeros((len(ratios), len(laws)))
    curves = {}
    lines = [f"# Hertz R = {R}, d = {d}, a = {a:.3g}, E = 1, nu = {nu}, lambda_s = {lam}, "
             f"d_c = {slip_distance}",
             "# open grid of side 4a; friction coefficients F_f / (lambda_s F_n)",
             f"{'a/h':>4} {'bonds':>6} {'break':>8} {'sw 0.1':>8} {'sw 0':>8}"]
    for i, ratio in enumerate(ratios):
        h, n = a / ratio, 4 * ratio
        problem = Problem(sphere((n, n), radius=R, a=h), Grid((n, n), h), Material(1.0, nu))
        normal = NormalSolver(problem, tol=1e-12).solve(depth=d)
        for j, (_, ld) in enumerate(laws):
            r = (pull(normal, lam=lam, early_stop=False) if ld is None else
                 pull(normal, lam=lam, slip_law="slip-weakening", lam_dynamic=ld,
                      slip_distance=slip_distance))
            mu[i, j] = r.friction_force / (lam * normal.normal_force)
            if ratio == 16:
                dx, fx = r.curve.dx[1:], r.curve.fx[1:]  # the events after the start
                c = (pull_curve(dx, fx, exhausted=True) if ld is None else
                     landing_curve(dx, fx, r.curve.site[1:]))
                curves[j] = (c.dx / slip_distance, c.fx / (lam * normal.normal_force))
        lines.append(f"{ratio:4d} {int(normal.contact.sum()):6d} " +
                     " ".join(f"{m:8.4f}" for m in mu[i]))
    (out / "weakening_resolution.txt").write_text("\n".join(lines) + "\n")

    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(7.5, 3.5), layout="constrained")
    x = np.array(ratios, dtype=float)
    for j, (name, _) in enumerate(laws):
        left.semilogx(x, mu[:, j], "os^"[j] + "-", color=f"C{j}", label=name)
        if 16 in ratios:
            right.plot(*curves[j], "-", color=f"C{j}", lw=0.9, label=name)
    left.set_xlabel("contact radius over pixel size, $a/h$", fontsize=8)
    left.set_ylabel("friction coefficient $F_f / (\\lambda_s F_n)$", fontsize=8)
    left.set_ylim(0, 1.0)
    left.set_xticks(x, [f"{r:g}" for r in ratios])
    left.minorticks_off()
    left.set_title("friction against the pixel size", fontsize=9)
    right.set_xlabel("pull displacement over the slip distance, $D_x / d_c$", fontsize=8)
    right.set_ylabel("$F_x / (\\lambda_s F_n)$", fontsize=8)
    right.set_ylim(top=1.0)  # room for the legend above the curves
    right.set_title("pull curves under a monotone drive, $a/h$ = 16", fontsize=9)
    for ax in (left, right):
        ax.tick_params(labelsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"one Hertz contact (a = {a:.3g}, $\\nu$ = {nu}, $\\lambda_s$ = {lam}, "
                 f"$d_c$ = {slip_distance:g})", fontsize=10)
    save(plt, fig, out / "weakening_resolution.png")


#: the marker of each event kind in :func:`coupled_events`
EVENT_MARKERS = {"slip+": ("^", "C3", "bond fails, $f_x = +\\lambda f_z$ (slip+)"),
                 "slip-": ("v", "C0", "bond fails, $f_x = -\\lambda f_z$ (slip-)"),
                 "lost": ("x", "C4", "contact lost, $f_z = 0$"),
                 "gained": ("P", "C2", "contact gained, gap $= 0$")}


def _event_path(problem, depth: float, result) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pull curve of a coupled break-law pull under monotone :math:`D_x`, drawn exactly.

    Between events the forces are affine in :math:`D_x`; each recorded state's sets (contact
    and stick, ``record_states``) give them by two dense solves of the block operator. The
    totals at each event's own :math:`D_x` are checked against the recorded ones. Returns the
    vertices ``(D_x, F_x)`` and, for each event, the force just before it at the drive.
    """
    from threadpoolctl import threadpool_limits

    from roughslip.testing import dense_block

    A = dense_block(problem)
    n = problem.base.size
    ubar = problem.overlap(depth).ravel()
    drive, xs, ys, at = 0.0, [], [], []
    for (D, _, _, _, C, S), event in zip(result.details.states, result.events, strict=True):
        C, S = C.ravel(), S.ravel()
        nc, ns = int(C.sum()), int(S.sum())
        rows = np.concatenate([np.flatnonzero(C), n + np.flatnonzero(S)])
        rhs = np.zeros((nc + ns, 2))
        rhs[:nc, 0] = ubar[C]  # the squeeze's part, at D_x = 0
        rhs[nc:, 1] = 1.0  # the rate: stuck bonds follow D_x
        with threadpool_limits(1):  # small systems: threads only wait for each other
            f = np.linalg.solve(A[np.ix_(rows, rows)], rhs)
        F0, F1 = f[nc:].sum(axis=0)
        if abs(F0 + D * F1 - event.fx) > 1e-8 * max(abs(event.fx), 1.0):
            raise RuntimeError(f"coupled event path: F_x at the {event.kind} event is "
                               f"{F0 + D * F1!r}, recorded {event.fx!r}")
        if not xs:
            xs, ys = [0.0], [F0]
        new = max(drive, D)
        xs += [drive, new]
        ys += [F0 + drive * F1, F0 + new * F1]
        at.append(F0 + new * F1)
        drive = new
    return np.array(xs), np.array(ys), np.array(at)


def coupled_events(out: Path, n: int = 24, seed: int = 7, depth: float = 1.6,
                   lam: float = 0.2, nus=(0.25, 0.45)) -> None:
    """The coupled theory page's figure: the event path of a small coupled pull at two
    Poisson ratios, with the event kinds marked, and its contact and stick sets at the
    friction peak (the ``bonded`` history, the break law, unbonded gains: the defaults)."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from roughslip import Grid, Material, Problem, couple
    from roughslip.analysis.plotting import pyplot, save
    from roughslip.surfaces.synthetic import sample_rng, self_affine

    h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(seed, 0), oversample=2)
    plt = pyplot()
    fig = plt.figure(figsize=(7.5, 7.4), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[1.0, 1.05])
    path_ax = top.subplots()
    map_axes = bottom.subplots(1, len(nus))
    kinds_seen: set[str] = set()
    lines = [f"# {n} x {n}, H = 0.8, seed {seed}, depth {depth} rms, lambda = {lam}, "
             "history bonded, break law"]
    colours = ListedColormap(["0.6", "C1", "C0", "C2"])
    for j, (nu, ax) in enumerate(zip(nus, map_axes, strict=True)):
        problem = Problem(h, Grid((n, n), 1.0), Material(1.0, nu))
        r = couple(problem, depth=depth, lam=lam, record_states=True)
        xs, ys, at = _event_path(problem, depth, r)
        style = "-" if j == 0 else "--"
        path_ax.plot(xs, ys, style, color="0.25", lw=0.9,
                     label=f"$\\nu$ = {nu}: $F_x$ under monotone $D_x$")
        for kind, (marker, colour, _) in EVENT_MARKERS.items():
            pick = [i for i, e in enumerate(r.events) if e.kind == kind]
            if pick:
                kinds_seen.add(kind)
                drive = np.maximum.accumulate(r.curve.dx)[pick]
                path_ax.plot(drive, at[pick], marker, color=colour, ms=4.5, mfc="none", mew=0.9)
        path_ax.plot(r.peak_dx, r.friction_force, "*", color="k", ms=11, zorder=5)
        path_ax.annotate(f"peak, $\\nu$ = {nu}", (r.peak_dx, r.friction_force),
                         xytext=(8, 4), textcoords="offset points", fontsize=8)
        # 0 out of contact, 1 contact without a bond since D_x = 0, 2 bond failed in the
        # pull, 3 stuck at the peak, 4 gained during the pull (unbonded)
        sets = np.zeros((n, n))
        start, peak = r.start, r.peak
        sets[peak.contact & ~start.contact] = 4
        sets[peak.contact & start.contact & ~start.stick] = 1
        sets[peak.contact & start.stick & ~peak.stick] = 2
        sets[peak.stick] = 3
        sets[sets == 0] = np.nan
        ax.imshow(sets, origin="lower", cmap=colours, vmin=1, vmax=4, extent=(0, n, 0, n),
                  interpolation="nearest")
        ax.contour(np.arange(n) + 0.5, np.arange(n) + 0.5, h, levels=6, colors="0.8",
                   linewidths=0.6, linestyles="solid")
        ax.set_title(f"$\\nu$ = {nu}: {int(start.contact.sum())} contacts, "
                     f"{int(start.stick.sum())} bonds at $D_x = 0$", fontsize=9)
        ax.set_xlabel("x, pull direction (pixels)", fontsize=8)
        ax.set_ylabel("y (pixels)", fontsize=8)
        ax.tick_params(labelsize=8)
        kinds = ", ".join(f"{k} {sum(e.kind == k for e in r.events)}" for k in EVENT_MARKERS
                          if any(e.kind == k for e in r.events))
        lines += [f"nu = {nu}: {int(start.contact.sum())} contacts, {int(start.stick.sum())} "
                  f"bonds at D_x = 0 ({r.details.released} released)",
                  f"{'':11}peak F_x = {r.friction_force:.4g} at D_x = {r.peak_dx:.4g}, "
                  f"{int(peak.stick.sum())} bonds stuck there",
                  f"{'':11}events: {kinds}"]
    handles = path_ax.get_legend_handles_labels()[0]
    handles += [path_ax.plot([], [], m, color=c, mfc="none", label=text)[0]
                for k, (m, c, text) in EVENT_MARKERS.items() if k in kinds_seen]
    handles.append(path_ax.plot([], [], "*", color="k", ms=9, label="friction force (peak)")[0])
    path_ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                   frameon=False)
    path_ax.set_xlabel("pull displacement $D_x$ (pixels)", fontsize=8)
    path_ax.set_ylabel("pull force $F_x$ ($E\\,\\times$ pixel$^2$)", fontsize=8)
    path_ax.tick_params(labelsize=8)
    path_ax.grid(True, alpha=0.3)
    path_ax.margins(y=0.08)
    path_ax.set_title(f"event path of one {n} x {n} rough contact (H = 0.8, depth {depth} rms, "
                      f"$\\lambda$ = {lam})", fontsize=9)
    bottom.legend(handles=[Patch(color="C0", label="stuck at the peak"),
                           Patch(color="C1", label="bond failed in the pull"),
                           Patch(color="0.6", label="released before the pull (no bond)"),
                           Patch(color="C2", label="gained in the pull (no bond)")],
                  loc="outside lower center", ncol=2, fontsize=8, frameon=False)
    bottom.suptitle("contact and stick at the friction peak (thin lines: height contours)",
                    fontsize=9)
    save(plt, fig, out / "coupled_events.png")
    (out / "coupled_events.txt").write_text("\n".join(lines) + "\n")


def coulomb_cone(out: Path, a_over_h: int = 12, nu: float = 0.5, lam: float = 0.3,
                 fraction: float = 0.5, facets: int = 64) -> None:
    """The results page's partial-slip state of the Coulomb cone: a Hertz contact (R = 1,
    approach 1/16) pulled along x to Q = ``fraction`` lambda P with the traction vector
    (:meth:`~roughslip.friction.cone.ConeState.run_to`), its traction along the drive and
    across it, the stick zone and Mindlin's circle (computed here, about a second)."""
    from roughslip.analysis.plotting import pyplot, save
    from roughslip.analysis.verify import hertz_scene
    from roughslip.contact.squeeze import squeeze
    from roughslip.friction.bonds import Bonds, PullOptions
    from roughslip.friction.cone import STICK, ConeState

    heights, h, depth, _ = hertz_scene(a_over_h, 1.0, 1 / 16)
    normal = squeeze(heights, depth=depth, a=h, nu=nu, tol=1e-13)
    b = Bonds(normal, lam, components=("x", "y"))
    st = ConeState(b, PullOptions(slip_law="coulomb"), facets)
    F = st.force(st.run_to(fraction * lam * normal.normal_force))
    scale = lam * float(normal.fz.max())
    qx, qy = b.field(F[:, 0]) / scale, b.field(F[:, 1]) / scale
    stick = b.mask(np.flatnonzero(st.mode == STICK))
    contact = normal.fz > 0
    ny, nx = heights.shape
    ext = (-nx / 2 / a_over_h, nx / 2 / a_over_h, -ny / 2 / a_over_h, ny / 2 / a_over_h)
    centres = (np.arange(nx) - nx / 2 + 0.5) / a_over_h
    c = (1 - fraction) ** (1 / 3)
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(8.0, 3.7), layout="constrained")
    for ax, q, title, cmap, lim in (
            (axes[0], qx, "$q_x$, along the drive", "viridis", (0.0, float(qx.max()))),
            (axes[1], qy, "$q_y$, across it (zero in the x-only model)", "RdBu_r",
             (-float(np.abs(qy).max()), float(np.abs(qy).max())))):
        shown = np.where(contact, q, np.nan)
        im = ax.imshow(shown, origin="lower", extent=ext, cmap=cmap, vmin=lim[0], vmax=lim[1],
                       interpolation="nearest")
        ax.contour(centres, centres, stick.astype(float), levels=[0.5], colors="k",
                   linewidths=1.0)
        _disc_axes(ax, c, 1.15)
        ax.set_title(title, fontsize=9)
        bar = fig.colorbar(im, ax=ax, shrink=0.85)
        bar.ax.tick_params(labelsize=7)
        bar.set_label("traction / ($\\lambda\\, p_{\\max}$)", fontsize=8)
    fig.suptitle(f"Hertz contact at $Q = {fraction:g}\\,\\lambda P$, $\\nu$ = {nu:g}, "
                 f"$a/h$ = {a_over_h}, {facets} facets: stick zone (solid), Mindlin's "
                 "(dashed), contact (dotted)", fontsize=9)
    save(plt, fig, out / "coulomb_cone.png")


def spence_sphere(out: Path, a_over_h: int = 8, lam: float = 0.2986, facets: int = 32) -> None:
    """The results page's Spence sphere: the stick fraction c/a against lambda, the
    ring-element solution (computed here, about 5 s) and the pixel model from the page's
    table; and the state of one indentation at ``a_over_h`` (computed here, about 5 s): the
    stick zone and the tangential tractions."""
    from roughslip.analysis.plotting import pyplot, save
    from roughslip.analysis.verify import hertz_scene
    from roughslip.contact.analytic import sphere_indentation_friction
    from roughslip.contact.problem import Problem
    from roughslip.coupling.cone import indent_cone

    rows = _markdown_table(RESULTS, "| $\\lambda$ | ring elements")
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(8.6, 3.9), layout="constrained")
    ax = axes[0]
    k = np.linspace(0.04, 0.96, 24)
    ax.plot([sphere_indentation_friction(float(x), n=20) for x in k], k, "-", color="0.3",
            lw=2.5, alpha=0.5, label="ring elements (the continuum)")
    heads = ["8", "12", "16"]
    for j, head in enumerate(heads):
        pts = [(_number(r[0]), _number(r[2 + j])) for r in rows if _numbers(r[2 + j])]
        x, y = (np.array(v) for v in zip(*pts, strict=True))
        ax.plot(x, y, "osD^"[j] + ("-" if len(pts) > 1 else ""), color=f"C{j}", ms=4, lw=1,
                label=f"pixel model, $a/h$ = {head}", zorder=3)
    ax.plot([0.2986], [0.5], "+", color="k", ms=12, mew=1.0, label="Spence: 0.5 at 0.2986",
            zorder=2)
    ax.set_xlabel("friction coefficient $\\lambda$", fontsize=8)
    ax.set_ylabel("stick fraction $c/a$ (over the loading's second half)", fontsize=8)
    ax.set_xlim(0.1, 0.55)
    ax.set_ylim(0, 1)
    _style(ax)
    ax.legend(fontsize=7)
    ax.set_title("stick fraction against the friction, $\\nu$ = 0", fontsize=9)

    heights, h, depth, ac = hertz_scene(a_over_h)
    res = indent_cone(Problem.from_arrays(heights, a=h, E=1.0, nu=0.0), depth, lam=lam,
                      facets=facets)
    nx = heights.shape[1]
    centres = (np.arange(nx) - (nx - 1) / 2) * h / ac
    X, Y = np.meshgrid(centres, centres)
    ax = axes[1]
    state = np.where(res.contact, np.where(res.stick, 1.0, 0.0), np.nan)
    ext = (centres[0] - 0.5 * h / ac, centres[-1] + 0.5 * h / ac) * 2
    from matplotlib.colors import ListedColormap

    ax.imshow(state, origin="lower", extent=ext, cmap=ListedColormap(["#f3e3bd", "#9ecae1"]),
              vmin=0, vmax=1, interpolation="nearest")
    c = res.contact
    scale = lam * float(res.fz.max())
    ax.quiver(X[c], Y[c], res.fx[c] / scale, res.fy[c] / scale, angles="xy",
              scale_units="xy", scale=4.0, width=0.006, color="k")
    _disc_axes(ax, 0.5, 1.2)
    ax.set_title(f"$a/h$ = {a_over_h}, $\\lambda$ = {lam:g}: stick (blue), slip (sand),\n"
                 "traction on the half-space (arrows), $c = a/2$ (dashed)", fontsize=9)
    save(plt, fig, out / "spence_sphere.png")


def _disc_axes(ax, inner: float, lim: float) -> None:
    """A contact map's axes in units of the contact radius: the contact circle (dotted), a
    circle of radius ``inner`` (dashed), equal scales to +-``lim``."""
    t = np.linspace(0, 2 * np.pi, 200)
    for r, style in ((1.0, ":"), (inner, "--")):
        ax.plot(r * np.cos(t), r * np.sin(t), style, color="0.3", lw=0.9)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ax.set_xlabel("$x / a$", fontsize=8)
    ax.set_ylabel("$y / a$", fontsize=8)
    ax.tick_params(labelsize=8)


def _markdown_table(page: Path, header: str) -> list[list[str]]:
    """The rows of the Markdown table of ``page`` whose header row starts with ``header``,
    as lists of cell texts; an error naming the page when there is none."""
    lines = page.read_text().splitlines()
    for i, line in enumerate(lines):
        if line.startswith(header):
            rows = []
            for row in lines[i + 2:]:
                if not row.startswith("|"):
                    break
                rows.append([c.strip() for c in row.strip().strip("|").split("|")])
            return rows
    raise RuntimeError(f"{page}: no table whose header starts with {header!r}")


def _plus_minus(cell: str) -> tuple[float, float]:
    value, _, error = cell.partition("±")
    return float(value), float(error) if error.strip() else math.nan


def histories(out: Path) -> None:
    """The squeeze-histories study of the results page as a figure: the coupled/decoupled
    friction ratio against N for each history, with its bootstrap error, read from the
    page's own table."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(ROOT / "docs" / "results.md", "| N | $\\nu$ | history |")
    data: dict[tuple[float, str], list[tuple[int, float, float]]] = {}
    for row in rows:
        ratio, err = _plus_minus(row[4])
        data.setdefault((float(row[1]), row[2]), []).append((int(row[0]), ratio, err))
    order = ("bonded", "simultaneous", "indent", "frictionless")
    nus = sorted({nu for nu, _ in data})
    plt = pyplot()
    fig, axes = plt.subplots(1, len(nus), figsize=(7.5, 3.6), sharey=True, layout="constrained")
    for ax, nu in zip(np.atleast_1d(axes), nus, strict=True):
        ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
        for j, name in enumerate(order):
            pts = sorted(data.get((nu, name), []))
            if not pts:
                continue
            N, ratio, err = (np.array(c, dtype=float) for c in zip(*pts, strict=True))
            shift = 2.0 ** (0.045 * (j - 1.5))  # side by side: bonded and simultaneous agree
            ax.errorbar(N * shift, ratio, yerr=err, fmt="os^D"[j] + "-", color=f"C{j}", ms=4,
                        lw=1, capsize=2.5, label=name)
        ax.set_xscale("log", base=2)
        ax.set_xticks([64, 128, 256], ["64", "128", "256"])
        ax.minorticks_off()
        ax.set_xlim(50, 320)
        ax.set_ylim(0, 1.1)
        ax.set_title(f"$\\nu$ = {nu:g}", fontsize=9)
        ax.set_xlabel("grid size N (unit pixels: a larger patch)", fontsize=8)
        ax.tick_params(labelsize=8)
        ax.grid(True, alpha=0.3)
    _panels_done(fig, axes, "$F_{\\rm fric}$ coupled / decoupled", 4,
                 "squeeze history (mean over 20 samples, $\\pm$ bootstrap s.d.)",
                 "coupled over decoupled friction force, break law, $\\lambda$ = 0.2; "
                 "H = 0.8, 6 depths 0.3-2 rms")
    save(plt, fig, out / "histories.png")


def _panels_done(fig, axes, ylabel: str, ncol: int, legend: str, title: str) -> None:
    """A row of panels finished: the first panel's y label, one legend below them all (from
    the first panel's lines, titled ``legend``) and the figure's title."""
    first = np.atleast_1d(axes)[0]
    first.set_ylabel(ylabel, fontsize=8)
    handles, labels = first.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=ncol, fontsize=8,
               frameon=False, title=legend, title_fontsize=8)
    fig.suptitle(title, fontsize=10)


def histories_weakening(out: Path) -> None:
    """The squeeze-histories study under slip-weakening: the coupled/decoupled friction
    ratio against N for each history and law (break, and slip-weakening at two slip
    distances), with its bootstrap error, read from the results page's table."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(ROOT / "docs" / "results.md", "| N | $\\nu$ | history | law |")
    data: dict[tuple[float, str, str], list[tuple[int, float, float]]] = {}
    for row in rows:
        ratio, err = _plus_minus(row[5])
        data.setdefault((float(row[1]), row[2], row[3]), []).append((int(row[0]), ratio, err))
    order = ("bonded", "simultaneous", "indent", "frictionless")
    # the break law dotted with open markers, then the slip distances from the longest
    # (solid) down (dashed, dash-dotted)
    weak = sorted({law for _, _, law in data} - {"break"}, reverse=True)
    laws = ["break", *weak] if any(law == "break" for _, _, law in data) else weak
    styles = {law: (":", "white") if law == "break" else ("-", "--", "-.")[weak.index(law)]
              for law in laws}
    styles = {law: s if isinstance(s, tuple) else (s, None) for law, s in styles.items()}
    nus = sorted({nu for nu, _, _ in data})
    sizes = sorted({n for pts in data.values() for n, _, _ in pts})
    plt = pyplot()
    fig, axes = plt.subplots(1, len(nus), figsize=(7.5, 3.9), sharey=True, layout="constrained")
    for ax, nu in zip(np.atleast_1d(axes), nus, strict=True):
        ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
        for j, name in enumerate(order):
            for k, law in enumerate(laws):
                pts = sorted(data.get((nu, name, law), []))
                if not pts:
                    continue
                N, ratio, err = (np.array(c, dtype=float) for c in zip(*pts, strict=True))
                shift = 2.0 ** (0.03 * (4 * k + j - 5.5))  # side by side
                ls, mfc = styles[law]
                ax.errorbar(N * shift, ratio, yerr=err, fmt="os^D"[j] + ls, color=f"C{j}",
                            mfc=mfc or f"C{j}", ms=4, lw=1, capsize=2)
        ax.set_xscale("log", base=2)
        ax.set_xticks(sizes, [str(n) for n in sizes])
        ax.minorticks_off()
        ax.set_xlim(min(sizes) / 1.3, max(sizes) * 1.3)
        ax.set_ylim(0, 1.1)
        ax.set_title(f"$\\nu$ = {nu:g}", fontsize=9)
        ax.set_xlabel("grid size N (unit pixels: a larger patch)", fontsize=8)
        ax.tick_params(labelsize=8)
        ax.grid(True, alpha=0.3)
    first = np.atleast_1d(axes)[0]
    first.set_ylabel("$F_{\\rm fric}$ coupled / decoupled", fontsize=8)
    handles = [first.plot([], [], "os^D"[j], color=f"C{j}", ms=4, label=name)[0]
               for j, name in enumerate(order)]
    handles += [first.plot([], [], styles[law][0], color="0.3", lw=1,
                           label=law if law == "break" else f"slip-weakening, {law}")[0]
                for law in laws]
    fig.legend(handles=handles, loc="outside lower center", ncol=4, fontsize=8, frameon=False,
               title="squeeze history and law (mean over the samples, $\\pm$ bootstrap s.d.)",
               title_fontsize=8)
    fig.suptitle("coupled over decoupled friction force, $\\lambda_s$ = 0.2, $\\lambda_d$ = "
                 "0.1; H = 0.8, 6 depths 0.3-2 rms", fontsize=10)
    save(plt, fig, out / "histories_weakening.png")


#: the results page, whose tables the figures of :func:`results_figures` are drawn from
RESULTS = ROOT / "docs" / "results.md"


def _number(cell: str) -> float:
    """The first number of a table cell (``0.853 ± 0.010``, ``+7.46e-03``, ``0.087 / 0.082``)."""
    m = re.search(r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?", cell.replace("−", "-"))
    if m is None:
        raise RuntimeError(f"docs/results.md: no number in the cell {cell!r}")
    return float(m.group(0))


def _numbers(cell: str) -> list[float]:
    """Every number of a table cell, in order."""
    # a hyphen after a digit is a range (0.073-0.091), not a sign
    return [float(x) for x in re.findall(r"(?<![\d.])[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?",
                                         cell.replace("−", "-"))]


def _size_axis(ax, sizes, label: str = "grid size N") -> None:
    """A log2 axis of grid sizes, labelled at each size."""
    ax.set_xscale("log", base=2)
    ax.set_xticks(sizes, [f"{n:g}" for n in sizes])
    ax.minorticks_off()
    ax.set_xlim(min(sizes) / 1.3, max(sizes) * 1.3)
    ax.set_xlabel(label, fontsize=8)


def _reference(ax, y: float, text: str, style: str = "--", color: str = "0.4") -> None:
    """A reference value across the axes, named on the line at its right end (not in the
    legend, which then has fewer entries to place)."""
    ax.axhline(y, color=color, lw=0.9, ls=style)
    ax.annotate(text, (1.0, y), xycoords=("axes fraction", "data"), xytext=(-4, 2),
                textcoords="offset points", ha="right", va="bottom", fontsize=8, color=color)


def _style(ax) -> None:
    ax.tick_params(labelsize=8)
    ax.grid(True, alpha=0.3)


def hertz_exponents(out: Path) -> None:
    """The Hertz table of the results page: the load and friction exponents against N, with
    the report's values at N = 24 and 32."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(RESULTS, "| N | a | $\\beta$")
    N = np.array([_number(r[0]) for r in rows])
    beta, dbeta = (np.array([_number(r[k]) for r in rows]) for k in (2, 3))
    alpha, dalpha = (np.array([_number(r[k]) for r in rows]) for k in (5, 6))
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(7.5, 3.3), layout="constrained")
    report = np.array([24, 32]) * 1.06  # beside our points at the same N
    _reference(left, 1.5, "Hertz, $\\beta$ = 3/2", "--")
    left.errorbar(N, beta, yerr=dbeta, fmt="o-", color="C0", ms=4, capsize=2,
                  label="here (± regression)")
    left.errorbar(report, [1.53, 1.53], yerr=0.1, fmt="s", color="C3", mfc="white", ms=4,
                  capsize=2, label="report, N = 24 and 32")
    left.set_ylabel("load exponent $\\beta$ ($F_n \\propto D_z^{\\beta}$)", fontsize=8)
    left.set_title("squeeze: converges to Hertz's 3/2", fontsize=9)
    _reference(right, 1.0, "Amontons, $\\alpha$ = 1", ":")
    _reference(right, 2 / 3, "$\\alpha$ = 2/3", "--")
    right.errorbar(N, alpha, yerr=dalpha, fmt="o-", color="C0", ms=4, capsize=2,
                   label="here (± regression)")
    right.errorbar(report, [0.86, 0.86], yerr=0.1, fmt="s", color="C3", mfc="white", ms=4,
                   capsize=2, label="report, N = 24 and 32")
    right.set_ylabel("friction exponent $\\alpha$ ($F_{\\rm friction} \\propto F_n^{\\alpha}$)",
                     fontsize=8)
    right.set_title("pull: break law, $\\lambda$ = 0.2", fontsize=9)
    right.set_ylim(0.6, 1.2)  # room for the legend above the line of Amontons
    for ax in (left, right):
        _size_axis(ax, N, "grid size N (pixel 1.28/N: a finer grid)")
        _style(ax)
        ax.legend(fontsize=8)
    fig.suptitle("one Hertz contact ($R$ = 1, $\\nu$ = 0.3), eight depths, against the grid size",
                 fontsize=10)
    save(plt, fig, out / "hertz_exponents.png")


def rough_exponents(out: Path) -> None:
    """The rough-surface table of the results page: the exponents against N for both Hurst
    exponents, with the report's values at N = 24 and Batrouni et al.'s."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(RESULTS, "| H | N | samples | quantity |")
    data: dict[tuple[str, float], list[tuple[float, float, float]]] = {}
    for r in rows:
        symbol = re.search(r"\\(beta|alpha|gamma)", r[3]).group(1)
        data.setdefault((symbol, float(r[0])), []).append(
            (float(r[1]), _number(r[4]), _number(r[5])))
    report = {("beta", 0.6): 1.14, ("beta", 0.8): 1.11, ("alpha", 0.6): 1.23,
              ("alpha", 0.8): 1.27}
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(7.5, 3.4), layout="constrained")
    titles = {"beta": "load: $F_n \\propto D_z^{\\beta}$",
              "alpha": "friction: $F_{\\rm friction} \\propto F_n^{\\alpha}$",
              "gamma": "area: $A \\propto F_n^{\\gamma}$"}
    for ax, symbol in zip(axes, ("beta", "alpha", "gamma"), strict=True):
        for j, H in enumerate((0.6, 0.8)):
            N, value, err = (np.array(c) for c in zip(*sorted(data[(symbol, H)]), strict=True))
            shift = 1.04 if j else 1 / 1.04
            ax.errorbar(N * shift, value, yerr=err, fmt="os"[j] + "-", color=f"C{j}", ms=4,
                        capsize=2, label=f"here, H = {H}")
            if (symbol, H) in report:
                ax.plot([24 * shift], [report[(symbol, H)]], "os"[j], color=f"C{j}",
                        mfc="white", ms=6, label=f"report, H = {H}")
        if symbol == "beta":
            for j, (H, limit) in enumerate(((0.6, 2.25), (0.8, 2.05))):
                ax.axhline(limit, color=f"C{j}", lw=0.9, ls="--",
                           label=f"Batrouni et al., $L \\to \\infty$, H = {H}")
        if symbol == "gamma":
            ax.axhline(0.91, color="0.4", lw=0.9, ls="--", label="Batrouni et al., 0.91")
        ax.set_title(titles[symbol], fontsize=9)
        ax.set_ylabel(f"exponent $\\{symbol}$ (± bootstrap)", fontsize=8)
        _size_axis(ax, [24, 128, 256])
        _style(ax)
    found = {lab: h for ax in axes for h, lab in zip(*ax.get_legend_handles_labels(),
                                                      strict=True)}
    order = [f"{who}, H = {H}" for who in ("here", "report") for H in (0.6, 0.8)]
    order += [f"Batrouni et al., $L \\to \\infty$, H = {H}" for H in (0.6, 0.8)]
    order.append("Batrouni et al., 0.91")
    fig.legend([found[lab] for lab in order], order, loc="outside lower center", ncol=4,
               fontsize=8, frameon=False)
    fig.suptitle("self-affine surfaces (rms 1, pixel 1, open), ten depths 0.1-2 rms, "
                 "$\\nu$ = 0.3; friction: break law, $\\lambda$ = 0.2", fontsize=10)
    save(plt, fig, out / "rough_exponents.png")


def coupled_finite_size(out: Path) -> None:
    """The coupled finite-size table of the results page: the coupled/decoupled friction
    ratio, the exponents and the bonds released at D_x = 0 against N, per Poisson ratio."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(RESULTS, "| scene | N | $\\nu$ | $\\alpha$ decoupled | $\\alpha$ "
                           "coupled | $F_{\\rm fric}$ coupled / decoupled | bonds released")
    nus = sorted({float(r[2]) for r in rows})
    plt = pyplot()
    fig, (ratio_ax, alpha_ax, freed_ax) = plt.subplots(1, 3, figsize=(7.5, 3.4),
                                                       layout="constrained")
    for j, nu in enumerate(nus):
        sel = sorted((r for r in rows if float(r[2]) == nu), key=lambda r: float(r[1]))
        N = np.array([float(r[1]) for r in sel])
        dec, ddec = (np.array([_numbers(r[3])[k] for r in sel]) for k in (0, 1))
        cou, dcou = (np.array([_numbers(r[4])[k] for r in sel]) for k in (0, 1))
        ratio_ax.plot(N, [_number(r[5]) for r in sel], "os"[j] + "-", color=f"C{j}", ms=4,
                      label=f"$\\nu$ = {nu:g}")
        shift = 1.03 if j else 1 / 1.03
        alpha_ax.errorbar(N * shift, cou, yerr=dcou, fmt="os"[j] + "-", color=f"C{j}", ms=4,
                          capsize=2)
        alpha_ax.errorbar(N * shift, dec, yerr=ddec, fmt="os"[j] + "--", color=f"C{j}", ms=4,
                          mfc="white", capsize=2)
        freed_ax.plot(N, [_number(r[6]) for r in sel], "os"[j] + "-", color=f"C{j}", ms=4,
                      label=f"$\\nu$ = {nu:g}")
    alpha_ax.plot([], [], "o-", color="0.3", ms=4, label="coupled")
    alpha_ax.plot([], [], "o--", color="0.3", mfc="white", ms=4, label="decoupled")
    ratio_ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
    ratio_ax.set_ylim(0, 1.25)  # room for the legend above the dotted line (no coupling)
    ratio_ax.set_ylabel("$F_{\\rm fric}$ coupled / decoupled", fontsize=8)
    ratio_ax.set_title("friction force", fontsize=9)
    alpha_ax.set_ylim(0.4, 1.0)
    alpha_ax.set_ylabel("$\\alpha$ ($F_{\\rm fric} \\propto F_n^{\\alpha}$, ± bootstrap)",
                        fontsize=8)
    alpha_ax.set_title("friction exponent", fontsize=9)
    freed_ax.set_ylim(0, 1.05)
    freed_ax.set_ylabel("fraction of the contact sites", fontsize=8)
    freed_ax.set_title("bonds released at $D_x = 0$", fontsize=9)
    sizes = sorted({float(r[1]) for r in rows})
    for ax in (ratio_ax, alpha_ax, freed_ax):
        _size_axis(ax, sizes, "grid size N (unit pixels)")
        _style(ax)
        ax.legend(fontsize=8)
    fig.suptitle("coupled model, break law, $\\lambda$ = 0.2, history bonded; H = 0.8, "
                 "20 samples, 6 depths 0.3-2 rms", fontsize=10)
    save(plt, fig, out / "coupled_finite_size.png")


def indentation(out: Path) -> None:
    """The frictional-indentation table of the results page: the stick fraction c/a against
    lambda/beta, the limit and the model at each Poisson ratio."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(RESULTS, "| $\\lambda/\\beta$ | $c/a$ limit")
    x = np.array([_number(r[0]) for r in rows])
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.0), layout="constrained")
    ax.plot(x, [_number(r[1]) for r in rows], "-", color="0.3", lw=2.5, alpha=0.5,
            label="limit $\\beta\\lambda \\to 0$ (singular integral equation)")
    spread = np.array([_numbers(r[2])[2:4] for r in rows])
    ax.fill_between(x, spread[:, 0], spread[:, 1], color="C0", alpha=0.2, lw=0,
                    label="$\\nu$ = 0.49, $a$ = 107: smallest to largest")
    for j, (col, nu) in enumerate(((2, 0.49), (3, 0.4), (4, 0.25), (5, 0.0))):
        small, large = (np.array([_numbers(r[col])[k] for r in rows]) for k in (0, 1))
        ax.plot(x, large, "osD^"[j] + "-", color=f"C{j}", ms=4, lw=1,
                label=f"$\\nu$ = {nu:g}, $a$ = {107 if nu == 0.49 else 105}")
        ax.plot(x, small, "x", color="k", ms=4, mew=0.9, zorder=3)
    ax.plot([], [], "x", color="k", ms=4, mew=0.9,
            label="each $\\nu$ at $a$ = 37 (35) pixels")
    ax.set_xlabel("$\\lambda/\\beta$, $\\beta = (1 - 2\\nu)/(2(1 - \\nu))$", fontsize=8)
    ax.set_ylabel("stick fraction $c/a$ (median over the loading)", fontsize=8)
    ax.set_ylim(0, 1.05)
    _style(ax)
    ax.legend(fontsize=8)
    ax.set_title("frictional indentation of a parabolic cylinder (plane strain),\n"
                 "coupled model, Coulomb law", fontsize=9)
    save(plt, fig, out / "indentation.png")


def traction_direction(out: Path) -> None:
    """The drive-angle table of the results page: the friction ratio to the x-only model
    against the drive's angle, anisotropic and isotropic surfaces, one panel per nu."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(RESULTS, "| $\\nu$ | drive | anisotropic")
    nus = sorted({float(r[0]) for r in rows})
    plt = pyplot()
    fig, axes = plt.subplots(1, len(nus), figsize=(7.5, 3.6), sharey=True,
                             layout="constrained")
    for ax, nu in zip(np.atleast_1d(axes), nus, strict=True):
        mine = [r for r in rows if float(r[0]) == nu]
        angle = np.array([_number(r[1]) for r in mine])
        ax.axhline(1.0, color="0.5", lw=0.8, ls=":")
        for j, (col, name) in enumerate(((3, "anisotropic, $\\gamma$ = 4: ridges along y, "
                                              "pulled across them at 0, along at 90"),
                                         (5, "isotropic (the control)"))):
            ratio, err = (np.array(c) for c in zip(*(_plus_minus(r[col]) for r in mine),
                                                   strict=True))
            ax.errorbar(angle + 0.8 * (j - 0.5), ratio, yerr=err, fmt="os"[j] + "-",
                        color=f"C{j}", ms=4, lw=1, capsize=2.5, label=name)
        ax.set_xticks([0, 15, 30, 45, 60, 75, 90])
        ax.set_title(f"$\\nu$ = {nu:g}", fontsize=9)
        ax.set_xlabel("drive angle from x (degrees)", fontsize=8)
        _style(ax)
    _panels_done(fig, axes, "$F_{\\rm fric}$ / x-only model along x", 1,
                 "traction vector, mean over 20 samples $\\pm$ bootstrap s.d.",
                 "friction against the drive's angle, break law, $\\lambda$ = 0.2; "
                 "N = 128, H = 0.8, 6 depths 0.3-2 rms")
    save(plt, fig, out / "traction_direction.png")


def weakening_rough(out: Path) -> None:
    """The slip-weakening table of rough surfaces on the results page: the friction
    coefficient at three depths and the exponent, per law and grid."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(RESULTS, "| scene | law | $\\alpha$")
    depths = np.geomspace(0.1, 2.0, 10)[[0, 4, 9]]  # depths 1, 5 and 10 of the study
    scenes = list(dict.fromkeys(r[0] for r in rows))
    laws = list(dict.fromkeys(r[1] for r in rows))
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(7.5, 3.6), layout="constrained",
                                      gridspec_kw={"width_ratios": [1.5, 1]})
    styles = ("-", "--", ":")
    for r in rows:
        i, j = scenes.index(r[0]), laws.index(r[1])
        values = _numbers(r[4])
        mean, err = np.array(values[0::2]), np.array(values[1::2])
        left.errorbar(depths * 1.03 ** (i - 1), mean, yerr=err, fmt="osD"[j] + styles[i],
                      color=f"C{j}", ms=4, capsize=2, lw=1)
        right.errorbar([i + 0.15 * (j - 1)], [_number(r[2])], yerr=[_number(r[3])],
                       fmt="osD"[j], color=f"C{j}", ms=5, capsize=2)
    names = ["break law" if law == "break" else law for law in laws]
    for j, name in enumerate(names):
        left.plot([], [], "osD"[j], color=f"C{j}", label=name)
    for i, scene in enumerate(scenes):
        left.plot([], [], styles[i], color="0.3", label=scene)
    left.axhline(0.5, color="0.5", lw=0.8, ls=":")
    left.set_xscale("log")
    left.set_xticks(depths, [f"{d:.2g}" for d in depths])
    left.minorticks_off()
    left.set_xlabel("depth from first touch (rms heights)", fontsize=8)
    left.set_ylabel("$F_f / (\\lambda_s F_n)$ (± s.e.)", fontsize=8)
    left.set_ylim(0, 1.25)
    left.set_title("friction coefficient (dotted: the residual $\\lambda_d/\\lambda_s$)",
                   fontsize=9)
    right.set_xticks(range(len(scenes)),
                     [re.sub(r" \(patch \d+\)", "", s).replace(", h", "\nh") for s in scenes])
    right.set_xlim(-0.5, len(scenes) - 0.5)
    right.set_ylabel("$\\alpha$ ($F_f \\propto F_n^{\\alpha}$, ± bootstrap)", fontsize=8)
    right.set_title("friction exponent (the last two:\none patch of 64 × 64)", fontsize=9)
    for ax in (left, right):
        _style(ax)
    right.tick_params(axis="x", labelsize=7)
    left.legend(fontsize=7, ncol=2)
    fig.suptitle("rough surfaces (H = 0.8, $\\nu$ = 0.3), break law and slip-weakening: "
                 "$\\lambda_s$ = 0.2, $\\lambda_d$ = 0.1", fontsize=10)
    save(plt, fig, out / "weakening_rough.png")


def burst_exponents(out: Path) -> None:
    """The burst table of the results page: the exponents of the burst sizes and of the
    force drops, per phase, against N for both Hurst exponents."""
    from roughslip.analysis.plotting import pyplot, save

    rows = _markdown_table(RESULTS, "| H | N | samples | pulls | phase |")
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(7.5, 3.5), layout="constrained", sharey=True)
    phases = ("before", "after", "all")
    for ax, (col, what) in zip(axes, ((6, "burst sizes"), (10, "force drops")), strict=True):
        for j, phase in enumerate(phases):
            for k, H in enumerate((0.6, 0.8)):
                sel = sorted((r for r in rows if r[4] == phase and float(r[0]) == H),
                             key=lambda r: float(r[1]))
                N = np.array([float(r[1]) for r in sel]) * 1.04 ** (j - 1 + 0.3 * k)
                ax.errorbar(N, [float(r[col]) for r in sel],
                            yerr=[float(r[col + 1]) for r in sel], fmt="os"[k] + "-:"[k],
                            color=f"C{j}", ms=4, capsize=2, lw=1,
                            mfc=f"C{j}" if k else "white")
        if col == 6:
            _reference(ax, 2.5, "5/2, fibre bundles", "--")
        ax.set_title(f"exponent of the {what}, $p(x) \\propto x^{{-\\alpha}}$", fontsize=9)
        _size_axis(ax, [128, 256])
        _style(ax)
    handles = [axes[0].plot([], [], "-", color=f"C{j}", label=f"{phase} the peak"
                            if phase != "all" else "the whole pull")[0]
               for j, phase in enumerate(phases)]
    handles += [axes[0].plot([], [], "o-", color="0.3", mfc="white", label="H = 0.6")[0],
                axes[0].plot([], [], "s:", color="0.3", label="H = 0.8")[0]]
    axes[0].set_ylabel("exponent $\\alpha$ (± statistical)", fontsize=8)
    fig.legend(handles=handles, loc="outside lower center", ncol=5, fontsize=8, frameon=False)
    fig.suptitle("bursts of the pull: break law, $\\lambda$ = 0.2, $\\nu$ = 0.3, three depths "
                 "(1-2 rms), exact pull to the last bond", fontsize=10)
    save(plt, fig, out / "burst_exponents.png")


def results_figures(out: Path) -> None:
    """The figures of the results page drawn from its own tables (recorded numbers: the
    studies take minutes to hours and are not run again)."""
    histories(out)
    histories_weakening(out)
    hertz_exponents(out)
    rough_exponents(out)
    coupled_finite_size(out)
    indentation(out)
    traction_direction(out)
    weakening_rough(out)
    burst_exponents(out)


def _text_rows(page: str, start: str, first: str, occurrence: int = 0) -> list[list[str]]:
    """The whitespace-separated rows of the text block of ``page`` after the ``occurrence``-th
    line that starts with ``start``, to the block's end or its next comment line, without the
    column headers (rows whose first field is ``first``)."""
    lines = page.splitlines()
    found = [i for i, line in enumerate(lines) if line.strip().startswith(start)]
    if len(found) <= occurrence:
        raise RuntimeError(f"docs/benchmarks.md: no text block after a line {start!r}")
    rows = []
    for row in lines[found[occurrence] + 1:]:
        fields = row.split()
        if not fields or fields[0].startswith(("#", "`")):
            break
        if fields[0] != first:
            rows.append(fields)
    return rows


def _slope(x, y) -> float:
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def benchmarks(out: Path) -> None:
    """The benchmarks page at a glance, drawn from its own tables: time against size with
    the fitted slopes (operator, squeeze, pull) and against the peer codes."""
    from roughslip.analysis.plotting import log_ticks, pyplot, save

    page = (ROOT / "docs" / "benchmarks.md").read_text()
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(7.5, 6.6), layout="constrained")
    (op, sq), (pl, peers) = axes

    rows = _text_rows(page, "# cores: 2, FFT threads: 1, medians of 11", "N")
    for j, (boundary, style) in enumerate((("open", "o-"), ("periodic", "s-"))):
        sel = [r for r in rows if r[1] == boundary and r[2] == "pyfftw"]
        N = np.array([float(r[0]) for r in sel])
        t = np.array([float(r[4]) for r in sel])
        op.loglog(N, t, style, color=f"C{j}", ms=4,
                  label=f"{boundary} (slope {_slope(N, t):.2f})")
    op.set_title("operator: one convolution (pyfftw, 1 thread)", fontsize=9)
    op.set_ylabel("time per convolution (ms)", fontsize=8)

    rows = _text_rows(page, "# cores: 2, FFT: pyfftw ESTIMATE, 1 thread, tol 1e-08, "
                      "medians of 3", "N")
    for j, (scene, bound, style) in enumerate((("rough", "open", "o-"),
                                               ("rough", "periodic", "s-"),
                                               ("hertz", "open", "^-"))):
        sel = [r for r in rows if r[1] == scene and r[2] == bound and r[3] == "0.050"
               and r[4] == "depth"]
        N = np.array([float(r[0]) for r in sel])
        t = np.array([float(r[7]) for r in sel])
        sq.loglog(N, t, style, color=f"C{j}", ms=4,
                  label=f"{scene}, {bound} (slope {_slope(N, t):.2f})")
    sq.set_title("squeeze to 5 % contact, tol $10^{-8}$", fontsize=9)
    sq.set_ylabel("time per squeeze (s)", fontsize=8)
    sq.set_ylim(top=2e3)  # room for the legend above the curves
    for ax in (op, sq):
        ax.set_xlabel("grid size N ($N \\times N$)", fontsize=8)
        ax.set_xticks([256, 512, 1024], ["256", "512", "1024"])
        ax.minorticks_off()

    rows = _text_rows(page, "# cores: 2, BLAS/FFT threads: 2, lambda 0.2, tol 1e-10", "N")
    # the larger contact of the bullet below the table (its own block, the same columns)
    rows += _text_rows(page, "N   area  bonds   method       sec  steps     F_friction", "N",
                       occurrence=1)
    series = (("literal", "0.050", "o-", "C0"), ("cg", "0.050", "s-", "C1"),
              ("inverse", "0.050", "^-", "C2"), ("inverse", "0.200", "^--", "C2"))
    for method, area, style, colour in series:
        # 0.199 and 0.200 are the same target of 20 % contact
        pts = sorted((float(r[2]), float(r[4])) for r in rows
                     if r[3] == method and abs(float(r[1]) - float(area)) < 0.005)
        n = np.array([p[0] for p in pts])
        t = np.array([p[1] for p in pts])
        big = n >= 800  # the smallest pulls are overhead
        pl.loglog(n, t, style, color=colour, ms=4, mfc="white" if area == "0.200" else colour,
                  label=f"{method}, {float(area):.0%} contact (slope "
                        f"{_slope(n[big], t[big]):.2f})")
    pl.set_title("exact pull: time against the bonds", fontsize=9)
    pl.set_xlabel("bonds at the start of the pull", fontsize=8)
    pl.set_ylabel("time per pull (s)", fontsize=8)
    log_ticks(pl.xaxis)
    pl.set_ylim(top=3e5)  # room for the legend above the curves
    for ax in (op, sq, pl):
        log_ticks(ax.yaxis)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
        ax.tick_params(labelsize=8)

    rows = _text_rows(page, "# after, 2 threads", "peer")
    cases = []
    for r in rows:
        line = " ".join(r)
        m = re.match(r"(tamaas|contactmech) [\d.]+ (\w+) (\w+) 512\^2, ([FD]) (\d) ([\d.]+) "
                     r"[\d.]+ \S+ ([\d.]+) ([\d.]+)", line)
        if m is None:
            raise RuntimeError(f"docs/benchmarks.md: a peer row not understood: {line!r}")
        peer = {"tamaas": "Tamaas", "contactmech": "ContactMechanics"}[m.group(1)]
        cases.append((f"{peer}\n{m.group(3)} {m.group(2)}, {100 * float(m.group(6)):.1f} %",
                      float(m.group(7)), float(m.group(8))))
    y = np.arange(len(cases))
    ours = np.array([c[1] for c in cases])
    theirs = np.array([c[2] for c in cases])
    peers.barh(y + 0.2, theirs, height=0.38, color="0.6", label="peer code")
    peers.barh(y - 0.2, ours, height=0.38, color="C0", label="roughslip")
    for yi, a, b in zip(y, ours, theirs, strict=True):
        peers.text(b + 0.2, yi + 0.2, f"{b:.1f} s", va="center", fontsize=8)
        peers.text(a + 0.2, yi - 0.2, f"{a:.2f} s ({b / a:.1f}x faster)", va="center",
                   fontsize=8)
    peers.set_yticks(y, [c[0] for c in cases], fontsize=8)
    peers.invert_yaxis()
    peers.set_xlim(0, theirs.max() * 1.25)
    peers.set_xlabel("s, 512 x 512 squeeze, best of 3", fontsize=8)
    peers.set_title("against the peer codes, 2 threads", fontsize=9)
    peers.tick_params(labelsize=8)
    peers.legend(fontsize=8, loc="upper right")
    save(plt, fig, out / "bench_scaling.png")


def python_tutorial(out: Path) -> None:
    """Run the Python tutorial ``docs/guide/python_tutorial.py`` cell by cell (``# %% name``
    lines) in a scratch folder, in one namespace as a script runs: each cell's code and what
    it prints go to ``python_<name>.py`` and ``python_<name>.txt``, the figures it saves to
    ``python_<file>.png``."""
    import matplotlib

    matplotlib.use("Agg")
    source = ROOT / "docs" / "guide" / "python_tutorial.py"
    parts = re.split(r"^# %% (\w+)\n", source.read_text(), flags=re.M)
    cells = list(zip(parts[1::2], parts[2::2], strict=True))
    if not cells:
        raise RuntimeError(f"{source}: no cells (lines '# %% name')")
    namespace = {"__name__": "__main__", "__file__": str(source)}
    with tempfile.TemporaryDirectory(prefix="roughslip-docs-") as tmp, contextlib.chdir(tmp):
        for name, code in cells:
            code = code.strip("\n") + "\n"
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                exec(compile(code, f"{source.name} (cell {name})", "exec"), namespace)
            (out / f"python_{name}.py").write_text(code)
            (out / f"python_{name}.txt").write_text(printed.getvalue())
        for png in sorted(Path(tmp).glob("*.png")):
            shutil.copy(png, out / f"python_{png.name}")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", type=Path, help="folder for the figures and text files")
    args = ap.parse_args(argv)
    # the pages show the package's current names: a deprecated one fails the build
    warnings.filterwarnings("error", r"(roughslip\.|PullResult\.|SlipResult|CoupledResult)",
                            DeprecationWarning)
    args.out.mkdir(parents=True, exist_ok=True)
    quickstart(args.out)
    topography(args.out)
    hurst_loop(args.out)
    hertz_resolution(args.out)
    weakening_resolution(args.out)
    coupled_events(args.out)
    coulomb_cone(args.out)
    spence_sphere(args.out)
    results_figures(args.out)
    benchmarks(args.out)
    python_tutorial(args.out)


if __name__ == "__main__":
    main()
