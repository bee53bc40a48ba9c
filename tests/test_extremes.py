"""Stiff and extreme cases, bad input and faults: correct answers or clear errors."""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import struct
import zipfile

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from roughslip.cli import cli
from roughslip.contact.analytic import mindlin_bonded_punch_stiffness
from roughslip.contact.squeeze import squeeze
from roughslip.elastic.operators import ElasticOperator
from roughslip.errors import (
    InputError,
    MemoryLimitError,
    NumericalError,
    OutputError,
    WorkerError,
)
from roughslip.friction.pull import pull
from roughslip.linalg import memory
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.executor import estimate_memory, run
from roughslip.run.scene import Scene
from roughslip.run.store import read_run
from roughslip.surfaces.synthetic import punch, sample_rng, self_affine, sphere
from roughslip.testing import differences


@pytest.fixture(scope="module")
def rough():
    return self_affine((32, 28), hurst=0.8, rms_height=1.0, rng=sample_rng(21, 0), oversample=2)


# ------------------------------------------------------------------------------ Poisson ratio


@pytest.mark.parametrize("nu", [0.5, 0.4999, 0.0, -0.5, -0.99])
def test_normal_force_scales_with_the_contact_modulus(rough, nu):
    """G_zz is proportional to 1 - nu^2: F(nu) = F(0) / (1 - nu^2), same contact."""
    base = squeeze(rough, depth=1.0, nu=0.0, tol=1e-11)
    r = squeeze(rough, depth=1.0, nu=nu, tol=1e-11)
    assert r.converged and np.array_equal(r.contact, base.contact)
    assert r.normal_force == pytest.approx(base.normal_force / (1 - nu * nu), rel=1e-9)


@pytest.mark.parametrize("nu", [0.5, 0.4999, 0.0, -0.5, -0.99])
def test_tangential_punch_stiffness_at_extreme_nu(nu):
    """Bonded punch: K = 8 G a / (2 - nu) (docs/methods.rst#mindlin) within the staircase error."""
    ah = 12
    h = 1.0 / ah
    normal = squeeze(punch((2 * ah + 2, 2 * ah + 2), radius=1.0, a=h), depth=1e-3, a=h, nu=nu)
    res = pull(normal, lam=0.3)
    assert res.converged and np.isfinite(res.curve.fx[1:]).all()
    a_eq = math.sqrt(normal.n_contact * h * h / math.pi)
    k = mindlin_bonded_punch_stiffness(a_eq, nu=nu)
    err = (res.curve.fx[1:][0] / res.curve.dx[1:][0] - k) / k
    assert -0.2 * h < err < 0


@pytest.mark.parametrize("nu", [-1.0, -1.5, 0.5000001, 0.7, float("nan")])
def test_poisson_ratio_out_of_range_is_rejected(rough, nu):
    with pytest.raises(InputError, match="nu"):
        squeeze(rough, depth=1.0, nu=nu)


# ------------------------------------------------------------------------------ grids


@pytest.mark.parametrize("shape", [(1, 1), (2, 2), (1, 40), (40, 1), (97, 97), (13, 31)])
def test_odd_tiny_and_strip_grids(shape):
    h = sphere(shape, radius=10.0 * max(shape))
    r = squeeze(h, depth=0.05 * max(shape) / 10 + 1e-3, tol=1e-11)
    assert r.converged and r.n_contact >= 1 and np.isfinite(r.fz).all()
    p = pull(r)
    assert p.converged and 0 < p.friction_force <= 0.2 * r.normal_force * (1 + 1e-12)
    # symmetric shapes give symmetric forces
    assert np.allclose(r.fz, r.fz[::-1, ::-1], rtol=1e-9, atol=1e-12 * r.fz.max())


def test_prime_size_uses_fast_fft_lengths():
    op = ElasticOperator((97, 97))
    assert op.padded_shape == (200, 200)


