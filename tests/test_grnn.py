"""The GRNN positional-error predictor: features from
real traces, the dataset command, training (shapes, determinism), the model file (round
trip, refusals), evaluation, and that ``hexhil run`` never imports torch."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from hexhil.cli import main as cli
from hexhil.papers.tactile_hexapod.grnn import data, held_out_report, model, train
from hexhil.papers.tactile_hexapod.grnn.features import LEGS, SENSING, StepSampler, hip_errors_m
from conftest import ROOT

PY = sys.executable


def _write(tmp: Path, name: str, walks: int, seed: int, first: int) -> Path:
    runs, rows = data.synthetic(walks, seed, first)
    return data.write(tmp / name, runs, rows, data.feature_meta())


@pytest.fixture(scope="module")
def synth(tmp_path_factory) -> dict[str, Path]:
    """A synthetic training set (terrain seeds 1-12), a held-out one (101-106) and a model
    trained on the first for a few epochs."""
    tmp = tmp_path_factory.mktemp("grnn")
    out = {"train": _write(tmp, "train", 12, 0, 1), "test": _write(tmp, "test", 6, 1, 101),
           "model": tmp / "model.pt"}
    train.main(str(out["train"]), str(out["model"]), epochs=3)
    return out


@pytest.fixture(scope="module")
def traced(tmp_path_factory) -> Path:
    """Two short real with-method runs (tripod, wave), recorded, read back by the command."""
    from hexhil.papers.tactile_hexapod import experiment as th

    tmp = tmp_path_factory.mktemp("traces")
    paths = [th.run_one(th.RunSpec("with", g, 1.0, True, s, "high", "large", periods=p),
                        None, str(tmp))["trace"] for g, s, p in (("tripod", 5, 3), ("wave", 6, 2))]
    assert cli(["grnn", "dataset", "--out", str(tmp / "ds"), *paths]) == 0
    return tmp / "ds" / "dataset.npz"


def test_sampler_closes_a_step_every_six_lift_offs_with_onboard_sensing_only():
    s = StepSampler("tripod", 2.0, 0.05)
    q = [0.0] * 18
    assert s.truth(0, 1.0, 2.0, 0.1, q) is None              # the first sample is the origin
    s.tactile(10, 0b000001, 0, 3)
    s.tactile(20, 0, 0b000010, 6)                             # step 1 closes here
    s.tactile(30, 0b100000, 0, 7)                             # step 2's, not step 1's
    row = s.truth(40, 1.08, 2.0, 0.1, q)
    assert row is not None and row.step == 1 and row.t_us == 40
    assert row.sensing[:LEGS] == [1, 0, 0, 0, 0, 0] and row.sensing[LEGS:2 * LEGS] == [0, 1, 0, 0, 0, 0]
    assert len(row.sensing) == len(SENSING)
    planned = 0.05 * 2 / (1 * 2.0) * 2.0                      # Eq. 2-3 tripod: v T = 2 l
    assert row.planned_x_m == pytest.approx(planned)
    assert row.body_x_m == pytest.approx(0.08) and row.yaw_rad == pytest.approx(0.0)
    assert row.error_m == pytest.approx([planned - 0.08] * LEGS)
    assert s.truth(50, 1.09, 2.0, 0.1, q) is None              # one row per step


def test_hip_errors_average_to_the_body_error_and_a_left_turn_puts_the_right_hips_ahead():
    e = hip_errors_m(0.5, 0.4, 0.0, 0.1)
    assert np.mean(e) == pytest.approx(0.1, abs=1e-12)
    assert e[3] < e[0]                                        # RF ahead of LF when turned left


def test_dataset_from_real_traces(traced):
    ds = data.read(traced)
    assert [r["gait"] for r in ds.runs] == ["tripod", "wave"]
    assert [int(r["periods"]) for r in ds.runs] == [3, 2]
    for w, r in zip(ds.sequences, ds.runs):
        assert list(w.step) == list(range(1, len(w.step) + 1)) and len(w.step) == r["periods"]
        assert w.sensing.shape == (len(w.step), len(SENSING)) and w.error_m.shape == (len(w.step), 6)
        assert np.all(np.diff(w.body_x_m) > 0)                 # it walks forward
        assert math.isnan(r["model_dx_m"])                    # no calibrated speed in a trace
        assert r["dx_m"] == pytest.approx(r["distance_m"] - r["x_end_m"])
    side = json.loads((traced.parent / "dataset.json").read_text())
    assert side["terrain_seeds"] == [5, 6] and side["sensing"] == list(SENSING)
    assert "code_version" in side and "definitions" in side


def test_dataset_refuses_a_file_that_is_not_a_trace(tmp_path, capsys):
    bad = tmp_path / "x.mcap"
    bad.write_bytes(b"not a trace")
    assert cli(["grnn", "dataset", "--out", str(tmp_path / "ds"), str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not an MCAP file" in err


def test_dataset_command_runs_the_sweep(tmp_path, capsys):
    """The command's own sweep: probe, two traced with-method runs, d = 0.2 m (about 8 s)."""
    assert cli(["grnn", "dataset", "--out", str(tmp_path), "--terrains", "2", "--seed", "3",
                "--distance", "0.2", "--workers", "2", "--json"]) == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert res["runs"] == 2 and len(res["build_s_per_run"]) == 2
    ds = data.read(tmp_path)
    assert [int(r["terrain_seed"]) for r in ds.runs] == [3, 4]
    assert [(r["gait"], r["density"], r["height_class"]) for r in ds.runs] == [
        ("tripod", "high", "large"), ("wave", "low", "small")]        # 3 % 8, 4 % 8
    assert all(math.isfinite(r["model_dx_m"]) for r in ds.runs)       # Eq. 8-14 from run_one
    assert all(len(w.step) == r["periods"] for w, r in zip(ds.sequences, ds.runs))
    assert len(list((tmp_path / "traces").glob("*.mcap"))) == 2


