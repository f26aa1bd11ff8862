"""Run comparison and the confusion-matrix model on real tiny runs (knn, lopo) of
virtual participants; the statistics against scipy on known inputs."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import scipy.stats as ss
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main
from tactile_studio.errors import UserError
from tactile_studio.learn.evaluation.stats import mcnemar_exact, wilcoxon_signed_rank
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.learn.results.compare import compare_runs, config_difference
from tactile_studio.learn.results.confusion import ConfusionModel
from tactile_studio.learn.results.trialpreds import TrialPrediction, load_predictions

GESTURES = ("Poke", "Heavy Pat", "Back & Forth Rub", "Tickle")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("cmp")
    make_dataset_folder(root / "data", participants=5, blocks=2, gestures=GESTURES)
    out = {}
    for channels in ("normal", "both"):
        cfg = ExperimentConfig(data=[str(root / "data")], model="knn", channels=channels,
                               evaluation="lopo", preset="tiny", cache_dir=str(root / "cache"))
        run_experiment(cfg, root / channels)
        out[channels] = root / channels
    return out


def _fold_correct(run) -> dict[tuple[int, int], bool]:
    """(round, owner) -> correct, read straight from fold.json (non-windowed model)."""
    res = {}
    for f in sorted((run / "folds").glob("*/fold.json")):
        rec = json.loads(f.read_text())
        p = rec["predictions"]
        for o, y, pr in zip(p["owner"], p["y_true"], p["probs"]):
            res[(rec["round"], o)] = int(np.argmax(pr)) == y
    return res


def test_trial_predictions_carry_identity(runs):
    run = runs["both"]
    assert (run / "trials.json").is_file()
    preds = load_predictions(run)
    metrics = json.loads((run / "metrics.json").read_text())
    assert len(preds.trials) == metrics["n"] == 5 * 2 * len(GESTURES)
    assert {t.participant for t in preds.trials} == {f"P0{i}" for i in range(1, 6)}
    for t in preds.trials:
        assert t.uid == f"{t.participant}.h5#{t.trial}" and t.session == f"{t.participant}.h5"
        assert t.condition == "FLAT" and t.fold == t.participant  # lopo
        assert t.runner_up != t.pred and 0 <= t.confidence <= 1
    model = ConfusionModel(preds.labels, preds.trials)
    assert model.counts().tolist() == metrics["confusion_counts"]
    assert model.accuracy() == pytest.approx(metrics["accuracy"])
    # an older run folder (no trials.json) is rebuilt from its sessions, identically
    (run / "trials.json").rename(run / "trials.bak")
    try:
        old = load_predictions(run)
    finally:
        (run / "trials.bak").rename(run / "trials.json")
    assert [t.uid for t in old.trials] == [t.uid for t in preds.trials]


def test_confusion_model_views_filters_and_cells(runs):
    preds = load_predictions(runs["normal"])
    m = ConfusionModel(preds.labels, preds.trials)
    counts = m.matrix("counts")
    rows, cols = m.matrix("row"), m.matrix("column")
    np.testing.assert_allclose(rows.sum(axis=1), 1.0)
    np.testing.assert_allclose(cols[:, counts.sum(axis=0) > 0].sum(axis=0), 1.0)
    pc = m.per_class()
    for i in range(len(GESTURES)):
        tp = counts[i, i]
        assert pc["recall"][i] == pytest.approx(tp / counts[i].sum())
        if counts[:, i].sum():
            assert pc["precision"][i] == pytest.approx(tp / counts[:, i].sum())
    m.set_filter(participant="P02")
    assert m.counts().sum() == 2 * len(GESTURES)
    assert all(t.participant == "P02" for t in m.selected())
    m.set_filter(condition="NOPE")
    assert m.counts().sum() == 0
    m.set_filter()
    off = [(i, j) for i in range(len(GESTURES)) for j in range(len(GESTURES))
           if counts[i, j] and i != j] or [(0, 0)]
    i, j = off[0]
    cell = m.cell_trials(i, j)
    assert len(cell) == counts[i, j] == m.cell_info(i, j)[0]
    assert all(t.true == m.order[i] and t.pred == m.order[j] for t in cell)
    assert [t.confidence for t in cell] == sorted(t.confidence for t in cell)


def _fake(true: int, pred: int, k: int) -> TrialPrediction:
    return TrialPrediction(0, "all", f"s#{k}", "P1", "s", k, "", true, pred, 0.5, 0,
                           np.zeros(5))


def test_order_by_confusion_puts_confused_gestures_together():
    # 0<->3 and 1<->4 are confused with each other; 2 is clean
    pairs = [(0, 3), (3, 0), (1, 4), (4, 1)] * 3 + [(g, g) for g in range(5)] * 4
    m = ConfusionModel(list("ABCDE"), [_fake(t, p, k) for k, (t, p) in enumerate(pairs)])
    order = m.order_by_confusion()
    assert sorted(order) == list(range(5))
    pos = {g: order.index(g) for g in range(5)}
    assert abs(pos[0] - pos[3]) == 1 and abs(pos[1] - pos[4]) == 1
    assert m.ordered_labels() == [m.labels[i] for i in order]
    # counts follow the order: the total and the diagonal are unchanged
    assert np.trace(m.matrix("counts")) == 20 and m.matrix("counts").sum() == 32


def test_compare_runs_numbers_against_independent_computation(runs, capsys):
    r = compare_runs(runs["normal"], runs["both"])
    a, b = _fold_correct(runs["normal"]), _fold_correct(runs["both"])
    assert r["n_matched"] == len(a) == len(b)
    assert r["accuracy_a"] == pytest.approx(np.mean(list(a.values())))
    assert r["accuracy_b"] == pytest.approx(np.mean(list(b.values())))
    assert r["difference"] == pytest.approx(r["accuracy_b"] - r["accuracy_a"])
    only_a = sum(a[k] and not b[k] for k in a)
    only_b = sum(b[k] and not a[k] for k in a)
    expected = ss.binomtest(min(only_a, only_b), only_a + only_b, 0.5).pvalue \
        if only_a + only_b else 1.0
    assert r["mcnemar_p"] == pytest.approx(expected)
    per_fold_a = {f["name"]: f["accuracy"] for f in
                  json.loads((runs["normal"] / "metrics.json").read_text())["per_fold"]}
    per_fold_b = {f["name"]: f["accuracy"] for f in
                  json.loads((runs["both"] / "metrics.json").read_text())["per_fold"]}
    for p, v in r["per_participant"].items():
        assert v["accuracy_a"] == pytest.approx(per_fold_a[p])
        assert v["accuracy_b"] == pytest.approx(per_fold_b[p])
    diffs = np.array([per_fold_b[p] - per_fold_a[p] for p in sorted(per_fold_a)])
    if np.any(diffs != 0):
        ref = ss.wilcoxon(diffs, zero_method="wilcox").pvalue
        assert r["wilcoxon_p"] == pytest.approx(ref, rel=1e-6)
    assert r["name_a"] == "normal" and r["name_b"] == "both"
    assert "channels: normal → both" in r["config_difference"]
    assert "over 5 participants" in r["sentence"]
    assert f"McNemar on {r['n_matched']} matched test trials" in r["sentence"]
    # CLI parity
    assert main(["compare", str(runs["normal"]), str(runs["both"]), "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    for key in ("accuracy_a", "accuracy_b", "difference", "wilcoxon_p", "mcnemar_p",
                "per_participant"):
        assert js[key] == pytest.approx(r[key]) if not isinstance(r[key], dict) else \
            js[key] == r[key]
    assert main(["compare", str(runs["normal"]), str(runs["both"])]) == 0
    text = capsys.readouterr().out
    assert r["sentence"] in text and "P03" in text


def test_compare_bad_run_folders(runs, tmp_path, capsys):
    broken = tmp_path / "broken"
    shutil.copytree(runs["normal"], broken)
    for f in (broken / "folds").glob("*/fold.json"):
        rec = json.loads(f.read_text())
        del rec["predictions"]
        f.write_text(json.dumps(rec))
    with pytest.raises(UserError, match="not a run folder of this version"):
        load_predictions(broken)
    assert main(["compare", str(broken), str(runs["both"])]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "broken" in err[0] and "Traceback" not in err[0]
    assert main(["compare", str(tmp_path / "nothing"), str(runs["both"])]) == 1
    assert "no such run folder" in capsys.readouterr().err


def test_wilcoxon_and_mcnemar_against_scipy():
    rng = np.random.default_rng(3)
    for n in (6, 10, 17):
        x = rng.normal(size=n)
        y = x + rng.normal(0.3, 1.0, size=n)
        stat, p, used = wilcoxon_signed_rank(x, y)
        ref = ss.wilcoxon(x, y, zero_method="wilcox", method="exact")
        assert used == n and stat == pytest.approx(ref.statistic)
        assert p == pytest.approx(ref.pvalue, rel=1e-9)
    # ties and zeros: normal approximation with tie correction
    a = np.array([0.8, 0.7, 0.9, 0.6, 0.75, 0.8, 0.7, 0.9, 0.5])
    b = np.array([0.85, 0.7, 0.95, 0.7, 0.8, 0.9, 0.65, 0.95, 0.6])
    _, p, used = wilcoxon_signed_rank(a, b)
    ref = ss.wilcoxon(a, b, zero_method="wilcox", method="approx", correction=False)
    assert used == 8 and p == pytest.approx(ref.pvalue, rel=1e-6)
    for b_, c_ in ((3, 12), (0, 5), (7, 7), (1, 0)):
        assert mcnemar_exact(b_, c_) == pytest.approx(ss.binomtest(b_, b_ + c_, 0.5).pvalue)
    assert mcnemar_exact(0, 0) == 1.0


def test_config_difference_in_words():
    a = {"model": "rf", "channels": "normal", "overrides": {"n_estimators": 40}, "seed": 0}
    b = {"model": "rf", "channels": "both", "overrides": {"n_estimators": 80, "k": 3}, "seed": 0}
    assert config_difference(a, b) == ["channels: normal → both", "k: default → 3",
                                       "n_estimators: 40 → 80"]
    assert config_difference(a, a) == []
    # a run written before a setting existed ran with its default: no difference
    assert config_difference(a, {**a, "adapt": "none", "balance": False}) == []
    assert config_difference(a, {**a, "adapt": "person"}) == ["adapt: none → person"]


def test_runs_are_named_by_what_differs_and_the_cli_tables_line_up(runs, capsys):
    """Two runs that differ in more than one setting were named by their folders ("rf-tiny
    beats normal"); a long folder name broke the CLI's columns."""
    both = runs["both"]
    root = both.parent
    long = root / "knn-three-neighbours-both-channels-a-long-folder-name"
    cfg = ExperimentConfig(data=[str(root / "data")], model="knn", channels="both",
                           evaluation="lopo", preset="tiny", cache_dir=str(root / "cache"),
                           overrides={"n_neighbors": 3})
    run_experiment(cfg, long)
    r = compare_runs(runs["normal"], long)
    assert r["name_a"] == "normal channels · n_neighbors default"
    assert r["name_b"] == "both channels · n_neighbors 3"
    assert r["name_b"] in r["sentence"] and r["name_a"] in r["sentence"]
    assert compare_runs(runs["normal"], both)["name_b"] == "both"  # one difference: its value
    assert main(["compare", str(runs["normal"]), str(long)]) == 0
    lines = capsys.readouterr().out.splitlines()
    runs_table = [ln for ln in lines if ln.startswith(("A ", "B "))]
    assert len(runs_table) == 2
    assert runs_table[0].index("%") == runs_table[1].index("%")  # accuracies in one column
    people = [ln for ln in lines if ln.startswith(("participant", "P0"))]
    assert len(people) == 6 and len({len(ln) for ln in people}) == 1  # right-aligned rows


def test_a_run_on_the_models_default_channels_is_named_by_the_channels_it_used(runs):
    """train without --channels stores channels None: compare named that run "None
    channels" beside a run on the same channels (walking the README: rf vs cnn1d)."""
    root = runs["both"].parent
    cfg = ExperimentConfig(data=[str(root / "data")], model="knn", channels=None,
                           evaluation="lopo", preset="tiny", cache_dir=str(root / "cache"),
                           overrides={"n_neighbors": 3})
    run_experiment(cfg, root / "default-channels")
    r = compare_runs(root / "default-channels", runs["both"])
    assert (r["name_a"], r["name_b"]) == ("n_neighbors 3", "n_neighbors default")
    assert compare_runs(runs["normal"], root / "default-channels")["name_b"] == \
        "both channels · n_neighbors 3"
    assert "None" not in r["sentence"]


def test_every_setting_a_run_config_holds_is_named_when_it_differs():
    """compare said "differ in: nothing recorded" for an rf run against an rf --shots
    0,1,2 run: only some settings were described. Now every result-changing setting is,
    where it acts (the folds of a k-fold mean nothing under lopo)."""
    base = ExperimentConfig(data=["d"], model="rf", evaluation="lopo").to_dict()
    changed = {"data": ["d", "e"], "model": "knn", "channels": "normal", "grid": "virtual",
               "evaluation": "group-kfold", "rounds": 3, "preset": "tiny", "epochs": 5,
               "overrides": {"k": 3}, "seed": 1, "window_s": 12.0, "window_overlap": 0.25,
               "aggregate": "vote", "augment": "flip", "participant_norm": True,
               "balance": True, "val_by": "participant", "adapt": "person", "shots": [0, 1],
               "val_fraction": 0.3}
    # settings that act only beside another: changed together with it
    along = {"folds": {"evaluation": "group-kfold", "folds": 5},
             "heldout_fraction": {"evaluation": "group-kfold", "heldout_fraction": 0.2},
             "split": {"evaluation": "all-inclusive", "split": [0.6, 0.2, 0.2]},
             "shots_by": {"shots": [0, 1], "shots_by": "fine-tune"},
             "augment_copies": {"augment": "flip", "augment_copies": 3}}
    from tactile_studio.learn.experiments.experiment import RESULT_KEYS
    assert set(changed) | set(along) == set(RESULT_KEYS)
    for key in RESULT_KEYS:
        other = {**base, **along.get(key, {key: changed.get(key)})}
        said = config_difference(base, other)
        named = "k" if key == "overrides" else key
        assert any(p.startswith(f"{named}: ") for p in said), (key, said)
    assert config_difference(base, {**base, "shots": [0, 1, 2]}) == ["shots: none → 0,1,2"]
    assert config_difference(base, {**base, "participant_norm": True}) == \
        ["participant_norm: off → on"]
    # a setting that does not act here is no difference
    assert config_difference(base, {**base, "folds": 5, "split": [0.5, 0.25, 0.25],
                                     "shots_by": "join"}) == []


def _result(diff: float, wilcoxon: float | None, mcnemar: float) -> dict:
    return {"difference": diff, "accuracy_a": 0.5, "name_a": "normal", "name_b": "both",
            "wilcoxon_p": wilcoxon, "n_participants": 10 if wilcoxon is not None else 1,
            "mcnemar_p": mcnemar, "n_matched": 270}


def test_a_difference_its_tests_do_not_support_is_not_said_as_a_win():
    """"both beats normal by 1.5 points, p = 0.27" said a win the test did not show."""
    from tactile_studio.learn.results.compare import sentence

    s = sentence(_result(0.015, 0.27, 0.40))
    assert "beats" not in s
    assert s.startswith("both is 1.5 points above normal, not significant: p = 0.27")
    assert sentence(_result(0.079, 0.02, 0.004)).startswith(
        "both beats normal by 7.9 points, p = 0.020")
    assert sentence(_result(-0.04, 0.30, 0.01)).startswith(
        "normal is 4.0 points above both, significant over trials, not over participants:")
    assert sentence(_result(0.04, 0.01, 0.20)).startswith(
        "both is 4.0 points above normal, significant over participants, not over trials:")
    assert sentence(_result(0.04, None, 0.01)).startswith("both beats normal by 4.0")
    assert "beats" not in sentence(_result(0.04, None, 0.2))


def test_compare_names_the_channels_and_shots_the_runs_used(runs, capsys):
    """compare named the channel sets "normal → default" (a run left to the model's
    channels) and printed no difference for a --shots run against a plain one."""
    root = runs["both"].parent
    for name, kw in (("model-channels", {"channels": None}), ("with-shots",
                                                              {"shots": (0, 1)})):
        cfg = ExperimentConfig(data=[str(root / "data")], model="knn", evaluation="lopo",
                               preset="tiny", cache_dir=str(root / "cache"), **kw)
        run_experiment(cfg, root / name)
    r = compare_runs(runs["normal"], root / "model-channels")
    assert r["config_difference"] == ["channels: normal → both"]
    assert "default" not in r["sentence"]
    assert main(["compare", str(runs["both"]), str(root / "with-shots")]) == 0
    out = capsys.readouterr().out
    assert "differ in: shots: none → 0,1" in out
    assert "few-shot (K 0,1)" in out and "plain" in out


def test_a_run_written_before_protocol_was_renamed_evaluation_still_loads(runs, tmp_path,
                                                                         capsys):
    """Runs made before the house step say ``"protocol": "lopo"`` in config.json: the
    workspace, compare and a resumed train read it as today's ``evaluation``."""
    from tactile_studio.learn.results.workspace_index import read_run_row

    old = tmp_path / "old"
    shutil.copytree(runs["both"], old)
    cfg = json.loads((old / "config.json").read_text())
    cfg["config"]["protocol"] = cfg["config"].pop("evaluation")
    (old / "config.json").write_text(json.dumps(cfg))
    row = read_run_row(old)
    assert row.error == "" and row.evaluation == "lopo"
    assert ExperimentConfig.from_dict(cfg["config"]).evaluation == "lopo"
    same = compare_runs(old, runs["both"])
    assert same["n_matched"] > 0 and same["config_difference"] == []
    # resuming it with today's settings is the same run, not "a different run"
    again = ExperimentConfig.from_dict(json.loads((runs["both"] / "config.json").read_text())
                                       ["config"])
    again.cache_dir = str(tmp_path / "cache")
    run_experiment(again, old)
