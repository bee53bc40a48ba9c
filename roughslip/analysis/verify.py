r"""Exact solutions, and the error-against-run-time study (``roughslip verify``).

Each scene compares a computed quantity with a closed form (docs/methods.rst#exact-solutions) at
several resolutions,
solver tolerances and methods, and records the error and the run time:

``hertz``
    Rigid sphere, apex on a pixel corner: total force :math:`F = \tfrac43 E^*R^{1/2}d^{3/2}`
    (second order in h) and contact radius :math:`\sqrt{Rd}` from the pixel count (first order).
``punch``
    Flat circular punch: :math:`F = 2aE^*d` with :math:`a` from the pixel count (first order).
``wavy``
    Periodic 1-D wavy surface (Westergaard), load control, both periodic kernels: crest
    pressure :math:`2\bar p/\sin(\pi a/\lambda)`.
``cattaneo``
    Cattaneo–Mindlin: Coulomb tangential force at :math:`\delta = \delta_s/2`.
``pull``
    A small rough contact: each exact pull method against the report's literal algorithm, and
    the approximate ``batch`` method with its stated error estimate.

The depth of the Hertz scene is the true approach of the apex: with the apex on a pixel corner
the highest pixel sits :math:`h^2/4R` below it (``depth = d + max(heights)``).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from roughslip.contact import analytic
from roughslip.contact.pull import coulomb_force_at, pull
from roughslip.contact.squeeze import squeeze
from roughslip.surfaces.synthetic import punch as punch_shape
from roughslip.surfaces.synthetic import sample_rng, self_affine, sinusoid, sphere


@dataclass(frozen=True)
class Row:
    """One measurement: relative error of ``quantity`` against its exact value."""

    scene: str
    quantity: str
    method: str
    resolution: str
    tol: float
    error: float  # signed relative error
    seconds: float
    converged: bool

    def as_dict(self) -> dict:
        return asdict(self)


def hertz_scene(a_over_h: int, R: float = 1.0, d: float = 1 / 16
                ) -> tuple[np.ndarray, float, float, float]:
    r"""A sphere of radius ``R`` on a grid ``2.4 a_c`` wide with ``a_c / h = a_over_h``.

    Returns ``(heights, h, depth, a_c)``: the depth from first touch that gives the Hertz
    approach ``d`` of the apex (the apex sits on a pixel corner, ``-max(heights)`` above the
    highest pixel centre, so the depth is ``d + max(heights)``; docs/methods.rst#hertz), and the
    Hertz contact radius :math:`a_c = \sqrt{R d}`.
    """
    ac = math.sqrt(R * d)
    h = ac / a_over_h
    n = math.ceil(2.4 * ac / h)
    n += n % 2
    heights = sphere((n, n), radius=R, a=h)
    return heights, h, d + float(heights.max()), ac


def _hertz(ah: int, method: str, tol: float) -> list[Row]:
    R, d, E, nu = 1.0, 1 / 16, 1.0, 0.0
    heights, h, depth, ac = hertz_scene(ah, R, d)
    t0 = time.perf_counter()
    r = squeeze(heights, depth=depth, a=h, E=E, nu=nu, method=method, tol=tol)
    dt = time.perf_counter() - t0
    F = analytic.hertz(R, d, E, nu).force
    a_eq = math.sqrt(r.n_contact * h * h / math.pi)
    res = f"a/h={ah}"
    return [Row("hertz", "normal force", method, res, tol, (r.normal_force - F) / F, dt,
                r.converged),
            Row("hertz", "contact radius", method, res, tol, (a_eq - ac) / ac, dt, r.converged)]


def _punch(ah: int, method: str, tol: float) -> list[Row]:
    radius, d = 1.0, 1e-3
    h = radius / ah
    n = 2 * ah + 2
    t0 = time.perf_counter()
    r = squeeze(punch_shape((n, n), radius=radius, a=h), depth=d, a=h, E=1.0, nu=0.0,
                method=method, tol=tol)
    dt = time.perf_counter() - t0
    a_eq = math.sqrt(r.n_contact * h * h / math.pi)
    F = analytic.flat_punch_force(a_eq, d, E=1.0, nu=0.0)
    return [Row("punch", "normal force", method, f"a/h={ah}", tol, (r.normal_force - F) / F, dt,
                r.converged)]


def _wavy(n: int, kind: str, tol: float) -> list[Row]:
    amp, lam, ratio = 0.01, 1.0, 0.6
    a = lam / n
    heights = sinusoid((4, n), amplitude=amp, wavelength=lam, a=a)
    p_star = analytic.westergaard(0.0, amp, lam, E=1.0, nu=0.0).p_star
    pbar = ratio * p_star
    exact = analytic.westergaard(pbar, amp, lam, E=1.0, nu=0.0)
    t0 = time.perf_counter()
    r = squeeze(heights, force=pbar * 4 * n * a * a, a=a, E=1.0, nu=0.0, boundary="periodic",
                periodic_kernel=kind, tol=tol)
    dt = time.perf_counter() - t0
    crest = exact.crest_pressure
    got = r.fz[:, 0].mean() / a**2
    frac = exact.contact_fraction
    res = f"lambda/h={n}"
    return [Row("wavy", "crest pressure", f"pk/{kind}", res, tol, (got - crest) / crest, dt,
                r.converged),
            Row("wavy", "contact fraction", f"pk/{kind}", res, tol,
                (r.contact_area - frac) / frac, dt, r.converged)]


def _cattaneo(ah: int, tol: float) -> list[Row]:
    nu, lam, R, d = 0.3, 0.3, 1.0, 1 / 16
    heights, h, depth, ac = hertz_scene(ah, R, d)
    t0 = time.perf_counter()
    normal = squeeze(heights, depth=depth, a=h, nu=nu, tol=tol)
    res = pull(normal, lam=lam, slip_law="coulomb", tol=max(tol, 1e-12))
    dt = time.perf_counter() - t0
    P = normal.normal_force
    cm = analytic.cattaneo_mindlin(P, ac, lam, nu=nu)
    q = float(coulomb_force_at(res, 0.5 * cm.delta_s))
    q_exact = cm.force(0.5 * cm.delta_s)
    return [Row("cattaneo", "tangential force", "coulomb/inverse", f"a/h={ah}", tol,
                (q - q_exact) / (lam * P), dt, normal.converged and res.converged)]


def _pull_methods(n: int, tol: float) -> list[Row]:
    h = self_affine((n, n), hurst=0.8, rms_height=1.0, rng=sample_rng(7, 0), oversample=2)
    normal = squeeze(h, depth=1.5, tol=1e-12)
    t0 = time.perf_counter()
    ref = pull(normal, method="literal", tol=1e-12)
    t_ref = time.perf_counter() - t0
    rows = [Row("pull", "friction force", "literal", f"N={n}", 1e-12, 0.0, t_ref,
                ref.converged)]
    for method in ("inverse", "cg", "batch"):
        t0 = time.perf_counter()
        r = pull(normal, method=method, tol=tol, batch_size=8)
        dt = time.perf_counter() - t0
        err = (r.friction_force - ref.friction_force) / ref.friction_force
        rows.append(Row("pull", "friction force", method, f"N={n}", tol, err, dt, r.converged))
        if method == "batch":
            rows.append(Row("pull", "batch error estimate", method, f"N={n}", tol,
                            r.error_estimate, dt, r.converged))
    return rows


def study(quick: bool = False, progress: Callable[[str], None] | None = None) -> list[Row]:
    """Run the verification study (``quick``: small sizes, two tolerances, under a minute)."""
    say = progress or (lambda s: None)
    rows: list[Row] = []
    ahs = (8, 16) if quick else (8, 16, 32, 64)
    tols = (1e-6, 1e-10) if quick else (1e-4, 1e-6, 1e-8, 1e-10)
    for ah in ahs:
        for method in ("pk", "active-set"):
            for tol in tols:
                say(f"hertz a/h={ah} {method} tol={tol:g}")
                rows += _hertz(ah, method, tol)
                rows += _punch(ah, method, tol)
    for n in ((32, 64) if quick else (32, 64, 128, 256)):
        for kind in ("pixel", "continuous"):
            say(f"wavy lambda/h={n} {kind}")
            rows += _wavy(n, kind, 1e-10)
    for ah in ((8, 16) if quick else (8, 16, 32)):
        say(f"cattaneo a/h={ah}")
        rows += _cattaneo(ah, 1e-10)
    for n in ((32,) if quick else (32, 48, 64)):
        say(f"pull methods N={n}")
        rows += _pull_methods(n, 1e-10)
    return rows


def format_table(rows: list[Row]) -> str:
    """Fixed-width text table of the study."""
    head = f"{'scene':<9} {'quantity':<21} {'method':<16} {'resolution':<12} {'tol':>7} " \
           f"{'rel. error':>11} {'seconds':>8} {'conv':>5}"
    lines = [head]
    for r in rows:
        lines.append(f"{r.scene:<9} {r.quantity:<21} {r.method:<16} {r.resolution:<12} "
                     f"{r.tol:>7.0e} {r.error:>+11.3e} {r.seconds:>8.3f} "
                     f"{'yes' if r.converged else 'NO':>5}")
    return "\n".join(lines)


def to_json(rows: list[Row]) -> str:
    return json.dumps([r.as_dict() for r in rows], indent=1)


def plot(rows: list[Row], path: str) -> None:
    """Log-log error against run time, one panel per scene."""
    from roughslip.analysis.plotting import finish_axes, pyplot, save

    plt = pyplot()
    scenes = list(dict.fromkeys(r.scene for r in rows))
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.2 * len(scenes), 3.8), squeeze=False)
    for ax, sc in zip(axes[0], scenes, strict=True):
        sel = [r for r in rows if r.scene == sc and r.error != 0]
        keys = list(dict.fromkeys((r.quantity, r.method) for r in sel))
        for q, m in keys:
            pts = sorted((r.seconds, abs(r.error)) for r in sel if (r.quantity, r.method) == (q, m))
            if pts:
                x, y = np.array(pts).T
                ax.loglog(x, y, "o-", ms=4, label=f"{q}, {m}")
        ax.set_title(sc)
        finish_axes(ax, "run time [s]", "|relative error|", fontsize=6)
    save(plt, fig, path)
