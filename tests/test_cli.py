"""The command line: thin wrappers with documented exit codes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from click.testing import CliRunner

from roughslip import __version__
from roughslip.cli import cli
from roughslip.run.config import dumps_toml

BASE = {
    "grid": {"n": 16},
    "surface": {"kind": "sphere", "radius": 10.0},
    "squeeze": {"depths": [0.1]},
}


def test_version():
    r = CliRunner().invoke(cli, ["--version"])
    assert r.exit_code == 0 and __version__ in r.output
    assert "CITATION.cff" in r.output  # what to cite


def test_module_entry_point():
    out = subprocess.run([sys.executable, "-m", "roughslip", "--version"], capture_output=True,
                         text=True, check=True)
    assert __version__ in out.stdout


def test_show_config_and_exit_code_2(tmp_path):
    p = tmp_path / "run.toml"
    p.write_text(dumps_toml(BASE))
    r = CliRunner().invoke(cli, ["show-config", str(p), "--set", "material.E=3"])
    assert r.exit_code == 0, r.output
    assert "E = 3.0" in r.output
    r = CliRunner().invoke(cli, ["show-config", str(p), "--set", "material.nu=0.7"])
    assert r.exit_code == 2
    assert "material.nu = 0.7: must satisfy -1 < nu <= 0.5" in r.output
    assert "Traceback" not in r.output


def test_missing_file_exit_2(tmp_path):
    r = CliRunner().invoke(cli, ["show-config", str(tmp_path / "nope.toml")])
    assert r.exit_code == 2 and "no such configuration file" in r.output


def test_every_shipped_config_loads_and_rejects_bad_nu():
    from pathlib import Path

    configs = sorted((Path(__file__).parents[1] / "configs").glob("*.toml"))
    assert configs
    for p in configs:
        r = CliRunner().invoke(cli, ["show-config", str(p)])
        assert r.exit_code == 0, (p.name, r.output)
        r = CliRunner().invoke(cli, ["show-config", str(p), "--set", "material.nu=0.7"])
        assert r.exit_code == 2 and "material.nu = 0.7" in r.output, p.name


def test_progress_lines_give_no_eta_until_it_means_something(monkeypatch, capsys):
    """Set-up time (imports, kernels, worker start) is not work: the rate is measured from the
    first finished solve, and no ETA is printed before 3 solves and 5 % of the work follow it."""
    from roughslip import cli as cli_mod

    clock = {"t": 0.0}
    monkeypatch.setattr(cli_mod.time, "monotonic", lambda: clock["t"])
    progress = cli_mod._Progress(quiet=False, every=0.0)
    progress.tty = False
    progress({"kind": "start", "total": 40, "samples": 10, "depths": 4, "skipped": 0})
    lines = []
    for k, t in enumerate([100.0, 101.0, 102.0, 103.0, 104.0]):  # 100 s of set-up
        clock["t"] = t
        progress({"kind": "depth", "sample": 0, "depth_index": k % 4})
        lines.append(capsys.readouterr().err.strip())
    assert all("ETA" not in line for line in lines[:3])
    assert lines[3].endswith("103 s elapsed, ETA 36 s")  # 1 s per solve, 36 to go
    assert lines[4].endswith("ETA 35 s")


def test_a_short_run_shows_its_progress_and_a_long_one_does_not_flood(monkeypatch, capsys):
    """Away from a terminal: a line after the first solve (set-up included), one per quarter
    of the work at least a second apart, one every 10 s, and one at the last solve without an
    ETA. A 12 s run of 96 solves after 10 s of set-up gets five lines, not one."""
    from roughslip import cli as cli_mod

    clock = {"t": 0.0}
    monkeypatch.setattr(cli_mod.time, "monotonic", lambda: clock["t"])

    def lines(total: int, setup: float, per: float) -> list[str]:
        clock["t"] = 0.0
        progress = cli_mod._Progress(quiet=False)
        progress.tty = False
        progress({"kind": "start", "total": total, "samples": total, "depths": 1,
                  "skipped": 0})
        for k in range(total):
            clock["t"] = setup + (k + 1) * per
            progress({"kind": "depth", "sample": k, "depth_index": 0})
        return capsys.readouterr().err.strip().splitlines()

    short = lines(96, 10.0, 12.0 / 96)
    assert [line.split()[1] for line in short] == ["1/96", "24/96", "48/96", "72/96", "96/96"]
    assert short[0].endswith("10 s elapsed") and "ETA" not in short[-1]
    long = lines(1000, 5.0, 1.0)  # 1000 s: every 10 s, and the quarters
    assert 95 <= len(long) <= 110
    fast = lines(8, 0.0, 0.01)  # a fraction of a second: first and last only
    assert [line.split()[1] for line in fast] == ["1/8", "8/8"]


def test_make_demo_draws_the_figures():
    """`make demo` runs, inspects and plots: the figures are written beside the run file."""
    make = (Path(__file__).parents[1] / "Makefile").read_text()
    recipe = make.split("\ndemo:", 1)[1].split("\n\n", 1)[0]
    assert "roughslip run configs/demo.toml -o results/demo.h5" in recipe
    assert "roughslip plot results/demo.h5 -o results/demo" in recipe


def _one_line_error(r) -> str:
    """The message of a failed command: exactly one line on stderr, no traceback."""
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("roughslip: error: "), r.output[:2000]
    return lines[0]


def test_a_huge_value_is_one_short_line_and_exit_2(tmp_path):
    p = tmp_path / "run.toml"
    p.write_text(dumps_toml({**BASE, "surface": {"kind": "x" * 10_000_000}}))
    r = CliRunner().invoke(cli, ["run", str(p), "-o", str(tmp_path / "o.h5")])
    assert r.exit_code == 2
    line = _one_line_error(r)
    assert len(line) < 300 and "run.toml: surface.kind = " in line
    assert "... (10000000 characters): must be one of 'self-affine'" in line
    assert not (tmp_path / "o.h5").exists()


def test_deep_nesting_is_one_line_and_exit_2(tmp_path):
    """Nesting too deep for the TOML parser (it recursed into a 3,000-line traceback and exit
    1): one line naming the file, or the --set, and the limit."""
    p = tmp_path / "deep.toml"
    p.write_text(dumps_toml(BASE) + "[output]\nfields = " + "[" * 1000 + "]" * 1000 + "\n")
    for args in (["run", str(p)], ["show-config", str(p)]):
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 2
        assert _one_line_error(r) == (
            "roughslip: error: deep.toml: nested too deep to read: tables, inline tables and "
            "arrays may nest at most 32 levels")
    ok = tmp_path / "run.toml"
    ok.write_text(dumps_toml(BASE))
    r = CliRunner().invoke(cli, ["show-config", str(ok), "--set",
                                 "squeeze.depths=" + "[" * 40 + "]" * 40])
    assert r.exit_code == 2
    line = _one_line_error(r)
    assert line.startswith("roughslip: error: --set squeeze.depths=[[[")
    assert "squeeze.depths[0]" in line and "at most 32 levels" in line


def test_a_huge_command_line_name_is_echoed_short():
    """Names given on the command line (fit --x) are echoed like configuration values."""
    import pytest

    from roughslip.analysis.fit import quantity
    from roughslip.errors import InputError

    with pytest.raises(InputError) as e:
        quantity(None, "q" * 1_000_000)
    msg = str(e.value)
    assert len(msg) < 400 and " '" + "q" * 79 + "... (1000000 characters); choose from" in msg
