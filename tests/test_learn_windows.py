"""Long trials become windows: every model (rf, knn and torch) trains on 2 s windows of
8 s performances, reports per-window ``accuracy`` and per-trial ``trial_accuracy`` with a
confusion matrix of each, and no trial's windows straddle train and test."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.errors import UserError
from tactile_studio.learn.data import windowing
from tactile_studio.learn.data.dataset import build_dataset
from tactile_studio.learn.evaluation.summary import headline
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.learn.learners.baselines import BASELINES

GESTURES = ("Poke", "Circular Stroke", "Heavy Pat")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("windows")
    make_dataset_folder(root / "data", participants=3, blocks=2, gestures=GESTURES,
                        trial_s=8.0)
    return root


def _config(data, model, **kw):
    torch_model = model not in BASELINES
    base = dict(data=[str(data / "data")], model=model, evaluation="lopo", preset="tiny",
                epochs=6 if torch_model else None, cache_dir=str(data / "cache"),
                overrides={"lr": "0.01"} if torch_model else {}, threads=1)
    base.update(kw)
    return ExperimentConfig(**base)


def test_cut_keeps_short_trials_whole_and_windows_long_ones(data):
    ds = build_dataset([data / "data"], cache_dir=data / "cache")
    spec = windowing.WindowSpec(2.0, 0.5)
    n = ds.trials[0].shape[1]  # 8 s at 43 Hz = 344 frames
    pieces, owner = windowing.cut(ds, spec)
    w = spec.frames(ds.rates[0])
    assert w == 86 and all(p.shape[1] == w for p in pieces.trials)
    per_trial = len(range(0, n - w + 1, 43)) + ((n - w) % 43 != 0)
    assert np.all(np.bincount(owner) == per_trial)
    assert np.array_equal(pieces.labels, ds.labels[owner])
    short = windowing.cut(ds, windowing.WindowSpec(8.0))[0]
    assert short is ds  # a trial no longer than 1.5 windows stays one piece


def test_mean_and_vote_aggregate_differently():
    owner = np.array([0, 0, 0, 1])
    probs = np.array([[0.4, 0.6], [0.45, 0.55], [1.0, 0.0], [0.2, 0.8]])
    assert windowing.aggregate(owner, probs, "vote")[1].tolist() == [1, 1]
    assert windowing.aggregate(owner, probs, "mean")[1].tolist() == [0, 1]


@pytest.mark.parametrize("model", ["rf", "knn", "cnn3d"])
def test_models_train_on_windows_and_report_both_accuracies(data, tmp_path, model):
    result = run_experiment(_config(data, model), tmp_path / "run")
    m = result.metrics
    ds = build_dataset([data / "data"], cache_dir=data / "cache")
    assert m["window_s"] == 2.0 and m["windows"] > 3 * len(ds)
    assert m["n_trials"] == len(ds)  # LOPO tests every trial once
    assert int(np.sum(m["trial_confusion_counts"])) == len(ds)
    assert int(np.sum(m["confusion_counts"])) == m["n"] > 3 * len(ds)
    assert m["trial_accuracy"] > 1 / len(GESTURES) and m["accuracy"] > 1 / len(GESTURES)
    for fold in result.folds:
        owners = set(fold["predictions"]["owner"])
        test = {ds.uids.index(u) for u in fold["test"]}
        train = {ds.uids.index(u) for u in fold["train"] + fold["val"]}
        assert owners == test and not owners & train
    rows = list(csv.reader(open(tmp_path / "run" / "trial_confusion_matrix.csv")))
    assert rows[0][1:] == list(GESTURES)
    assert (tmp_path / "run" / "trial_confusion_matrix.png").stat().st_size > 1000


def test_vote_aggregate_and_bad_settings(data, tmp_path):
    m = run_experiment(_config(data, "rf", aggregate="vote")).metrics
    assert m["aggregate"] == "vote" and 0 <= m["trial_accuracy"] <= 1
    with pytest.raises(UserError, match="aggregate"):
        run_experiment(_config(data, "rf", aggregate="median"))
    with pytest.raises(UserError, match="window"):
        run_experiment(_config(data, "rf", window_s=-1.0))


@pytest.mark.parametrize("how", ["mean", "vote"])
def test_per_trial_predictions_aggregate_as_the_run_does(data, tmp_path, how):
    from tactile_studio.learn.results import trialpreds

    run = run_experiment(_config(data, "rf", aggregate=how), tmp_path / how)
    preds = trialpreds.load_predictions(tmp_path / how)
    assert preds.accuracy() == pytest.approx(run.metrics["trial_accuracy"])
    for rec in run.folds:  # the same aggregation from the fold's window probabilities
        p = rec["predictions"]
        trials, pred = windowing.aggregate(np.asarray(p["owner"]), np.asarray(p["probs"]), how)
        rows = [t.pred for t in preds.trials if t.fold == rec["name"]]  # in trial order
        assert len(trials) == len(rows) and rows == pred.tolist()
    # windows on which mean and vote disagree (above): each row follows its run's setting
    rec = {"round": 0, "name": "f", "predictions": {
        "owner": [0, 0, 0, 1], "y_true": [0, 0, 0, 1],
        "probs": [[0.4, 0.6], [0.45, 0.55], [1.0, 0.0], [0.2, 0.8]]}}
    rows = trialpreds._trial_rows(rec, ["a", "b"], [{"uid": "t0"}, {"uid": "t1"}], how)
    assert [r.pred for r in rows] == ([0, 1] if how == "mean" else [1, 1])


def _old_csv(path, style: int, gestures: dict[str, str], perf_s: float = 10.0) -> None:
    """An old-software CSV: one labelled ~10 s performance per key (the pressed key's
    ASCII code on every row of it), made by repeating the gesture."""
    from tactile_studio.simulate import SensorSimulator
    from tactile_studio.storage.exchange.shearsense import write_shearsense_csv

    rate = 44.0
    sim = SensorSimulator(rate=rate, seed=7, gesture="idle", style_seed=style, difficulty="easy")
    frame, runs = int(rate), []
    for key, g in gestures.items():
        start = frame
        for _ in range(int(perf_s / 2)):
            sim.perform(g, 2.0, at_frame=frame)
            frame += int(2 * rate)
        runs.append((start, frame, ord(key)))
        frame += int(rate)
    raw = sim.step(frame)
    labels = np.zeros(frame, dtype=np.int64)
    for a, b, code in runs:
        labels[a:b] = code
    times = 1.69e9 + np.arange(frame) / rate
    write_shearsense_csv(path, raw, times, labels, raw[: int(rate)].mean(axis=0))


def test_imported_long_performances_train_on_windows(tmp_path):
    from tactile_studio.storage.exchange.importers import import_shearsense

    keys = {"1": "Poke", "3": "Heavy Pat", "7": "Circular Stroke"}
    csvs = []
    for p in range(3):
        csvs.append(tmp_path / f"P0{p + 1}_demo_FLAT.csv")
        _old_csv(csvs[-1], 300 + p, keys)
    (tmp_path / "sessions").mkdir()
    import_shearsense(csvs, tmp_path / "sessions")
    ds = build_dataset([tmp_path / "sessions"], use_cache=False)
    assert len(ds) == 9 and ds.lengths().min() >= 10 * 44 - 2  # one trial per performance
    m = run_experiment(ExperimentConfig(data=[str(tmp_path / "sessions")], model="rf",
                                        evaluation="lopo", preset="tiny", use_cache=False)).metrics
    assert m["windows"] == 9 * 9  # 10 s at 2 s windows, 50% overlap: 9 windows each
    assert m["n"] == 81 and m["n_trials"] == 9
    assert m["trial_accuracy"] > 0.5
    assert headline(m) == (f"accuracy {m['trial_accuracy']:.3f} per trial "
                           f"({m['accuracy']:.3f} per window)")


def test_the_cli_names_accuracy_per_trial_and_per_window_when_trials_were_cut(tmp_path,
                                                                             capsys):
    """A performance cut into windows has two accuracies; people quote the one per
    performance, so the summary line and the fold table must say which is which."""
    from tactile_studio.cli import main
    from tactile_studio.storage.exchange.importers import import_shearsense

    keys = {"1": "Poke", "3": "Heavy Pat", "7": "Circular Stroke"}
    csvs = [tmp_path / f"P0{p + 1}_demo_FLAT.csv" for p in range(3)]
    for p, path in enumerate(csvs):
        _old_csv(path, 300 + p, keys)
    (tmp_path / "sessions").mkdir()
    import_shearsense(csvs, tmp_path / "sessions")
    assert main(["train", "--data", str(tmp_path / "sessions"), "--model", "knn",
                 "--preset", "tiny", "--no-cache", "--out", str(tmp_path / "run")]) == 0
    printed = capsys.readouterr()
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert headline(m) in printed.err + printed.out
    assert "per trial (" in headline(m)
    header = next(line for line in printed.out.splitlines() if "test participants" in line)
    assert "trial accuracy" in header and header.rstrip().endswith("per window")
    fold = m["per_fold"][0]
    row = next(line for line in printed.out.splitlines()
               if line.split()[1:2] == [fold["name"]]
                  and line.split()[0] == "1")  # rounds counted from 1
    assert row.split()[-2:] == [f"{fold['trial_accuracy']:.3f}", f"{fold['accuracy']:.3f}"]
