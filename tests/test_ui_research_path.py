"""The researcher's first day: the live-inference dock beside a usable device panel, the
train panel's run folder, the main window's import entry. Real windows (pytest-qt,
offscreen) at their default sizes.
"""

from __future__ import annotations

from pathlib import Path

import pyqtgraph as pg
import pytest
from PySide6.QtCore import Qt

from tactile_studio.ui.main_window import DEVICE_PANEL_MIN_WIDTH, MainWindow
from tactile_studio.ui.research.menu import live_inference_dock
from tactile_studio.ui.settings import SETTINGS_ENV


@pytest.fixture(autouse=True)
def isolated(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def fully_shown(widget) -> bool:
    """Wide enough for its own text (not cut off) and inside its window."""
    return widget.isVisible() and widget.width() >= widget.minimumSizeHint().width() \
        and widget.visibleRegion().boundingRect().width() >= widget.width() - 1


def test_the_live_inference_dock_leaves_the_device_panel_usable(qtbot):
    w = MainWindow(device="simulated", settings={"gesture": "idle"}, connect=False,
                   persist=False)
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    assert w.size().width() == 1280  # the default window size
    dock = live_inference_dock(w)
    dock.show()
    qtbot.waitUntil(lambda: dock.isVisible() and dock.width() > 100, timeout=2000)
    assert w.device_dock.width() >= DEVICE_PANEL_MIN_WIDTH and not w.device_panel_squeezed()
    p = w.panel
    for button in (p.connect_button, p.disconnect_button, p.record_button, p.tare_button):
        assert fully_shown(button), button.text()
    assert fully_shown(dock.widget().load_button)
    w.shutdown()


def test_a_squeezed_layout_is_not_saved(qtbot, tmp_path):
    w = MainWindow(device="simulated", settings={"gesture": "idle"}, connect=False)
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    w.save_settings()  # a good layout
    dock = live_inference_dock(w)
    dock.show()
    w.resize(760, 800)  # a window too narrow for the map, the dock and the panel
    qtbot.waitUntil(w.device_panel_squeezed, timeout=3000)
    w.shutdown()  # saves, but not the squeezed layout
    again = MainWindow(device="simulated", settings={"gesture": "idle"}, connect=False)
    qtbot.addWidget(again)
    again.resize(1280, 800)
    again.show()
    qtbot.waitExposed(again)
    qtbot.waitUntil(lambda: again.device_dock.width() >= DEVICE_PANEL_MIN_WIDTH, timeout=3000)
    assert not again.device_panel_squeezed()
    again.shutdown()


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    from learn_fixtures import make_dataset_folder
    root = tmp_path_factory.mktemp("rpath")
    make_dataset_folder(root / "data", participants=3, blocks=3,
                        gestures=("Poke", "Heavy Pat", "Back & Forth Rub"))
    return root / "data"


def test_train_panel_names_its_run_folder_and_trains_without_one_typed(qtbot, sessions,
                                                                      tmp_path, monkeypatch):
    from PySide6.QtWidgets import QFileDialog

    from tactile_studio.learn.experiments.train_job import eta_from_folds
    from tactile_studio.ui.research.window import ResearchWindow
    w = ResearchWindow()
    qtbot.addWidget(w)
    w.show()
    panel = w.train
    out = Path(panel.out.text())
    assert out.parent == tmp_path / "data" / "runs" and out.name.startswith("et-")
    panel.model.setCurrentText("knn")  # the name the panel chose follows the model
    assert Path(panel.out.text()).name.startswith("knn-")
    picked = tmp_path / "mine"
    picked.mkdir()
    monkeypatch.setattr(QFileDialog, "getExistingDirectory",
                        staticmethod(lambda *a, **k: str(picked)))
    qtbot.mouseClick(panel.browse_out, Qt.MouseButton.LeftButton)
    assert panel.out.text() == str(picked)
    panel.model.setCurrentText("rf")  # a folder the user chose stays
    assert panel.out.text() == str(picked)
    panel.model.setCurrentText("knn")
    panel.out.clear()  # nothing typed: Train names one instead of refusing
    w.sessions.set_folders([str(sessions)])
    assert panel.start()
    run = Path(panel.job.out)
    assert run.parent == picked.parent and run.name.startswith("knn-")  # beside the last
    qtbot.waitUntil(lambda: not panel.job.running, timeout=120_000)
    assert panel.job.finished.type == "done", panel.job.finished
    job = panel.job
    assert len(job.fold_times) == job.folds_done == job.folds_total == 3 and job.eta() == 0
    assert panel.out.text() != str(run)  # Train again: a new run, not the finished one
    assert eta_from_folds([2.0, 4.0], 2, 5, 1.0) == pytest.approx(8.0)  # 3 x 3 s - 1 s
    assert eta_from_folds([], 0, 5, 10.0) is None  # start-up is not a fold's pace


def test_the_training_curve_legend_leaves_the_curves_clear(qtbot):
    from tactile_studio.ui.research.train_panel import TrainPanel
    panel = TrainPanel(lambda: [])
    qtbot.addWidget(panel)
    panel.resize(1300, 700)
    panel.show()
    item = panel.plot.getPlotItem()
    epochs = list(range(1, 21))
    curves = [item.plot(epochs, [min(0.97, 0.35 + 0.1 * e * (1 + i / 10)) for e in epochs],
                        name=f"cnn1d-20260101 P0{i}") for i in range(6)]  # six learning folds
    qtbot.waitExposed(panel)
    qtbot.waitUntil(lambda: item.vb.sceneBoundingRect().width() > 200, timeout=2000)
    item.vb.updateAutoRange()  # what the next paint does
    assert item.vb.viewRange()[0][1] >= 20
    legend = item.legend.sceneBoundingRect()
    assert legend.width() > 0
    for curve in curves:
        for x, y in zip(*curve.getData()):
            point = item.vb.mapViewToScene(pg.Point(x, y))
            assert not legend.contains(point), (x, y)


def test_the_main_windows_file_menu_imports_old_recordings(qtbot):
    w = MainWindow(device="simulated", settings={"gesture": "idle"}, connect=False,
                   persist=False)
    qtbot.addWidget(w)
    file_menu = w.menuBar().actions()[0].menu()
    texts = [a.text().replace("&", "") for a in file_menu.actions()]
    assert "Import old recordings (ShearSense CSV)…" in texts  # where the README points
    w.import_action.trigger()
    dialog = w.research_window.import_dialog
    qtbot.addWidget(w.research_window)
    assert dialog is not None and dialog.isVisible()
    dialog.close()
    w.research_window.close()
    w.shutdown()


def test_the_players_prediction_strip_has_a_colour_legend(qtbot, tmp_path):
    import numpy as np
    from learn_fixtures import write_participant

    from tactile_studio.playback import SessionPlayback
    from tactile_studio.ui.research.timeline import Timeline, gesture_colour
    path = tmp_path / "P01.h5"
    write_participant(path, "P01", 7, gestures=("Poke", "Heavy Pat", "Back & Forth Rub"),
                      blocks=1)
    pb = SessionPlayback(path)
    t = Timeline()
    qtbot.addWidget(t)
    t.resize(900, 160)
    t.set_playback(pb)
    frames = np.linspace(0, pb.trials[-1].end, 20).astype(int)
    probs = np.zeros((20, 3))
    probs[:10, 0], probs[10:, 2] = 0.9, 0.7  # two gestures predicted, one never
    labels = ["Back & Forth Rub", "Heavy Pat", "Poke"]
    t.set_predictions(frames, probs, labels)
    t.show()
    entries = t.legend_entries()
    assert [n for n, _ in entries] == ["Back & Forth Rub", "Poke"]  # what the strip shows
    assert all(c == gesture_colour(t.names, n) for n, c in entries)  # the trials' colours
    image = t.grab().toImage()
    caption_rows = range(0, image.height() // 2 + 20)
    for _, colour in entries:  # each swatch is drawn
        assert any(image.pixelColor(x, y) == colour for y in caption_rows
                   for x in range(image.width() // 3, image.width())), colour.name()
    pb.close()
