"""The stability report: extreme and stiff cases, each checked against a physical answer.

    python scripts/stability.py [--large 2048]     # the table of docs/stability.md

Every row runs one case and states what was checked: an exact relation (scaling, symmetry, a
closed form) or the expected error (an InputError for an impossible parameter, a
NumericalError for a NaN produced inside a solve). Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable

import numpy as np

from roughslip.contact.analytic import hertz, mindlin_bonded_punch_stiffness
from roughslip.contact.squeeze import squeeze
from roughslip.elastic.operators import ElasticOperator
from roughslip.errors import InputError, NumericalError
from roughslip.friction.pull import pull
from roughslip.surfaces.synthetic import punch, sample_rng, self_affine, sphere

ROWS: list[tuple[str, str, str, str, str, str]] = []


def case(name: str, fn: Callable[[], tuple[object, str, bool]]) -> None:
    """Run one case; ``fn`` returns (result with solver record or None, check, passed)."""
    t0 = time.perf_counter()
    try:
        res, check, ok = fn()
    except Exception as exc:  # the report records, it does not stop
        res, check, ok = None, f"raised {type(exc).__name__}: {exc}", False
    dt = time.perf_counter() - t0
    conv = getattr(res, "converged", None)
    it = getattr(res, "iterations", None)
    r = getattr(res, "residual", None)
    ROWS.append((name, "-" if conv is None else ("yes" if conv else "NO"),
                 "-" if it is None else str(it), "-" if r is None else f"{r:.1e}",
                 check, ("pass" if ok else "FAIL") + f" ({dt:.2f} s)"))
    print(f"  {name}: {'pass' if ok else 'FAIL'}", flush=True, file=sys.stderr)


def case_on(name: str, solve: Callable[[], object], judge: Callable[[object], tuple[str, bool]]
            ) -> None:
    """:func:`case` for one solve: ``judge(solve())`` returns (check, passed)."""

    def fn():
        r = solve()
        return (r, *judge(r))

    case(name, fn)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--large", type=int, default=2048, help="size of the large-grid case")
    args = ap.parse_args()
    rough = self_affine((64, 64), hurst=0.8, rms_height=1.0, rng=sample_rng(5, 0), oversample=2)
    base = squeeze(rough, depth=1.0, nu=0.0, tol=1e-11)

    for nu in (0.5, 0.4999, 0.0, -0.5, -0.99):
        def f(nu=nu):
            r = squeeze(rough, depth=1.0, nu=nu, tol=1e-11)
            err = abs(r.normal_force * (1 - nu * nu) / base.normal_force - 1)
            p = pull(r)
            return r, (f"$F\\,(1-\\nu^2) = F(\\nu=0)$: rel. err {err:.1e}; same contact; pull "
                       f"converged"), err < 1e-9 and np.array_equal(r.contact, base.contact) \
                and p.converged
        case(f"$\\nu$ = {nu}, rough $64^2$", f)

        def g(nu=nu):
            ah = 16
            h = 1.0 / ah
            n = squeeze(punch((2 * ah + 2,) * 2, radius=1.0, a=h), depth=1e-3, a=h, nu=nu)
            p = pull(n, lam=0.3)
            a_eq = math.sqrt(n.n_contact * h * h / math.pi)
            k = mindlin_bonded_punch_stiffness(a_eq, nu=nu)
            err = (p.curve.fx[1] / p.curve.dx[1] - k) / k
            return n, (f"bonded punch $K = 8Ga/(2-\\nu)$: err {err:+.4f} "
                       "(staircase $\\approx -0.12\\,h/a$)"), \
                -0.2 * h < err < 0
        case(f"$\\nu$ = {nu}, tangential punch a/h = 16", g)

    for nu in (-1.0, 0.7):
        def bad(nu=nu):
            try:
                squeeze(rough, depth=1.0, nu=nu)
            except InputError as exc:
                return None, f"`InputError: {exc}`", True
            return None, "accepted", False
        case(f"$\\nu$ = {nu} (out of range)", bad)

    for shape in ((1, 1), (2, 2), (1, 64), (64, 1), (97, 97), (61, 127)):
        def s(shape=shape):
            h = sphere(shape, radius=10.0 * max(shape))
            r = squeeze(h, depth=0.005 * max(shape) + 1e-3, tol=1e-11)
            sym = np.allclose(r.fz, r.fz[::-1, ::-1], rtol=1e-9, atol=1e-12 * r.fz.max())
            p = pull(r)
            return r, f"mirror-symmetric forces: {sym}; $0 < F_{{\\rm fric}} \\le \\lambda F_n$", \
                sym and 0 < p.friction_force <= 0.2 * r.normal_force * (1 + 1e-12)
        case(f"grid {shape[0]} x {shape[1]}", s)

    def large():
        n = args.large
        R, d = 1.0, 1 / 16
        ac = math.sqrt(R * d)
        h = 2.4 * ac / n
        hs = sphere((n, n), radius=R, a=h)
        r = squeeze(hs, depth=d + hs.max(), a=h, nu=0.0, tol=1e-8)
        F = hertz(R, d, nu=0.0).force
        err = (r.normal_force - F) / F
        return r, f"Hertz force at a/h = {ac / h:.0f}: rel. err {err:.1e} (< 2e-3)", \
            abs(err) < 2e-3
    case(f"grid {args.large} x {args.large} (Hertz)", large)

    rng_ = float(rough.max() - rough.min())
    case_on("no contact (depth < 0)", lambda: squeeze(rough, depth=-1.0),
            lambda r: ("F = 0, empty masks, pull F = 0", r.normal_force == 0
                       and not r.contact.any() and pull(r).friction_force == 0))
    case_on("single contact site", lambda: squeeze(rough, depth=1e-12),
            lambda r: ("one bond: $F_{\\rm fric} = \\lambda F_n$",
                       r.n_contact == 1 and math.isclose(
                pull(r).friction_force, 0.2 * r.normal_force, rel_tol=1e-12)))
    case_on("near-full contact (depth 4 x range)",
            lambda: squeeze(rough, depth=4 * rng_, tol=1e-10),
            lambda r: (f"contact {r.contact_area:.3f} in (0.9, 1)",
                       r.converged and 0.9 < r.contact_area < 1))
    case_on("full contact, open (depth 40 x range)",
            lambda: squeeze(rough, depth=40 * rng_, tol=1e-10),
            lambda r: ("all sites in contact", r.converged and r.contact.all()))
    hp = self_affine((64, 64), hurst=0.8, rms_height=1.0, rng=sample_rng(5, 1))
    flat = float(hp.max() - hp.mean())
    case_on("full contact, periodic (load control)",
            lambda: squeeze(hp, force=30.0 * hp.size, boundary="periodic", tol=1e-10),
            lambda r: (f"all in contact; $D = \\max h - \\bar h$ (err {abs(r.depth - flat):.1e})",
                       r.contact.all() and abs(r.depth - flat) < 1e-9))

    for H in (0.01, 0.99):
        def hu(H=H):
            h = self_affine((128, 128), hurst=H, rms_height=1.0, rng=sample_rng(8, 0))
            r = squeeze(h, depth=1.0)
            p = pull(r)
            return r, "finite, rms exactly 1, squeeze and pull converged", \
                bool(np.isfinite(h).all()) and abs(h.std() - 1) < 1e-12 and r.converged \
                and p.converged
        case(f"Hurst H = {H}", hu)

    p0 = pull(base)
    # (h, D) -> s (h, D) and E -> s E both scale every force by s
    scalings = [(f"heights x {s:g}", f"(h, D) x {s:g}", s, {"heights": rough * s, "depth": s},
                 1e-8) for s in (1e-9, 1e3)]
    scalings += [(f"E = {E:g}", "with E", E, {"heights": rough, "depth": 1.0, "E": E}, 1e-9)
                 for E in (1e-6, 1e12)]
    for name, what, s, kw, limit in scalings:
        def scaled(what=what, s=s, kw=kw, limit=limit):
            r = squeeze(nu=0.0, tol=1e-11, **kw)
            e1 = abs(r.normal_force / (s * base.normal_force) - 1)
            e2 = abs(pull(r).friction_force / (s * p0.friction_force) - 1)
            return r, f"$F$ and $F_{{\\rm fric}}$ scale {what}: errors {e1:.0e}, {e2:.0e}", \
                e1 < limit and e2 < limit
        case(name, scaled)
    for lam in (1e-8, 1e8):
        def la(lam=lam):
            p = pull(base, lam=lam)
            e = abs(p.friction_force / (lam / 0.2 * p0.friction_force) - 1)
            return p, f"$F_{{\\rm fric}}$ scales with $\\lambda$: error {e:.0e}", e < 1e-9
        case(f"$\\lambda$ = {lam:g}", la)

    def ill():
        n = 512
        r = squeeze(punch((n, n), radius=0.45 * n), depth=1.0, tol=1e-10, max_iter=5000)
        return r, f"cond $\\sim N$: met tol 1e-10 in {r.iterations} iterations", r.converged

    case("ill-conditioned: $512^2$ punch, radius 0.45 N", ill)

    def nan():
        real = ElasticOperator.apply
        calls = {"n": 0}

        def poisoned(self, c, f, out=None):
            calls["n"] += 1
            res = real(self, c, f, out)
            if calls["n"] == 20:
                res[1, 1] = np.nan
            return res

        ElasticOperator.apply = poisoned
        try:
            squeeze(rough, depth=1.0)
        except NumericalError as exc:
            return None, f"`NumericalError: {exc}`", True
        finally:
            ElasticOperator.apply = real
        return None, "NaN went unnoticed", False

    case("NaN injected into a convolution", nan)

    print("| case | converged | iterations | residual | check | result |")
    print("|---|---|---|---|---|---|")
    for row in ROWS:
        print("| " + " | ".join(x.replace("|", "/") for x in row) + " |")
    print(f"\n{sum('pass' in r[-1] for r in ROWS)} of {len(ROWS)} cases pass; "
          f"{os.cpu_count()} cores.")


if __name__ == "__main__":
    main()
