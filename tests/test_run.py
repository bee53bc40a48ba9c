"""`roughslip run`: HDF5 output, resume, parallel bitwise equality, faults."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from roughslip.cli import cli
from roughslip.elastic.operators import ElasticOperator, Material
from roughslip.errors import InputError
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.executor import run, run_sample
from roughslip.run.store import journal_dir, read_run
from roughslip.testing import differences

CFG = {
    "grid": {"n": 24},
    "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0, "oversample": 2},
    "squeeze": {"depths": {"start": 0.3, "stop": 1.5, "num": 3, "spacing": "log"},
                "depth_unit": "rms"},
    "pull": {"enabled": True, "lam": 0.2},
    "ensemble": {"samples": 4, "seed": 5},
    "output": {"fields": ["contact", "fz", "fx", "stick", "pull_curve"]},
}


def write_cfg(tmp_path: Path, data=CFG, name="run.toml") -> Path:
    p = tmp_path / name
    p.write_text(dumps_toml(data))
    return p


def assert_same_numbers(a: Path, b: Path) -> None:
    """Every dataset bitwise equal, the wall-clock timings excepted."""
    assert differences(a, b) == []


@pytest.fixture(scope="module")
def serial_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("serial")
    cfg = load_config(write_cfg(d))
    out = d / "serial.h5"
    summary = run(cfg, out, workers=1)
    return cfg, out, summary


def test_layout_and_contents(serial_run):
    cfg, out, summary = serial_run
    assert summary.computed == 4 and not journal_dir(out).exists()
    r = read_run(out)
    assert r.complete.all() and r.axis_name == "depth"
    assert np.allclose(r.axis, cfg.targets)
    for name in ("normal_force", "contact_area", "friction_force", "depth_length", "residual"):
        assert r.scalars[name].shape == (4, 3) and np.all(np.isfinite(r.scalars[name]))
    assert np.all(np.diff(r.scalars["normal_force"], axis=1) > 0)
    assert np.all(r.scalars["converged"] == 1) and np.all(r.scalars["pull_converged"] == 1)
    with h5py.File(out, "r") as f:
        assert f.attrs["format"] == "roughslip-run"
        for key in ("version", "command_line", "config", "config_digest", "libraries", "blas",
                    "fft_backend", "threads", "seed", "units"):
            assert key in f.attrs, key
        g = f["samples/s000002"]
        assert g.attrs["complete"] and "rigid_surface" in g and "elastic_surface" not in g
        d = g["d001"]
        assert set(d) == {"contact", "fz", "fx", "stick", "dx_lim", "fx_lim", "broken_site"}
        assert d["fz"].compression == "gzip" and d["fz"].chunks is not None
        assert "uz" not in d and "gap" not in d  # not listed: not stored
        # the stored pull curve's maximum is the stored friction force
        assert d["fx_lim"][()].max() == f["friction_force"][2, 1]
    # the sample is the pure function of (config, sample)
    again = run_sample(cfg, 2)
    assert np.array_equal(again.fields[1]["fz"], r.field(2, 1, "fz"))


def test_the_blas_and_its_kernel_are_recorded_and_shown_by_inspect(serial_run):
    """The run file records each BLAS library of the process that wrote it (library, version,
    the kernel OpenBLAS chose for the CPU), as threadpoolctl finds them once numpy and
    scipy.linalg are loaded, sorted by package and file; `roughslip inspect` shows them in one
    line."""
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_info

    _cfg, out, _ = serial_run
    with h5py.File(out, "r") as f:
        blas = json.loads(f.attrs["blas"])
    found = [i for i in threadpool_info() if i["user_api"] == "blas"]
    assert found and {(b["library"], b["version"], b["architecture"], b["file"])
                      for b in blas} == \
        {(i["internal_api"], i["version"], i.get("architecture") or "", i["filepath"])
         for i in found}
    assert all(b["file"] for b in blas) and len(blas) == len(found)
    # in a fixed order, whatever order the writing process loaded the libraries in
    assert blas == sorted(blas, key=lambda b: (b["package"], b["file"]))
    r = CliRunner().invoke(cli, ["inspect", str(out)])
    assert r.exit_code == 0, r.output
    lines = [line for line in r.output.splitlines() if line.lstrip().startswith("BLAS: ")]
    assert len(lines) == 1 and len(lines[0]) <= 120, lines
    for b in blas:
        assert " ".join(w for w in (b["library"], b["version"], b["architecture"]) if w) \
            in lines[0]


def test_workers_two_equals_one_bitwise(serial_run, tmp_path):
    cfg, out, _ = serial_run
    par = tmp_path / "par.h5"
    run(cfg, par, workers=2)
    assert_same_numbers(out, par)


def test_existing_file_is_not_overwritten(serial_run, tmp_path):
    cfg, _out, _ = serial_run
    target = tmp_path / "x.h5"
    target.write_bytes(b"precious")
    with pytest.raises(InputError, match="--overwrite"):
        run(cfg, target)
    assert target.read_bytes() == b"precious"
    run(cfg, target, overwrite=True)
    assert read_run(target).complete.all()


def test_resume_refuses_a_different_config(serial_run, tmp_path):
    _cfg, out, _ = serial_run
    other = load_config(data={**CFG, "material": {"nu": 0.25}})
    with pytest.raises(InputError, match="different configuration"):
        run(other, out, resume=True)
    r = CliRunner().invoke(cli, ["run", str(write_cfg(tmp_path)), "-o", str(out), "--resume",
                                 "--set", "material.nu=0.25", "--quiet"])
    assert r.exit_code == 2 and "different configuration" in r.output


def test_resume_names_the_keys_that_differ_with_both_values(serial_run, tmp_path):
    """From the run file, and from the journal of a killed run: the keys that differ, the
    stored value and the new one, and the way out."""
    _cfg, out, _ = serial_run
    r = CliRunner().invoke(cli, ["run", str(write_cfg(tmp_path)), "-o", str(out), "--resume",
                                 "--set", "pull.lam=0.3", "--set", "material.nu=0.25",
                                 "--set", "execution.threads=2", "--quiet"])
    assert r.exit_code == 2
    assert ("different configuration: material.nu = 0.3 in the file, 0.25 now; pull.lam = "
            "0.2 in the file, 0.3 now; resume with the stored values, or use --overwrite"
            in r.output)
    assert "threads" not in r.output  # settings that never change the numbers are not named
    cfg_path = _long_cfg(tmp_path)
    killed = tmp_path / "killed.h5"
    proc = _start(tmp_path, cfg_path, killed, stop_at=("sample-done", 1, "KILL"))
    proc.communicate(timeout=300)
    killed.unlink()  # only the journal is left
    stored = json.loads((journal_dir(killed) / "run.json").read_text())
    assert "config" in stored
    other = load_config(cfg_path, ["ensemble.seed=10"])
    with pytest.raises(InputError, match=r"ensemble\.seed = 9 in the file, 10 now"):
        run(other, killed, resume=True)


def test_resume_of_an_unreadable_file_without_journal_suggests_overwrite(tmp_path):
    out = tmp_path / "junk.h5"
    out.write_bytes(b"junk")
    r = CliRunner().invoke(cli, ["run", str(write_cfg(tmp_path)), "-o", str(out), "--resume",
                                 "--quiet"])
    assert r.exit_code == 2 and "not a readable HDF5 file" in r.output
    assert "use --overwrite to replace it" in r.output and out.read_bytes() == b"junk"


def test_units_and_methods_are_stored(serial_run, tmp_path):
    """Each scalar says its unit (dimensionless runs say so), the root attribute units names
    every kind of result, and each sample records the pull method each depth used."""
    _cfg, out, _ = serial_run
    with h5py.File(out, "r") as f:
        assert f["normal_force"].attrs["unit"].startswith("dimensionless")
        assert f["contact_area"].attrs["unit"] == "1" and f["seconds"].attrs["unit"] == "s"
        assert "unit" not in f["iterations"].attrs
        solvers = json.loads(f["samples/s000000"].attrs["solvers"])
    assert len(solvers) == 3 and all(s["pull_method"] in ("literal", "inverse", "cg")
                                     for s in solvers)
    data = {**CFG, "grid": {"n": 16, "pixel_size": "0.5 um"}, "material": {"E": "200 GPa"},
            "units": {"stress": "MPa"}, "ensemble": {"samples": 1}}
    run(load_config(write_cfg(tmp_path, data)), tmp_path / "um.h5")
    with h5py.File(tmp_path / "um.h5", "r") as f:
        units = json.loads(f.attrs["units"])
        assert f["friction_force"].attrs["unit"] == "uN" == units["force"]
        assert f["depth_length"].attrs["unit"] == "um" and units["area"] == "um^2"
        assert units["pressure"] == "MPa"


def test_resume_of_a_complete_file_does_nothing(serial_run):
    cfg, out, _ = serial_run
    s = run(cfg, out, resume=True)
    assert s.computed == 0 and s.skipped == 4


def _start(tmp_path: Path, cfg_path: Path, out: Path, *extra: str,
           stop_at: tuple[str, int, str] | None = None) -> subprocess.Popen:
    """``roughslip run`` in a subprocess; ``stop_at = (point, count, signal)`` makes it send
    itself the signal at that checkpoint of the writer (``tests/inject.py``)."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    head = [sys.executable, "-m", "roughslip"]
    if stop_at is not None:
        point, count, sig = stop_at
        head = [sys.executable, str(Path(__file__).with_name("inject.py")), "--signal", sig,
                point, str(count)]
    return subprocess.Popen(
        [*head, "run", str(cfg_path), "-o", str(out), "--quiet", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)


def _long_cfg(tmp_path: Path) -> Path:
    data = {**CFG, "grid": {"n": 32}, "ensemble": {"samples": 12, "seed": 9}}
    return write_cfg(tmp_path, data, "long.toml")


def _reference_and_killed(tmp_path: Path, name: str, done: int):
    """An uninterrupted run, and a run of the same config killed (SIGKILL) once ``done``
    samples are journaled."""
    cfg_path = _long_cfg(tmp_path)
    cfg = load_config(cfg_path)
    ref = tmp_path / "ref.h5"
    run(cfg, ref)
    out = tmp_path / name
    proc = _start(tmp_path, cfg_path, out, stop_at=("sample-done", done, "KILL"))
    proc.communicate(timeout=300)
    assert proc.returncode == -signal.SIGKILL
    return cfg, ref, out


def test_kill_and_resume_gives_the_same_numbers(tmp_path):
    cfg, ref, out = _reference_and_killed(tmp_path, "killed.h5", 3)
    assert len(list(journal_dir(out).glob("s*.h5"))) == 3
    s = run(cfg, out, resume=True)
    assert s.skipped == 3 and s.computed == 9
    assert_same_numbers(ref, out)
    assert not journal_dir(out).exists()


def test_unreadable_file_is_rebuilt_from_the_journal(tmp_path):
    cfg, ref, out = _reference_and_killed(tmp_path, "broken.h5", 2)
    out.write_bytes(b"\x89HDF\r\n garbage: a write cut in the middle")
    s = run(cfg, out, resume=True)
    assert s.skipped == 2
    assert_same_numbers(ref, out)


def test_ctrl_c_leaves_a_resumable_file(tmp_path):
    cfg_path = _long_cfg(tmp_path)
    out = tmp_path / "int.h5"
    proc = _start(tmp_path, cfg_path, out, stop_at=("sample-done", 2, "INT"))
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 130, err.decode()
    assert b"--resume" in err and b"Traceback" not in err
    r = read_run(out)  # a valid file: the interrupted run closed it
    assert r.n_complete == 2
    r2 = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(out), "--resume", "--quiet"])
    assert r2.exit_code == 0, r2.output
    assert read_run(out).complete.all()


