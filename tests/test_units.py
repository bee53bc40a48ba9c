"""Titles filled from the configuration (roughslip.run.titles): titles that follow a --set or
are refused."""

from __future__ import annotations

from pathlib import Path

import pytest

from roughslip.errors import ConfigError
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.titles import render

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
