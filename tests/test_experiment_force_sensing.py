"""`hexhil experiment force-sensing` (seed 000): tiny sweeps through every section, report and PNGs."""
import json
import subprocess
import sys

import numpy as np
import pytest

from hexhil.papers.beam_traversal import estimator, landscape
from hexhil.papers.beam_traversal.push import push_samples
from hexhil.papers.beam_traversal import force_sensing
from hexhil.papers.beam_traversal.force_sensing import sections as fs
from conftest import hexhil_in_process


def test_sensed_reproduces_the_worlds_sensor_draws():
    _, clean = push_samples(0.25, 0.27, 0.0, 0.0, 0.0, 300, 0)
    for seed, noise in ((0, 0.05), (7, 0.5)):
        _, noisy = push_samples(0.25, 0.27, 0.0, 0.0, noise, 300, seed)
        assert np.array_equal(fs.sensed(clean, noise, seed), noisy)


def test_preloaded_estimator_recovers_k_and_tau0_of_the_robot_rig():
    g = fs.robot_geometry(True)
    poses, forces, info = fs.robot_push(g, 0.0, 0)
    assert info["samples"] > 10
    est = estimator.estimate_preloaded(poses, forces, 0.0, fs.ROBOT_MB_KG, g)
    assert est.k == pytest.approx(fs.ROBOT_K, rel=1e-3) and est.tau0_nm == pytest.approx(fs.ROBOT_TAU0_NM, rel=1e-3)
    # leaving out the beam mass (Eq. 12's weight term) biases the fit: the term matters
    wrong = estimator.estimate_preloaded(poses, forces, 0.0, 0.0, g)
    assert abs(wrong.k - fs.ROBOT_K) > 0.01 or abs(wrong.tau0_nm - fs.ROBOT_TAU0_NM) > 0.01


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("fs")
    return out, force_sensing.main(True, out, seeds=2, grid=landscape.paper_grid(0.008, 10))


def test_tiny_run_writes_report_and_figures(tiny):
    out, s = tiny
    report = (out / "force-sensing.md").read_text()
    for name in ("fig3-noisy-forces.png", "fig4-landscape-path.png", "gap-readings.png", "fig7-energy-vs-delay.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f"]({name})" in report
    for heading in ("No control", "Table 1", "Table 2", "Table 3", "Table 4", "Cramer-Rao bound", "Planning",
                    "Energy", "Sensory delay", "Robot validation"):
        assert heading in report
    # the paper's numbers sit beside ours
    assert "| 195.0 |" in report and "| 60 |" in report and "0.67 / 0.21" in report


def test_tiny_run_key_outcomes(tiny):
    _, s = tiny
    assert s["k0"] == pytest.approx(0.028, abs=0.001)
    assert s["modes"] == {"0.01": "pitch", "0.25": "roll"}
    assert s["gap_modes"]["clear"] == {"0.01": "roll", "0.25": "roll"}
    assert s["no_control"]["1.0N/0.25"] == "flipped" and s["no_control"]["1.0N/0.01"] == "traversed"
    assert s["no_control"]["0.1N/0.25"] == "stuck"
    assert 0.005 < s["crossover_k"] < 0.05
    # Sec. III-E / Fig. 7B: with Sec. III-B's 1 N push, a longer delay costs more and all traverse
    delayed = [f"sensing/0.25/{d}" for d in fs.DELAYS_MS]
    energies = [s["energy_mJ"][k] for k in delayed]
    assert energies[0] < energies[1] < energies[2] and all(s["traversed"][k] for k in delayed)
    for name, r in s["robot"].items():
        assert r["k_noise_free"] == pytest.approx(0.78, rel=1e-3), name
    med = s["estimation_median"]
    assert med["2/0.05"][0] < med["2/0.5"][0]       # more noise, worse stiffness (Table 3's trend)
    assert all(len(v) in (2, 3, 4) for v in med.values())
    bound = s["estimation_bound_sd"]
    assert bound.keys() == med.keys() and all(len(bound[k]) == len(med[k]) for k in med)
    assert bound["4/0.2"][0] > bound["3/0.2"][0] > bound["2/0.2"][0] > bound["2/0.05"][0]


@pytest.mark.slow
def test_cli_quick(tmp_path):
    r = subprocess.run([sys.executable, "-m", "hexhil.cli", "experiment", "force-sensing", "--quick",
                        "--out", str(tmp_path), "--json"], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout.strip().splitlines()[-1])
    assert s["modes"] == {"0.01": "pitch", "0.25": "roll"} and all(s["traversed"].values())
    assert (tmp_path / "force-sensing.md").exists()


def test_cli_bad_out_or_seeds_is_one_line(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    for args in (["--out", str(f)], ["--out", str(tmp_path), "--seeds", "0"]):
        r = hexhil_in_process("experiment", "force-sensing", *args)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_cli_prints_the_experiment_style_not_the_report(tiny, tmp_path, monkeypatch, capsys):
    from experiment_output import check_output
    from hexhil.cli import main as cli

    out, s = tiny
    monkeypatch.setattr(force_sensing, "main", lambda quick, o, seeds: s)   # the tiny run's summary
    assert cli(["experiment", "force-sensing", "--out", str(out), "--json"]) == 0
    printed = capsys.readouterr().out
    assert check_output(printed, "force-sensing", out) == s
    assert "planned modes: k = 0.01 pitch, k = 0.25 roll" in printed
    assert "# " not in printed and (out / "force-sensing.md").read_text().startswith("# ")