def test_cli_run_and_inspect(tmp_path):
    cfg_path = write_cfg(tmp_path)
    out = tmp_path / "cli.h5"
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(out), "--set",
                                 "ensemble.samples=2"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(cli, ["inspect", str(out)])
    assert r.exit_code == 0 and "samples complete: 2 of 2" in r.output
    assert "friction_force" in r.output and "not converged: 0" in r.output
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "nope.h5")])
    assert r.exit_code == 2 and "no such file" in r.output
    (tmp_path / "junk.h5").write_bytes(b"junk")
    r = CliRunner().invoke(cli, ["inspect", str(tmp_path / "junk.h5")])
    assert r.exit_code == 2 and "not a readable HDF5 file" in r.output
    assert "Traceback" not in r.output


def test_fixed_shape_runs_one_sample_with_a_note(tmp_path):
    data = {"grid": {"n": 16}, "surface": {"kind": "sphere", "radius": 20.0},
            "squeeze": {"depths": [0.5, 1.0]}, "ensemble": {"samples": 5}}
    r = CliRunner().invoke(cli, ["run", str(write_cfg(tmp_path, data)), "-o",
                                 str(tmp_path / "s.h5")])
    assert r.exit_code == 0, r.output
    assert "running 1 sample" in r.output
    assert read_run(tmp_path / "s.h5").complete.shape == (1,)


