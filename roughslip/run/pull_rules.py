"""The rules of ``[pull]`` that look at other keys: the slip law's own parameters, the
methods, the precision and the tangential model each need of the law and of the coupled
model (:func:`check_pull`, one of the configuration's cross-section checks)."""

from __future__ import annotations

from roughslip.friction.laws import LAWS, LawParameterError
from roughslip.friction.pull import METHODS, methods_for, single_ok
from roughslip.run.messages import Errors
from roughslip.run.sections import LAW_PARAMS, RunConfig


def check_pull(cfg: RunConfig, errors: Errors) -> None:
    """Each broken rule of the pull's keys, kept in ``errors`` with the key it names."""
    law = LAWS.get(cfg.pull.slip_law)
    if cfg.pull.enabled:  # the slip law's own parameters ([pull] keys named as the law's)
        given = {k: getattr(cfg.pull, k) for k in LAW_PARAMS}
        try:
            law.bind(cfg.pull.lam, **given)
        except LawParameterError as exc:
            key = f"pull.{exc.key}"
            if exc.value is None:
                errors.add(key, rule=exc.rule)
            else:
                errors.add(key, exc.value, exc.rule)
    if cfg.coupling.enabled and not law.couples:
        errors.add("pull.slip_law", cfg.pull.slip_law,
                   "has no exact coupled model (its strength and f_z both vary, a "
                   "bilinear constraint); needs coupling.enabled = false")
    comps = cfg.pull.components
    # on an isotropic half-space (nu = 0) the traction vector is the x-only model turned, which
    # every law, method and precision runs; at nu > 0 it needs its own engine
    engine = comps != "x" and cfg.material.nu != 0
    if comps != "x" and cfg.coupling.enabled:  # the coupled cone: one history and control
        vector = "the coupled model with the traction vector"
        if not law.couples_vector:
            have = ", ".join(repr(n) for n in LAWS.names() if LAWS.get(n).couples_vector)
            errors.add("pull.components", comps, f"{vector} holds slip_law {have} (the "
                       "faceted cone) only; needs components = 'x'")
        if cfg.coupling.history != "indent":
            errors.add("coupling.history", cfg.coupling.history, f"{vector} starts from the "
                       "frictional indentation; needs history = 'indent'")
        if cfg.control != "depth":
            errors.add("squeeze.forces", cfg.squeeze.forces, f"{vector} squeezes to "
                       "depths; use squeeze.depths")
        if cfg.coupling.pull_control != "depth":
            errors.add("coupling.pull_control", cfg.coupling.pull_control,
                       f"{vector} holds the depth; needs pull_control = 'depth'")
    if comps == "x" and cfg.pull.direction != 0:
        errors.add("pull.direction", cfg.pull.direction, "the x-only model (pull.components "
                   "= 'x') pulls along x alone; use components = 'xy'")
    if engine and cfg.pull.error_estimate:
        errors.add("pull.error_estimate", True, f"has no estimate for pull.components = "
                   f"{comps!r} at nu > 0 yet; needs components = 'x'")
    if comps == "x" and "fy" in cfg.output.fields:
        errors.add("output.fields", cfg.output.fields, "'fy' needs pull.components = 'xy' "
                   "(the x-only model has no y force)")
    if cfg.pull.enabled and not cfg.coupling.enabled:
        laws = methods_for(cfg.pull.slip_law, comps if engine else "x")
        none = all(METHODS.get(m).chooses for m in laws)  # only the method that chooses
        if none and engine:
            have = ", ".join(repr(n) for n in LAWS.names()
                             if comps in LAWS.get(n).components)
            errors.add("pull.components", comps, f"slip_law = {cfg.pull.slip_law!r} has no "
                       f"pull of the traction vector at nu > 0; needs slip_law {have}, "
                       "material.nu = 0 or components = 'x'")
        elif none:
            errors.add("pull.slip_law", cfg.pull.slip_law,
                       "has no decoupled pull method; needs coupling.enabled = true")
        if cfg.pull.method not in laws and not (none and engine):
            what = f"pull.components = {comps!r}" if engine else \
                f"slip_law = {cfg.pull.slip_law!r}"
            errors.add("pull.method", cfg.pull.method, f"{what} needs one of {', '.join(laws)}")
    if cfg.pull.precision == "single" and (
            cfg.coupling.enabled or cfg.pull.method not in METHODS
            or not single_ok(law, cfg.pull.method, comps if engine else "x")):
        model = comps if engine else "x"
        single = ", ".join(repr(n) for n in LAWS.names() if model in LAWS.get(n).single)
        methods = ", ".join(repr(n) for n in METHODS.names() if single_ok(law, n, model))
        where = "" if model == "x" else f" with components = {model!r}"
        errors.add("pull.precision", "single", "is the decoupled single-precision matrix of "
                   f"slip_law {single}{where} only (coupling.enabled = false, method "
                   f"{methods or repr('auto')})")
