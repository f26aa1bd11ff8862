"""A learned model fused with the random forest (``--set rf_weight=W``, learn/learners/fused.py):
trained side by side on real folds, its probabilities are exactly the weighted mean of the
network's and the forest's alone (same seeds), and it evaluates, exports and predicts live
windows like any model."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.learn.experiments.train_job import model_settings
from tactile_studio.learn.learners.contract import LEARNER_MEMBERS, Learner
from tactile_studio.learn.learners.families import make_learner
from tactile_studio.learn.results.compare import compare_runs


@pytest.fixture(scope="module")
def runs(tmp_path_factory, shared_runs):
    """rf (basic features), cnn1d and cnn1d fused with rf 0.3 on 3 people x 3 gestures
    (tests/shared_runs.py), a copy of ours."""
    root = tmp_path_factory.mktemp("fused")
    return {"root": root, **shared_runs.copy_to(root, {"rf": "rf_basic", "fused": "fused_03",
                                                       "net": "net"})}


def test_fused_probabilities_are_the_weighted_mean_of_network_and_forest(runs):
    folds = zip(runs["rf"].folds, runs["net"].folds, runs["fused"].folds)
    for rf, net, fused in folds:
        p_rf, p_net, p_fused = (np.array(r["predictions"]["probs"]) for r in (rf, net, fused))
        assert p_fused.shape == p_net.shape and p_rf.shape[0] == p_net.shape[0]
        np.testing.assert_allclose(p_fused, 0.7 * p_net + 0.3 * p_rf, atol=2e-5)
        assert not np.allclose(p_fused, p_net, atol=1e-3)  # the forest did count
    fold_dir = runs["root"] / "fused" / "folds" / "r0-P01"
    assert (fold_dir / "model.safetensors").is_file() and (fold_dir / "rf.onnx").is_file()
    config = json.loads((runs["root"] / "fused" / "config.json").read_text())
    model = config["resolved"]["model"]
    assert model["kind"] == "fused" and model["rf_weight"] == 0.3
    assert model["rf"]["kind"] == "baseline" and "rf_weight" not in model["model_options"]
    names = compare_runs(runs["root"] / "rf", runs["root"] / "fused")
    assert (names["name_a"], names["name_b"]) == ("rf", "cnn1d + rf 0.3")


def test_a_fused_run_evaluates_and_exports_with_the_same_figures(runs, capsys):
    run = runs["root"] / "fused"
    metrics = json.loads((run / "metrics.json").read_text())
    assert main(["evaluate", str(run)]) == 0
    out = capsys.readouterr().out
    assert f"{metrics['accuracy']:.3f}" in out and "cnn1d + rf 0.3 ·" in out
    assert metrics["rf_weight"] == 0.3
    assert main(["export-model", str(run), "--format", "onnx"]) == 0
    report = json.loads((run / "export" / "onnx.json").read_text())
    assert report["accuracy_torch"] == pytest.approx(metrics["accuracy"])
    assert report["accuracy_export"] == pytest.approx(metrics["accuracy"])
    assert report["changed_predictions"] == 0 and "+ rf" in report["model"]
    for fold in report["folds"]:
        assert fold["rf_path"].endswith(".rf.onnx")
    capsys.readouterr()
    assert main(["export-model", str(run), "--format", "int8"]) == 1
    assert "exports as onnx only" in capsys.readouterr().err


def test_live_windows_of_a_fused_run_use_both_models(runs):
    model = WindowModel(runs["root"] / "fused")
    alone = WindowModel(runs["root"] / "net")
    assert not model.streams  # the forest needs the whole window
    rng = np.random.default_rng(0)
    windows = [np.abs(rng.normal(0, 2, (3, 86, 6, 6))).astype(np.float32) for _ in range(2)]
    from tactile_studio.sensor import SHEARSENSE_6X6

    fused = model.predict_windows(SHEARSENSE_6X6, windows, 43.0)
    net = alone.predict_windows(SHEARSENSE_6X6, windows, 43.0)
    assert fused.shape == (2, 3) and np.allclose(fused.sum(axis=1), 1, atol=1e-5)
    assert not np.allclose(fused, net, atol=1e-3)


@pytest.mark.parametrize("value", ["1", "-0.2", "half"])
def test_bad_rf_weights_are_one_line_errors(value):
    with pytest.raises(UserError, match="rf_weight"):
        make_learner("cnn1d", "tiny", {"rf_weight": value})


def test_rf_weight_is_for_learned_models_only_and_listed_in_their_options(capsys, runs):
    with pytest.raises(UserError, match="not a learned model"):
        make_learner("rf", "tiny", {"rf_weight": 0.5})
    assert make_learner("cnn1d", "tiny", {"rf_weight": 0}).kind == "torch"
    fused = make_learner("cnn1d", "tiny", {"rf_weight": 0.5})
    assert isinstance(fused, Learner) and fused.kind == "fused"
    assert [m for m in LEARNER_MEMBERS if not hasattr(fused, m)] == []
    options = {k: (v, h) for k, v, h in model_settings("cnn1d", "tiny")}
    assert options["rf_weight"][0] == 0.0 and "random forest" in options["rf_weight"][1]
    code = main(["train", "--data", str(runs["root"] / "data"), "--model", "knn",
                 "--set", "rf_weight=0.5", "--out", str(runs["root"] / "bad")])
    assert code == 1 and "not a learned model" in capsys.readouterr().err


def test_a_fused_sweep_task_brings_both_model_files_back(runs, tmp_path):
    from tactile_studio.learn.experiments.executors import LocalExecutor
    from tactile_studio.learn.experiments.sweep import format_rows, run_sweep

    base = ExperimentConfig(data=[str(runs["root"] / "data")], model="cnn1d", evaluation="lopo",
                            preset="tiny", epochs=2, device="cpu", overrides={"rf_weight": 0.3},
                            cache_dir=str(runs["root"] / "cache"))
    with LocalExecutor(1) as ex:
        result = run_sweep(base, ["cnn1d"], [None], ex, tmp_path / "sweep")
    run = result.rows[0]["run"]
    # the table names the fusion: a fused row is not mistaken for the network alone
    assert result.rows[0]["name"] == "cnn1d + rf 0.3"
    assert "cnn1d + rf 0.3" in format_rows(result.rows)
    assert "cnn1d + rf 0.3" in (tmp_path / "sweep" / "results.csv").read_text()
    for fold in ("r0-P01", "r0-P02", "r0-P03"):
        names = sorted(p.name for p in (tmp_path / "sweep" / "runs").glob(f"*/folds/{fold}/*"))
        assert names == ["fold.json", "model.safetensors", "rf.onnx"]
    # the same seeds give the same fused predictions in a worker as in-process
    swept = json.loads((next((tmp_path / "sweep" / "runs").glob("*/metrics.json"))).read_text())
    trained = json.loads((runs["root"] / "fused" / "metrics.json").read_text())
    assert swept["confusion_counts"] == trained["confusion_counts"]
    assert WindowModel(run).learner.kind == "fused"
