"""The learning CLI: train / evaluate / ablate / export-model, one-line errors, Ctrl-C.

Mostly the fast rf/knn baselines; one small cnn1d run for export (ONNX and int8 ONNX)
and a subprocess for Ctrl-C. Budget: about 30 s on 2 cores.
"""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time

import pytest
import torch
from learn_fixtures import (
    make_dataset_folder,
    trial_record,
    write_participant,
    write_pressure_session,
)

from tactile_studio.cli import main
from tactile_studio.learn.deploy.export import load_onnx_predictor
from tactile_studio.learn.results.rescore import load_run_data

GESTURES3 = ("Poke", "Heavy Pat", "Back & Forth Rub")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli")
    make_dataset_folder(root / "data", participants=3, blocks=3, gestures=GESTURES3)
    return root


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_train_evaluate_and_resume(data, capsys, tmp_path):
    out = tmp_path / "run"
    code, stdout, err = run_cli(capsys, "train", "--data", data / "data", "--model", "rf",
                                "--preset", "tiny", "--eval", "lopo", "--out", out,
                                "--cache-dir", data / "cache", "--set", "n_estimators=40")
    assert code == 0, err
    assert "accuracy" in stdout and "P03" in stdout and str(out) in stdout
    fold_rows = [ln.split() for ln in stdout.splitlines() if ln.split()[1:2] == ["P03"]]
    assert fold_rows and fold_rows[0][0] == "1"  # round 1, as "round 1/1" (stored as 0)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["accuracy"] > 0.6 and len(metrics["per_fold"]) == 3
    for name in ("config.json", "confusion_matrix.csv", "confusion_matrix.png"):
        assert (out / name).is_file()
    code, stdout, _ = run_cli(capsys, "evaluate", out)
    assert code == 0 and "folds mode" in stdout
    assert f"{metrics['accuracy']:.3f}" in stdout
    # a new participant's data: every fold model scores it (external mode)
    (tmp_path / "new").mkdir()
    write_participant(tmp_path / "new" / "P09.h5", "P09", 909, gestures=GESTURES3, blocks=2)
    code, stdout, _ = run_cli(capsys, "evaluate", out, "--data", tmp_path / "new",
                              "--cache-dir", data / "cache")
    assert code == 0 and "external mode" in stdout
    # re-running into the same folder resumes (nothing left to train) ...
    code, stdout, _ = run_cli(capsys, "train", "--data", data / "data", "--model", "rf",
                              "--preset", "tiny", "--eval", "lopo", "--out", out,
                              "--cache-dir", data / "cache", "--set", "n_estimators=40")
    assert code == 0 and f"{metrics['accuracy']:.3f}" in stdout
    # ... but a different run there is refused
    code, _, err = run_cli(capsys, "train", "--data", data / "data", "--model", "knn",
                           "--eval", "lopo", "--out", out, "--cache-dir", data / "cache")
    assert code == 1 and "holds a different run" in err


def test_ablate_prints_table(data, capsys, tmp_path):
    code, stdout, err = run_cli(capsys, "ablate", "--data", data / "data", "--model", "knn",
                                "--preset", "tiny", "--eval", "all-inclusive",
                                "--cache-dir", data / "cache", "--out", tmp_path / "abl")
    assert code == 0, err
    lines = stdout.strip().splitlines()
    assert lines[0].startswith("ablation: knn")
    assert [ln.split()[0] for ln in lines[2:]] == ["normal", "shear", "both"]
    assert all(float(ln.split()[1]) > 0.5 for ln in lines[2:])
    assert {p.name for p in (tmp_path / "abl").iterdir()} == {"normal", "shear", "both"}


def test_export_model_cli(data, capsys, tmp_path):
    out = tmp_path / "cnn1d"
    code, _, err = run_cli(capsys, "train", "--data", data / "data", "--model", "cnn1d",
                           "--preset", "tiny", "--eval", "all-inclusive", "--epochs", "10",
                           "--threads", "1", "--out", out, "--cache-dir", data / "cache")
    assert code == 0, err
    code, stdout, err = run_cli(capsys, "export-model", out, "--format", "onnx", "--threads", "1")
    assert code == 0, err
    assert "max |logit diff|" in stdout and "test accuracy" in stdout
    assert (out / "export" / "r0-all.onnx").is_file()
    code, stdout, err = run_cli(capsys, "export-model", out, "--format", "int8", "--threads", "1")
    assert code == 0, err
    assert "qoperator quantisation" in stdout and "KiB" in stdout
    report = json.loads((out / "export" / "int8.json").read_text())
    assert f"change {report['accuracy_change']:+.4f}" in stdout
    path = out / "export" / "r0-all.int8.onnx"
    fold = report["folds"][0]
    assert fold["path"] == str(path)
    assert fold["size_bytes"] == path.stat().st_size < fold["float_size_bytes"]
    assert fold["changed_predictions"] <= fold["n"] // 2
    # the file loads back on its own and predicts like the float fold model
    predict = load_onnx_predictor(path, threads=1)
    _, _, records, ds, learner, info = load_run_data(out, device="cpu")
    assert json.loads(predict.metadata["labels"]) == ds.label_names
    x = learner.apply_norm(learner.samples(ds)[0], records[0]["norm"])
    float_model = learner.load(path.parents[1] / "folds" / "r0-all" / "model.safetensors", info)
    with torch.no_grad():
        expected = float_model.model(torch.from_numpy(x)).argmax(1).numpy()
    assert (predict(x).argmax(1) == expected).mean() >= 0.8
    # a wrong format, or a run whose weights are gone: one-line errors
    assert "unknown export format 'fp16'" in _one_line_error(
        capsys, "export-model", out, "--format", "fp16")
    bare = tmp_path / "bare"
    shutil.copytree(out, bare, ignore=shutil.ignore_patterns("model.safetensors", "export"))
    assert "fold r0-all is finished but its model file is missing" in _one_line_error(
        capsys, "export-model", bare, "--format", "int8")
    damaged = tmp_path / "damaged"
    shutil.copytree(out, damaged, ignore=shutil.ignore_patterns("export"))
    (damaged / "folds" / "r0-all" / "model.safetensors").write_bytes(b"not weights")
    assert "not the one trained for it" in _one_line_error(capsys, "evaluate", damaged)
    fold_json = damaged / "folds" / "r0-all" / "fold.json"  # a run from before fingerprints
    record = json.loads(fold_json.read_text())
    del record["model_sha256"]
    fold_json.write_text(json.dumps(record))
    assert "cannot load model weights" in _one_line_error(capsys, "evaluate", damaged)