def test_dask_local_cluster_equals_serial(serial_run, tmp_path, blas_restored):
    distributed = pytest.importorskip("distributed", reason="the dask extra is not installed")
    cfg, out, _ = serial_run
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        dsk = tmp_path / "dask.h5"
        run(cfg, dsk, scheduler=cluster.scheduler_address)
    assert_same_numbers(out, dsk)


def test_coupled_run_end_to_end(tmp_path):
    data = {**CFG, "grid": {"n": 16}, "ensemble": {"samples": 2, "seed": 3},
            "material": {"nu": 0.25}, "coupling": {"enabled": True},
            "output": {"fields": ["contact", "fz", "fx", "stick", "pull_curve", "gap"]}}
    out = tmp_path / "coupled.h5"
    summary = run(load_config(write_cfg(tmp_path, data)), out)
    assert summary.computed == 2
    r = read_run(out)
    ff, fn = r.scalars["friction_force"], r.scalars["friction_normal_force"]
    assert np.all(ff > 0) and np.all(fn > 0) and np.all(r.scalars["converged"] == 1)
    with h5py.File(out, "r") as f:
        d = f["samples/s000000/d002"]
        assert {"dx_lim", "fx_lim", "fz_lim", "broken_site"} <= set(d)
        assert d["fx_lim"][()].max() == pytest.approx(f["friction_force"][0, 2])
        assert np.all(d["gap"][()] >= -1e-9)
        notes = json.loads(f["samples/s000000"].attrs["notes"])
    # the released-bond count is a scalar dataset, and the notes say the same
    released = [int(n.split(": ")[1].split()[0]) for n in notes if "released at D_x = 0" in n]
    assert released == list(r.scalars["released_bonds"][0])
    # counts are stored as float (NaN where not computed); the coupled model has no squeeze
    # iteration count of its own; every block solve is certified against the FFT operator
    assert r.scalars["released_bonds"].dtype == np.float64
    assert np.all(np.isnan(r.scalars["iterations"]))
    assert np.all(r.scalars["residual"] <= 1e-10)
    assert np.all(np.isnan(r.scalars["pull_error_estimate"]))
    # one solve gives both: the squeeze's time and the pull's are its two parts, not its total
    # stored twice
    sq, pl = r.scalars["seconds"], r.scalars["pull_seconds"]
    assert np.all(sq > 0) and np.all(pl > 0) and not np.array_equal(sq, pl)
    # nu = 1/2: no coupling, the decoupled path is used and the run says so
    half = {**data, "material": {"nu": 0.5}}
    r2 = CliRunner().invoke(cli, ["run", str(write_cfg(tmp_path, half, "half.toml")), "-o",
                                  str(tmp_path / "half.h5")])
    assert r2.exit_code == 0 and "G_zx vanishes" in r2.output
    assert np.all(read_run(tmp_path / "half.h5").scalars["released_bonds"] == 0)


