"""Configuration loading, validation and overrides."""

from __future__ import annotations

import dataclasses
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from roughslip.errors import ConfigError
from roughslip.run.config import dumps_toml, load_config, parse_override

BASE = {
    "grid": {"n": 32, "pixel_size": 0.5},
    "material": {"E": 2.0, "nu": 0.3},
    "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0},
    "squeeze": {"depths": [0.1, 0.2, 0.4]},
}


def write(tmp_path, data, name="run.toml"):
    p = tmp_path / name
    p.write_text(dumps_toml(data))
    return p


def test_valid_config_is_frozen_and_filled(tmp_path):
    cfg = load_config(write(tmp_path, BASE))
    assert cfg.shape == (32, 32)
    assert cfg.material.nu == 0.3 and cfg.pull.enabled is False
    assert cfg.targets == (0.1, 0.2, 0.4) and cfg.control == "depth"
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.material.nu = 0.1  # type: ignore[misc]


def test_error_names_file_key_value_and_rule(tmp_path):
    data = {**BASE, "material": {"nu": 0.7}}
    with pytest.raises(ConfigError) as e:
        load_config(write(tmp_path, data))
    assert str(e.value) == "run.toml: material.nu = 0.7: must satisfy -1 < nu <= 0.5"


def test_every_independent_error_is_reported_at_once(tmp_path):
    """A config with several mistakes names them all, each on its own line with where its
    value came from, so that one round of fixes is enough; a single error keeps its one
    line (the test above)."""
    data = {**BASE, "grid": {"n": -4}, "material": {"nu": 0.7},
            "surface": {"kind": "self-affine", "hurst": 1.7, "rms_height": 1.0},
            "pull": {"lamda": 0.2}, "materials": {}}
    with pytest.raises(ConfigError) as e:
        load_config(write(tmp_path, data), ["ensemble.samples=0"])
    assert str(e.value).splitlines() == [
        "run.toml: 6 errors:",
        "  run.toml: materials: unknown section or key (did you mean 'material'?)",
        "  run.toml: grid.n = -4: must be >= 1",
        "  run.toml: material.nu = 0.7: must satisfy -1 < nu <= 0.5",
        "  run.toml: surface.hurst = 1.7: must be in (0, 1)",
        "  run.toml: pull.lamda: unknown key (did you mean 'lam'?)",
        "  run.toml (--set ensemble.samples=0): ensemble.samples = 0: must be >= 1",
    ]
    # checks that need the sections come after them: a squeeze with both depths and forces
    # and a bad surface are two independent errors too
    bad = {**BASE, "surface": {"kind": "self-affine", "hurst": 0.8},
           "squeeze": {"depths": [0.1], "forces": [1.0]}}
    with pytest.raises(ConfigError, match=r"run.toml: 2 errors:\n  .*surface.rms_height.*\n"
                                          r"  .*exactly one of squeeze.depths"):
        load_config(write(tmp_path, bad))
    # and so are the rules across sections, once every section is valid
    with pytest.raises(ConfigError) as e:
        load_config(write(tmp_path, BASE), ["coupling.enabled=true", "output.fields=['fx']"])
    assert str(e.value).splitlines() == [
        "run.toml: 2 errors:",
        "  run.toml (--set coupling.enabled=true): coupling.enabled = true: needs "
        "pull.enabled = true",
        "  run.toml (--set output.fields=['fx']): output.fields = [\"fx\"]: ['fx'] need "
        "pull.enabled = true",
    ]


@pytest.mark.parametrize(
    ("override", "match"),
    [
        ("material.nu=0.7", r"material\.nu = 0\.7: must satisfy -1 < nu <= 0\.5"),
        ("material.nu=-1", r"material\.nu = -1"),
        ("surface.hurst=1.3", r"surface\.hurst = 1\.3: must be in \(0, 1\)"),
        ("grid.pixel_size=0", r"grid\.pixel_size = 0: must be > 0"),
        ("grid.n=2.5", r"grid\.n = 2\.5: must be an integer"),
        ("material.Nu=0.2", r"material\.Nu: unknown key \(did you mean 'nu'\?\)"),
        ("materials.nu=0.2", r"materials: unknown section"),
        ("surface.radius=2", r"surface\.radius = 2: not a parameter of kind 'self-affine'"),
        ("squeeze.depths=[0.2, 0.1]", r"strictly increasing"),
        ("squeeze.forces=[1.0]", r"exactly one of squeeze\.depths"),
        ("squeeze.method=cg", r"squeeze\.method = \"cg\": must be one of"),
        ("output.fields=['fz', 'heat']", r"unknown field"),
        ("output.fields=['fx']", r"need pull\.enabled"),
        ("pull.lam=-0.1", r"pull\.lam = -0\.1: must be > 0"),
        ("pull.enabled=1", r"pull\.enabled = 1: must be true or false"),
        ("ensemble.samples=0", r"ensemble\.samples = 0: must be >= 1"),
        ("surface.rms_slope=0.1", r"exactly one of rms_height and rms_slope"),
        ("coupling.enabled=true", r"needs pull\.enabled"),
    ],
)
def test_override_errors(tmp_path, override, match):
    with pytest.raises(ConfigError, match=match) as e:
        load_config(write(tmp_path, BASE), [override])
    assert str(e.value).startswith("run.toml")


