"""The research workspace driven like a user: sessions → runs → linked confusion matrix →
cell trials → compare, on real tiny knn runs of 9-gesture virtual participants, plus bad
run folders. Screenshots go to docs/screenshots/research_*.png."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage

from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.simulate import GESTURE_NAMES
from tactile_studio.ui.research.sessions_view import COLUMNS
from tactile_studio.ui.research.window import ResearchWindow

# screenshots for review: TACTILE_STUDIO_SCREENSHOTS=docs/screenshots pytest ...
SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    root = tmp_path_factory.mktemp("ws")
    make_dataset_folder(root / "data", participants=4, blocks=2, gestures=GESTURE_NAMES)
    for channels in ("normal", "both"):
        cfg = ExperimentConfig(data=[str(root / "data")], model="knn", channels=channels,
                               evaluation="lopo", preset="tiny", cache_dir=str(root / "cache"))
        run_experiment(cfg, root / "runs" / channels)
    broken = root / "runs" / "zz-broken"
    shutil.copytree(root / "runs" / "normal", broken)
    for f in (broken / "folds").glob("*/fold.json"):
        rec = json.loads(f.read_text())
        del rec["predictions"]
        f.write_text(json.dumps(rec))
    junk = root / "runs" / "zz-junk"
    (junk / "folds").mkdir(parents=True)
    (junk / "config.json").write_text("{not json")
    return root


@pytest.fixture
def window(qtbot):
    w = ResearchWindow()
    qtbot.addWidget(w)
    w.resize(1400, 820)
    w.show()
    return w


def shot(widget, name: str) -> None:
    SHOTS.mkdir(parents=True, exist_ok=True)
    widget.grab().save(str(SHOTS / f"research_{name}.png"))


def test_sessions_browser(window, workspace, tmp_path, qtbot):
    s = window.sessions
    s.set_folders([str(workspace / "data")])
    assert s.table.rowCount() == 4
    assert len(s.selected_paths()) == 4
    assert "4 participants, 72 ok trials" in s.summary.text()
    row = s.rows[0]
    assert row.participant == "P01" and row.condition == "FLAT" and row.sensor
    assert sum(row.per_gesture.values()) == row.ok == 18
    problem = COLUMNS.index("problem")
    qtbot.waitUntil(lambda: not s.checking, timeout=30_000)  # check runs in the background
    assert s.table.isColumnHidden(problem)  # nothing wrong: no empty column
    shot(window, "sessions")
    s.filter.setText("P02")
    visible = [r for r in range(4) if not s.table.isRowHidden(r)]
    assert len(visible) == 1 and s.selected_paths()[0].endswith("P02.h5")
    # a file that cannot be read: the column appears and says why; it is not trained on
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    s.filter.setText("")
    s.set_folders([str(workspace / "data"), str(tmp_path)])
    assert not s.table.isColumnHidden(problem)
    bad = next(r for r in range(s.table.rowCount()) if s.table.item(r, 0).text() == "junk.h5")
    assert s.table.item(bad, problem).text() and len(s.selected_paths()) == 4
    assert "5 of 5 sessions selected: 4 participants, 72 ok trials" in s.summary.text()


def test_closing_the_window_stops_the_sessions_checks(window, workspace, qtbot):
    """A listing's checks read every file on a worker: closing the workspace cancels them
    and waits for the file being read, so no thread reads the user's files after."""
    s = window.sessions
    s.set_folders([str(workspace / "data")])
    job = s.check_job  # its end is delivered by the event loop, which has not run yet
    assert job is not None and not job.token.cancelled
    window.close()
    assert job.token.cancelled and not job._thread.is_alive()
    assert s.check_job is None and not s.checking