def test_coupled_run_under_load_control_holds_the_force(tmp_path):
    """squeeze.forces with coupling: the squeeze reaches each load, the pull holds it
    (coupling.pull_control = "force") and the depth of every event is stored."""
    data = {**CFG, "grid": {"n": 16}, "ensemble": {"samples": 2, "seed": 3},
            "material": {"nu": 0.25}, "squeeze": {"forces": [2.0, 6.0]},
            "coupling": {"enabled": True, "pull_control": "force"},
            "output": {"fields": ["fz", "pull_curve"]}}
    out = tmp_path / "load.h5"
    run(load_config(write_cfg(tmp_path, data)), out)
    r = read_run(out)
    assert r.axis_name == "force_target"
    np.testing.assert_allclose(r.scalars["normal_force"], [[2.0, 6.0]] * 2, rtol=1e-10)
    assert np.all(np.diff(r.scalars["depth_length"], axis=1) > 0)
    with h5py.File(out, "r") as f:
        d = f["samples/s000001/d001"]
        np.testing.assert_allclose(d["fz_lim"][()], 6.0, rtol=1e-9)
        dz = d["dz_lim"][()]
        assert dz[0] == pytest.approx(f["depth_length"][1, 1]) and np.ptp(dz) > 0
    # the same loads with the depth held: a different pull, the same squeeze
    held = {**data, "coupling": {"enabled": True}}
    out2 = tmp_path / "held.h5"
    run(load_config(write_cfg(tmp_path, held, "held.toml")), out2)
    r2 = read_run(out2)
    np.testing.assert_allclose(r2.scalars["depth_length"], r.scalars["depth_length"],
                               rtol=1e-10)
    assert not np.allclose(r2.scalars["friction_force"], r.scalars["friction_force"])


