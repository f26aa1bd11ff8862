"""Few-shot personalisation (``train --shots``): K labelled performances per gesture of
the held-out person join the training; split by performance, never by window."""

from __future__ import annotations

import json

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main
from tactile_studio.errors import UserError
from tactile_studio.learn.data.dataset import read_sessions
from tactile_studio.learn.data.splits import lopo, with_shots
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment

GESTURES3 = ("Poke", "Heavy Pat", "Back & Forth Rub")


@pytest.fixture(scope="module")
def long_trials(tmp_path_factory):
    """3 people x 3 gestures x 3 performances of 6 s (each cut into 2 s windows)."""
    root = tmp_path_factory.mktemp("shots")
    make_dataset_folder(root / "data", participants=3, blocks=3, gestures=GESTURES3, repeats=3)
    return root


def test_shot_folds_add_whole_performances_of_the_test_person():
    labels = np.array([0, 1, 2] * 4 + [0, 1, 2] * 4)
    people = np.array(["A"] * 12 + ["B"] * 12)
    folds = with_shots(lopo(labels, people, 0), labels, (0, 1, 2), seed=3)
    assert [f.name for f in folds] == ["A k0", "A k1", "A k2", "B k0", "B k1", "B k2"]
    for base, one, two in (folds[0:3], folds[3:6]):
        assert base.shots == 0 and one.shots == 1 and two.shots == 2
        # every K tests on the same trials: those never drawn as a shot
        assert np.array_equal(base.test, one.test) and np.array_equal(one.test, two.test)
        assert len(base.test) == 12 - 3 * 2
        added1, added2 = np.setdiff1d(one.train, base.train), np.setdiff1d(two.train, base.train)
        assert sorted(labels[added1]) == [0, 1, 2] and sorted(labels[added2]) == [0, 0, 1, 1, 2, 2]
        assert set(added1) <= set(added2)  # K = 2 adds one more to K = 1's
        assert set(people[added2]) == set(base.test_participants)
        for f in (base, one, two):
            assert not set(f.train) & set(f.test) and not set(f.val) & set(f.test)


def test_a_gesture_keeps_one_performance_to_test():
    labels = np.array([0, 1, 1, 1, 0, 1, 1, 1])
    people = np.array(["A"] * 4 + ["B"] * 4)
    folds = with_shots(lopo(labels, people, 0), labels, (0, 2), seed=0)
    for f in folds:
        assert {0, 1} <= set(labels[f.test])  # gesture 0 has one trial: never a shot


def test_run_curve_and_no_window_leaks(long_trials):
    ds = read_sessions([long_trials / "data"]).select(None)
    cfg = ExperimentConfig(data=["unused"], model="rf", evaluation="lopo", preset="tiny",
                           window_s=2.0, shots=(0, 1), overrides={"n_estimators": 30})
    result = run_experiment(cfg, dataset=ds)
    m = result.metrics
    assert [s["k"] for s in m["shots"]] == [0, 1]
    # per person 2 of 3 per gesture
    assert m["shots"][0]["n_trials"] == m["shots"][1]["n_trials"] == 3 * 3 * 2
    assert m["trial_accuracy"] == m["shots"][0]["trial_accuracy"]
    assert m["shots"][0]["n"] > m["shots"][0]["n_trials"]  # windows, several per trial
    assert len(m["per_fold"]) == 6 and {f["shots"] for f in m["per_fold"]} == {0, 1}
    for rec in result.folds:
        train, test = set(rec["train"]) | set(rec["val"]), set(rec["test"])
        assert not train & test
        # every test window belongs to a test performance: none of a trained one
        owners = {ds.uids[i] for i in rec["predictions"]["owner"]}
        assert owners <= test and not owners & train


def test_cli_prints_the_curve_and_refuses_all_inclusive(long_trials, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["train", "--data", str(long_trials / "data"), "--model", "rf", "--preset",
                 "tiny", "--eval", "lopo", "--shots", "0,1", "--out", str(out), "--set",
                 "n_estimators=30", "--cache-dir", str(tmp_path / "cache")])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    assert "few-shot personalisation" in stdout and "points vs K=0" in stdout
    metrics = json.loads((out / "metrics.json").read_text())
    # the headline (the progress line's last) says the test set is not a plain run's:
    # "accuracy 0.556 (K=0, 45 trials)" stood beside a plain run's 0.504 (135) unsaid
    n, total = metrics["n_trials"], metrics["data_trials"]
    assert n < total
    assert f" at K=0, {n} of {total} trials tested (" in err  # the last progress line
    assert f"{n} test trials at every K; without --shots all {total} are tested" in stdout
    assert [s["k"] for s in metrics["shots"]] == [0, 1]
    assert json.loads((out / "config.json").read_text())["config"]["shots"] == [0, 1]
    with pytest.raises(UserError, match="all-inclusive"):
        ExperimentConfig(data=["x"], model="rf", evaluation="all-inclusive",
                         shots=(0, 1)).validate()
    with pytest.raises(SystemExit):
        main(["train", "--data", "x", "--model", "rf", "--out", "y", "--shots", "1,1"])
    assert "distinct" in capsys.readouterr().err