def test_a_pull_method_without_the_slip_law_is_refused_before_any_work(tmp_path):
    """The Coulomb law runs on the stick solvers only (or auto): a config asking for another
    method fails at load time, naming the key, not after samples were computed."""
    sets = ["pull.enabled=true", "pull.slip_law='coulomb'"]
    with pytest.raises(ConfigError, match=r"pull\.method = \"literal\": slip_law = "
                                          r"'coulomb' needs one of auto, inverse, "
                                          r"hierarchical") as e:
        load_config(write(tmp_path, BASE), [*sets, "pull.method='literal'"])
    assert str(e.value).startswith("run.toml (--set pull.method=")
    for ok in ("auto", "inverse", "hierarchical"):
        assert load_config(write(tmp_path, BASE), [*sets, f"pull.method='{ok}'"])
    # under coupling the pull's method is not used
    assert load_config(write(tmp_path, BASE),
                       [*sets, "pull.method='literal'", "coupling.enabled=true"])


def test_override_merging_and_inline_toml(tmp_path):
    cfg = load_config(
        write(tmp_path, BASE),
        ["surface.hurst=0.6", "pull={enabled = true, lam = 0.3}", "squeeze.method=active-set"],
    )
    assert cfg.surface.hurst == 0.6 and cfg.pull.enabled and cfg.pull.lam == 0.3
    assert cfg.squeeze.method == "active-set"  # bare word taken as a string
    data = {**BASE, "grid": {"shape": [16, 24]}}
    cfg = load_config(write(tmp_path, data), ["material.E=1e9"])
    assert cfg.shape == (16, 24) and cfg.material.E == 1e9


def test_depth_range_table(tmp_path):
    data = {**BASE, "squeeze": {"depths": {"start": 0.1, "stop": 10.0, "num": 3,
                                           "spacing": "log"}}}
    cfg = load_config(write(tmp_path, data))
    assert cfg.targets == pytest.approx((0.1, 1.0, 10.0))
    assert cfg.targets[-1] == 10.0


def test_invalid_toml_and_missing_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[grid\nn = 3")
    with pytest.raises(ConfigError, match=r"bad\.toml: invalid TOML"):
        load_config(p)
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(tmp_path / "missing.toml")


def test_round_trip_through_toml(tmp_path):
    cfg = load_config(write(tmp_path, BASE), ["pull.enabled=true"])
    again = load_config(data=tomllib.loads(cfg.to_toml()))
    assert again == cfg
    assert again.digest() == cfg.digest()
    assert load_config(data=tomllib.loads(cfg.to_toml()), overrides=["execution.workers=2"]
                       ).digest() == cfg.digest()


def test_parse_override():
    assert parse_override("a.b=[1, 2]") == (["a", "b"], [1, 2])
    assert parse_override("a=sphere") == (["a"], "sphere")
    assert parse_override("a='x y'") == (["a"], "x y")
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        parse_override("novalue")
    with pytest.raises(ConfigError, match="not valid TOML"):
        parse_override("a=[1,")


def test_fixed_shape_runs_one_sample(tmp_path):
    data = {**BASE, "surface": {"kind": "sphere", "radius": 3.0}, "ensemble": {"samples": 9}}
    assert load_config(write(tmp_path, data)).n_samples == 1


# ---------------------------------------------------------------------------- fuzzing

_scalars = st.one_of(
    st.integers(-5, 5), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
    st.text(max_size=6), st.lists(st.integers(-2, 40), max_size=3),
    st.lists(st.floats(-2, 5), max_size=4),
)
_keys = st.sampled_from([
    "grid.n", "grid.shape", "grid.pixel_size", "grid.boundary", "material.E", "material.nu",
    "surface.kind", "surface.hurst", "surface.rms_height", "surface.radius", "surface.path",
    "squeeze.depths", "squeeze.forces", "squeeze.tol", "pull.enabled", "pull.lam",
    "output.fields", "ensemble.samples", "execution.workers", "nonsense", "grid.nonsense",
    "elastic_surface.kind", "coupling.enabled", "squeeze.depths.num",
])


def _as_override(key, value):
    try:
        return f"{key}={dumps_toml({'v': value}).split(' = ', 1)[1].strip()}"
    except TypeError:
        return f"{key}=1"


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(_keys, _scalars), max_size=5))
def test_fuzz_overrides_accept_or_config_error(tmp_path_factory, pairs):
    path = write(tmp_path_factory.mktemp("fz"), BASE)
    overrides = [_as_override(k, v) for k, v in pairs]
    try:
        cfg = load_config(path, overrides)
    except ConfigError as exc:
        assert str(exc)
        return
    assert load_config(data=tomllib.loads(cfg.to_toml())) == cfg