def test_memory_guard_refuses_and_suggests(tmp_path):
    cfg = load_config(data={"grid": {"n": 256}, "squeeze": {"depths": [0.1]},
                            "surface": {"kind": "sphere", "radius": 100.0},
                            "execution": {"memory_limit_gb": 0.01}})
    with pytest.raises(MemoryLimitError, match=r"GiB.*available"):
        run(cfg, tmp_path / "m.h5")
    assert not (tmp_path / "m.h5").exists()
    assert memory.available_bytes() > 2**20  # run() restores the budget it set
    data = {"grid": {"n": 64}, "squeeze": {"depths": [0.5]},
            "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1},
            "ensemble": {"samples": 4}}
    per = estimate_memory(Scene.from_config(load_config(data=data)))
    data["execution"] = {"memory_limit_gb": 2.5 * per / 2**30}  # room for two workers
    with pytest.raises(MemoryLimitError, match="use --workers 2"):
        run(load_config(data=data), tmp_path / "w.h5", workers=4)
    run(load_config(data=data), tmp_path / "w.h5", workers=2)  # fits


def _guard(tmp_path, args, env=None, data=None):
    """`roughslip run` refused by the memory budget: exit 2, one line, nothing written."""
    out = tmp_path / "guard.h5"
    r = CliRunner().invoke(cli, ["run", str(_cfg_file(tmp_path, data or GOOD)), "-o", str(out),
                                 "--quiet", *args], env=env)
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("roughslip: error: c.toml: "), r.output
    assert not out.exists()
    return lines[0]


def test_the_memory_guard_names_the_size_key_and_a_hint_that_holds(tmp_path, monkeypatch):
    """grid.n = 100000 said "use --workers 1", which needs 8,270 GiB as well: the guard names
    the key that sets the size, and suggests fewer workers only when one fits, else the
    largest size that fits and the budget's own setting when that is the limit. It runs
    before any surface is made (a 100000 x 100000 one alone is 75 GiB)."""
    from roughslip.run.budget import _per_worker

    env = {"ROUGHSLIP_MEMORY_LIMIT_GB": "0.5"}
    need = _per_worker(load_config(_cfg_file(tmp_path, GOOD)))
    line = _guard(tmp_path, ["--set", "grid.n=100000", "--workers", "3"], env)
    n = int(re.search(r"grid\.n = (\d+) is the largest that fits", line).group(1))
    assert need((n, n)) <= 2**29 < need((n + 1, n + 1))
    assert line == (f"roughslip: error: c.toml: grid.n = 100000: a 100000 x 100000 grid needs "
                    f"~{need((100000, 100000)) / 2**30:.0f} GiB per worker (even one worker), "
                    "more than the 0.5 GiB available (ROUGHSLIP_MEMORY_LIMIT_GB=0.5); "
                    f"grid.n = {n} is the largest that fits, or raise "
                    "ROUGHSLIP_MEMORY_LIMIT_GB")
    assert "--workers" not in line
    # one worker fits, four do not: fewer workers is the hint
    m = int(n / 2.5**0.5)  # about 2.5 workers fit
    per = need((m, m))
    fewer = 2**29 // per
    assert fewer == 2
    line = _guard(tmp_path, ["--set", f"grid.n={m}", "--workers", "4"], env)
    assert line.endswith(f"4 workers need ~{4 * per / 2**30:.3g} GiB, more than the 0.5 GiB "
                         f"available (ROUGHSLIP_MEMORY_LIMIT_GB=0.5); use --workers {fewer}")
    assert f"grid.n = {m}: a {m} x {m} grid needs" in line
    # the configuration's own budget, and a rectangular grid
    line = _guard(tmp_path, ["--set", "execution.memory_limit_gb=0.25"],
                  data={**GOOD, "grid": {"shape": [3000, 1500]}})
    assert "grid.shape = [3000, 1500]: a 3000 x 1500 grid needs" in line
    m = re.search(r"grid\.shape = \[(\d+), (\d+)\] \(the same aspect\) is the largest", line)
    assert m and int(m.group(1)) == 2 * int(m.group(2))
    assert need((int(m.group(1)), int(m.group(2)))) <= 2**28
    assert line.endswith("(execution.memory_limit_gb = 0.25); " + m.group(0) + " that fits, "
                         "or raise execution.memory_limit_gb")


