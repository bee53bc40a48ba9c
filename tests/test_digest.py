"""Configuration digests across versions: run files of every earlier version resume, and a key
added with a default needs no edit anywhere for them (or for runs of this version) to resume."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import h5py
import pytest
from click.testing import CliRunner

from roughslip.cli import cli
from roughslip.errors import InputError
from roughslip.run import checkpoints, digest, sections
from roughslip.run.config import PullConfig, load_config
from roughslip.run.executor import run
from roughslip.run.rules import option
from roughslip.testing import differences

DATA = Path(__file__).parent / "data"
#: run files of earlier versions: (file, digest generation)
STORED = [("run_v1_demo.h5", 1), ("run_v1_coupled.h5", 1), ("run_v1_load.h5", 1),
          ("run_v2_coupled.h5", 2), ("run_v3_coupled.h5", 3)]


def _add_key(monkeypatch) -> type:
    """Make the schema a copy with one key more, ``pull.memory`` (default 0.0), and nothing
    else edited; returns the widened section."""
    plus = dataclasses.make_dataclass(
        "PullConfig", [("memory", float, option(0.0, "a key added in a later version"))],
        bases=(PullConfig,), frozen=True)
    monkeypatch.setitem(sections.SECTIONS, "pull", plus)
    return plus


@pytest.fixture
def added_key(monkeypatch):
    return _add_key(monkeypatch)


def _stored(tmp_path: Path, name: str) -> tuple[Path, Path, str]:
    src = tmp_path / name
    shutil.copy(DATA / name, src)
    with h5py.File(src, "r") as f:
        text, stored = f.attrs["config"], str(f.attrs["config_digest"])
        assert "defaults_version" not in f.attrs  # written before versioned defaults
    cfg_path = tmp_path / "old.toml"
    cfg_path.write_text(text)
    return src, cfg_path, stored


def _resume_finds_nothing_to_do(cfg_path: Path, src: Path) -> None:
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(src), "--resume"])
    assert r.exit_code == 0, r.output
    assert "(0 sample(s) computed" in r.output, r.output


@pytest.mark.parametrize(("name", "generation"), STORED)
def test_runs_of_every_earlier_version_resume(tmp_path, name, generation):
    src, cfg_path, stored = _stored(tmp_path, name)
    cfg = load_config(cfg_path)
    legacy = digest.legacy_digests(cfg._digest_input(), sections.defaults(), cfg.retired)
    assert legacy[3 - generation] == stored  # reproduced as that generation's digest
    assert cfg.matches(stored) and not cfg.matches(stored, digest.DEFAULTS_VERSION)
    _resume_finds_nothing_to_do(cfg_path, src)


@pytest.mark.parametrize(("name", "generation"), STORED)
def test_runs_of_every_earlier_version_resume_after_a_key_is_added(tmp_path, added_key, name,
                                                                   generation):
    src, cfg_path, stored = _stored(tmp_path, name)
    cfg = load_config(cfg_path)
    assert isinstance(cfg.pull, added_key) and cfg.pull.memory == 0.0
    assert cfg.matches(stored)
    _resume_finds_nothing_to_do(cfg_path, src)
    # the new key away from its default is another configuration
    other = load_config(cfg_path, ["pull.memory=0.5"])
    assert not other.matches(stored)


CFG = {"grid": {"n": 12}, "surface": {"kind": "self-affine", "hurst": 0.7, "rms_height": 1.0},
       "squeeze": {"depths": [0.5, 1.5], "depth_unit": "rms"}, "pull": {"enabled": True},
       "ensemble": {"samples": 3, "seed": 4}, "output": {"fields": ["contact", "fx"]}}


def test_a_run_of_this_version_resumes_after_a_key_is_added(tmp_path, monkeypatch):
    """Stopped after its first sample, a run resumes under a schema with a key more (at its
    default) and ends with the numbers of an uninterrupted run; the key set otherwise is
    refused."""
    cfg_path = tmp_path / "run.toml"
    cfg_path.write_text(load_config(data=CFG).to_toml())
    ref, out = tmp_path / "ref.h5", tmp_path / "out.h5"
    run(load_config(cfg_path), ref)

    def stop(name: str) -> None:
        if name == "sample-done":
            raise KeyboardInterrupt
    previous = checkpoints.listen(stop)
    try:
        with pytest.raises(KeyboardInterrupt):
            run(load_config(cfg_path), out)
    finally:
        checkpoints.listen(previous)
    with h5py.File(out, "r") as f:
        assert int(f.attrs["defaults_version"]) == digest.DEFAULTS_VERSION
        assert f["complete"][()].tolist() == [1, 0, 0]
    _add_key(monkeypatch)
    with pytest.raises(InputError, match="different configuration"):
        run(load_config(cfg_path, ["pull.memory=0.5"]), out, resume=True)
    summary = run(load_config(cfg_path), out, resume=True)
    assert summary.skipped == 1 and summary.computed == 2
    assert differences(ref, out) == []
    # a file made under defaults newer than this version knows says so
    with h5py.File(out, "r+") as f:
        f.attrs["defaults_version"] = digest.DEFAULTS_VERSION + 1
    with pytest.raises(InputError, match="written by a newer roughslip"):
        run(load_config(cfg_path), out, resume=True)


def test_a_changed_default_needs_its_old_value(monkeypatch):
    """A default that changes gets a new defaults version with the old value, so a
    configuration that relies on the new default does not match a run made under the old."""
    cfg = load_config(data=CFG)
    d = cfg._digest_input()
    base = sections.defaults()
    v1 = digest.digest(d, base, 1)
    assert v1 == cfg.digest()
    # today's default of pull.tol changes from 1e-10 to 1e-12 in version 2
    new = {**base, ("pull", "tol"): 1e-12}
    monkeypatch.setattr(digest, "DEFAULTS_VERSION", 2)
    monkeypatch.setattr(digest, "DEFAULTS_THEN", {1: {("pull", "tol"): 1e-10}})
    # a configuration that gives tol = 1e-10 explicitly is the old run ...
    old = {**d, "pull": {**d["pull"], "tol": 1e-10}}
    assert digest.digest(old, new, 1) == v1
    # ... one that takes the new default is not
    now = {**d, "pull": {**d["pull"], "tol": 1e-12}}
    assert digest.digest(now, new, 1) != v1
    with pytest.raises(ValueError, match="defaults version 3"):
        digest.digest(d, new, 3)