@settings(max_examples=200, deadline=None)
@given(st.dictionaries(st.sampled_from(["grid", "material", "surface", "squeeze", "pull", "x"]),
                       st.dictionaries(st.text(max_size=8), _scalars, max_size=4), max_size=5))
def test_fuzz_random_documents(data):
    try:
        load_config(data=data)
    except ConfigError:
        pass


def test_machine_file_sets_execution_beneath_the_experiment(tmp_path, monkeypatch):
    """The per-machine layer: defaults < machine file < experiment file < --set; it never
    enters the digest, and its errors name the machine file."""
    from roughslip.run.machine import MACHINE_ENV

    machine = tmp_path / "machine.toml"
    machine.write_text("[execution]\nworkers = 3\nthreads = 2\nfft = 'scipy'\n")
    exp = {"grid": {"n": 8}, "surface": {"kind": "sphere", "radius": 10.0},
           "squeeze": {"depths": [0.1]}, "execution": {"threads": 1}}
    plain = load_config(data=exp)
    monkeypatch.setenv(MACHINE_ENV, str(machine))
    cfg = load_config(data=exp)
    assert (cfg.execution.workers, cfg.execution.threads, cfg.execution.fft) == (3, 1, "scipy")
    assert cfg.machine == str(machine) and cfg.digest() == plain.digest()
    assert load_config(data=exp, overrides=["execution.workers=4"]).execution.workers == 4
    assert load_config(data=exp, use_machine=False).execution.workers == 1
    machine.write_text("[execution]\nworkers = 0\n")
    with pytest.raises(ConfigError, match=r"machine\.toml: execution\.workers = 0: must be >= 1"):
        load_config(data=exp)
    machine.write_text("[execution]\nworker = 2\n")
    with pytest.raises(ConfigError, match=r"machine\.toml: execution\.worker: unknown key"):
        load_config(data=exp)
    machine.write_text("[pull]\nlam = 0.3\n")
    with pytest.raises(ConfigError, match=r"machine\.toml: pull: a machine file holds only"):
        load_config(data=exp)
    monkeypatch.setenv(MACHINE_ENV, str(tmp_path / "none.toml"))
    with pytest.raises(ConfigError, match="no such machine file"):
        load_config(data=exp)
    # the default place, when the variable is not set
    monkeypatch.delenv(MACHINE_ENV)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    (tmp_path / "roughslip").mkdir()
    (tmp_path / "roughslip" / "machine.toml").write_text("[execution]\nworkers = 5\n")
    assert load_config(data=exp).execution.workers == 5


# ---------------------------------------------------------------------------- odd input


def test_a_huge_value_or_key_is_echoed_cut_with_its_length(tmp_path):
    """An error repeats at most ECHO_LIMIT characters of a value, a key or a --set text, with
    how long it was: a 10 MB value gives a one-line message, not a 10 MB one."""
    from roughslip.errors import ECHO_LIMIT

    huge = "x" * 10_000_000
    data = {**BASE, "surface": {"kind": huge}}
    with pytest.raises(ConfigError) as e:
        load_config(write(tmp_path, data))
    msg = str(e.value)
    assert len(msg.splitlines()) == 1 and len(msg) < 2 * ECHO_LIMIT + 150
    assert msg.startswith('run.toml: surface.kind = "' + "x" * (ECHO_LIMIT - 1) + '... '
                          '(10000000 characters): must be one of')
    data = {**BASE, "pull": {huge: 1}}
    with pytest.raises(ConfigError, match=r"^run\.toml: pull\.x{75}\.\.\. \(10000005 "
                                          r"characters\): unknown key \(known: ") as e:
        load_config(write(tmp_path, data))
    with pytest.raises(ConfigError) as e:
        load_config(write(tmp_path, BASE), [f"surface.hurst='{huge}'"])
    msg = str(e.value)
    assert len(msg) < 3 * ECHO_LIMIT + 100 and "(10000016 characters)" in msg
    assert "surface.hurst = " in msg and "(10000000 characters): must be a number" in msg
    # short values are shown whole, as before
    with pytest.raises(ConfigError, match=r"surface\.kind = \"rough\": must be one of"):
        load_config(write(tmp_path, {**BASE, "surface": {"kind": "rough"}}))


