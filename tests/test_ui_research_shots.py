"""Few-shot personalisation in the research workspace (issue 37 item 3): the train panel's
"Shots per gesture" choice, the confusion matrix per K (never K mixed), the runs table's
curve and the compare view's per-K comparison, on real runs of virtual participants."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder
from PySide6.QtCore import Qt

from tactile_studio.learn.data.dataset import read_sessions
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.learn.results.compare import compare_runs
from tactile_studio.learn.results.confusion import ConfusionModel
from tactile_studio.learn.results.trialpreds import load_predictions
from tactile_studio.ui.research.compare_view import CompareView
from tactile_studio.ui.research.confusion_view import ConfusionView
from tactile_studio.ui.research.runs_view import COLUMNS, RunsView
from tactile_studio.ui.research.window import ResearchWindow
from tactile_studio.ui.settings import app_settings

GESTURES = ("Poke", "Heavy Pat", "Back & Forth Rub")
SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """3 people x 3 gestures x 3 performances; rf and knn runs with shots 0,1."""
    root = tmp_path_factory.mktemp("shotsui")
    make_dataset_folder(root / "data", participants=3, blocks=3, gestures=GESTURES)
    ds = read_sessions([root / "data"]).select(None)
    out = {}
    for model in ("rf", "knn"):
        cfg = ExperimentConfig(data=[str(root / "data")], model=model, evaluation="lopo",
                               preset="tiny", shots=(0, 1))
        run_experiment(cfg, root / "runs" / model, dataset=ds)
        out[model] = root / "runs" / model
    return root, out


@pytest.fixture
def settings_env(monkeypatch, tmp_path):
    monkeypatch.setenv("TACTILE_STUDIO_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))


def test_the_panel_trains_a_few_shot_run(settings_env, runs, qtbot, tmp_path):
    root, _ = runs
    w = ResearchWindow()
    qtbot.addWidget(w)
    w.resize(1400, 820)
    w.show()
    w.sessions.set_folders([str(root / "data")])
    w.tabs.setCurrentWidget(w.train)
    panel = w.train
    panel.model.setCurrentText("rf")
    panel.preset.setCurrentText("tiny")
    panel.evaluation.setCurrentText("all-inclusive")
    assert not panel.shots.isEnabled() and not panel.shots_by.isEnabled()  # nobody held out
    panel.shots.setText("0,1")
    assert panel.config().shots == ()
    panel.evaluation.setCurrentText("lopo")
    assert panel.shots.isEnabled() and panel.config().shots == (0, 1)
    assert panel.shots_by.isEnabled() and panel.config().shots_by == "auto"
    # rf's shots always join the training: the choice is not offered, and auto is join
    assert not panel.shots_by.isVisibleTo(panel)
    assert panel.config().resolved().shots_by == "join"
    panel.model.setCurrentText("knn")
    panel.model.setCurrentText("cnn1d")  # a network: train --shots-by from the panel
    panel.shots_by.setCurrentIndex(panel.shots_by.findData("join"))
    assert panel.shots_by.isVisibleTo(panel) and panel.config().shots_by == "join"
    panel.model.setCurrentText("rf")
    panel.shots.setText("1,1")
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    assert "distinct counts" in w.message.text()  # refused before any training
    panel.shots.setText("0, 1")
    out = tmp_path / "few"
    panel.out.setText(str(out))
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: not panel.job.running, timeout=180_000)
    assert panel.job.finished.type == "done", panel.job.finished
    metrics = json.loads((out / "metrics.json").read_text())
    assert [s["k"] for s in metrics["shots"]] == [0, 1]
    curve = ", ".join(f"K={s['k']} {s['trial_accuracy']:.2f}" for s in metrics["shots"])
    assert f"few-shot curve {curve}" in panel.status.text()
    names = [panel.folds.item(r, 1).text() for r in range(panel.folds.rowCount())]
    assert sorted(names[:6]) == sorted(f"P0{p} k{k}" for p in (1, 2, 3) for k in (0, 1))
    # the curve under the folds: all people at each K
    assert names[6:] == ["all, K=0", "all, K=1"]
    assert [panel.folds.item(r, 4).text() for r in (6, 7)] == \
        [f"{100 * s['trial_accuracy']:.1f}%" for s in metrics["shots"]]
    SHOTS.mkdir(parents=True, exist_ok=True)
    w.grab().save(str(SHOTS / "research_train_shots.png"))
    # persisted with the panel's other choices
    from tactile_studio.ui.research.train_panel import TrainPanel
    again = TrainPanel(lambda: [], app_settings())
    assert again.shots.text() == "0, 1" and again.shots.isEnabled()
    again.deleteLater()


def test_the_matrix_shows_one_k_at_a_time(settings_env, runs, qtbot):
    _, folders = runs
    run = load_predictions(folders["rf"])
    assert run.shot_counts == [0, 1]
    model = ConfusionModel(run.labels, run.trials)
    assert model.shots == 0  # the smallest K by default
    at0 = model.counts().sum()
    assert at0 == len(run.at_shots(0).trials) == len(run.trials) // 2
    keys = [(t.path, t.trial) for t in model.selected()]
    assert len(keys) == len(set(keys))  # each test trial once: never K mixed
    model.set_shots(1)
    assert model.counts().sum() == at0
    assert {t.shots for t in model.selected()} == {1}
    view = ConfusionView()
    qtbot.addWidget(view)
    view.resize(1300, 700)
    view.show()
    view.set_run(run)
    assert view.shots.isVisible() and view.shots.count() == 2
    assert view.shots.currentData() == 0
    acc0 = ConfusionModel(run.labels, run.trials, shots=0).accuracy()
    acc1 = ConfusionModel(run.labels, run.trials, shots=1).accuracy()
    assert f"{100 * acc0:.1f}% over {at0} trials · K=0" in view.matrix.title
    view.shots.setCurrentIndex(1)
    assert f"{100 * acc1:.1f}% over {at0} trials · K=1" in view.matrix.title
    view.show_cell(0, 0)
    assert view.cell_rows and {t.shots for t in view.cell_rows} == {1}
    view.grab().save(str(SHOTS / "research_confusion_shots.png"))


def test_runs_and_compare_show_the_curve(settings_env, runs, qtbot):
    root, folders = runs
    view = RunsView()
    qtbot.addWidget(view)
    view.set_root(str(root / "runs"))
    col = COLUMNS.index("few-shot (trial acc. per K)")
    metrics = json.loads((folders["rf"] / "metrics.json").read_text())
    curve = ", ".join(f"K={s['k']} {s['trial_accuracy']:.2f}" for s in metrics["shots"])
    texts = {view.table.item(r, 0).text(): view.table.item(r, col).text()
             for r in range(view.table.rowCount())}
    assert texts["rf"] == curve and texts["knn"].startswith("K=0 ")
    view.select_paths(str(folders["rf"]))
    assert curve in view.difference.text()
    result = compare_runs(folders["rf"], folders["knn"])
    compare = CompareView()
    qtbot.addWidget(compare)
    compare.resize(1200, 700)
    compare.show()
    compare.set_result(result)
    assert compare.shots.isVisible()
    text = compare.shots.text()
    for s in result["shots"]:
        assert f"K = {s['k']}: rf {100 * s['accuracy_a']:.1f}%" in text and s["sentence"] in text
    compare.grab().save(str(SHOTS / "research_compare_shots.png"))


def test_the_workspace_compares_few_shot_runs_per_k(settings_env, runs, qtbot):
    _, folders = runs
    w = ResearchWindow()
    qtbot.addWidget(w)
    assert w.compare_runs(str(folders["rf"]), str(folders["knn"]))
    r = w.compare.result
    # each test trial matched once (at K = 0), not once per K
    assert r["n_matched"] == len(load_predictions(folders["rf"]).at_shots(0).trials)
    assert [s["k"] for s in r["shots"]] == [0, 1]


def test_the_status_line_counts_the_trials_the_matrix_shows(settings_env, runs, qtbot):
    """The status bar said "opened …: 135 test trials" under a matrix headed "over 45
    trials" (a few-shot run tests each trial once per K)."""
    _, folders = runs
    w = ResearchWindow()
    qtbot.addWidget(w)
    assert w.open_run(str(folders["rf"]))
    n = len(load_predictions(folders["rf"]).at_shots(0).trials)
    assert w.message.text().endswith(f": {n} test trials, each scored at K = 0, 1 (the "
                                     "header's K is shown)")
    assert f"over {n} trials · K=0" in w.confusion.matrix.title
