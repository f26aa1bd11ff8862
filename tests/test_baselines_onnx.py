"""rf and k-NN are ONNX files (skl2onnx) run by onnxruntime, predicting like scikit-learn.

The data is the pipeline's own: handcrafted features of simulated participants' trials,
split leave-one-participant-out, so the comparison is on real test sets.
Budget: about 15 s on 2 shared cores.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.errors import UserError
from tactile_studio.learn.data.dataset import build_dataset
from tactile_studio.learn.data.features import feature_matrix
from tactile_studio.learn.deploy.export_run import export_run
from tactile_studio.learn.deploy.streaming import StreamingPredictor
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.learn.learners.baselines import BaselineModel, baseline_options
from tactile_studio.learn.learners.families import DataInfo
from tactile_studio.learn.results.rescore import rescore_run


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("baselines")
    make_dataset_folder(root / "data", participants=3, blocks=2)
    ds = build_dataset([str(root / "data")], "physical", None, str(root / "cache"), True)
    x, _ = feature_matrix(ds.trials, ds.channel_names, ds.rates)
    return root, ds, x


def _splits(ds):
    people = np.array(ds.participants)
    for p in sorted(set(people)):
        yield people != p, people == p


@pytest.mark.parametrize("name,options", [
    ("rf", {"n_estimators": "40"}),
    ("et", {"n_estimators": "40"}),
    ("knn", {}),  # distance-weighted, the preset
    ("knn", {"weights": "uniform", "n_neighbors": "3"}),
])
def test_onnx_predicts_like_scikit_learn_on_test_sets(data, tmp_path, name, options):
    _, ds, x = data
    info = DataInfo.of(ds)
    opts = baseline_options(name, "tiny", options)
    for k, (train, test) in enumerate(_splits(ds)):
        model = BaselineModel(name, opts, ds.n_classes).fit(x[train], ds.labels[train], seed=k)
        labels, probs = model.predict_labels_and_proba(x[test])
        np.testing.assert_array_equal(labels, model.estimator.predict(x[test]))
        np.testing.assert_allclose(probs, model.sklearn_predict_proba(x[test]), atol=1e-5)
        assert probs.shape == (test.sum(), ds.n_classes)
        model.save(tmp_path / "model.onnx")  # the file alone predicts the same
        back = BaselineModel.load(tmp_path / "model.onnx", name, opts, info.n_classes)
        np.testing.assert_array_equal(back.predict_proba(x[test]), probs)
        assert json.loads(back.metadata["classes"]) == sorted(set(ds.labels[train].tolist()))


def test_a_class_missing_from_training_gets_zero_probability():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(80, 6))
    y = (x[:, 0] > 0).astype(int) + 2 * (x[:, 1] > 0.5)  # classes 0..3 of 5
    for name in ("rf", "knn"):
        model = BaselineModel(name, baseline_options(name, "tiny", {}), 5).fit(x, y, seed=1)
        probs = model.predict_proba(rng.normal(size=(30, 6)))
        assert probs.shape == (30, 5) and not probs[:, 4].any()
        np.testing.assert_allclose(probs.sum(axis=1), 1.0, atol=1e-5)


def test_damaged_model_file_is_a_one_line_error(tmp_path):
    bad = tmp_path / "model.onnx"
    bad.write_bytes(b"not a model")
    with pytest.raises(UserError, match="damaged or unreadable model file"):
        BaselineModel.load(bad, "rf", baseline_options("rf", "tiny", {}), 5)
    with pytest.raises(UserError, match="no such model file"):
        BaselineModel.load(tmp_path / "nope.onnx", "rf", baseline_options("rf", "tiny", {}), 5)


@pytest.mark.parametrize("name", ["rf", "et", "knn"])
def test_run_folder_holds_onnx_that_evaluate_export_and_streaming_load(data, name):
    root, ds, _ = data
    cfg = ExperimentConfig(data=[str(root / "data")], model=name, evaluation="lopo",
                           preset="tiny", cache_dir=str(root / "cache"), seed=0)
    out = root / f"run-{name}"
    result = run_experiment(cfg, out)
    folds = sorted((out / "folds").glob("r0-*"))
    assert folds and all((f / "model.onnx").is_file() for f in folds)
    assert not list((out / "folds").glob("*/model.safetensors"))
    again = rescore_run(out)  # onnxruntime on the saved files reproduces the run
    assert again["accuracy"] == pytest.approx(result.metrics["accuracy"])
    report = export_run(out, "onnx")
    assert report["changed_predictions"] == 0 and report["folds"][0]["max_abs_diff"] < 1e-4
    exported = out / "export" / f"{folds[0].name}.onnx"
    model = BaselineModel.load(exported, name, baseline_options(name, "tiny", {}), ds.n_classes)
    assert json.loads(model.metadata["labels"]) == ds.label_names
    with pytest.raises(UserError, match="onnx only"):
        export_run(out, "int8")
    # a run trained before rf/knn became ONNX files: a clear one-line error
    old = root / f"old-{name}"
    shutil.copytree(out, old)
    for f in (old / "folds").glob("*/model.onnx"):
        f.rename(f.with_name("model.safetensors"))
    with pytest.raises(UserError, match="train again"):
        rescore_run(old)
    # streaming: the newest window of frames -> features -> the ONNX model
    trial = ds.trials[0]  # (C, T, R, X)
    predictor = StreamingPredictor(model, None, window=trial.shape[1], rate=float(ds.rates[0]))
    outputs = predictor.push_many(trial.transpose(1, 0, 2, 3))
    assert len(outputs) == 1
    np.testing.assert_allclose(outputs[0], model.predict_trial(trial, float(ds.rates[0])))
    x_one, _ = feature_matrix([trial], ds.channel_names, ds.rates[:1],
                              touch=model.options["features"] == "touch")
    np.testing.assert_allclose(outputs[0], model.predict_proba(x_one)[0])
