"""Text summary of a run file (``roughslip inspect``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from roughslip.analysis.fit import PULLED, means, unconverged_pulls
from roughslip.friction.pull import METHODS
from roughslip.run.blas import blas_line
from roughslip.run.store import read_run


def mean_sem(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error of the mean over samples (axis 0), of the entries that are not
    NaN (entries left out); the SEM is 0 where one sample is left."""
    rows = np.asarray(rows, dtype=float)
    if rows.shape[0] == 0:
        return np.full(rows.shape[1:], np.nan), np.zeros(rows.shape[1:])
    if not np.isnan(rows).any():
        n = rows.shape[0]
        sem = rows.std(axis=0, ddof=1) / np.sqrt(n) if n > 1 else np.zeros(rows.shape[1:])
        return rows.mean(axis=0), sem
    n = (~np.isnan(rows)).sum(axis=0)
    mean = means(rows)
    with np.errstate(invalid="ignore", divide="ignore"):
        var = np.nansum((rows - mean) ** 2, axis=0) / (n - 1)
        sem = np.where(n > 1, np.sqrt(var / n), 0.0)
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


def axis_unit(run) -> str:
    """The unit of the run's depths or loads (``rms``, ``range``, ``pressure``), with
    ``length`` and ``force`` replaced by the run's named units; empty when they have none
    (a dimensionless run)."""
    from roughslip.run.units import Units

    unit = run.axis_unit
    if unit in ("length", "force"):
        return Units.of(run.config_dict()).of_dimension(unit)
    return unit


def pixel_size(run) -> float:
    """The run's pixel size, in its length unit (a file surface's, as stored)."""
    return float(run.attrs.get("pixel_size",
                               run.config_dict().get("grid", {}).get("pixel_size", 1.0)))


def closed_form(run) -> tuple[str, np.ndarray] | None:
    r"""The exact normal force at each depth of each complete sample, when the run's scene has
    a closed form: ``(name, F)`` with ``F`` of shape ``(complete samples, depths)``, NaN where
    the closed form does not apply; None for other scenes.

    ``sphere``
        Hertz, :math:`F = \tfrac43E^*R^{1/2}d^{3/2}` with the apex approach
        :math:`d = D_z - \max h` (the apex lies at height 0, the highest pixel below it), while
        the contact radius :math:`\sqrt{Rd}` stays within 40 % of the grid's smaller side
        from its centre.
    ``punch``
        Boussinesq, :math:`F = 2aE^*D_z` with :math:`a` the radius of the pixel count.

    Only for an open grid, one rigid surface against a flat elastic one, and no coupling (the
    coupled model changes the normal force unless :math:`\nu = 1/2`).
    """
    from roughslip.contact.analytic import flat_punch_force, hertz

    cfg = run.config_dict()
    s, mat = cfg.get("surface", {}), cfg.get("material", {})
    kind = s.get("kind")
    coupled = cfg.get("coupling", {}).get("enabled", False) and mat.get("nu") != 0.5
    if (kind not in ("sphere", "punch") or cfg.get("grid", {}).get("boundary") != "open"
            or cfg.get("elastic_surface") or coupled or run.n_complete == 0
            or run.axis_name != "depth"):
        return None
    sel = run.complete
    depth = np.asarray(run.scalars["depth_length"][sel], dtype=float)
    E, nu = float(mat["E"]), float(mat["nu"])
    pixel = pixel_size(run)
    area = np.asarray(run.scalars["contact_area"][sel], dtype=float)
    out = np.full(depth.shape, np.nan)
    for row, sample in enumerate(run.sample_index[sel]):
        h = run.surface(int(sample))
        reach = 0.4 * min(h.shape) * pixel
        for k, dz in enumerate(depth[row]):
            if kind == "sphere":
                d = dz - float(h.max())
                if d > 0 and np.sqrt(float(s["radius"]) * d) <= reach:
                    out[row, k] = hertz(float(s["radius"]), d, E, nu).force
            else:
                n = area[row, k] * h.size
                out[row, k] = flat_punch_force(float(np.sqrt(n / np.pi)) * pixel, dz, E, nu)
    return ("Hertz" if kind == "sphere" else "flat punch"), out


class _ClosedForm:
    """The default of :func:`solves_table`'s ``exact``: the run's closed form, computed."""

    def __repr__(self) -> str:
        return "CLOSED_FORM"


#: ``solves_table``'s default ``exact``: compute the run's :func:`closed_form`
CLOSED_FORM = _ClosedForm()


def solves_table(run, exact: Any = CLOSED_FORM) -> list[dict[str, float]]:
    """Per depth (or load): the record of the solves over the complete samples.

    Worst squeeze residual, mean iterations, median squeeze and pull seconds, worst pull
    error estimate (only when ``pull.error_estimate`` asked for it), and the worst relative
    error of the normal force against ``exact``, the :func:`closed_form` of the run (computed
    when not given; it reads every surface, so pass it when you have it), each NaN where the
    run has none.
    """
    sel = run.complete
    if exact is CLOSED_FORM:
        exact = closed_form(run)
    pull_cfg = run.config_dict().get("pull", {})
    # files of earlier versions stored 0 for an estimate nobody asked for
    asked = pull_cfg.get("error_estimate", pull_cfg.get("error_bound", False))

    def col(name: str) -> np.ndarray:
        if name not in run.scalars or (name == "pull_error_estimate" and not asked):
            return np.full((int(sel.sum()), len(run.axis)), np.nan)
        return np.asarray(run.scalars[name][sel], dtype=float)

    def over(values: np.ndarray, fn) -> float:
        v = values[~np.isnan(values)]
        return float(fn(v)) if v.size else float("nan")

    fn_err = (np.abs(col("normal_force") - exact[1]) / exact[1] if exact is not None
              else col("normal_force") * np.nan)
    rows = []
    for k, x in enumerate(run.axis):
        rows.append({"axis": float(x),
                     "residual": over(col("residual")[:, k], np.max),
                     "iterations": over(col("iterations")[:, k], np.mean),
                     "seconds": over(col("seconds")[:, k], np.median),
                     "pull_seconds": over(col("pull_seconds")[:, k], np.median),
                     "pull_error_estimate": over(col("pull_error_estimate")[:, k], np.max),
                     "normal_force_error": over(fn_err[:, k], np.max)})
    return rows


