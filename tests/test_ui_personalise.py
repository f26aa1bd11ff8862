"""Live inference's "Calibrate to person…" on the simulated sensor: the dialog prompts
each gesture of an rf run K times, the simulated person performs the named gesture, each
prompt records a labelled window (Skip and Redo too), the run's model is refit with them
off the GUI thread (progress, Cancel keeps the touches for Retrain) and predicts on; the
result line says what was done and the held-out check measured on their touches;
"Forget personalisation" returns to the run's model."""

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
    cfg = ExperimentConfig(data=[str(root / "data")], model="rf", evaluation="lopo",
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
        assert not panel.calibrate_button.isEnabled()  # no run yet
        assert panel.load_run(str(run))
        assert panel.calibrate_button.isEnabled() and not panel.forget_button.isEnabled()
        assert not hasattr(panel, "personalise_button")  # one way: Calibrate to person…
        run_model = panel.model.trained
        panel.calibrate_button.click()
        dialog = panel.dialog
        qtbot.addWidget(dialog)
        # an rf trained without --adapt has no statistics to take from a recording
        assert not dialog.recording_button.isEnabled()
        dialog.k.setValue(2)
        engine = w.acquisition.engine
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
        # the retraining started by itself, off the GUI thread: the dialog answers meanwhile
        assert dialog.retraining or dialog.result is not None
        qtbot.waitUntil(lambda: dialog.result is not None, timeout=60_000)
        first = dialog.result
        # in use at once; its held-out check is measured next, off the GUI thread too
        assert panel.model.personalised is first
        assert dialog.checking or first.check is not None
        qtbot.waitUntil(lambda: not dialog.retraining, timeout=60_000)
        windows, gestures, _ = p.labelled()
        assert gestures == [p.prompts[i] for i in (0, 2, 3, 4, 5)]
        assert all(x.shape[1] == panel.model.window_for(43.0) for x in windows)
        assert first.how == "refit" and first.per_gesture == 1
        # K = 2: each round's touches checked by the model personalised with the other
        assert first.check is not None and first.check.touches == 5
        state = dialog.state.text()
        assert "refit on the fold's training windows plus their 5 labelled windows" in state
        assert (f"Held-out check on their 5 touches, each round predicted by the model "
                f"personalised with the other: accuracy as trained {first.check.before:.2f}, "
                f"personalised {first.check.after:.2f}.") in state, state
        text = panel.calibration_label.text()
        assert "personalised to this person with 1 touch per gesture" in text, text
        assert f"held-out check {first.check.before:.2f} as trained" in text, text
        assert panel.model.personalised is first
        assert panel.model.trained is not run_model and panel.forget_button.isEnabled()
        # retrain with the same touches, cancelled: nothing changes, the touches stay
        assert dialog.retrain() and dialog.retraining and dialog.result is first
        assert dialog.prompt.text() == "Retraining…" and not dialog.recording_button.isEnabled()
        dialog.grab().save(str(SHOTS / "research_live_personalise_progress.png"))
        dialog.cancel_button.click()
        qtbot.waitUntil(lambda: not dialog.retraining, timeout=60_000)
        assert dialog.isVisible() and dialog.prompt.text() == "Not personalised"
        assert "retraining cancelled" in dialog.state.text()
        assert "the 5 touches are kept" in dialog.state.text()
        assert dialog.retrain_button.isVisible() and panel.model.personalised is first
        # retrained, and its check cancelled as soon as the model is in use: the model stays
        cancel_check = dialog.cancel_button.click
        dialog.personalised.connect(cancel_check)
        dialog.retrain_button.click()
        qtbot.waitUntil(lambda: dialog.result is not first and not dialog.retraining,
                        timeout=60_000)
        dialog.personalised.disconnect(cancel_check)
        assert panel.model.personalised is dialog.result and not dialog.retrain_button.isVisible()
        assert dialog.result.check is None and dialog.isVisible()
        assert dialog.state.text().endswith("Held-out check cancelled: nothing measured.")
        assert "held-out" not in panel.calibration_label.text()
        # and once more to the end: the same touches measure the same
        assert dialog.retrain()
        qtbot.waitUntil(lambda: dialog.result.check is not None and not dialog.retraining,
                        timeout=60_000)
        assert dialog.result.check == first.check  # same touches, same seed
        assert f"held-out check {first.check.before:.2f}" in panel.calibration_label.text()
        dialog.grab().save(str(SHOTS / "research_live_personalise_result.png"))
        assert dialog.start_button.isEnabled() and dialog.start_button.text() == "Start again"
        # closed while retraining: the retraining is cancelled and not used
        second_result = dialog.result
        assert dialog.retrain() and not dialog.start_button.isEnabled()
        job = dialog.job
        dialog.close()
        assert job.wait(60) and job.token.cancelled
        assert panel.model.personalised is second_result and dialog.result is second_result
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