def test_the_memory_guard_of_a_file_grid_and_of_a_cluster_run(tmp_path, monkeypatch):
    from roughslip.run.budget import check_budget
    from roughslip.surfaces import synthetic

    np.save(tmp_path / "scan.npy", self_affine((64, 48), hurst=0.8, rms_height=1.0,
                                               rng=sample_rng(1, 0)))
    cfg = load_config(_cfg_file(tmp_path, {"surface": {"kind": "file", "path": "scan.npy"},
                                           "squeeze": {"depths": [0.1]}}))
    scene = Scene.from_config(cfg)
    per = estimate_memory(scene)
    check_budget(cfg, 1)  # the file sets the grid: not checked before it is read
    with memory.limited(0.6 * per / 2**30):
        with pytest.raises(MemoryLimitError, match=r"^c\.toml: surface\.path = 'scan\.npy': "
                                                   r"its 64 x 48 grid needs .* per worker "
                                                   r"\(even one worker\).*; surface\.downsample "
                                                   r"= 2 fits \(32 x 24\)$"):
            check_budget(cfg, 1, scene)
    # a cluster's workers are not this machine: no local check, but a surface too large to
    # make here is one line too, not a traceback
    def no_memory(*args, **kw):
        raise MemoryError

    monkeypatch.setattr(synthetic, "sphere", no_memory)
    r = CliRunner().invoke(cli, ["run", str(_cfg_file(tmp_path, {
        "grid": {"n": 100_000}, "surface": {"kind": "sphere", "radius": 1.0},
        "squeeze": {"depths": [0.1]}})), "--scheduler", "tcp://127.0.0.1:9", "-o",
        str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and r.output.strip() == (
        "roughslip: error: [surface]: a 100000 x 100000 sphere (74.5 GiB of heights) does not "
        "fit in this machine's memory (grid.n or grid.shape)")


# ------------------------------------------------------------------------------ contact extremes


def test_no_single_full_and_near_full_contact(rough):
    none = squeeze(rough, depth=-0.5)
    assert none.normal_force == 0 and not none.contact.any() and pull(none).friction_force == 0
    one = squeeze(rough, depth=1e-12)
    assert one.n_contact == 1 and pull(one).friction_force == pytest.approx(
        0.2 * one.normal_force)
    rng_ = rough.max() - rough.min()
    near = squeeze(rough, depth=4.0 * rng_, tol=1e-10)
    assert near.converged and 0.9 < near.contact_area < 1.0
    full = squeeze(rough, depth=40.0 * rng_, tol=1e-10)
    assert full.converged and full.contact.all()


def test_ill_conditioned_large_punch_converges_or_reports():
    """A large contact patch on a large grid: cond ~ N; the solver meets tol or says so."""
    n = 192
    h = punch((n, n), radius=0.45 * n)
    r = squeeze(h, depth=1.0, tol=1e-10, max_iter=5000)
    assert r.converged and r.residual <= 1e-10
    r2 = squeeze(h, depth=1.0, tol=1e-10, max_iter=5)
    assert not r2.converged and "max_iter" in r2.message and np.isfinite(r2.fz).all()


# ------------------------------------------------------------------------------ scales


@pytest.mark.parametrize("hurst", [0.01, 0.05, 0.95, 0.99])
def test_extreme_hurst_exponents(hurst):
    h = self_affine((48, 48), hurst=hurst, rms_height=1.0, rng=sample_rng(3, 0))
    assert np.isfinite(h).all() and h.std() == pytest.approx(1.0)
    r = squeeze(h, depth=1.0)
    assert r.converged and pull(r).converged


@pytest.mark.parametrize("scale", [1e-9, 1e-4, 1e3])
def test_height_scale_gives_exactly_scaled_forces(rough, scale):
    base = squeeze(rough, depth=0.8)
    r = squeeze(rough * scale, depth=0.8 * scale)
    assert r.normal_force == pytest.approx(scale * base.normal_force, rel=1e-8)
    assert pull(r).friction_force == pytest.approx(scale * pull(base).friction_force, rel=1e-8)


@pytest.mark.parametrize("E", [1e-6, 1e12])
def test_modulus_scale(rough, E):
    base = squeeze(rough, depth=0.8)
    r = squeeze(rough, depth=0.8, E=E)
    assert r.normal_force == pytest.approx(E * base.normal_force, rel=1e-9)
    assert pull(r).friction_force == pytest.approx(E * pull(base).friction_force, rel=1e-9)


@pytest.mark.parametrize("lam", [1e-8, 1e8])
def test_extreme_friction_coefficients(rough, lam):
    normal = squeeze(rough, depth=0.8)
    assert pull(normal, lam=lam).friction_force == pytest.approx(
        lam / 0.2 * pull(normal, lam=0.2).friction_force, rel=1e-9)


# ------------------------------------------------------------------------------ NaN guard


def test_a_nan_inside_a_solve_stops_the_sample_with_a_clear_error(tmp_path, monkeypatch):
    cfg = load_config(data={"grid": {"n": 16}, "squeeze": {"depths": [0.5, 1.0]},
                            "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1},
                            "ensemble": {"samples": 2}})
    real = ElasticOperator.apply
    calls = {"n": 0}

    def poisoned(self, component, f, out=None):
        calls["n"] += 1
        res = real(self, component, f, out)
        if calls["n"] == 40:
            res[3, 3] = np.nan
        return res

    monkeypatch.setattr(ElasticOperator, "apply", poisoned)
    with pytest.raises(NumericalError, match=r"sample \d+, depth index \d+"):
        run(cfg, tmp_path / "nan.h5")


# ------------------------------------------------------------------------------ bad input, CLI


def _cfg_file(tmp_path, data, name="c.toml"):
    p = tmp_path / name
    p.write_text(dumps_toml(data))
    return p


GOOD = {"grid": {"n": 12}, "squeeze": {"depths": [0.3, 0.6]},
        "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0},
        "ensemble": {"samples": 3}}


@pytest.mark.parametrize(
    ("args", "code", "match"),
    [
        (["--set", "surface.hurst=1.3"], 2, "surface.hurst = 1.3"),
        (["--set", "grid.pixel_size=-1"], 2, "grid.pixel_size = -1"),
        (["--set", "grid.n='x'"], 2, "grid.n"),
        (["--set", "nonsense=1"], 2, "nonsense: unknown"),
        (["--set", "squeeze.depths=[1, 0.5]"], 2, "strictly increasing"),
        (["--workers", "0"], 2, "workers"),
    ],
)
def test_cli_bad_input_exit_codes(tmp_path, args, code, match):
    out = tmp_path / "o.h5"
    r = CliRunner().invoke(cli, ["run", str(_cfg_file(tmp_path, GOOD)), "-o", str(out),
                                 "--quiet", *args])
    assert r.exit_code == code, r.output
    assert match in r.output and "Traceback" not in r.output
    assert not out.exists()


def test_malformed_toml_and_missing_topography(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[grid]\nn = = 3\n")
    r = CliRunner().invoke(cli, ["run", str(bad)])
    assert r.exit_code == 2 and "invalid TOML" in r.output
    data = {"surface": {"kind": "file", "path": "nothere.npy"}, "squeeze": {"depths": [0.1]}}
    r = CliRunner().invoke(cli, ["run", str(_cfg_file(tmp_path, data))])
    assert r.exit_code == 2 and "surface.path" in r.output and "no such file" in r.output


def test_topography_with_nan_exits_2_naming_the_file(tmp_path):
    h = sphere((8, 8), radius=10.0)  # not flat: a flat file is refused as such
    h[2, 5] = np.nan
    np.save(tmp_path / "topo.npy", h)
    data = {"surface": {"kind": "file", "path": "topo.npy"}, "squeeze": {"depths": [0.1]}}
    r = CliRunner().invoke(cli, ["run", str(_cfg_file(tmp_path, data)), "-o",
                                 str(tmp_path / "o.h5")])
    assert r.exit_code == 2 and "topo.npy" in r.output and "[2, 5]" in r.output


def test_bad_input_never_damages_an_existing_output(tmp_path):
    cfg_path = _cfg_file(tmp_path, GOOD)
    out = tmp_path / "keep.h5"
    run(load_config(cfg_path), out)
    before = out.read_bytes()
    for args in (["--set", "material.nu=2"], ["--resume", "--set", "material.nu=0.2"],
                 []):  # the last: exists without --overwrite
        r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(out), "--quiet", *args])
        assert r.exit_code == 2, r.output
        assert out.read_bytes() == before


def test_corrupt_files_for_resume_fit_inspect(tmp_path):
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"\x00" * 100)
    cfg_path = _cfg_file(tmp_path, GOOD)
    for cmd in (["run", str(cfg_path), "-o", str(junk), "--resume"], ["fit", str(junk)],
                ["inspect", str(junk)], ["plot", str(junk)]):
        r = CliRunner().invoke(cli, cmd)
        assert r.exit_code == 2, (cmd, r.output)
        assert "junk.h5" in r.output and "Traceback" not in r.output
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    r = CliRunner().invoke(cli, ["inspect", str(other)])
    assert r.exit_code == 2 and "not a roughslip run file" in r.output