def _format_solves(run, axis_label: str) -> list[str]:
    exact = closed_form(run)
    rows = solves_table(run, exact)
    has = {k: any(np.isfinite(r[k]) for r in rows) for k in rows[0]}
    cols = [("residual", "sq. residual", "{:>12.2e}"), ("iterations", "iters", "{:>6.1f}"),
            ("seconds", "sq. seconds", "{:>11.3g}"), ("pull_seconds", "pull seconds",
                                                      "{:>12.3g}"),
            ("pull_error_estimate", "pull est. err", "{:>13.2e}"),
            ("normal_force_error", f"F_n vs {exact[0] if exact else ''}", "{:>14.2e}")]
    cols = [c for c in cols if has[c[0]]]
    what = "worst residual, mean iterations and median seconds over the samples"
    if has["pull_error_estimate"]:
        what += "; the friction force's estimated error (worst)"
    if has["normal_force_error"]:
        what += f"; F_n against the {exact[0]} closed form (worst: the discretisation error)"
    w = max(12, len(axis_label))
    lines = [f"  solves per depth: {what}",
             f"  {axis_label:>{w}} " + " ".join(f"{t:>{len(f.format(0.0))}}" for _, t, f in cols)]
    for r in rows:
        lines.append(f"  {r['axis']:>{w}.5g} " + " ".join(
            f.format(r[k]) if np.isfinite(r[k]) else f"{'-':>{len(f.format(0.0))}}"
            for k, _, f in cols))
    return lines


def summarize(path: str | Path) -> str:
    """What a run was and what it gave, within :data:`~roughslip.analysis.model.WIDTH`
    columns: title, version, machine and command line; the resolved model (slip law and its
    parameters, the methods actually used, the coupled history, units); every configuration
    key that differs from the defaults; the run's notes; progress; per-depth means +-
    standard errors in named units (a single sample's values); convergence problems and the
    solves per depth."""
    from roughslip.analysis import model

    run = read_run(path)
    a = run.attrs
    cfg = run.config_dict()
    lines = [f"{run.path}"]
    title = model.title(run)
    if title:
        lines += model.wrap("title: ", title, indent=2)
    lines.append(f"  roughslip {a.get('version', '?')}")
    lines += model.wrap("BLAS: ", blas_line(a.get("blas")), indent=2)
    lines += model.wrap("made by: ", str(a.get("command_line", "?")), indent=2, cut=True)
    lines.append(f"  samples complete: {run.n_complete} of {run.complete.size}")
    lines.append("  model:")
    lines += model.model_lines(run)
    lines.append("  configuration (the keys that differ from the defaults):")
    lines += model.config_lines(run)
    said = model.notes(run)
    if said:
        lines.append("  notes:")
        for n in said:
            lines += model.wrap("- ", n)
    if run.n_complete == 0:
        lines.append("  no complete samples yet")
        return "\n".join(lines)
    u = model.units(run)
    sel = run.complete
    names = ["normal_force", "contact_area"] + (["friction_force"]
                                                 if "friction_force" in run.scalars else [])
    axis = run.axis_name
    au = axis_unit(run)
    axis_label = f"{axis} ({au})" if au else axis
    one = int(sel.sum()) == 1  # one sample: its values, no standard error
    dims = {"normal_force": "force", "contact_area": "fraction", "friction_force": "force"}
    forces = u.of_dimension("force")
    lines += model.wrap("", ("values of the one sample" if one else
                             f"means +- standard errors over {int(sel.sum())} samples")
                        + (f"; forces in {forces}" if forces else "; dimensionless")
                        + "; contact area: fraction of the nominal area", indent=2)
    unit_of = {n: u.of_dimension(dims[n]) for n in names}
    head = f"  {axis_label:>12} " + " ".join(
        f"{n + (f' ({unit_of[n]})' if unit_of[n] not in ('', '1') else ''):>23}"
        for n in names)
    lines.append(head)
    out = unconverged_pulls(run)  # left out of the pull's means

    def values(name: str) -> np.ndarray:
        v = np.asarray(run.scalars[name][sel], dtype=float)
        return np.where(out, np.nan, v) if name in PULLED and out.any() else v

    stats = {n: mean_sem(values(n)) for n in names}
    for k, x in enumerate(run.axis):
        row = f"  {x:>12.5g} "
        for n in names:
            m, e = stats[n][0][k], stats[n][1][k]
            row += f"{m:>23.6g} " if one else f"{m:>11.6g} +- {e:<8.2g} "
        lines.append(row.rstrip())
    bad, total = _count_false(run.scalars["converged"][sel])
    problems = [f"  squeeze solves not converged: {bad} of {total}"]
    if "pull_converged" in run.scalars:
        bad, total = _count_false(run.scalars["pull_converged"][sel])
        problems.append(f"  pulls not converged: {bad} of {total}"
                        + (" (left out of the friction means and fits)" if bad else ""))
        method = cfg.get("pull", {}).get("method", "auto")
        if method in METHODS and not METHODS.get(method).exact:
            problems.append(f"  approximate pulls (method {method!r}): biased low, with no "
                            "error estimate")
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
    lines.extend(_format_solves(run, axis_label))
    return "\n".join(lines)
