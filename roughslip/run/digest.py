"""Configuration digests: which run file belongs to which configuration.

A run file stores the SHA-256 digest of the configuration that made it, and ``--resume``
continues it only under a configuration with the same digest. The digest covers what
determines the numbers: every section but ``[execution]``, without the title.

Versioned defaults (run files written since the ``defaults_version`` attribute exists)
    The digest covers only the values that differ from the defaults in force when the run was
    created, and the file stores the version of those defaults (:data:`DEFAULTS_VERSION`). A
    key added later with a default is therefore absent from the digest of every configuration
    that leaves it at its default, old or new, and older runs resume with no edit here. A
    default that changes needs a new version and an entry of :data:`DEFAULTS_THEN` with the
    old value, so that a configuration relying on the new default does not match a run made
    with the old one.

Earlier run files (no ``defaults_version``)
    Their digests hashed the whole resolved configuration, in four generations (0 to 3) that
    differ by keys renamed, retired and added (:data:`RENAMED`, :data:`RETIRED`,
    :data:`ADDED`). :func:`legacy_digests` reproduces them from today's configuration. The
    keys those files knew are frozen in :data:`LEGACY_KEYS`: a key added since is left out
    of the reproduction when it is at its default, and so needs no entry either.

The serialisation (:func:`canonical`) is frozen: a digest must not change when a TOML writer's
formatting does.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

from roughslip.run.tomlio import toml_key, toml_value

#: the version of the configuration defaults (stored as ``defaults_version``)
DEFAULTS_VERSION = 1

#: defaults that changed since version 1: version -> {(section, key): the default of that
#: version}, for every key whose default then differs from today's
DEFAULTS_THEN: dict[int, dict[tuple[str, str], Any]] = {}

#: keys renamed since they were introduced: old (section, key) -> new key (still read)
RENAMED = {("pull", "error_bound"): "error_estimate"}

#: keys that no longer do anything: (section, key) -> (default, the key before which it stood
#: in the resolved configuration, why). Still accepted and checked, so older configurations
#: load, and part of the digests of the generations that had them (0 and 1).
RETIRED = {("pull", "coulomb_steps"): (32, "early_stop", "the Coulomb pull curve is exact, "
                                       "event by event")}

#: keys added during the legacy generations: (section, key) -> (the default that reproduces
#: the former behaviour, the first generation that has the key). Frozen.
ADDED = {("pull", "early_stop"): (True, 1),
         **{(role, k): (v, 1) for role in ("surface", "elastic_surface")
            for k, v in (("unit", None), ("override_pixel_size", False), ("missing", "error"),
                         ("detrend", "none"), ("crop", None), ("downsample", 1),
                         ("tiles", None))},
         ("coupling", "pull_control"): ("depth", 2), ("coupling", "gained"): ("unbonded", 2),
         ("coupling", "history"): ("bonded", 3)}

#: the keys of the newest legacy generation (3), per section. Frozen.
LEGACY_KEYS: dict[str, frozenset[str]] = {
    name: frozenset(keys.split()) for name, keys in {
        "grid": "n shape pixel_size boundary periodic_kernel",
        "material": "E nu",
        "surface": "kind hurst rms_height rms_slope rolloff_wavelength cutoff_wavelength "
                   "oversample radius center step amplitude wavelength direction phase slope "
                   "path key scale unit override_pixel_size missing detrend crop downsample "
                   "tiles",
        "squeeze": "depths forces depth_unit force_unit method tol max_iter warm_start",
        "pull": "enabled lam slip_law lam_dynamic slip_distance method tol batch_size "
                "error_estimate early_stop",
        "coupling": "enabled pull_control gained history",
        "ensemble": "samples seed first_sample",
        "output": "fields compression compression_level",
        "units": "length",
    }.items()}
LEGACY_KEYS["elastic_surface"] = LEGACY_KEYS["surface"]

Defaults = Mapping[tuple[str, str], Any]


def canonical(d: Mapping[str, Any]) -> str:
    """The text a digest hashes: top-level values, then one table per section. Frozen."""
    lines = [f"{toml_key(k)} = {toml_value(v)}" for k, v in d.items() if not isinstance(v, dict)]
    for k, v in d.items():
        if isinstance(v, dict):
            if lines:
                lines.append("")
            lines.append(f"[{toml_key(k)}]")
            lines.extend(f"{toml_key(kk)} = {toml_value(vv)}" for kk, vv in v.items())
    return "\n".join(lines) + "\n"


def _sha(d: Mapping[str, Any]) -> str:
    return hashlib.sha256(canonical(d).encode()).hexdigest()


def defaults_of(defaults: Defaults, version: int) -> dict[tuple[str, str], Any]:
    """The defaults in force in ``version``, from today's."""
    if not 1 <= version <= DEFAULTS_VERSION:
        raise ValueError(f"defaults version {version}: this version knows 1 to "
                         f"{DEFAULTS_VERSION}")
    return {**defaults, **DEFAULTS_THEN.get(version, {})}


def digest(d: Mapping[str, Any], defaults: Defaults, version: int = DEFAULTS_VERSION) -> str:
    """Digest of a resolved configuration ``d`` (sections as dicts, execution and title
    removed) under the defaults of ``version``: the values that differ from them."""
    then = defaults_of(defaults, version)
    missing = object()
    kept: dict[str, Any] = {}
    for section, table in d.items():
        t = {k: v for k, v in table.items() if then.get((section, k), missing) != v}
        if t:
            kept[section] = t
    return _sha(kept)


def legacy_digests(d: Mapping[str, Any], defaults: Defaults, retired: Mapping[str, Any]
                   ) -> tuple[str, ...]:
    """The digests the configuration ``d`` had in the legacy generations 3, 2, 1 and 0.

    ``retired``: retired keys the configuration gives (dotted key -> value).
    """
    base: dict[str, dict[str, Any]] = {}
    for section, table in d.items():
        known = LEGACY_KEYS.get(section, frozenset())
        base[section] = {k: v for k, v in table.items()
                         if k in known or defaults.get((section, k), object()) != v}
    out = []
    for generation in (3, 2, 1, 0):
        g = {s: dict(t) for s, t in base.items()}
        if generation <= 1:
            for (section, key), (default, before, _) in RETIRED.items():
                if section in g:
                    value = retired.get(f"{section}.{key}", default)
                    items = list(g[section].items())
                    at = next((i for i, (k, _) in enumerate(items) if k == before), len(items))
                    items.insert(at, (key, value))
                    g[section] = dict(items)
        for (section, key), (default, since) in ADDED.items():
            if since > generation and g.get(section, {}).get(key, default) == default:
                g.get(section, {}).pop(key, None)
        if generation <= 0:
            for (section, old), new in RENAMED.items():
                if section in g and new in g[section]:
                    g[section] = {old if k == new else k: v for k, v in g[section].items()}
        out.append(_sha(g))
    return tuple(out)