# ------------------------------------------------------------------------------ faults


def test_full_disk_keeps_completed_samples_and_resume_finishes(tmp_path, monkeypatch):
    from roughslip.run import store

    cfg = load_config(_cfg_file(tmp_path, GOOD))
    out = tmp_path / "disk.h5"
    real = store.RunWriter._write_main
    count = {"n": 0}

    def failing(self, res):
        count["n"] += 1
        if count["n"] == 2:
            raise OSError(28, "No space left on device")
        return real(self, res)

    monkeypatch.setattr(store.RunWriter, "_write_main", failing)
    with pytest.raises(OutputError, match=r"No space left on device.*--resume"):
        run(cfg, out)
    monkeypatch.setattr(store.RunWriter, "_write_main", real)
    r = read_run(out)
    assert r.n_complete == 1  # the first sample is kept
    s = run(cfg, out, resume=True)
    assert read_run(out).complete.all() and s.skipped >= 1


def _full_disk_after(monkeypatch, calls: int) -> None:
    """The file system reports no free space from the ``calls``-th question on."""
    import shutil
    from collections import namedtuple

    real, n = shutil.disk_usage, {"n": 0}
    usage = namedtuple("usage", "total used free")

    def disk_usage(path):
        n["n"] += 1
        return usage(1 << 30, 1 << 30, 0) if n["n"] >= calls else real(path)

    monkeypatch.setattr(shutil, "disk_usage", disk_usage)


