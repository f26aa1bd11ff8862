"""Live inference in the main window on the simulated sensor: a knn run trained on
virtual participants is loaded into the Live inference dock; predictions follow the
simulated gesture, show top-3 and latency, and are recorded as events while recording."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.storage import SessionFile
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.research.menu import live_inference_dock
from tactile_studio.ui.settings import SETTINGS_ENV

GESTURES = ("Poke", "Heavy Pat", "Twist")
# screenshots for review: TACTILE_STUDIO_SCREENSHOTS=docs/screenshots pytest ...
SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("live")
    make_dataset_folder(root / "data", participants=3, blocks=4, gestures=GESTURES)
    cfg = ExperimentConfig(data=[str(root / "data")], model="knn", evaluation="lopo",
                           preset="tiny", cache_dir=str(root / "cache"))
    run_experiment(cfg, root / "run")
    return root / "run"


def _window(qtbot) -> MainWindow:
    """The main window on the simulated sensor performing Heavy Pat."""
    w = MainWindow(device="simulated", settings={"rate": "43", "gesture": "Heavy Pat",
                                                    "difficulty": "easy"},
                   connect=True, persist=False)
    qtbot.addWidget(w)
    w.resize(1300, 760)
    w.show()
    return w


@pytest.mark.slow
def test_live_inference_follows_the_simulated_gesture(run, qtbot, tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    w = _window(qtbot)
    try:
        action = next(a for m in w.menuBar().actions() for a in m.menu().actions()
                      if "Live inference" in a.text())
        action.trigger()
        panel = w.live_dock.widget()
        assert live_inference_dock(w) is w.live_dock
        assert not panel.load_run(str(tmp_path / "nope"))
        assert "no such run folder" in panel.message.text()
        assert panel.load_run(str(run))
        # a full window of the gesture (86 frames at 43 Hz) after the baseline
        qtbot.waitUntil(lambda: panel.inference is not None and panel.inference.count >= 14,
                        timeout=40_000)
        qtbot.wait(300)
        first = panel.top()
        assert first == "Heavy Pat", panel.inference.latest.top3
        assert "latency" in panel.latency.text() and "ms" in panel.latency.text()
        assert sum(bar.value() for _, bar in panel.rows) <= 101
        SHOTS.mkdir(parents=True, exist_ok=True)
        w.grab().save(str(SHOTS / "research_live_inference.png"))
        # record while the gesture changes: the prediction changes and is recorded
        path = tmp_path / "rec.h5"
        w.acquisition.connect("simulated", {"rate": "43", "gesture": "Poke", "difficulty": "easy"})
        w.acquisition.start_recording(path)
        qtbot.waitUntil(lambda: panel.inference is not None
                        and panel.inference.engine is w.acquisition.engine
                        and panel.inference.count >= 14, timeout=40_000)
        assert panel.top() == "Poke", panel.inference.latest.top3
        w.acquisition.stop_recording()
        with SessionFile(path) as s:
            preds = [e for e in s.events if e.get("kind") == "prediction"]
        assert preds and preds[-1]["gesture"] == "Poke"
        assert all(e["gesture"] in GESTURES and e["run"] == "run" for e in preds)
    finally:
        if getattr(w, "live_dock", None) is not None:
            w.live_dock.widget().stop()
        w.shutdown()


@pytest.mark.slow
def test_an_adapted_rf_predicts_as_trained_until_calibrated_to_the_person(run, qtbot, tmp_path,
                                                                       monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    root = run.parent
    cfg = ExperimentConfig(data=[str(root / "data")], model="rf", evaluation="lopo",
                           preset="tiny", cache_dir=str(root / "cache"), adapt="person")
    run_experiment(cfg, root / "rf_adapted")
    w = _window(qtbot)
    try:
        panel = live_inference_dock(w).widget()
        assert panel.load_run(str(root / "rf_adapted"))
        assert panel.running_box.isEnabled() and panel.running_box.isChecked()  # default
        assert "from their own last touches" in panel.calibration_label.text()
        panel.running_box.setChecked(False)
        assert "pooled feature statistics" in panel.calibration_label.text()
        assert "a recording of them" in panel.calibration_label.text()
        panel.refresh()  # as trained: features standardised with the training people's
        assert panel.inference is not None and panel.model.reference is None
        qtbot.waitUntil(lambda: panel.top() in GESTURES, timeout=40_000)
        w.grab().save(str(SHOTS / "research_live_rf_as_trained.png"))
        # Calibrate to person… > From an earlier recording… (an rf trained with --adapt)
        panel.calibrate_button.click()
        dialog = panel.dialog
        qtbot.addWidget(dialog)
        assert dialog.recording_button.isEnabled()
        assert not dialog.from_recording(str(tmp_path / "nope.h5"))
        assert "nope.h5" in dialog.state.text() and "\n" not in dialog.state.text()
        assert dialog.prompt.text() == "Not calibrated"
        assert dialog.from_recording(str(root / "data" / "P02.h5"))
        assert "calibrated to the person in P02.h5" in panel.calibration_label.text()
        assert "calibrated to the person in P02.h5" in dialog.state.text()
        dialog.close()
        qtbot.waitUntil(lambda: panel.inference is not None and panel.top() in GESTURES,
                        timeout=40_000)
        assert panel.inference.error is None
        w.grab().save(str(SHOTS / "research_live_calibrated.png"))
        # adapting as they touch instead: from their last touches
        panel.running_box.setChecked(True)
        assert panel.model.reference is None and panel.inference is None
        qtbot.waitUntil(lambda: "their last" in panel.calibration_label.text()
                        and panel.top() in GESTURES, timeout=40_000)
        assert panel.inference.error is None and panel.inference.adapting.count >= 3
        w.grab().save(str(SHOTS / "research_live_adapting.png"))
        assert panel.load_run(str(run))  # knn as trained: no statistics to take, touches only
        assert panel.calibrate_button.isEnabled() and not panel.running_box.isEnabled()
        assert not panel.open_personalise().recording_button.isEnabled()
        assert "as trained" in panel.calibration_label.text()
    finally:
        panel.stop()
        w.shutdown()


@pytest.mark.slow
def test_a_network_fused_with_an_adapted_forest_predicts_as_trained_too(run, qtbot, tmp_path,
                                                                       monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    root = run.parent
    cfg = ExperimentConfig(data=[str(root / "data")], model="cnn1d", evaluation="lopo",
                           preset="tiny", epochs=2, cache_dir=str(root / "cache"),
                           adapt="person", overrides={"rf_weight": 0.5})
    run_experiment(cfg, root / "fused_adapted")
    w = _window(qtbot)
    try:
        panel = live_inference_dock(w).widget()
        assert panel.load_run(str(root / "fused_adapted"))
        assert "cnn1d + rf 0.5 (all)" in panel.run_label.text()
        assert panel.calibrate_button.isEnabled() and panel.running_box.isChecked()
        assert "(as trained until enough touches)" in panel.calibration_label.text()
        panel.running_box.setChecked(False)
        text = panel.calibration_label.text()
        assert "pooled feature statistics for its forest" in text and "5 points" not in text
        panel.refresh()  # the network's batch norm and the forest's pooled view
        assert panel.inference is not None and panel.model.reference is None
        qtbot.waitUntil(lambda: panel.top() in GESTURES, timeout=40_000)
        assert panel.inference.error is None
        w.grab().save(str(SHOTS / "research_live_fused_as_trained.png"))
    finally:
        panel.stop()
        w.shutdown()