def _nested(kind: str, depth: int) -> str:
    """A value (or, for "tables", a table header) nested ``depth`` levels below its section."""
    if kind == "arrays":
        return "[output]\nfields = " + "[" * depth + "]" * depth + "\n"
    if kind == "inline":
        return "[ensemble]\nx = " + "{a = " * depth + "1" + "}" * depth + "\n"
    return "[" + ".".join(["a"] * depth) + "]\nb = 1\n"


@pytest.mark.parametrize("kind", ["arrays", "inline", "tables"])
@pytest.mark.parametrize("depth", [33, 400, 5000])
def test_nesting_deeper_than_the_limit_is_one_line(tmp_path, kind, depth):
    """Tables, inline tables or arrays nested past MAX_NESTING: one line naming the file and
    the limit, whether the parser reads them (then the key is named too) or would recurse
    too deep (it raised RecursionError, and the loader's copy did for deep tables)."""
    from roughslip.run.tomlio import MAX_NESTING

    p = tmp_path / "deep.toml"
    p.write_text(dumps_toml(BASE) + _nested(kind, depth if kind == "tables" else depth - 1))
    with pytest.raises(ConfigError) as e:
        load_config(p)
    msg = str(e.value)
    assert len(msg.splitlines()) == 1 and len(msg) < 300, msg[:500]
    assert msg.startswith("deep.toml: ")
    assert msg.endswith(f"tables, inline tables and arrays may nest at most {MAX_NESTING} "
                        "levels")
    if depth < 300:  # read, then measured: the key where it went too deep is named
        first = {"arrays": "output.fields[0]", "inline": "ensemble.x.a", "tables": "a.a.a"}
        assert msg.startswith(f"deep.toml: {first[kind]}") and "nested more than 32" in msg


@pytest.mark.parametrize("kind", ["arrays", "inline", "tables"])
def test_nesting_at_the_limit_is_read(tmp_path, kind):
    p = tmp_path / "deep.toml"
    p.write_text(dumps_toml(BASE) + _nested(kind, 32 if kind == "tables" else 31))
    with pytest.raises(ConfigError, match=r"unknown|must be a string") as e:  # read, checked
        load_config(p)
    assert "nest" not in str(e.value)


def test_nesting_of_a_set_value_and_of_a_given_mapping(tmp_path):
    p = write(tmp_path, BASE)
    for depth in (32, 2000):
        with pytest.raises(ConfigError) as e:
            load_config(p, ["output.fields=" + "[" * depth + "]" * depth])
        msg = str(e.value)
        assert len(msg.splitlines()) == 1 and len(msg) < 400
        assert msg.startswith("--set output.fields=[[[[") and "at most 32 levels" in msg
    with pytest.raises(ConfigError, match=r"must be a string"):  # 31 arrays and the section
        load_config(p, ["output.fields=" + "[" * 31 + "]" * 31])
    keys = ".".join(["a"] * 34)
    with pytest.raises(ConfigError, match=r"^--set a\.a.*: nested more than 32 levels deep"):
        load_config(p, [f"{keys}=1"])
    deep: dict = {}
    node = deep
    for _ in range(5000):  # as a library caller might pass it
        node["a"] = {}
        node = node["a"]
    with pytest.raises(ConfigError, match=r"^<config>: x\.a\.a.*nested more than 32 levels"):
        load_config(data={**BASE, "x": deep})


def test_a_registered_boundary_is_a_configuration_choice(tmp_path):
    """A boundary registered after the configuration module was imported (the test-only one of
    tests/examples) is a valid ``grid.boundary`` at once, and a name not registered is refused
    in one line that names the key and the choices."""
    from roughslip.elastic.boundaries import BOUNDARIES

    extra = [n for n in BOUNDARIES.names() if n not in ("open", "periodic")]
    assert extra, "tests/examples registers a boundary"
    cfg = load_config(write(tmp_path, BASE), [f'grid.boundary="{extra[0]}"'])
    assert cfg.grid.boundary == extra[0]
    with pytest.raises(ConfigError, match=r"grid\.boundary.*must be one of.*" + extra[0]):
        load_config(write(tmp_path, BASE), ['grid.boundary="closed"'])
