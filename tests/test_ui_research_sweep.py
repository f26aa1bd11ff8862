"""The workspace's sweep panel driven like a user, on 3 virtual participants: rf + knn x
normal / shear under LOPO through local worker processes → per-task progress → the
sweep's table (equal to results.json) → the runs join the Runs tab and open; cancel
mid-way ends the workers promptly and keeps the finished tasks; the choices persist;
bad input is one line; the same sweep on a local Ray instance gives the same table."""

from __future__ import annotations

import json
import multiprocessing
import tempfile
from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication

from tactile_studio.ui.research.sweep_panel import RESULT_COLUMNS, SweepPanel
from tactile_studio.ui.research.window import ResearchWindow
from tactile_studio.ui.settings import app_settings

pytestmark = pytest.mark.slow  # real worker processes train real models

GESTURES = ("Poke", "Heavy Pat", "Back & Forth Rub")
# a look at the panel on easy data (docs/screenshots come from tools/screenshots/
# make_sweep_screenshots.py, on data where the models differ)
SHOTS = Path(tempfile.gettempdir())


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("wssweep")
    make_dataset_folder(root / "data", participants=3, blocks=2, gestures=GESTURES)
    return root


@pytest.fixture
def window(qtbot, monkeypatch, tmp_path, data):
    monkeypatch.setenv("TACTILE_STUDIO_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    w = ResearchWindow()
    qtbot.addWidget(w)
    w.resize(1400, 860)
    w.show()
    w.sessions.set_folders([str(data / "data")])
    w.tabs.setCurrentWidget(w.sweep)
    yield w
    job = w.sweep.job
    if job is not None and job.running:
        job.cancel()
        job.wait(30)


def _pumped(cond):
    """``cond`` after letting Qt run its timers (the panel polls the job on a QTimer)."""
    def check() -> bool:
        QApplication.processEvents()
        return bool(cond())
    return check


def _choose(panel: SweepPanel, out: Path, models, channels, executor="local", jobs=2,
            address="") -> None:
    panel.set_models(models)
    panel.set_channels(channels)
    panel.evaluation.setCurrentText("lopo")
    panel.preset.setCurrentText("tiny")
    panel.executor.setCurrentIndex(panel.executor.findData(executor))
    panel.jobs.setValue(jobs)
    panel.address.setText(address)
    panel.out.setText(str(out))


def _table(panel: SweepPanel) -> dict[tuple[str, str], dict[str, str]]:
    t = panel.results
    return {(t.item(r, 0).text(), t.item(r, 1).text()):
            {RESULT_COLUMNS[c]: t.item(r, c).text() for c in range(t.columnCount())}
            for r in range(t.rowCount())}


def test_local_sweep_shows_progress_table_and_runs(window, tmp_path, wait_until, qtbot):
    panel = window.sweep
    out = tmp_path / "sweep"
    assert panel.preset.currentText() == "full"  # as the CLI: the recipe for unseen people
    _choose(panel, out, ["rf", "knn"], ["normal", "shear"])
    panel.adapt.setCurrentIndex(panel.adapt.findData("person"))  # each test person's own
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    assert panel.job is not None and panel.cancel_button.isEnabled()
    assert not panel.start_button.isEnabled()
    wait_until(_pumped(lambda: panel.tasks.rowCount() >= 1), timeout=240, what="a first task")
    assert "/ 12" in panel.counts.text() and "elapsed" in panel.counts.text()
    SHOTS.mkdir(parents=True, exist_ok=True)
    window.grab().save(str(SHOTS / "research_sweep_running.png"))
    wait_until(_pumped(lambda: not panel.job.running), timeout=300, what="the sweep's end")
    assert panel.job.finished.type == "done", panel.job.finished
    assert panel.tasks.rowCount() == 12 and "tasks 12 / 12" in panel.counts.text()
    # the table is the sweep's results.json, row for row
    saved = json.loads((out / "results.json").read_text())
    shown = _table(panel)
    assert set(shown) == {(f"{m} (adapted)", c) for m in ("rf", "knn")
                          for c in ("normal", "shear")}
    for row in saved["rows"]:
        assert row["adapt"] == "person"
        cells = shown[(row["name"], row["channels"])]
        assert cells["folds"] == "3/3"
        assert cells["accuracy"] == f"{100 * row['accuracy']:.1f}%"
        assert cells["trial acc."] == f"{100 * row['trial_accuracy']:.1f}%"
        assert cells["macro F1"] == f"{100 * row['f1_macro']:.1f}%"
    assert "best per trial" in panel.status.text()
    window.grab().save(str(SHOTS / "research_sweep_done.png"))
    # the sweep's runs are workspace runs: listed, and a row opens its confusion matrix
    assert sorted(r.name for r in window.runs.rows) == ["knn-normal", "knn-shear",
                                                        "rf-normal", "rf-shear"]
    assert all(r.complete and r.folds == 3 and not r.error for r in window.runs.rows)
    panel.results.cellDoubleClicked.emit(0, 0)
    assert window.tabs.currentWidget() is window.confusion
    assert len(window.confusion.run.trials) == 18
    # the choices persist
    again = SweepPanel(lambda: [], app_settings())
    assert set(again.checked_models()) == {"rf", "knn"}
    assert again.checked_channels() == ["normal", "shear"]
    assert again.executor.currentData() == "local" and again.jobs.value() == 2
    assert again.adapt.currentData() == "person"
    metrics = json.loads((out / "runs" / "rf-normal" / "metrics.json").read_text())
    assert metrics["adapt"] == "person"
    again.deleteLater()


def test_cancel_stops_workers_and_keeps_finished_tasks(window, tmp_path, wait_until, qtbot):
    panel = window.sweep
    out = tmp_path / "cancelled"
    before = {p.pid for p in multiprocessing.active_children()}
    panel.rounds.setValue(3)
    _choose(panel, out, ["rf", "knn"], ["normal", "shear", "both"], jobs=1)
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    wait_until(_pumped(lambda: panel.tasks.rowCount() >= 1), timeout=240, what="a first task")
    workers = [p for p in multiprocessing.active_children() if p.pid not in before]
    assert workers, "the sweep runs in worker processes"
    qtbot.mouseClick(panel.cancel_button, Qt.MouseButton.LeftButton)
    wait_until(_pumped(lambda: not panel.job.running), timeout=30, what="the cancel")
    wait_until(lambda: not any(p.is_alive() for p in workers), timeout=15,
               what="the workers to end")
    job = panel.job
    assert job.finished.type == "cancelled" and 1 <= job.done < job.total == 54
    assert len(list((out / "tasks").glob("*.json"))) == job.done
    assert "cancelled" in panel.status.text() and "continues" in panel.status.text()
    assert panel.start_button.isEnabled() and not panel.cancel_button.isEnabled()
    saved = json.loads((out / "results.json").read_text())
    assert saved["complete"] is False
    assert sum(r["folds_done"] for r in saved["rows"]) == job.done
    assert panel.results.rowCount() == 6  # the partial table is shown


def test_bad_input_is_one_line(window, tmp_path, wait_until, qtbot):
    panel = window.sweep
    # the Train tab hands its model and channel set over to the Sweep tab
    _choose(panel, tmp_path / "s", ["rf"], ["normal"])
    window.tabs.setCurrentWidget(window.train)
    window.train.model.setCurrentText("cnn1d")
    window.train.channels.setCurrentText("shear")
    qtbot.mouseClick(window.train.sweep_button, Qt.MouseButton.LeftButton)
    assert window.tabs.currentWidget() is panel
    assert set(panel.checked_models()) == {"rf", "cnn1d"}
    assert panel.checked_channels() == ["normal", "shear"]
    _choose(panel, tmp_path / "s", [], ["normal"])
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    assert window.message.text() == "tick at least one model"
    _choose(panel, tmp_path / "s", ["rf"], ["normal"], executor="ray", address="127.0.0.1:1")
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    wait_until(_pumped(lambda: not panel.job.running), timeout=30, what="the ray error")
    text = window.message.text()
    assert text.startswith("ray: cannot reach 127.0.0.1:1") and "\n" not in text
    _choose(panel, tmp_path / "s2", ["rf"], ["normal"], executor="ray", address="nowhere")
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    wait_until(_pumped(lambda: not panel.job.running), timeout=30, what="the address error")
    assert "is not HOST:PORT" in window.message.text()
    window.sessions.set_folders([])
    qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
    assert "no sessions selected" in window.message.text()
    assert window.isVisible()


def test_ray_sweep_from_the_gui_matches_local_workers(window, tmp_path, wait_until, qtbot):
    panel = window.sweep
    tables = {}
    for executor in ("local", "ray"):  # ray: a local instance of 2 CPUs, started for the run
        _choose(panel, tmp_path / executor, ["rf", "knn"], ["both"], executor=executor)
        qtbot.mouseClick(panel.start_button, Qt.MouseButton.LeftButton)
        wait_until(_pumped(lambda: not panel.job.running), timeout=300, what=executor)
        assert panel.job.finished.type == "done", panel.job.finished
        tables[executor] = {k: {c: v for c, v in row.items() if c != "train s"}
                            for k, row in _table(panel).items()}
    assert tables["ray"] == tables["local"] and len(tables["ray"]) == 2
