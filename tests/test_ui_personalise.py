"""Live inference's "Personalise with touches…" on the simulated sensor: the dialog prompts
each gesture of an rf run K times, the simulated person performs the named gesture, each
prompt records a labelled window (Skip and Redo too), the run's model is refit with them
and predicts on; "Forget personalisation" returns to the run's model."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.research.menu import live_inference_dock
from tactile_studio.ui.settings import SETTINGS_ENV

GESTURES = ("Poke", "Heavy Pat", "Twist")
SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("personal_ui")
    make_dataset_folder(root / "data", participants=3, blocks=3, gestures=GESTURES)
    cfg = ExperimentConfig(data=[str(root / "data")], model="rf", protocol="lopo",
                           preset="tiny", cache_dir=str(root / "cache"))
    run_experiment(cfg, root / "run")
    return root / "run"


@pytest.mark.slow
def test_prompted_touches_personalise_the_live_model(run, qtbot, tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    # the fixtures' data are easy virtual people: the live person is too
    w = MainWindow(device="simulated", settings={"rate": "43", "gesture": "idle",
                                                    "difficulty": "easy"},
                   connect=True, persist=False)
    qtbot.addWidget(w)
    w.resize(1300, 760)
    w.show()
    try:
        panel = live_inference_dock(w).widget()
        assert not panel.personalise_button.isEnabled()  # no run yet
        assert panel.load_run(str(run))
        assert panel.personalise_button.isEnabled() and not panel.forget_button.isEnabled()
        run_model = panel.model.trained
        dialog = panel.open_personalise()
        qtbot.addWidget(dialog)
        dialog.k.setValue(2)
        engine = w.controller.engine
        qtbot.waitUntil(lambda: engine.baseline is not None, timeout=20_000)
        assert dialog.start()
        p = dialog.prompts
        assert p.prompts == list(panel.model.labels) * 2
        asked = []

        def perform_prompt() -> None:
            """The person performs what the dialog asks, until it takes the window."""
            pos, gesture = p.pos, p.gesture
            asked.append(gesture)
            assert f"Perform {gesture} now" in dialog.prompt.text()
            engine.device.perform(gesture, 2.0)
            qtbot.waitUntil(lambda: p.pos > pos, timeout=30_000)

        perform_prompt()
        dialog.grab().save(str(SHOTS / "research_live_personalise_prompt.png"))
        qtbot.waitUntil(lambda: engine.device.current_gesture == "idle", timeout=10_000)
        dialog.redo()  # the first gesture again: its window is dropped
        assert p.pos == 0 and not p.answers and not dialog.redo_button.isEnabled()
        perform_prompt()
        qtbot.waitUntil(lambda: engine.device.current_gesture == "idle", timeout=10_000)
        dialog.skip()  # the second gesture's first round is left out
        assert p.pos == 2 and sorted(p.answers) == [0]
        while not p.done:
            perform_prompt()
            qtbot.waitUntil(lambda: engine.device.current_gesture == "idle", timeout=10_000)
        qtbot.waitUntil(lambda: dialog.result is not None, timeout=60_000)
        windows, gestures, _ = p.labelled()
        assert gestures == [p.prompts[i] for i in (0, 2, 3, 4, 5)]
        assert all(x.shape[1] == panel.model.window_for(43.0) for x in windows)
        assert dialog.result.how == "refit" and dialog.result.per_gesture == 1
        text = panel.calibration_label.text()
        assert "personalised to this person with 1 touch per gesture" in text, text
        assert panel.model.personalised is dialog.result
        assert panel.model.trained is not run_model and panel.forget_button.isEnabled()
        dialog.close()
        # the personalised model predicts on the live stream
        engine.device.set_gesture("Heavy Pat")
        qtbot.waitUntil(lambda: panel.inference is not None and panel.inference.count >= 14,
                        timeout=40_000)
        assert panel.inference.error is None and panel.top() in GESTURES
        w.grab().save(str(SHOTS / "research_live_personalised.png"))
        panel.forget_button.click()
        assert panel.model.personalised is None and panel.model.trained is run_model
        assert "personalised" not in panel.calibration_label.text()
        assert not panel.forget_button.isEnabled()
        # prompts for one run end when another run is loaded: they are not applied to it
        second = panel.open_personalise()
        qtbot.addWidget(second)
        assert second.start() and second.timer.isActive()
        assert panel.load_run(str(run))
        assert not second.isVisible() and not second.timer.isActive()
    finally:
        panel = live_inference_dock(w).widget()
        panel.stop()
        w.shutdown()