@pytest.mark.parametrize("verbose", [False, True])
def test_a_full_disk_is_one_line_and_resume_gives_the_same_file(tmp_path, monkeypatch,
                                                                verbose):
    """The free space is checked before a sample is written: a full disk stops the run with
    one line naming the file, the cause and the resume hint (the library's detail only with
    --verbose); the samples before are kept and --resume gives bitwise the same file."""
    cfg_path = _cfg_file(tmp_path, GOOD)
    out, ref = tmp_path / "disk.h5", tmp_path / "ref.h5"
    assert CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(ref), "--quiet",
                                    "--workers", "1"]).exit_code == 0
    _full_disk_after(monkeypatch, 2)
    r = CliRunner().invoke(cli, [*(["--verbose"] if verbose else []), "run", str(cfg_path),
                                 "-o", str(out), "--quiet", "--workers", "1"])
    monkeypatch.undo()
    assert r.exit_code == 1, r.output
    lines = r.output.strip().splitlines()
    assert lines[-1].startswith(f"roughslip: error: {out}: cannot write sample 1: No space "
                                "left on device")
    assert lines[-1].endswith("free some space, then run again with --resume")
    assert ("Traceback" in r.output and "OSError" in r.output) == verbose
    assert len(lines) == 1 or verbose
    assert read_run(out).n_complete == 1
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(out), "--resume", "--quiet",
                                 "--workers", "1"])
    assert r.exit_code == 0, r.output
    assert differences(out, ref) == []


def test_a_vanished_folder_is_one_line_that_says_what_is_lost(tmp_path):
    folder = tmp_path / "runs"
    folder.mkdir()
    cfg = load_config(_cfg_file(tmp_path, GOOD))

    def progress(event):
        if event.get("kind") == "sample":
            import shutil

            shutil.rmtree(folder)

    with pytest.raises(OutputError) as e:
        run(cfg, folder / "gone.h5", workers=1, progress=progress)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{folder / 'gone.h5'}: cannot write sample 1")
    assert f"the folder {folder} is gone" in msg and "run again" in msg