def test_runs_matrix_cell_trials_and_compare(window, workspace, qtbot, tmp_path):
    window.tabs.setCurrentWidget(window.runs)
    runs = window.runs
    runs.set_root(str(workspace / "runs"))
    names = sorted(r.name for r in runs.rows)
    assert names == ["both", "normal", "zz-broken", "zz-junk"]
    junk = next(r for r in runs.rows if r.name == "zz-junk")
    assert "not valid JSON" in junk.error
    # sortable by accuracy
    runs.table.sortItems(5, Qt.SortOrder.DescendingOrder)
    accs = [runs.rows[runs.table.item(r, 0).data(Qt.ItemDataRole.UserRole)].accuracy
            for r in range(runs.table.rowCount())]
    known = [a for a in accs if a is not None]
    assert known == sorted(known, reverse=True)
    runs.select_paths(str(workspace / "runs" / "normal"), str(workspace / "runs" / "both"))
    assert {"channels: normal → both", "channels: both → normal"} & set(
        runs.difference.text().split(": ", 1)[1].split("; "))
    shot(window, "runs")
    # a broken run: one clear message, the window lives
    runs.select_paths(str(workspace / "runs" / "zz-broken"))
    qtbot.mouseClick(runs.open_button, Qt.MouseButton.LeftButton)
    assert "not a run folder of this version" in window.message.text()
    # open the real run
    runs.select_paths(str(workspace / "runs" / "both"))
    qtbot.mouseClick(runs.open_button, Qt.MouseButton.LeftButton)
    conf = window.confusion
    assert window.tabs.currentWidget() is conf and conf.model is not None
    assert len(conf.matrix.labels) == 9
    counts = conf.model.matrix("counts")
    assert counts.sum() == 72
    conf.ordered.setChecked(True)
    assert sorted(conf.model.order) == list(range(9))
    assert conf.matrix.labels == conf.model.ordered_labels()
    counts = conf.model.matrix("counts")
    # click the largest off-diagonal cell (or the first diagonal one)
    off = [(counts[i, j], i, j) for i in range(9) for j in range(9) if i != j and counts[i, j]]
    _, i, j = max(off) if off else (0, 0, 0)
    qtbot.mouseClick(conf.matrix, Qt.MouseButton.LeftButton, pos=conf.matrix.cell_center(i, j))
    assert conf.table.rowCount() == int(counts[i, j]) == len(conf.cell_rows) > 0
    assert conf.table.item(0, 3).text() == conf.model.ordered_labels()[i]
    assert conf.table.item(0, 4).text() == conf.model.ordered_labels()[j]
    assert "true" in conf._tooltip(i, j) and f"{int(counts[i, j])} trials" in conf._tooltip(i, j)
    conf.mode.setCurrentIndex(1)  # row %
    assert conf.matrix.texts[i][j].endswith("%")
    shot(window, "confusion")
    with qtbot.waitSignal(conf.trialActivated, timeout=2000) as sig:
        item = conf.table.item(0, 0)
        rect = conf.table.visualItemRect(item)
        qtbot.mouseClick(conf.table.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
        qtbot.mouseDClick(conf.table.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
    trial = sig.args[0]
    assert trial is conf.cell_rows[0]
    # the trial opens in the player at its start, with the run's prediction over time
    player = window.player
    assert window.tabs.currentWidget() is player
    span = player.pb.trial(trial.trial)
    assert player.current_frame() == span.start == trial.start_sample
    assert player.pb.path.name == trial.session and player.pred_probs is not None
    assert player.prediction.text().startswith("prediction:")
    # trial numbers count from 1 on every screen, as the console's "Trial 22" (index 21):
    # the cell's list, the player's trial box and position line say the same number
    assert conf.table.item(0, 2).text() == str(trial.trial + 1)
    assert player.trial_box.currentText().startswith(f"{trial.trial + 1}: ")
    assert player.position.text().endswith(f"· trial {trial.trial + 1} {span.gesture}")
    assert player.strip.curve_names() == [player.pb.layout.taxel_name(r, c)
                                          for r, c in player.taxels] and player.taxels
    had = (5, 5) in player.taxels
    player.toggle_taxel(5, 5)  # a click on the map adds (or removes) a charted taxel
    assert ((5, 5) in player.taxels) != had
    assert (player.pb.layout.taxel_name(5, 5) in player.strip.curve_names()) != had
    player.loop.setChecked(True)
    player.speed.setCurrentIndex(player.speed.count() - 1)  # 8x
    qtbot.mouseClick(player.play_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: player.current_frame() > span.start + 5, timeout=5000)
    frames = set()
    for _ in range(40):  # looping: never leaves the trial
        qtbot.wait(20)
        frames.add(player.current_frame())
    assert all(span.start <= f < span.end for f in frames)
    qtbot.mouseClick(player.play_button, Qt.MouseButton.LeftButton)  # pause
    player.step(1)
    here = player.current_frame()
    player.step(-1)
    assert player.current_frame() == here - 1
    shot(window, "player")
    window.tabs.setCurrentWidget(conf)
    conf.participant.setCurrentText("P03")
    assert conf.model.matrix("counts").sum() == 18 and "over 18 trials" in conf.matrix.title
    for suffix in ("png", "svg", "csv"):
        conf.export(tmp_path / f"m.{suffix}")
    assert not QImage(str(tmp_path / "m.png")).isNull()
    assert "<svg" in (tmp_path / "m.svg").read_text()
    assert (tmp_path / "m.csv").read_text().splitlines()[0].endswith("precision,recall,f1,support")
    # compare
    window.tabs.setCurrentWidget(runs)
    runs.select_paths(str(workspace / "runs" / "normal"), str(workspace / "runs" / "both"))
    qtbot.mouseClick(runs.compare_button, Qt.MouseButton.LeftButton)
    cmp = window.compare
    assert window.tabs.currentWidget() is cmp
    assert "Wilcoxon signed-rank over 4 participants" in cmp.sentence.text()
    assert "McNemar on 72 matched test trials" in cmp.sentence.text()
    assert len(cmp.bars.result["per_participant"]) == 4
    shot(window, "compare")


def test_main_window_menu_opens_workspace(qtbot, tmp_path, monkeypatch):
    from tactile_studio.ui.main_window import MainWindow
    from tactile_studio.ui.settings import SETTINGS_ENV

    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    w = MainWindow(device="simulated", settings={"rate": "200"})
    qtbot.addWidget(w)
    try:
        action = next(a for m in w.menuBar().actions() for a in m.menu().actions()
                      if "Research" in a.text())
        action.trigger()
        assert w.research_window.isVisible()
        w.research_window.close()
    finally:
        w.shutdown()


def test_fourteen_long_gesture_names_stay_readable(window, workspace):
    """A 14-class matrix with long names: every label fits (no clipping) at the window's
    size, and the screenshot is kept for review."""
    import numpy as np

    from tactile_studio.learn.results.trialpreds import RunPredictions, TrialPrediction

    names = [f"{g} ({k})" for k, g in enumerate(
        ["Back & Forth Rub", "Circular Stroke", "Constant Touch", "Heavy Pat", "Isometric Rub",
         "Poke", "Tickle", "Twist", "Wide Pinch", "Light Stroke", "Squeeze", "Scratch",
         "Tap", "Slap"])]
    rng = np.random.default_rng(1)
    trials = []
    for k in range(14 * 12):
        true = k % 14
        pred = true if rng.random() < 0.7 else int(rng.integers(14))
        trials.append(TrialPrediction(0, "all", f"s#{k}", f"P{k % 5}", "s.h5", k, "", true,
                                      pred, 0.6, (pred + 1) % 14, np.zeros(14)))
    window.confusion.set_run(RunPredictions(workspace / "fake", {"model": "demo"}, {}, names,
                                            trials))
    window.tabs.setCurrentWidget(window.confusion)
    m = window.confusion.matrix
    left, top, cell, mw = m._layout(m.width(), m.height())
    assert m.minimumSizeHint().width() <= m.width() + 1
    assert left + 14 * cell + 3 * mw <= m.width()
    assert top + 14 * cell + m.fontMetrics().height() <= m.height()  # "predicted" shows
    window.confusion.mode.setCurrentIndex(1)  # the widest cell text, "100%", still fits
    assert cell >= m.fontMetrics().horizontalAdvance("100%")
    shot(window, "confusion_14")


def test_run_without_weights_and_bad_session_give_messages(window, workspace, tmp_path):
    bare = tmp_path / "bare"
    shutil.copytree(workspace / "runs" / "normal", bare,
                    ignore=shutil.ignore_patterns("model.safetensors", "model.onnx"))
    assert not window.open_run(str(bare))
    assert "its model file is missing" in window.message.text()
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not a session")
    assert not window.open_session(str(bad))
    assert "bad.h5" in window.message.text()
    window.sessions.set_folders([str(tmp_path)])
    assert window.sessions.rows[0].error and window.sessions.selected_paths() == []
    assert window.isVisible()