def test_train_refuses_bad_input_in_one_line(synth, tmp_path, capsys):
    bad = tmp_path / "x.npz"
    bad.write_bytes(b"nope")
    for argv in (["grnn", "train", str(bad), "--out", str(tmp_path / "m.pt")],
                 ["grnn", "train", str(synth["train"]), "--out", str(tmp_path / "no" / "m.pt")],
                 ["grnn", "train", str(synth["train"]), "--out", str(tmp_path / "m.pt"),
                  "--epochs", "0"]):
        assert cli(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("hexhil: ") and err.count("\n") == 1, err


def test_training_reports_each_epoch_with_its_loss(synth):
    seen = []
    _, _, losses, _ = train.fit(data.read(synth["train"]), 3, progress=lambda *a: seen.append(a))
    assert seen == [("epochs", 0, 3, "")] + [("epochs", i + 1, 3, f"loss={loss:.4f}")
                                            for i, loss in enumerate(losses)]


def test_training_shapes_and_loss_goes_down(synth):
    pred = model.load(synth["model"])
    loss = pred.meta["loss"]
    assert len(loss) == 3 and loss[-1] < loss[0]
    ds = data.read(synth["train"])
    norm = train.fit_norm(ds)
    t = train.tensors(ds, norm)
    y = pred.model(t["sensing"], t["error"], t["n_known"], t["error0"])
    assert y.shape == t["error"].shape == (12, t["sensing"].shape[1], LEGS)
    assert isinstance(pred.model.cell, torch.nn.LSTMCell) and pred.model.cell.hidden_size == 64


def test_same_data_gives_byte_identical_weights(synth, tmp_path):
    a, b = tmp_path / "a.pt", tmp_path / "b.pt"
    for p in (a, b):
        train.main(str(synth["train"]), str(p), epochs=2)
    sa, sb = model.load(a).model.state_dict(), model.load(b).model.state_dict()
    assert all(sa[k].numpy().tobytes() == sb[k].numpy().tobytes() for k in sa)
    c = tmp_path / "c.pt"
    train.main(str(synth["train"]), str(c), epochs=2, seed=1)
    assert model.load(c).model.state_dict()["head.bias"].numpy().tobytes() != \
        sa["head.bias"].numpy().tobytes()


def test_save_load_round_trip_predicts_the_same(synth, tmp_path):
    p = model.load(synth["model"])
    again = tmp_path / "again.pt"
    model.save(again, p.model, p.norm, p.meta)
    q = model.load(again)
    ds = data.read(synth["test"])
    w = ds.sequences[0]
    for pr in (p, q):
        pr.reset()
    for t in range(len(w.step)):
        known = w.error_m[t].tolist() if t < 5 else None
        assert p.step(w.sensing[t].tolist(), known) == q.step(w.sensing[t].tolist(), known)


def test_predictor_step_feeds_back_its_own_output(synth):
    p = model.load(synth["model"])
    s = [0.0] * len(SENSING)
    p.reset()
    first = p.step(s)
    p.reset()
    assert p.step(s) == first                                  # reset really resets
    fed = p.step(s)
    p.reset()
    p.step(s, [0.5] * LEGS)
    assert p.step(s) != fed                                    # a known error changes what follows


@pytest.mark.parametrize("change", ["feature_version", "sensing"])
def test_a_mismatched_model_is_refused_in_one_line(synth, tmp_path, capsys, change):
    blob = torch.load(synth["model"], weights_only=True)
    blob[change] = "grnn-features-0" if change == "feature_version" else blob["sensing"][:-1]
    bad = tmp_path / "bad.pt"
    torch.save(blob, bad)
    assert cli(["grnn", "eval", str(bad), str(synth["test"]), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "do not match" in err and "Traceback" not in err


def test_a_file_that_is_not_a_model_is_refused(synth, tmp_path, capsys):
    for content in (b"hello", b""):
        bad = tmp_path / "x.pt"
        bad.write_bytes(content)
        assert cli(["grnn", "eval", str(bad), str(synth["test"]), "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "not a GRNN model file" in err
    torch.save({"weights": torch.zeros(3)}, bad)
    assert cli(["grnn", "eval", str(bad), str(synth["test"]), "--out", str(tmp_path)]) == 2
    assert "not a GRNN model file" in capsys.readouterr().err


def test_eval_refuses_terrains_the_model_trained_on(synth, tmp_path, capsys):
    assert cli(["grnn", "eval", str(synth["model"]), str(synth["train"]),
                "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "training data" in err


def test_eval_writes_the_table_and_plots(synth, tmp_path, capsys):
    assert cli(["grnn", "eval", str(synth["model"]), str(synth["test"]),
                "--out", str(tmp_path / "ev"), "--json"]) == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert res["runs"] == 6 and len(res["cases"]) == 6
    assert all(Path(p).stat().st_size > 1000 for p in res["plots"])
    assert (tmp_path / "ev" / "eval.md").read_text().count("\n") > 8


def test_trained_model_beats_a_constant_on_held_out_walks(tmp_path):
    """Synthetic walks, because real ones take minutes to simulate: the body loses 2 cm for
    every switch hit and slips by a gait-specific fraction, so the dx at the goal varies
    with what the robot senses along the walk, which a constant (the training mean) cannot
    follow. 30 epochs on 24 walks, evaluated on 8 held-out terrain seeds."""
    tr = _write(tmp_path, "train", 24, 0, 1)
    te = _write(tmp_path, "test", 8, 1, 101)
    train.main(str(tr), str(tmp_path / "m.pt"), epochs=30)
    res = held_out_report.evaluate(str(tmp_path / "m.pt"), str(te))
    assert res["mae_grnn_m"] < 0.5 * res["mae_constant_m"], res


def test_hexhil_run_does_not_import_torch():
    code = ("import sys; from hexhil.cli import main; "
            "rc = main(['run', 'scenarios/flat-tripod.toml', '--duration', '1']); "
            "assert rc == 0, rc; print('torch' in sys.modules)")
    out = subprocess.run([PY, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "False"