@pytest.mark.parametrize(("exc", "cause", "remedy"), [
    (RuntimeError("Can't close file (file write failed: time = Tue, filename = 'x.h5', file "
                  "descriptor = 16, errno = 28, error message = 'No space left on device', "
                  "buf = 0x5, total write size = 5594)"),
     "No space left on device", "free some space, then run again with --resume"),
    (PermissionError(13, "Permission denied"), "Permission denied",
     "make the file and its folder writable, then run again with --resume"),
    (OSError(30, "Read-only file system"), "Read-only file system",
     "make the file system writable, then run again with --resume"),
    (RuntimeError("Something HDF5 says\nwith a second line"), "Something HDF5 says",
     "remove the cause, then run again with --resume"),
])
def test_io_failures_name_file_cause_and_remedy_in_one_line(exc, cause, remedy):
    from roughslip.errors import io_cause, io_failure

    assert io_cause(exc) == cause
    err = io_failure("runs/x.h5", "cannot write sample 3", exc, resume=True)
    assert str(err) == (f"runs/x.h5: cannot write sample 3: {cause}; the samples completed "
                        f"before are kept: {remedy}")
    assert str(io_failure("a.png", "cannot write the figure", exc)) == \
        f"a.png: cannot write the figure: {cause}"


def test_worker_crash_keeps_completed_samples(tmp_path, monkeypatch):
    """A worker process that dies (here: os._exit while computing sample 2, injected into the
    spawned workers through sitecustomize) ends the run with a clear error; the samples
    completed so far are kept and --resume finishes the job."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(
        "import os\n"
        "if os.environ.get('ROUGHSLIP_CRASH_SAMPLE'):\n"
        "    import roughslip.run.pool as e\n"
        "    real = e._pool_task\n"
        "    def task(config, sample):\n"
        "        if sample == int(os.environ['ROUGHSLIP_CRASH_SAMPLE']):\n"
        "            os._exit(9)\n"
        "        return real(config, sample)\n"
        "    e._pool_task = task\n")
    cfg = load_config(_cfg_file(tmp_path, {**GOOD, "ensemble": {"samples": 5}}))
    out = tmp_path / "crash.h5"
    monkeypatch.setenv("PYTHONPATH", str(hook) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    monkeypatch.setenv("ROUGHSLIP_CRASH_SAMPLE", "2")
    with pytest.raises(WorkerError, match=r"worker process died.*--resume"):
        run(cfg, out, workers=2)
    monkeypatch.delenv("ROUGHSLIP_CRASH_SAMPLE")
    r = read_run(out)
    assert not r.complete[2]
    s = run(cfg, out, resume=True)
    assert read_run(out).complete.all() and s.computed >= 1



# ------------------------------------------------------------------------------ hostile files


def _x3p_xml(nx: int, ny: int, pad: int = 0) -> bytes:
    """main.xml of an areal X3P of ``nx`` x ``ny`` doubles, with ``pad`` bytes of comment."""
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<p:ISO5436_2 xmlns:p="x"><Record1>'
            '<Revision>ISO5436 - 2000</Revision><FeatureType>SUR</FeatureType><Axes>'
            '<CX><AxisType>I</AxisType><DataType>D</DataType><Increment>1e-6</Increment></CX>'
            '<CY><AxisType>I</AxisType><DataType>D</DataType><Increment>1e-6</Increment></CY>'
            '<CZ><AxisType>A</AxisType><DataType>D</DataType></CZ></Axes></Record1><Record3>'
            f'<MatrixDimension><SizeX>{nx}</SizeX><SizeY>{ny}</SizeY><SizeZ>1</SizeZ>'
            '</MatrixDimension><DataLink><PointDataLink>bindata/data.bin</PointDataLink>'
            f'</DataLink></Record3><!--{" " * pad}--></p:ISO5436_2>').encode()


def _x3p(path, xml: bytes, data: bytes, method: int = zipfile.ZIP_DEFLATED) -> None:
    with zipfile.ZipFile(path, "w", method) as z:
        z.writestr("main.xml", xml)
        z.writestr("bindata/data.bin", data)


def _declare(path, member: str, size: int) -> None:
    """Make the archive declare ``size`` bytes for ``member`` (central directory and local
    header), whatever its data holds: a size that lies."""
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as z:
        local = z.getinfo(member).header_offset
    struct.pack_into("<I", raw, local + 22, size)
    start = 0
    while (i := raw.find(b"PK\x01\x02", start)) >= 0:
        n = struct.unpack_from("<H", raw, i + 28)[0]
        if raw[i + 46:i + 46 + n].decode() == member:
            struct.pack_into("<I", raw, i + 24, size)
        start = i + 4
    path.write_bytes(bytes(raw))


def _refused(path, match: str) -> str:
    """read_raw refuses ``path`` in one line naming it, and so does `roughslip topography`
    (exit 2); returns the message."""
    from roughslip.surfaces.topography import read_raw

    with pytest.raises(InputError, match=match) as e:
        read_raw(path)
    msg = str(e.value)
    assert len(msg.splitlines()) == 1 and len(msg) < 400 and path.name in msg, msg
    r = CliRunner().invoke(cli, ["topography", str(path)])
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert r.output.strip() == f"roughslip: error: {msg}"
    return msg


def test_an_x3p_zip_bomb_is_refused_before_it_is_read(tmp_path, monkeypatch):
    """A main.xml that inflates past MAX_XML_BYTES, or by more than MAX_COMPRESSION_RATIO, is
    refused from its declared size and ratio; a size that lies is caught by the bounded read;
    point data whose size is not SizeX x SizeY x 8 is refused before it is read."""
    from roughslip.surfaces import limits

    h = sphere((8, 8), radius=5.0) * 1e-6
    good = tmp_path / "good.x3p"
    _x3p(good, _x3p_xml(8, 8), h.tobytes())
    from roughslip.surfaces.topography import read_raw

    assert np.array_equal(read_raw(good).heights, h)
    # 1. inflates past the cap (16 MiB + a little of spaces: 17 kB compressed, ratio ~1000)
    big = tmp_path / "big.x3p"
    _x3p(big, _x3p_xml(8, 8, pad=limits.MAX_XML_BYTES), h.tobytes())
    assert big.stat().st_size < 100_000
    _refused(big, r"big\.x3p: 'main\.xml' declares 16777\d+ bytes, more than the 16777216 "
                  r"allowed$")
    # 2. a ratio no deflate stream reaches (bzip2 of 2 MB of spaces), under the cap
    ratio = tmp_path / "ratio.x3p"
    _x3p(ratio, _x3p_xml(8, 8, pad=2_000_000), h.tobytes(), zipfile.ZIP_BZIP2)
    _refused(ratio, r"ratio\.x3p: 'main\.xml' declares \d+ bytes compressed to \d+ \(ratio "
                    r"\d+:1\): an archive member may be compressed at most 1100:1$")
    # 3. declared sizes that lie: smaller than the data (the bounded read stops at the
    # declared size, and the checksum of the archive fails), and larger
    for name, size in (("small.x3p", 100), ("large.x3p", 5000)):
        p = tmp_path / name
        _x3p(p, _x3p_xml(8, 8, pad=3000), h.tobytes(), zipfile.ZIP_STORED)
        _declare(p, "main.xml", size)
        _refused(p, re.escape(name) + r": 'main\.xml': (damaged archive|\d+ bytes read where)")
    # 4. point data of the wrong size: read never
    wrong = tmp_path / "wrong.x3p"
    _x3p(wrong, _x3p_xml(8, 8), h.tobytes()[:-8])
    real_open = zipfile.ZipFile.open

    def guarded(self, name, *args, **kw):  # the data of a wrong size may never be read
        assert getattr(name, "filename", name) != "bindata/data.bin"
        return real_open(self, name, *args, **kw)

    monkeypatch.setattr(zipfile.ZipFile, "open", guarded)
    _refused(wrong, r"wrong\.x3p: 'bindata/data\.bin' declares 504 bytes; 8 x 8 x 1 float64 "
                    r"values \(SizeX x SizeY x SizeZ of main\.xml\) need 512$")
    monkeypatch.undo()
    # 5. a matrix whose points would exceed MAX_SCAN_POINTS, or the memory available
    huge = tmp_path / "huge.x3p"
    _x3p(huge, _x3p_xml(40_000, 40_000), h.tobytes())
    _refused(huge, r"huge\.x3p: declares a 40000 x 40000 array \(1\.6e\+09 points\): a height "
                   r"map may have at most 1073741824")
    monkeypatch.setenv("ROUGHSLIP_MEMORY_LIMIT_GB", "0.001")
    mem = tmp_path / "mem.x3p"
    _x3p(mem, _x3p_xml(400, 400), h.tobytes())
    with pytest.raises(MemoryLimitError, match=r"mem\.x3p: a 400 x 400 height map needs "
                                               r"~0\.00238 GiB to read but 0\.001 GiB"):
        read_raw(mem)


def _npy_header(path, shape, descr="<f8", data=b"\0" * 128) -> None:
    """A .npy file (or stream) whose header declares ``shape`` whatever ``data`` holds."""
    from numpy.lib import format as npy

    with contextlib.nullcontext(path) if hasattr(path, "write") else open(path, "wb") as f:
        npy.write_array_header_1_0(f, {"descr": descr, "fortran_order": False, "shape": shape})
        f.write(data)


def test_array_headers_are_checked_before_the_data_is_read(tmp_path):
    """.npy, .npz and HDF5: a header that declares more than MAX_SCAN_POINTS, or another size
    than the data holds, is one line naming the file (numpy said "-2446744073709551616
    elements"); a dataset stored in (almost) nothing is refused by its compression ratio."""
    _npy_header(tmp_path / "huge.npy", (4_000_000_000, 4_000_000_000))
    _refused(tmp_path / "huge.npy", r"huge\.npy: declares a 4000000000 x 4000000000 array "
                                    r"\(1\.6e\+19 points\): a height map may have at most")
    _npy_header(tmp_path / "short.npy", (40, 40))
    _refused(tmp_path / "short.npy", r"short\.npy: declares a 40 x 40 float64 array \(12800 "
                                     r"bytes of data\) but holds 128: the file is damaged")
    h = sphere((6, 5), radius=4.0)
    _npy_header(tmp_path / "long.npy", (6, 5), data=h.tobytes() + b"\0" * 8)
    _refused(tmp_path / "long.npy", r"long\.npy: declares a 6 x 5 float64 array \(240 bytes "
                                    r"of data\) but holds 248")
    good = tmp_path / "ok.npy"
    np.save(good, np.asfortranarray(h.astype(">f4")))
    from roughslip.surfaces.topography import read_raw

    assert np.array_equal(read_raw(good).heights, h.astype(">f4"))
    # .npz: the member's header too, and its ratio
    buf = io.BytesIO()
    _npy_header(buf, (20_000, 20_000), data=b"")
    with zipfile.ZipFile(tmp_path / "lie.npz", "w") as z:
        z.writestr("h.npy", buf.getvalue() + h.tobytes())
    _refused(tmp_path / "lie.npz", r"lie\.npz \(array 'h'\): declares a 20000 x 20000 float64 "
                                   r"array \(3200000000 bytes of data\) but holds 240")
    with zipfile.ZipFile(tmp_path / "bomb.npz", "w", zipfile.ZIP_BZIP2) as z:
        z.writestr("h.npy", b"\0" * 2_000_000)
    _refused(tmp_path / "bomb.npz", r"bomb\.npz: 'h\.npy' declares 2000000 bytes compressed "
                                    r"to \d+ \(ratio \d+:1\)")
    # HDF5: a 30000 x 30000 dataset never written is all fill value, stored in 0 bytes
    with h5py.File(tmp_path / "fill.h5", "w") as f:
        f.create_dataset("h", shape=(30000, 30000), dtype="f8", chunks=(64, 64),
                         compression="gzip")
    _refused(tmp_path / "fill.h5", r"fill\.h5 \(dataset 'h'\): declares 7200000000 bytes "
                                   r"stored in 0 \(ratio 7200000000:1\): a dataset may be "
                                   r"compressed at most 1100:1")
    with h5py.File(tmp_path / "many.h5", "w") as f:
        f.create_dataset("h", shape=(2**16, 2**15), dtype="f4", chunks=(64, 64))
    _refused(tmp_path / "many.h5", r"many\.h5 \(dataset 'h'\): declares a 65536 x 32768 "
                                   r"array \(2\.15e\+09 points\)")
