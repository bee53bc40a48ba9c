"""Text summary of a run file (``roughslip inspect``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from roughslip.run.store import read_run


def mean_sem(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error of the mean over samples (axis 0); SEM is 0 for one sample."""
    rows = np.asarray(rows, dtype=float)
    n = rows.shape[0]
    mean = rows.mean(axis=0) if n else np.full(rows.shape[1:], np.nan)
    sem = rows.std(axis=0, ddof=1) / np.sqrt(n) if n > 1 else np.zeros(rows.shape[1:])
    return mean, sem


def _computed(values: np.ndarray) -> np.ndarray:
    """The entries that were computed (not NaN), as floats."""
    v = np.asarray(values, dtype=float).ravel()
    return v[~np.isnan(v)]


def _count_false(flags: np.ndarray) -> tuple[int, int]:
    """(entries that are 0, entries computed) of a flag column."""
    v = _computed(flags)
    return int((v == 0).sum()), int(v.size)


def length_unit(run) -> str | None:
    """The run's length unit (``units.length``), or None for bare numbers."""
    return run.config_dict().get("units", {}).get("length")


def summarize(path: str | Path) -> str:
    """Config, progress, per-depth means +- standard errors, and convergence problems."""
    run = read_run(path)
    a = run.attrs
    lines = [
        f"{run.path}",
        f"  roughslip {a.get('version', '?')}, made by: {a.get('command_line', '?')}",
        f"  samples complete: {run.n_complete} of {run.complete.size}",
    ]
    cfg = run.config_dict()
    title = cfg.get("title")
    if title:
        lines.append(f"  title: {title}")
    s = cfg.get("surface", {})
    g = cfg.get("grid", {})
    unit = length_unit(run)
    shape = g.get("shape") or [g.get("n"), g.get("n")]
    if run.n_complete:  # file surfaces set the grid; the stored surface has its shape
        shape = list(run.surface(int(run.sample_index[run.complete][0])).shape)
    pixel = a.get("pixel_size", g.get("pixel_size"))
    where = f", from {Path(str(s['path'])).name}" if s.get("kind") == "file" else ""
    lines.append(f"  surface: {s.get('kind')}{where}"
                 + (f", H = {s['hurst']}" if "hurst" in s else "")
                 + f"; grid {shape[0]} x {shape[1]}, a = {pixel}{' ' + unit if unit else ''}, "
                 f"{g.get('boundary')}; E = {cfg['material']['E']}, nu = {cfg['material']['nu']}")
    if unit:
        lines.append(f"  length unit: {unit} (forces in units of E x {unit}^2)")
    if run.n_complete == 0:
        lines.append("  no complete samples yet")
        return "\n".join(lines)
    sel = run.complete
    names = ["normal_force", "contact_area"] + (["friction_force"]
                                                 if "friction_force" in run.scalars else [])
    axis = run.axis_name
    axis_unit = run.axis_unit
    if axis_unit == "length" and unit:
        axis_unit = unit
    axis_label = f"{axis} ({axis_unit})" if axis_unit else axis
    head = f"  {axis_label:>12} " + " ".join(f"{n + ' (mean +- sem)':>30}" for n in names)
    lines.append(head)
    stats = {n: mean_sem(run.scalars[n][sel]) for n in names}
    for k, x in enumerate(run.axis):
        row = f"  {x:>12.5g} "
        for n in names:
            m, e = stats[n][0][k], stats[n][1][k]
            row += f"{m:>17.6g} +- {e:<10.3g}"
        lines.append(row)
    bad, total = _count_false(run.scalars["converged"][sel])
    problems = [f"  squeeze solves not converged: {bad} of {total}"]
    if "pull_converged" in run.scalars:
        bad, total = _count_false(run.scalars["pull_converged"][sel])
        problems.append(f"  pulls not converged: {bad} of {total}")
        est = _computed(run.scalars["pull_error_estimate"][sel])
        if np.any(est > 0):
            problems.append(f"  approximate pulls: max estimated error {est.max():.2e}")
    parts = []
    for name, text in (("residual", "worst squeeze residual: {:.2e}"),
                       ("iterations", "mean iterations {:.1f}"),
                       ("seconds", "mean solve seconds {:.3g}")):
        v = _computed(run.scalars[name][sel])
        if v.size:
            parts.append(text.format(v.max() if name == "residual" else v.mean()))
    if parts:
        problems.append("  " + "; ".join(parts))
    lines.extend(problems)
    return "\n".join(lines)