def test_compare_reads_the_curve(long_trials, tmp_path, capsys):
    runs = []
    for model in ("rf", "knn"):
        out = tmp_path / model
        assert main(["train", "--data", str(long_trials / "data"), "--model", model,
                     "--preset", "tiny", "--eval", "lopo", "--shots", "0,1", "--out", str(out),
                     "--cache-dir", str(tmp_path / "cache")]) == 0
        runs.append(out)
    capsys.readouterr()
    from tactile_studio.learn.results.compare import compare_runs
    r = compare_runs(*runs)
    assert [s["k"] for s in r["shots"]] == [0, 1]
    assert r["n_matched"] == r["shots"][0]["n_matched"] == 18  # each trial once, at K = 0
    assert main(["compare", str(runs[0]), str(runs[1])]) == 0
    assert "with 1 shot(s) per gesture:" in capsys.readouterr().out


def _ft_config(ds_path, shots_by: str, model: str = "cnn1d", **kw) -> ExperimentConfig:
    return ExperimentConfig(data=[str(ds_path)], model=model, evaluation="lopo",
                            preset="tiny", window_s=2.0, shots=(0, 1, 2), shots_by=shots_by,
                            epochs=2, **kw)


def test_fine_tune_trains_each_fold_once_and_tests_what_join_tests(long_trials):
    """--shots-by fine-tune: one training per held-out person (K = 0), each K > 0 its
    copy fine-tuned on that K's shot performances; the same test trials as join, and no
    window of a shot performance in the test."""
    ds = read_sessions([long_trials / "data"]).select(None)
    trained: list[str] = []  # the folds whose training ran epochs
    from tactile_studio.learn.experiments.job_events import Epoch

    def listen(event) -> None:
        if isinstance(event, Epoch) and event.fold_name not in trained:
            trained.append(event.fold_name)

    fine = run_experiment(_ft_config(long_trials, "fine-tune"), dataset=ds, listener=listen)
    assert trained == ["P01 k0", "P02 k0", "P03 k0"]  # K = 0 once per person, nothing else
    join = run_experiment(_ft_config(long_trials, "join"), dataset=ds)
    assert [r["name"] for r in fine.folds] == [r["name"] for r in join.folds] == [
        f"P0{p} k{k}" for p in (1, 2, 3) for k in (0, 1, 2)]
    for f, j in zip(fine.folds, join.folds):
        assert f["test"] == j["test"] and f["train"] == j["train"] and f["shots"] == j["shots"]
        assert f["predictions"]["owner"] == j["predictions"]["owner"]
        if f["shots"]:  # fine-tuned on exactly the windows of its shot performances
            shots = set(f["train"]) - set(fine.folds[f["fold"] - f["shots"]]["train"])
            assert len(shots) == 3 * f["shots"]
            owners = {ds.uids[i] for i in f["predictions"]["owner"]}
            assert not owners & shots and owners <= set(f["test"])
            assert f["fine_tuned_windows"] == 3 * f["shots"] * 5  # 6 s -> five 2 s windows
            assert f["history"] == [] and f["norm"] == fine.folds[f["fold"] - f["shots"]]["norm"]
        else:
            assert f["history"] and "fine_tuned_windows" not in f
    assert [s["k"] for s in fine.metrics["shots"]] == [0, 1, 2]
    assert [s["n_trials"] for s in fine.metrics["shots"]] == [
        s["n_trials"] for s in join.metrics["shots"]]
    assert fine.config.shots_by == "fine-tune"
    assert fine.metrics["shots_by"] == "fine-tune" and "shots_by" not in join.metrics


def test_the_printed_curve_says_how_the_shots_were_used(capsys):
    from tactile_studio.cli.learn import print_shots

    curve = [{"k": 0, "accuracy": 0.5, "n_trials": 9}, {"k": 1, "accuracy": 0.6, "n_trials": 9}]
    m = {"shots": curve, "shots_by": "fine-tune", "n_trials": 9, "data_trials": 27}
    print_shots(m, False)
    out = capsys.readouterr().out
    assert "output layers fine-tuned on them" in out
    # a few-shot run tests fewer trials than a plain run: said, in the curve's line
    assert "9 test trials at every K; without --shots all 27 are tested" in out
    print_shots({**m, "shots_by": "join"}, False)
    assert "person in the training" in capsys.readouterr().out


