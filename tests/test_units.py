"""Physical units (roughslip.run.units) and titles filled from the configuration
(roughslip.run.titles): quantities in a configuration, named units of the results, and titles
that follow a --set or are refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from roughslip.errors import ConfigError
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.titles import render
from roughslip.run.units import Units, convert, parse

CONFIGS = Path(__file__).parents[1] / "configs"
BASE = {
    "grid": {"n": 16, "pixel_size": 0.5},
    "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 0.02},
    "squeeze": {"depths": [0.01, 0.02]},
    "pull": {"enabled": True},
}


def write(tmp_path, data, name="run.toml"):
    p = tmp_path / name
    p.write_text(dumps_toml(data))
    return p


def merged(**sections):
    out = {k: dict(v) for k, v in BASE.items()}
    for k, v in sections.items():
        out[k] = {**out.get(k, {}), **v}
    return out


# ------------------------------------------------------------------------------ quantities


def test_quantities_convert_by_exact_decimal_shifts():
    """A conversion is one rounding of the exact decimal: 2.3 um in metres is 2.3e-06, the
    float of the number typed, not the 2.2999999999999996e-06 of a float product."""
    assert convert(parse("2.3 um", "length"), 0) == 2.3e-6
    assert 2.3 * 1e-6 != 2.3e-6  # what a float product would give
    assert convert(parse("1.1 mm", "length"), -6) == 1100.0
    assert convert(parse("20 um", "length"), -3) == 0.02
    assert convert(parse("70 GPa", "stress"), 6) == 70000.0
    assert convert(parse("0.5 µm", "length"), -6) == 0.5
    assert convert(parse("2 mN", "force"), -6) == 2000.0
    for text, dim in (("0.5 um", "stress"), ("70 GPa", "length"), ("fast", "length"),
                      ("3 furlongs", "length")):
        with pytest.raises(ValueError):
            parse(text, dim)


def test_a_configuration_with_quantities_is_the_one_with_numbers_in_its_units(tmp_path):
    """E = "70 GPa" and pixel_size = "0.5 um" give the run's units (E's and the pixel's, when
    [units] does not name them), the numbers in them, and the digest of the same
    configuration written with numbers."""
    q = load_config(write(tmp_path, merged(
        grid={"pixel_size": "0.5 um"}, material={"E": "70 GPa"},
        surface={"rms_height": "20 nm"}, squeeze={"depths": ["10 nm", 0.02]},
        pull={"slip_law": "slip-weakening", "lam_dynamic": 0.1,
              "slip_distance": "0.002 mm"})))
    plain = load_config(write(tmp_path, merged(
        material={"E": 70.0}, pull={"slip_law": "slip-weakening", "lam_dynamic": 0.1,
                                    "slip_distance": 2.0},
        units={"length": "um", "stress": "GPa"}), "plain.toml"))
    assert (q.length_unit, q.stress_unit) == ("um", "GPa")
    assert q.grid.pixel_size == 0.5 and q.material.E == 70.0
    assert q.surface.rms_height == 0.02 and q.squeeze.depths == [0.01, 0.02]
    assert q.pull.slip_distance == 2.0
    assert q.to_dict() == plain.to_dict() and q.digest() == plain.digest()
    assert q.quantities["material.E"] == "70 GPa"
    # a unit the configuration names converts the quantities to it
    mpa = load_config(write(tmp_path, merged(material={"E": "70 GPa"},
                                             units={"stress": "MPa"}), "mpa.toml"))
    assert mpa.material.E == 70000.0 and mpa.stress_unit == "MPa"
    # the table form of depths, and loads as forces once both units are named
    t = load_config(write(tmp_path, merged(
        units={"length": "um", "stress": "MPa"},
        squeeze={"depths": {"start": "10 nm", "stop": "0.1 um", "num": 3}}), "t.toml"))
    assert t.squeeze.depths[0] == 0.01 and t.squeeze.depths[-1] == 0.1
    data = merged(units={"length": "um", "stress": "MPa"})
    data["squeeze"] = {"forces": ["1 mN", "2000 uN"]}
    f = load_config(write(tmp_path, data, "f.toml"))
    assert f.squeeze.forces == [1000.0, 2000.0]  # MPa x um^2 = uN


@pytest.mark.parametrize("sections, match", [
    ({"material": {"E": "70 um"}}, r"material.E = \"70 um\": 'um' is not a stress unit"),
    ({"grid": {"pixel_size": "half a micron"}},
     r"grid.pixel_size = \"half a micron\": must be a number or a quantity like '0.5 um'"),
    ({"squeeze": {"depths": ["1 um"], "depth_unit": "rms"}},
     r"squeeze.depths = \"1 um\": must be a number \(a unit applies only to depths in "
     r"length units"),
    ({"squeeze": {"depths": None, "forces": ["1 mN"]}},
     r"squeeze.forces .*needs the run's length and stress units"),
])
def test_a_quantity_that_cannot_be_used_names_key_value_and_rule(tmp_path, sections, match):
    data = merged(**{k: v for k, v in sections.items()})
    if data["squeeze"].get("depths") is None:
        data["squeeze"].pop("depths")
    with pytest.raises(ConfigError, match=match):
        load_config(write(tmp_path, data))


def test_results_get_named_units_and_a_dimensionless_run_says_so():
    u = Units("um", "MPa")
    assert u.force == "uN" and u.of_dimension("area") == "um^2"
    assert Units("nm", "GPa").force == "nN" and Units("m", "Pa").force == "N"
    assert u.label("force") == " (µN)" and u.label("length") == " (µm)"
    attrs = u.attributes()
    assert attrs["force"] == "uN" and attrs["pressure"] == "MPa" and attrs["area"] == "um^2"
    half = Units("um", None)
    assert half.of_dimension("force") == "E x um^2"
    assert half.label("force") == r" (E $\times$ µm$^2$)"
    assert half.attributes()["stress"].startswith("not named")
    free = Units()
    assert free.dimensionless and free.label("force") == " (dimensionless)"
    assert free.of_dimension("length") == "" and free.label("fraction") == ""
    assert all(v.startswith("dimensionless") for k, v in free.attributes().items()
               if k in ("length", "stress", "force", "pressure", "area"))
    assert free.describe().startswith("dimensionless")


def test_the_shipped_scan_configs_state_their_units_and_keep_their_numbers():
    """from_file.toml and scan_tiles.toml give E with its unit: stored as the 200000 (MPa)
    they gave before, with forces in uN."""
    for name in ("from_file.toml", "scan_tiles.toml"):
        cfg = load_config(CONFIGS / name)
        assert cfg.material.E == 200e3 and (cfg.length_unit, cfg.stress_unit) == ("um", "MPa")
        assert Units(cfg.length_unit, cfg.stress_unit).force == "uN"


# ------------------------------------------------------------------------------ titles


def test_a_title_with_placeholders_follows_the_set_of_a_hurst_loop():
    """The README's loop, --set surface.hurst=0.6 on rough_h08.toml: the title says 0.6."""
    for h in ("0.6", "0.7"):
        cfg = load_config(CONFIGS / "rough_h08.toml", [f"surface.hurst={h}"])
        assert cfg.title == "rough surface, H = {surface.hurst}"  # stored as written
        assert render(cfg.title, cfg.to_dict()) == f"rough surface, H = {h}"
    cfg = load_config(CONFIGS / "scan_tiles.toml")
    assert render(cfg.title, cfg.to_dict()) == "measured scan, 2 x 2 tiles"
    assert render("{pull.lam:.3f} {{literal}}", {"pull": {"lam": 0.2}}) == "0.200 {literal}"


