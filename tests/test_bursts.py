"""The pull curve under monotone D_x, bursts, and the power-law estimator."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from roughslip.analysis.bursts import fit_power_law, log_binned, pull_curve
from roughslip.cli import cli
from roughslip.contact.squeeze import squeeze
from roughslip.errors import InputError
from roughslip.friction.pull import pull
from roughslip.run.config import dumps_toml, load_config
from roughslip.run.executor import run
from roughslip.surfaces.synthetic import sample_rng, self_affine


def test_sawtooth_of_a_hand_made_sequence():
    # stiffnesses K = F/D: 4, 3, 2.5, 1, 0.5 (decreasing, as removing bonds does)
    d = np.array([1.0, 0.9, 0.8, 2.0, 1.5])
    f = d * np.array([4.0, 3.0, 2.5, 1.0, 0.5])
    c = pull_curve(d, f, exhausted=True)
    # record at 1.0 (F 4), burst of 3 breaks at D = 1; record at 2.0, burst of 2
    assert list(c.burst_start) == [0, 3] and list(c.burst_size) == [3, 2]
    assert np.allclose(c.burst_dx, [1.0, 2.0])
    # drops: from 4 to K_3 * 1 = 1; from 2 to 0 (no bond left)
    assert np.allclose(c.burst_drop, [3.0, 2.0])
    assert np.all(np.diff(c.dx) >= 0)  # D_x never goes back
    expected_x = [0, 1, 1, 1, 1, 2, 2, 2]
    expected_y = [0, 4, 3, 2.5, 1, 2, 1, 0]
    assert np.allclose(c.dx, expected_x) and np.allclose(c.fx, expected_y)
    assert c.peak == 4.0 and c.peak_break == 0
    # cut by an early stop: the last burst has no known end
    cut = pull_curve(d, f)
    assert list(cut.complete) == [True, False] and np.isnan(cut.burst_drop[1])
    assert cut.dx[-1] == 2.0 and cut.fx[-1] == 2.0


def test_curve_input_is_checked():
    with pytest.raises(InputError, match="dx_lim"):
        pull_curve(np.array([1.0, -1.0]), np.array([1.0, 1.0]))
    c = pull_curve(np.zeros(0), np.zeros(0))
    assert c.peak == 0.0 and c.burst_size.size == 0


@pytest.fixture(scope="module")
def rough_pulls():
    out = []
    for i in range(3):
        h = self_affine((48, 48), hurst=0.8, rms_height=1.0, rng=sample_rng(31, i),
                        oversample=2)
        normal = squeeze(h, depth=2.0, tol=1e-12)
        out.append((pull(normal, lam=0.2, method="inverse", early_stop=False),
                    pull(normal, lam=0.2, method="inverse")))
    return out


def test_peak_of_the_curve_is_the_friction_force_exactly(rough_pulls):
    for full, fast in rough_pulls:
        assert full.steps == full.details.n_bonds and fast.details.early_stopped
        for res, exhausted in ((full, True), (fast, False)):
            c = pull_curve(res.curve.dx[1:], res.curve.fx[1:], exhausted=exhausted)
            assert c.peak == res.friction_force  # bitwise
            assert c.peak_break == (res.peak_event - 1)
            assert np.all(np.diff(c.dx) >= 0)
        c = pull_curve(full.curve.dx[1:], full.curve.fx[1:], exhausted=True)
        # every break belongs to exactly one burst; drops are positive and end at zero force
        assert c.burst_size.sum() == full.steps and np.all(c.burst_drop > 0)
        assert c.fx[-1] == 0.0
        # the early-stopped sequence is a prefix: same bursts up to its last (open) one
        e = pull_curve(fast.curve.dx[1:], fast.curve.fx[1:])
        m = int(e.complete.sum())
        assert np.array_equal(e.burst_size[:m], c.burst_size[:m])


@pytest.mark.parametrize("alpha", [1.8, 2.5, 3.2])
def test_discrete_estimator_recovers_known_exponents(alpha):
    x = np.random.default_rng(int(alpha * 10)).zipf(alpha, 20000)
    fit = fit_power_law(x, discrete=True)
    assert abs(fit.alpha - alpha) < max(4 * fit.sigma, 0.03)
    assert fit.xmin <= 3 and fit.sigma < 0.05


@pytest.mark.parametrize("alpha", [1.6, 2.5])
def test_continuous_estimator_recovers_known_exponents_and_the_cut(alpha):
    rng = np.random.default_rng(7)
    tail = 2.0 * (1 - rng.uniform(size=8000)) ** (-1 / (alpha - 1))  # Pareto from 2
    body = rng.uniform(0.1, 2.0, size=4000)  # not a power law below 2
    fit = fit_power_law(np.concatenate([tail, body]), discrete=False)
    assert abs(fit.alpha - alpha) < 4 * fit.sigma
    assert 1.5 < fit.xmin < 3.0


def test_estimator_refuses_too_few_points():
    with pytest.raises(InputError, match="at least 50"):
        fit_power_law(np.arange(1, 10), discrete=True)


def test_log_bins_integrate_to_one():
    x = np.random.default_rng(3).zipf(2.5, 5000)
    c, dens = log_binned(x, discrete=True)
    assert np.all(np.diff(c) > 0) and np.all(dens > 0)
    y = np.random.default_rng(4).pareto(1.5, 5000) + 1
    c, dens = log_binned(y)
    edges = np.geomspace(y.min(), y.max() * (1 + 1e-12), len(c) + 1)
    assert dens.size <= edges.size


def test_bursts_command_on_a_run(tmp_path):
    data = {"grid": {"n": 40},
            "surface": {"kind": "self-affine", "hurst": 0.8, "rms_height": 1.0},
            "squeeze": {"depths": [1.0, 2.0], "depth_unit": "rms"},
            "pull": {"enabled": True, "method": "inverse", "early_stop": False},
            "ensemble": {"samples": 4, "seed": 2},
            "output": {"fields": ["pull_curve"]}}
    cfg = tmp_path / "b.toml"
    cfg.write_text(dumps_toml(data))
    out = tmp_path / "b.h5"
    run(load_config(cfg), out)
    r = CliRunner().invoke(cli, ["bursts", str(out), "--min-tail", "20", "--json"])
    assert r.exit_code == 0, r.output
    res = json.loads(r.output)
    assert res["pulls"] == 8
    size = res["fits"][0]["size"]
    assert res["fits"][0]["phase"] == "all" and size["alpha"] > 1 and size["sigma"] > 0
    r = CliRunner().invoke(cli, ["bursts", str(out), "--min-tail", "20",
                                 "--plot", str(tmp_path / "b.png")])
    assert r.exit_code == 0 and "alpha" in r.output and (tmp_path / "b.png").stat().st_size
    # slip-weakening: its bursts land at the drive, and the same command reads them
    sw = dict(data, pull={"enabled": True, "slip_law": "slip-weakening", "lam_dynamic": 0.0,
                          "slip_distance": 0.01})
    cfg.write_text(dumps_toml(sw))
    run(load_config(cfg), tmp_path / "sw.h5")
    r = CliRunner().invoke(cli, ["bursts", str(tmp_path / "sw.h5"), "--min-tail", "20",
                                 "--json"])
    assert r.exit_code == 0, r.output
    res = json.loads(r.output)
    assert res["pulls"] == 8 and res["fits"][0]["bursts"] > 20
    # a run without pull curves: one clear line
    data["output"] = {"fields": ["fz"]}
    cfg.write_text(dumps_toml(data))
    run(load_config(cfg), tmp_path / "nocurve.h5")
    r = CliRunner().invoke(cli, ["bursts", str(tmp_path / "nocurve.h5")])
    assert r.exit_code == 2 and "pull_curve" in r.output and "Traceback" not in r.output