def test_coupled_run_with_the_coulomb_law_is_the_library_result(tmp_path):
    """pull.slip_law = "coulomb" with coupling: the run stores what the library computes for
    the same scene, and its notes count the bonds slipping from the start."""
    from roughslip.contact.problem import Problem
    from roughslip.coupling.coupled import couple
    from roughslip.run.scene import Scene

    data = {**CFG, "grid": {"n": 16}, "ensemble": {"samples": 1, "seed": 3},
            "material": {"nu": 0.25}, "coupling": {"enabled": True},
            "pull": {"enabled": True, "lam": 0.2, "slip_law": "coulomb"},
            "output": {"fields": ["pull_curve"]}}
    cfg = load_config(write_cfg(tmp_path, data))
    out = tmp_path / "coulomb.h5"
    run(cfg, out)
    r = read_run(out)
    brk = tmp_path / "break.h5"
    run(load_config(write_cfg(tmp_path, {**data, "pull": {"enabled": True, "lam": 0.2}},
                              "break.toml")), brk)
    assert np.all(r.scalars["friction_force"] > read_run(brk).scalars["friction_force"])
    scene = Scene.from_config(cfg)
    pb = Problem(scene.surfaces(0).composite, scene.grid, scene.material)
    depth = float(r.scalars["depth_length"][0, -1])
    lib = couple(pb, depth=depth, lam=0.2, slip_law="coulomb", tol=1e-10)
    assert r.scalars["friction_force"][0, -1] == pytest.approx(lib.friction_force, rel=1e-9)
    with h5py.File(out, "r") as f:
        notes = json.loads(f["samples/s000000"].attrs["notes"])
    assert any("slipping at D_x = 0" in n for n in notes)


def test_ctrl_c_with_workers_stops_promptly_and_resumes(tmp_path):
    cfg_path = _long_cfg(tmp_path)
    out = tmp_path / "pool.h5"
    proc = _start(tmp_path, cfg_path, out, "--workers", "2", stop_at=("sample-done", 1, "INT"))
    _, err = proc.communicate(timeout=300)  # a hang fails here
    assert proc.returncode == 130, err.decode()
    assert b"--resume" in err and b"Traceback" not in err
    assert not read_run(out).complete.all()  # queued samples were cancelled, not run
    r = CliRunner().invoke(cli, ["run", str(cfg_path), "-o", str(out), "--resume", "--quiet"])
    assert r.exit_code == 0, r.output
    assert read_run(out).complete.all()


