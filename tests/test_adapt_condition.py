"""Adapting per person *and* condition (``--adapt person-condition``): a participant who
recorded on two surfaces (FLAT, PILLOW: one session each, like the real recordings) is
met with the statistics of each surface's session on its own. Real sessions, real folds,
real tiny training; the stored predictions are recomputed by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main
from tactile_studio.learn.data.dataset import build_dataset
from tactile_studio.learn.data.windowing import WindowSpec, cut
from tactile_studio.learn.experiments.experiment import (
    ExperimentConfig,
    prepare_inputs,
    run_experiment,
)
from tactile_studio.learn.experiments.runfolder import model_file
from tactile_studio.learn.learners.generalise import adapt_groups
from tactile_studio.learn.results.rescore import load_run_data, rescore_run

GESTURES = ("Poke", "Heavy Pat", "Twist")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("adapt_condition")
    make_dataset_folder(root / "data", participants=3, blocks=1, gestures=GESTURES,
                        conditions=("FLAT", "PILLOW"))
    make_dataset_folder(root / "flat", participants=3, blocks=2, gestures=GESTURES)
    return root


def _run(root, model: str, name: str, adapt: str, data: str = "data"):
    cfg = ExperimentConfig(data=[str(root / data)], model=model, evaluation="lopo",
                           preset="tiny", epochs=None if model == "rf" else 2, threads=1,
                           device="cpu", cache_dir=str(root / "cache"), adapt=adapt)
    return run_experiment(cfg, root / name)


def test_trials_carry_their_sessions_condition_through_cache_and_windows(data):
    fresh = build_dataset([str(data / "data")], cache_dir=str(data / "cache"))
    cached = build_dataset([str(data / "data")], cache_dir=str(data / "cache"))
    for ds in (fresh, cached):
        by_session = {u.split("#")[0]: c for u, c in zip(ds.uids, ds.trial_conditions())}
        assert by_session == {f"P0{p}_{c}.h5": c for p in (1, 2, 3) for c in ("FLAT", "PILLOW")}
    groups = adapt_groups("person-condition", cached)
    assert len(set(groups.tolist())) == 6  # 3 people x 2 surfaces
    assert np.array_equal(adapt_groups("person", cached), cached.participants)
    assert adapt_groups("none", cached) is None
    pieces, owner = cut(cached, WindowSpec(0.5, 0.5))  # long trials cut into windows
    assert len(pieces) > len(cached)
    assert np.array_equal(pieces.trial_conditions(), cached.trial_conditions()[owner])
    assert np.array_equal(cached.subset([0, 5]).trial_conditions(),
                          cached.trial_conditions()[[0, 5]])


def test_rf_standardises_each_persons_features_per_condition(data):
    run = _run(data, "rf", "rf_pc", "person-condition")
    config, _, _, ds, learner, _ = load_run_data(data / "rf_pc")
    ds, x, owner, *_ = prepare_inputs(learner, ds, config)
    groups = adapt_groups("person-condition", ds)[owner]
    for g in np.unique(groups):
        varying = x[groups == g].std(0) > 0  # constant features are only centred
        np.testing.assert_allclose(x[groups == g].mean(0), 0, atol=1e-4)
        np.testing.assert_allclose(x[groups == g][:, varying].std(0), 1, atol=1e-4)
    person = _run(data, "rf", "rf_p", "person")
    assert run.metrics["adapt"] == "person-condition"
    plain = np.concatenate([r["predictions"]["probs"] for r in person.folds])
    per_surface = np.concatenate([r["predictions"]["probs"] for r in run.folds])
    assert not np.allclose(plain, per_surface, atol=1e-3)  # the surfaces were told apart
    assert rescore_run(data / "rf_pc")["confusion_counts"] == run.metrics["confusion_counts"]


def test_a_network_adapts_to_each_persons_session_on_each_surface(data):
    _run(data, "cnn1d", "net_pc", "person-condition")
    config, _, records, ds, learner, info = load_run_data(data / "net_pc", device="cpu")
    ds, x, owner, *_ = prepare_inputs(learner, ds, config)
    conditions = ds.trial_conditions()[owner]
    for rec in records:
        person = rec["test_participants"][0]
        fitted = learner.load(model_file(rec["_dir"]), info)
        rows = ds.participants[owner] == person
        xp = learner.apply_norm(x[rows], rec["norm"])
        by_hand = np.zeros((len(xp), len(ds.label_names)), dtype=np.float32)
        for c in ("FLAT", "PILLOW"):
            on = conditions[rows] == c
            by_hand[on] = fitted.adapted(xp[on]).predict_proba(xp[on])
        stored = np.array(rec["predictions"]["probs"])
        np.testing.assert_allclose(stored, by_hand, atol=1e-4)
        pooled = fitted.adapted(xp).predict_proba(xp)
        assert not np.allclose(stored, pooled, atol=1e-3)  # not the person's pooled statistics


def test_one_condition_per_person_adapts_exactly_as_per_person(data):
    a = _run(data, "rf", "flat_p", "person", data="flat")
    b = _run(data, "rf", "flat_pc", "person-condition", data="flat")
    assert a.metrics["confusion_counts"] == b.metrics["confusion_counts"]


def test_person_condition_from_the_cli(data, capsys):
    args = ["--data", str(data / "data"), "--cache-dir", str(data / "cache")]
    assert main(["train", *args, "--model", "knn", "--preset", "tiny", "--adapt",
                 "person-condition", "--out", str(data / "knn")]) == 0
    assert "adapted to each person and condition" in capsys.readouterr().out
    config = json.loads((data / "knn" / "config.json").read_text())
    assert config["config"]["adapt"] == "person-condition"
    # a network trained as usual is scored per person and surface after the fact
    _run(data, "cnn1d", "net_plain", "none")
    assert main(["evaluate", str(data / "net_plain"), "--adapt", "person-condition"]) == 0
    assert "adapted to each person and condition" in capsys.readouterr().out
    rescored = json.loads((data / "net_plain" / "rescore.json").read_text())
    assert rescored["adapt"] == "person-condition"
    code = main(["train", *args, "--model", "rf", "--adapt", "person-condition",
                 "--eval", "all-inclusive", "--out", str(data / "bad")])
    err = capsys.readouterr().err
    assert code == 1 and "--adapt person-condition" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