def test_every_shipped_title_renders_completely():
    for p in sorted(CONFIGS.glob("*.toml")):
        cfg = load_config(p)
        text = render(cfg.title, cfg.to_dict())
        assert text and "{" not in text, p.name


def test_a_literal_title_that_a_set_would_contradict_is_refused_with_its_fix(tmp_path):
    p = write(tmp_path, {**merged(), "title": "rough, H = 0.8, break law"})
    with pytest.raises(ConfigError) as err:
        load_config(p, ["surface.hurst=0.6"])
    msg = str(err.value)
    assert 'quotes surface.hurst = 0.8, which --set surface.hurst=0.6 changes to 0.6' in msg
    assert 'title = "rough, H = {surface.hurst}, break law"' in msg
    with pytest.raises(ConfigError, match=r"quotes pull\.slip_law"):
        load_config(p, ["pull.slip_law=coulomb"])
    # a --set the title does not quote, the same value, or a new title: accepted
    load_config(p, ["pull.lam=0.3"])
    load_config(p, ["surface.hurst=0.8"])
    assert load_config(p, ["surface.hurst=0.6", 'title="H = 0.6"']).title == "H = 0.6"
    # a default that the title quotes counts too (nu = 0.3 is the default)
    q = write(tmp_path, {**merged(), "title": "nu 0.3"}, "nu.toml")
    with pytest.raises(ConfigError, match=r"quotes material\.nu = 0\.3"):
        load_config(q, ["material.nu=0.25"])


def test_a_placeholder_that_names_no_key_is_an_error_with_a_suggestion(tmp_path):
    p = write(tmp_path, {**merged(), "title": "H = {surface.hurts}"})
    with pytest.raises(ConfigError, match=r"\{surface.hurts\} names no key .*did you mean "
                                          r"\{surface.hurst\}"):
        load_config(p)
    with pytest.raises(ConfigError, match="names no key"):  # a key without a value
        load_config(write(tmp_path, {**merged(), "title": "{pull.lam_dynamic}"}, "ld.toml"))