def test_pull_error_estimate_is_stored_when_asked_and_reproducible(serial_run, tmp_path):
    data = {**CFG, "ensemble": {"samples": 2, "seed": 5},
            "pull": {**CFG["pull"], "method": "inverse", "error_estimate": True}}
    cfg = load_config(write_cfg(tmp_path, data))
    out, again = tmp_path / "est.h5", tmp_path / "est2.h5"
    run(cfg, out)
    run(cfg, again, workers=2)
    assert_same_numbers(out, again)  # every dataset bitwise, the estimate included
    r = read_run(out)
    est = r.scalars["pull_error_estimate"]
    # est = kappa * residual with residual <= pull.tol (converged); the Lanczos estimate of
    # kappa never exceeds the true condition number on the bonds, which by interlacing is at
    # most that of G_xx on the whole grid
    n = CFG["grid"]["n"]
    op = ElasticOperator((n, n), material=Material(1.0, 0.3), components=("xx",))  # config defaults
    w = np.linalg.eigvalsh(op.tables.dense("xx"))
    assert np.all(r.scalars["pull_converged"] == 1)
    assert np.all(est >= 0) and np.any(est > 0) and np.all(est <= w[-1] / w[0] * 1e-10)
    # not estimated: NaN, not 0
    assert np.all(np.isnan(read_run(serial_run[1]).scalars["pull_error_estimate"]))
    with h5py.File(out, "r") as f:
        assert "estimate" in f["pull_error_estimate"].attrs["description"]
    # the former name of the key is still read, as the same configuration
    old = {**data, "pull": {**CFG["pull"], "method": "inverse", "error_bound": True}}
    assert load_config(write_cfg(tmp_path, old, "old.toml")).digest() == cfg.digest()


def test_runs_started_before_keys_were_renamed_or_added_resume(tmp_path):
    """A file whose stored digest is that of the configuration before `pull.error_bound`
    became `pull.error_estimate` and `pull.early_stop` was added resumes as the same run."""
    import hashlib

    from roughslip.run.digest import canonical as dump

    cfg = load_config(write_cfg(tmp_path))
    old = cfg.to_dict()
    old.pop("execution", None)
    old["pull"] = {("error_bound" if k == "error_estimate" else k): v
                   for k, v in old["pull"].items()
                   if k not in ("early_stop", "precision", "components", "direction",
                                "facets")}
    old["pull"]["coulomb_steps"] = 32  # a key of that version, retired since
    old["coupling"].pop("pull_control")  # keys added later
    old["coupling"].pop("gained")
    old["coupling"].pop("history")
    old["surface"].pop("anisotropy")
    legacy = hashlib.sha256(dump(old).encode()).hexdigest()
    assert legacy != cfg.digest() and cfg.matches(legacy)
    out = tmp_path / "old.h5"
    run(load_config(data={**CFG, "ensemble": {"samples": 4, "seed": 5}}), out)
    with h5py.File(out, "r+") as f:  # a file of that version: no defaults version
        f.attrs["config_digest"] = legacy
        del f.attrs["defaults_version"]
    assert run(cfg, out, resume=True).skipped == 4
    # a real change is still refused
    other = load_config(data={**CFG, "pull": {**CFG["pull"], "early_stop": False}})
    with pytest.raises(InputError, match="different configuration"):
        run(other, out, resume=True)


def test_coupled_run_says_when_the_dense_inverse_did_not_fit(tmp_path, monkeypatch):
    """A coupled run whose block inverse does not fit the memory budget goes on matrix-free:
    same friction forces, and the sample's notes say why."""
    from roughslip.coupling import blocksolvers

    data = {**CFG, "grid": {"n": 16}, "ensemble": {"samples": 1, "seed": 3},
            "material": {"nu": 0.25}, "coupling": {"enabled": True}}
    cfg = load_config(write_cfg(tmp_path, data))
    run(cfg, tmp_path / "dense.h5", workers=1)
    monkeypatch.setattr(blocksolvers, "DENSE_BYTES_PER_UNKNOWN2", 2**50)  # no inverse fits
    run(cfg, tmp_path / "cg.h5", workers=1)
    dense, cg = read_run(tmp_path / "dense.h5"), read_run(tmp_path / "cg.h5")
    np.testing.assert_allclose(cg.scalars["friction_force"], dense.scalars["friction_force"],
                               rtol=1e-8)
    with h5py.File(tmp_path / "cg.h5", "r") as f:
        notes = json.loads(f["samples/s000000"].attrs["notes"])
    with h5py.File(tmp_path / "dense.h5", "r") as f:
        dense_notes = json.loads(f["samples/s000000"].attrs["notes"])
    assert not any("auto chose cg" in n for n in dense_notes)
    assert any("auto chose cg: the dense solver needs" in n and "GiB" in n for n in notes)