def _one_line_error(capsys, *argv) -> str:
    code, _, err = run_cli(capsys, *argv)
    assert code == 1
    lines = err.strip().splitlines()  # progress bar lines, then the error on its own line
    assert lines[-1].startswith("tactile-studio: error:") and "Traceback" not in err, err
    assert sum("error" in ln for ln in lines) == 1
    return lines[-1]


def test_bad_inputs_give_one_line_errors(data, capsys, tmp_path):
    d, c = data / "data", data / "cache"
    assert "unknown model 'resnet'" in _one_line_error(
        capsys, "train", "--data", d, "--model", "resnet", "--out", tmp_path / "a")
    assert "unknown option 'wings'" in _one_line_error(
        capsys, "train", "--data", d, "--model", "cnn3d", "--preset", "tiny", "--set",
        "wings=3", "--out", tmp_path / "b", "--cache-dir", c)
    assert "bad --set" in _one_line_error(
        capsys, "train", "--data", d, "--model", "rf", "--set", "oops", "--out", tmp_path / "b2")
    single = tmp_path / "single"
    single.mkdir()
    write_participant(single / "P01.h5", "P01", 3, gestures=GESTURES3, blocks=1)
    assert "at least 2 participants" in _one_line_error(
        capsys, "train", "--data", single, "--model", "rf", "--eval", "lopo",
        "--out", tmp_path / "c", "--cache-dir", c)
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    write_participant(mixed / "a.h5", "P01", 3, gestures=GESTURES3, blocks=1)
    write_pressure_session(mixed / "b.h5", "S2", [30, 30])
    assert "mismatched layouts" in _one_line_error(
        capsys, "train", "--data", mixed, "--model", "rf", "--out", tmp_path / "d",
        "--cache-dir", c)
    empty = tmp_path / "notrials"
    empty.mkdir()
    write_participant(empty / "a.h5", "P01", 3, gestures=GESTURES3, blocks=0,
                      extra_trials=[trial_record(0, "Poke", 0, 30, status="discarded")])
    assert "no trials" in _one_line_error(
        capsys, "train", "--data", empty, "--model", "rf", "--out", tmp_path / "e",
        "--cache-dir", c)
    cost = tmp_path / "cost"
    cost.mkdir()
    write_pressure_session(cost / "s1.h5", "S1", [30, 40])
    assert "pressure only" in _one_line_error(
        capsys, "train", "--data", cost, "--model", "rf", "--channels", "shear",
        "--out", tmp_path / "f", "--cache-dir", c)
    assert "no such file or folder" in _one_line_error(
        capsys, "train", "--data", tmp_path / "nowhere", "--model", "rf", "--out", tmp_path / "g")
    assert "no such run folder" in _one_line_error(capsys, "evaluate", tmp_path / "nowhere")
    assert not (tmp_path / "a").exists()  # nothing written for a run that never started


@pytest.mark.slow
def test_ctrl_c_stops_cleanly_and_keeps_finished_folds(data, tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "tactile_studio", "train", "--data", str(data / "data"),
         "--model", "cnn3d", "--preset", "tiny", "--eval", "lopo", "--epochs", "60",
         "--set", "patience=60", "--threads", "1", "--out", str(out),
         "--cache-dir", str(data / "cache")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 240
        while not list(out.glob("folds/*/fold.json")) and proc.poll() is None:
            assert time.monotonic() < deadline, "no fold finished in time"
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)  # Ctrl-C during the second fold
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    finished = list(out.glob("folds/*/fold.json"))
    assert 1 <= len(finished) < 3
    # the last line says what was kept, and where
    assert err.strip().splitlines()[-1] == (
        f"tactile-studio: training cancelled: {len(finished)} of 3 folds finished, kept in "
        f"{out}; the same --out resumes")
    partial = json.loads((out / "metrics.json").read_text())
    assert partial["complete"] is False and len(partial["per_fold"]) == len(finished)


def test_end_to_end_from_collected_sessions(capsys, tmp_path):
    """Sessions recorded by `collect --virtual-participant`, then `train` on them."""
    for p in ("P01", "P02", "P03"):
        code, _, err = run_cli(capsys, "collect", "--protocol", "shear9", "--participant", p,
                               "--virtual-participant", "--speed", "0", "--blocks", "2",
                               "--out", tmp_path / "sessions")
        assert code == 0, err
    code, stdout, err = run_cli(capsys, "train", "--data", tmp_path / "sessions", "--model", "rf",
                                "--preset", "tiny", "--eval", "lopo", "--out", tmp_path / "run",
                                "--cache-dir", tmp_path / "cache")
    assert code == 0, err
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert len(m["labels"]) == 9 and len(m["per_fold"]) == 3
    assert m["accuracy"] > 3 / 9
