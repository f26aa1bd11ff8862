"""Exporting a run scores the same windows training did: on 6 s performances cut into
2 s windows, the export report's reference accuracy per window and per trial equals the
run's metrics.json, for a baseline (rf, recorded probabilities) and a torch model (cnn1d);
the vote aggregate gives the run's vote figures."""

from __future__ import annotations

import json

import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main as cli_main
from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.export_run import export_run
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.learn.learners.baselines import BASELINES

GESTURES = ("Poke", "Circular Stroke", "Heavy Pat")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("export-windows")
    make_dataset_folder(root / "data", participants=3, blocks=2, gestures=GESTURES,
                        trial_s=6.0)
    return root


def _run(data, model: str, name: str, **kw):
    torch_model = model not in BASELINES
    cfg = ExperimentConfig(data=[str(data / "data")], model=model, evaluation="lopo",
                           preset="tiny", epochs=4 if torch_model else None,
                           cache_dir=str(data / "cache"), threads=1,
                           overrides={"lr": "0.01"} if torch_model else {}, **kw)
    out = data / name
    return run_experiment(cfg, out).metrics, out


@pytest.mark.parametrize("model", ["rf", "cnn1d"])
def test_export_scores_windows_and_matches_metrics_json(data, model):
    metrics, out = _run(data, model, f"run-{model}")
    assert metrics["windows"] > metrics["n_trials"] == 18  # 6 s trials became windows
    report = export_run(out, "onnx", threads=1)
    saved = json.loads((out / "metrics.json").read_text())
    assert report["n"] == sum(f["n"] for f in report["folds"]) == saved["windows"]
    assert report["n_trials"] == saved["n_trials"] == 18
    assert report["accuracy_torch"] == pytest.approx(saved["accuracy"], abs=1e-9)
    assert report["trial_accuracy_torch"] == pytest.approx(saved["trial_accuracy"], abs=1e-9)
    assert report["changed_predictions"] <= 1  # float ONNX = the model
    assert report["accuracy_export"] == pytest.approx(report["accuracy_torch"],
                                                      abs=1 / report["n"] + 1e-9)
    for fold, per_fold in zip(report["folds"], saved["per_fold"]):
        assert fold["accuracy_torch"] == pytest.approx(per_fold["accuracy"], abs=1e-9)
        assert fold["trial_accuracy_torch"] == pytest.approx(per_fold["trial_accuracy"],
                                                             abs=1e-9)
        assert fold["n_trials"] == per_fold["n_test_trials"] == 6


def test_vote_aggregate_matches_a_vote_run_and_bad_aggregate(data, capsys):
    metrics, out = _run(data, "rf", "run-rf-vote", aggregate="vote")
    report = export_run(out, "onnx")
    assert report["aggregate"] == "vote"
    assert report["trial_accuracy_torch"] == pytest.approx(metrics["trial_accuracy"], abs=1e-9)
    with pytest.raises(UserError, match="unknown aggregate"):
        export_run(out, "onnx", aggregate="median")
    assert cli_main(["export-model", str(out), "--format", "onnx", "--aggregate", "mean"]) == 0
    printed = capsys.readouterr().out
    assert "trial accuracy (mean over windows)" in printed and "18 trials" in printed
