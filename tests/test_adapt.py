"""Adapting to each test person (``--adapt person``, learn/learners/generalise.py): a network's
batch-norm statistics are re-estimated on the person's own unlabelled windows (AdaBN), rf
and knn standardise every person's features by that person's own statistics. Real
folds, real tiny training; the stored predictions are recomputed by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from learn_fixtures import write_participant
from shared_runs import GESTURES

from tactile_studio.cli import main
from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.experiments.experiment import (
    ExperimentConfig,
    prepare_inputs,
)
from tactile_studio.learn.experiments.runfolder import model_file
from tactile_studio.learn.learners.generalise import person_standardised
from tactile_studio.learn.learners.train import adapt_batchnorm
from tactile_studio.learn.results.compare import compare_runs
from tactile_studio.learn.results.rescore import load_run_data, rescore_run


@pytest.fixture(scope="module")
def runs(tmp_path_factory, shared_runs):
    """Tiny lopo runs on 3 people x ``GESTURES`` (tests/shared_runs.py), a copy of ours."""
    root = tmp_path_factory.mktemp("adapt")
    names = ("net", "net_adapted", "rf", "rf_adapted", "fused_adapted", "fused_auto")
    return {"root": root, **shared_runs.copy_to(root, {n: n for n in names})}


def _batchnorm_means(model: torch.nn.Module, x: np.ndarray) -> dict[str, np.ndarray]:
    """Every batch-norm layer's mean input per channel in an eval-mode forward of ``x``
    (a layer may be called several times, e.g. once per mirror image)."""
    seen: dict[str, list[torch.Tensor]] = {}

    def keep(name: str, value: torch.Tensor) -> None:
        dims = [d for d in range(value.dim()) if d != 1]
        seen.setdefault(name, []).append(value.mean(dim=dims))

    hooks = [m.register_forward_hook(lambda mod, inp, out, n=name: keep(n, inp[0]))
             for name, m in model.named_modules()
             if isinstance(m, torch.nn.modules.batchnorm._BatchNorm)]
    with torch.no_grad():
        model.eval()(torch.from_numpy(x))
    for h in hooks:
        h.remove()
    return {k: torch.stack(v).mean(0).numpy() for k, v in seen.items()}


def test_adapted_batchnorm_holds_the_persons_statistics_and_leaves_the_model_alone(runs):
    config, _, records, ds, learner, info = load_run_data(runs["root"] / "net", device="cpu")
    ds, x, owner, *_ = prepare_inputs(learner, ds, config)
    fitted = learner.load(model_file(records[0]["_dir"]), info)
    xp = learner.apply_norm(x[ds.participants[owner] == "P01"], records[0]["norm"])
    before = {k: v.clone() for k, v in fitted.model.state_dict().items()}
    adapted = adapt_batchnorm(fitted.model, xp)
    inputs = _batchnorm_means(adapted, xp)
    assert inputs  # the model has batch-norm layers, so the check below means something
    layers = dict(adapted.named_modules())
    for name, mean in inputs.items():  # (training-mode passes normalise by the biased
        # variance, eval mode by the stored unbiased one: a layer's input moves slightly)
        np.testing.assert_allclose(layers[name].running_mean.numpy(), mean, atol=5e-3)
    for key, value in fitted.model.state_dict().items():  # the trained model is untouched
        assert torch.equal(value, before[key]), key
    assert not torch.allclose(adapted.state_dict()[next(iter(inputs)) + ".running_mean"],
                              before[next(iter(inputs)) + ".running_mean"])
    one = adapt_batchnorm(fitted.model, xp[:1])  # one sample: nothing to estimate
    for key, value in one.state_dict().items():
        assert torch.equal(value, before[key]), key


def test_an_adapted_network_predicts_each_person_after_adapting_to_them(runs):
    root = runs["root"]
    config, _, records, ds, learner, info = load_run_data(root / "net_adapted", device="cpu")
    ds, x, owner, *_ = prepare_inputs(learner, ds, config)
    for rec in records:
        person = rec["test_participants"][0]
        xp = learner.apply_norm(x[ds.participants[owner] == person], rec["norm"])
        fitted = learner.load(model_file(rec["_dir"]), info)
        by_hand = fitted.adapted(xp).predict_proba(xp)
        stored = np.array(rec["predictions"]["probs"])
        np.testing.assert_allclose(stored, by_hand, atol=1e-4)
        assert not np.allclose(stored, fitted.predict_proba(xp), atol=1e-3)  # it adapted
    metrics = json.loads((root / "net_adapted" / "metrics.json").read_text())
    assert metrics["adapt"] == "person" and "adapt" not in runs["net"].metrics
    rescored = rescore_run(root / "net_adapted")  # evaluate adapts the same way
    assert rescored["confusion_counts"] == metrics["confusion_counts"]
    assert rescored["adapt"] == "person"
    compared = compare_runs(root / "net", root / "net_adapted")  # named by what differs
    assert (compared["name_a"], compared["name_b"]) == ("as trained", "adapted")
    assert compared["config_difference"] == ["adapt: none → person"]


def test_rf_standardises_every_persons_features_by_their_own(runs):
    rng = np.random.default_rng(0)
    x = rng.normal(3.0, 2.0, (12, 4)).astype(np.float32)
    x[:, 3] = 7.0  # constant: only centred
    people = np.array(["A"] * 5 + ["B"] * 7)
    z = person_standardised(x, people)
    for p in ("A", "B"):
        np.testing.assert_allclose(z[people == p, :3].mean(0), 0, atol=1e-5)
        np.testing.assert_allclose(z[people == p, :3].std(0), 1, atol=1e-5)
    assert np.all(z[:, 3] == 0)
    root = runs["root"]
    plain = np.concatenate([r["predictions"]["probs"] for r in runs["rf"].folds])
    adapted = np.concatenate([r["predictions"]["probs"] for r in runs["rf_adapted"].folds])
    assert plain.shape == adapted.shape and not np.allclose(plain, adapted, atol=1e-3)
    rescored = rescore_run(root / "rf_adapted")
    assert rescored["confusion_counts"] == runs["rf_adapted"].metrics["confusion_counts"]


def test_a_fused_model_adapts_both_parts_and_evaluates_the_same(runs):
    root = runs["root"]
    rescored = rescore_run(root / "fused_adapted")
    metrics = runs["fused_adapted"].metrics
    assert rescored["confusion_counts"] == metrics["confusion_counts"]
    assert metrics["adapt"] == "person" and metrics["rf_weight"] == 0.5


def test_auto_adapts_a_fused_network_and_keeps_its_forest_as_trained(runs):
    """On real people standardising a forest's features per person cost rf 1.7 points,
    so ``--adapt auto`` keeps a fused model's forest as rf alone is kept (``rf_adapt=0``,
    recorded in the run) while its network adapts; ``--adapt person`` adapts both, as
    every fused run before the option did."""
    from dataclasses import replace

    from tactile_studio.learn.learners.families import make_learner

    def overrides(adapt: str, **given) -> dict:
        cfg = ExperimentConfig(data=[], model="cnn1d", adapt=adapt,
                               overrides={"rf_weight": 0.5, **given})
        return cfg.resolved().overrides

    assert overrides("auto") == {"rf_weight": 0.5, "rf_adapt": 0}
    assert overrides("person") == {"rf_weight": 0.5}  # as before: both parts adapt
    assert overrides("auto", rf_adapt=1)["rf_adapt"] == 1  # asked for: kept
    with pytest.raises(UserError, match="rf_adapt"):
        make_learner("cnn1d", "tiny", {"rf_weight": 0.5, "rf_adapt": "2"})
    root = runs["root"]
    config, _, _, ds, learner, _ = load_run_data(root / "fused_auto", device="cpu")
    assert config.adapt == "person" and config.overrides["rf_adapt"] == 0
    _, kept, _, _, _, _, moments = prepare_inputs(learner, ds, config)
    _, plain, *_ = prepare_inputs(learner, ds, replace(config, adapt="none"))
    assert moments is None and np.array_equal(kept, plain)  # the forest's features as trained
    both = make_learner("cnn1d", "tiny", {"rf_weight": 0.5}, 2, "cpu")
    _, standardised, _, _, _, _, moments = prepare_inputs(both, ds, config)
    assert moments is not None and not np.array_equal(standardised, plain)
    live = WindowModel(root / "fused_auto", ds.participants[0])
    assert not live.reads_person_features and live.has_view_as_trained
    assert WindowModel(root / "fused_adapted", ds.participants[0]).reads_person_features
    rescored = rescore_run(root / "fused_auto")
    assert rescored["confusion_counts"] == runs["fused_auto"].metrics["confusion_counts"]


def test_adapt_from_the_cli_and_its_one_line_errors(runs, capsys):
    root = runs["root"]
    code = main(["train", "--data", str(root / "data"), "--model", "rf", "--preset", "tiny",
                 "--adapt", "person", "--augment", "flip", "--cache-dir", str(root / "cache"),
                 "--out", str(root / "bad")])
    err = capsys.readouterr().err
    assert code == 1 and "--adapt person" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    with pytest.raises(UserError, match="unknown adaptation"):
        ExperimentConfig(data=[], model="rf", adapt="people").validate()
    with pytest.raises(UserError, match="holds whole people out"):
        ExperimentConfig(data=[], model="cnn1d", adapt="person",
                         evaluation="all-inclusive").validate()
    code = main(["train", "--data", str(root / "data"), "--model", "knn", "--preset", "tiny",
                 "--adapt", "person", "--cache-dir", str(root / "cache"),
                 "--out", str(root / "knn")])
    assert code == 0
    config = json.loads((root / "knn" / "config.json").read_text())
    assert config["config"]["adapt"] == "person"
    assert "adapted to each person" in capsys.readouterr().out


def test_train_adapts_every_model_to_held_out_people_by_default(runs, capsys):
    root = runs["root"]
    args = ["train", "--data", str(root / "data"), "--model", "cnn1d", "--preset", "tiny",
            "--epochs", "2", "--threads", "1", "--device", "cpu",
            "--cache-dir", str(root / "cache"), "--out", str(root / "default")]
    assert main(args) == 0
    assert "adapted to each person" in capsys.readouterr().out
    config = json.loads((root / "default" / "config.json").read_text())["config"]
    assert config["adapt"] == "person"  # recorded as resolved: resumes and compares so
    saved = json.loads((root / "default" / "metrics.json").read_text())
    assert saved["confusion_counts"] == runs["net_adapted"].metrics["confusion_counts"]

    def resolved(model: str, evaluation: str = "lopo", augment: str = "", **overrides) -> str:
        cfg = ExperimentConfig(data=[], model=model, evaluation=evaluation, adapt="auto",
                               augment=augment, overrides=overrides)
        cfg.validate()
        return cfg.resolved().adapt

    assert resolved("cnn1d") == resolved("mts3d", "group-kfold") == "person"
    assert resolved("cnn1d", rf_weight=0.5) == "person"  # a network, fused with rf or not
    # on the real recordings adapting cost rf 1.7 points: forests stay as trained
    assert resolved("rf") == resolved("knn") == resolved("rf", "group-kfold") == "none"
    assert resolved("cnn1d", augment="scale") == "person"
    # augmented windows have no person's statistics for a forest's features; a fused
    # model's network adapts all the same, its forest kept as trained (rf_adapt=0)
    assert resolved("rf", augment="scale") == resolved("cnn1d", augment="scale",
                                                       rf_weight=0.5, rf_adapt=1) == "none"
    assert resolved("cnn1d", augment="scale", rf_weight=0.5) == "person"
    assert resolved("cnn1d", "all-inclusive") == resolved("rf", "all-inclusive") == "none"
    explicit = ExperimentConfig(data=[], model="cnn1d", adapt="none", shots_by="join")
    assert explicit.resolved() is explicit  # nothing left to resolve: the config itself
    assert ExperimentConfig(data=[], model="cnn1d", adapt="none").resolved().adapt == "none"


def test_export_and_live_say_what_an_adapted_run_needs(runs, capsys):
    root = runs["root"]
    code = main(["export-model", str(root / "net_adapted"), "--format", "onnx"])
    out = capsys.readouterr().out
    assert code == 0 and "note: the run adapted to each person" in out
    assert "batch-norm statistics" in out
    report = json.loads((root / "net_adapted" / "export" / "onnx.json").read_text())
    assert report["adapt"] == "person" and report["changed_predictions"] == 0
    assert WindowModel(root / "net_adapted").learner.kind == "torch"  # trained statistics
    rf = WindowModel(root / "rf_adapted")  # the person's statistics, or the pooled view
    assert rf.reads_person_features and rf.has_view_as_trained and not rf.needs_calibration


def test_a_run_folder_from_before_adapt_existed_still_resumes(runs, capsys):
    root = runs["root"]
    args = ["train", "--data", str(root / "data"), "--model", "rf", "--preset", "tiny",
            "--cache-dir", str(root / "cache"), "--out", str(root / "old")]
    assert main([*args, "--adapt", "none"]) == 0
    path = root / "old" / "config.json"
    config = json.loads(path.read_text())
    del config["config"]["adapt"]  # as written by the version before --adapt
    path.write_text(json.dumps(config))
    capsys.readouterr()
    assert main([*args, "--adapt", "none"]) == 0, capsys.readouterr().err  # every fold loaded
    assert main(args) == 0  # today's default leaves a forest as trained, as the old run did
    assert main([*args, "--adapt", "person"]) == 1  # not what the old run did
    assert "differs in adapt: 'none' there, 'person' now" in capsys.readouterr().err


def test_evaluate_adapts_any_trained_network_after_the_fact(runs, capsys):
    root = runs["root"]
    # net and net_adapted trained alike (adaptation happens only when predicting), so a
    # plain run evaluated with --adapt person scores exactly as the adapted run
    assert main(["evaluate", str(root / "net"), "--adapt", "person"]) == 0
    assert "adapted to each person" in capsys.readouterr().out
    rescored = json.loads((root / "net" / "rescore.json").read_text())
    assert rescored["adapt"] == "person"
    assert rescored["confusion_counts"] == runs["net_adapted"].metrics["confusion_counts"]
    assert rescore_run(root / "net_adapted", adapt="none")["confusion_counts"] == \
        runs["net"].metrics["confusion_counts"]
    code = main(["evaluate", str(root / "rf"), "--adapt", "person"])
    err = capsys.readouterr().err
    assert code == 1 and "cannot be re-standardised" in err and "Traceback" not in err


def test_evaluate_adapts_an_all_inclusive_run_only_to_new_people(runs, capsys):
    root = runs["root"]
    code = main(["train", "--data", str(root / "data"), "--model", "cnn1d", "--preset", "tiny",
                 "--epochs", "1", "--eval", "all-inclusive", "--cache-dir", str(root / "cache"),
                 "--out", str(root / "inclusive")])
    assert code == 0
    capsys.readouterr()
    # its test trials belong to people it trained on: adapting to them is no measurement
    code = main(["evaluate", str(root / "inclusive"), "--adapt", "person"])
    err = capsys.readouterr().err
    assert code == 1 and "all-inclusive" in err and "Traceback" not in err
    assert len([line for line in err.splitlines() if "error" in line]) == 1
    assert not (root / "inclusive" / "rescore.json").exists()
    # a new person's session: the deployed model meets them with their own statistics
    (root / "new").mkdir()
    write_participant(root / "new" / "P09.h5", "P09", 909, GESTURES, blocks=2)
    code = main(["evaluate", str(root / "inclusive"), "--adapt", "person",
                 "--data", str(root / "new"), "--cache-dir", str(root / "cache")])
    assert code == 0, capsys.readouterr().err
    rescored = json.loads((root / "inclusive" / "rescore.json").read_text())
    assert (rescored["mode"], rescored["adapt"]) == ("external", "person")