def test_fine_tune_is_for_networks_only(long_trials, tmp_path, capsys):
    for model, name in (("rf", "rf"), ("knn", "knn")):
        with pytest.raises(UserError, match=f"^{name} has no fine-tuning: its shots join the "
                                            r"training \(--shots-by join\)$"):
            ExperimentConfig(data=["x"], model=model, shots=(0, 1),
                             shots_by="fine-tune").validate()
    with pytest.raises(UserError, match="no fine-tuning"):
        ExperimentConfig(data=["x"], model="cnn1d", shots=(0, 1), shots_by="fine-tune",
                         overrides={"rf_weight": 0.5}).validate()
    code = main(["train", "--data", str(long_trials / "data"), "--model", "rf", "--eval",
                 "lopo", "--shots", "0,1", "--shots-by", "fine-tune", "--out",
                 str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 1 and err.strip().splitlines() == [
        "tactile-studio: error: rf has no fine-tuning: its shots join the training "
        "(--shots-by join)"]


def test_auto_fine_tunes_a_network_and_joins_for_a_forest():
    def by(model: str, shots=(0, 1), **kw) -> str:
        return ExperimentConfig(data=["x"], model=model, shots=shots, **kw).resolved().shots_by

    assert by("sefusion") == "fine-tune" and by("cnn1d") == "fine-tune"
    assert by("rf") == by("knn") == by("cnn1d", overrides={"rf_weight": 0.5}) == "join"
    assert by("cnn1d", shots=()) == "join"  # no shots: as a run from before the setting
    assert by("cnn1d", shots_by="join") == "join"


def test_an_adapted_runs_output_layers_are_fine_tuned_on_what_its_test_sees():
    """With ``--adapt person`` a held-out person's windows are tested with the batch norm
    re-estimated on them: fine-tuning first adapts the network to those windows, so the
    output layers learn on the features the test sees (and re-adapting on the same
    windows changes nothing); without ``adapt_to`` the batch norm stays as trained."""
    import torch

    from tactile_studio.learn.learners.families import TorchFitted
    from tactile_studio.learn.learners.fine_tune import FineTuning, fine_tune_head
    from tactile_studio.learn.models import MODELS

    torch.manual_seed(0)
    fitted = TorchFitted(MODELS["cnn1d"].build(3, 3, (6, 6), "tiny"), "cpu")
    rng = np.random.default_rng(0)
    person = rng.normal(0.5, 2.0, (24, 3, 50, 6, 6)).astype(np.float32)  # not as trained
    shots, labels = person[:6], np.array([0, 1, 2] * 2)

    def norms(f) -> list[torch.Tensor]:
        return [b for n, b in f.model.named_buffers() if n.endswith("running_mean")]

    tuned = fine_tune_head(fitted, shots, labels, 3, tuning=FineTuning(steps=5), adapt_to=person)
    adapted = fitted.adapted(person)
    assert norms(tuned) and all(torch.equal(a, b) for a, b in zip(norms(tuned), norms(adapted)))
    assert not all(torch.equal(a, b) for a, b in zip(norms(tuned), norms(fitted)))
    assert np.allclose(tuned.adapted(person).predict_proba(person),
                       tuned.predict_proba(person), atol=1e-5)
    plain = fine_tune_head(fitted, shots, labels, 3, tuning=FineTuning(steps=5))
    assert all(torch.equal(a, b) for a, b in zip(norms(plain), norms(fitted)))


def test_an_adapted_fine_tuned_run_saves_the_person_s_batch_norm(long_trials, tmp_path):
    """The wiring in run_experiment: an adapted run's K = 1 fold is fine-tuned on the
    network adapted to the held-out person (its batch-norm statistics are no longer the
    K = 0 model's); only its output layers and batch norm differ from K = 0."""
    from safetensors.numpy import load_file

    ds = read_sessions([long_trials / "data"]).select(None)
    cfg = _ft_config(long_trials, "fine-tune", adapt="person")
    cfg = ExperimentConfig(**{**cfg.__dict__, "shots": (0, 1)})
    run_experiment(cfg, tmp_path / "run", dataset=ds)
    folds = sorted((tmp_path / "run" / "folds").iterdir())
    k0 = load_file(str(next(f for f in folds if f.name.endswith("P01_k0")) / "model.safetensors"))
    k1 = load_file(str(next(f for f in folds if f.name.endswith("P01_k1")) / "model.safetensors"))
    changed = {n for n in k0 if not np.array_equal(k0[n], k1[n])}
    assert any(n.endswith("running_mean") for n in changed)
    frozen = [n for n in k0 if n.endswith(".weight") and k0[n].ndim > 1 and n not in changed]
    assert frozen  # the convolutions before the head stay as trained