def test_keys_the_coupled_model_does_not_use_are_stated_not_ignored(tmp_path):
    """Under coupling, squeeze and pull keys that the coupled model does not read are named
    in the run's notes when they are set (none when left at their defaults); a pull.tol above
    the coupled model's largest is said to be tightened."""
    from roughslip.run.scene import Scene

    base = {**CFG, "material": {"nu": 0.25}, "coupling": {"enabled": True}}
    quiet = Scene.from_config(load_config(write_cfg(tmp_path, base)))
    assert not [n for n in quiet.notes if n.startswith("coupling:")]
    data = {**base, "squeeze": {**CFG["squeeze"], "method": "active-set", "tol": 1e-8},
            "pull": {**CFG["pull"], "method": "cg", "batch_size": 4, "early_stop": False,
                     "error_estimate": True, "tol": 1e-6}}
    notes = [n for n in Scene.from_config(load_config(write_cfg(tmp_path, data))).notes
             if n.startswith("coupling:")]
    named = {n.split(" = ")[0].removeprefix("coupling: ") for n in notes}
    # squeeze.method is honoured: it finds the starting contact set under load control
    assert named == {"squeeze.tol", "pull.method", "pull.batch_size",
                     "pull.early_stop", "pull.error_estimate", "pull.tol"}
    assert any("tightened to 1e-10" in n for n in notes)
    # at nu = 1/2 the decoupled model runs and reads them all: nothing to say
    half = {**data, "material": {"nu": 0.5}}
    assert not [n for n in Scene.from_config(load_config(write_cfg(tmp_path, half))).notes
                if n.startswith("coupling:")]


def test_a_derived_column_is_written_and_read(tmp_path, derived_column):
    """A registered derived column (the test-only one) is stored by the process that writes,
    so a run on two worker processes, which never import it, stores the same numbers as a
    run in this process; the reader and the table give it like any other."""
    from roughslip.analysis import tables

    cfg = load_config(write_cfg(tmp_path), ["ensemble.samples=2"])
    one, two = tmp_path / "one.h5", tmp_path / "two.h5"
    run(cfg, one, workers=1)
    run(cfg, two, workers=2)
    assert_same_numbers(one, two)
    r = read_run(one)
    ratio = r.scalars[derived_column.name]
    assert ratio.shape == r.scalars["friction_force"].shape
    assert np.array_equal(ratio, r.scalars["friction_force"] / r.scalars["friction_normal_force"])
    df = tables.to_dataframe(one)
    assert np.array_equal(df[derived_column.name].to_numpy(), ratio.ravel())


def test_a_run_resumes_only_with_the_derived_columns_it_started_with(tmp_path):
    """Resuming with a derived column registered that the run did not have, or without one it
    had, is refused in one line naming the column, and the file is untouched."""
    from roughslip.errors import InputError
    from tests.examples import ratio

    cfg = load_config(write_cfg(tmp_path), ["ensemble.samples=1"])
    plain, with_ratio = tmp_path / "plain.h5", tmp_path / "ratio.h5"
    run(cfg, plain)
    with ratio.registered():
        run(cfg, with_ratio)
        before = plain.read_bytes()
        with pytest.raises(InputError, match="registered now only: friction_ratio;"):
            run(cfg, plain, resume=True)
        assert plain.read_bytes() == before
        assert run(cfg, with_ratio, resume=True).skipped == 1
    with pytest.raises(InputError, match="in the file only: friction_ratio\\)"):
        run(cfg, with_ratio, resume=True)
