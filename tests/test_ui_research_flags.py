"""The research workspace filters trials by flag: the session player lists all trials,
the flagged ones, or one flag's (each flagged trial says why, the model's reason too),
the sessions view can list only the sessions with flagged trials, and the Train tab
can leave flagged trials out (train --exclude-flagged).

The session is a real collection (the simulated sensor, the runner, a model check of
the test's own that flags a trial nobody touched as 'looks like nothing'), so the flags
and checks are exactly what a collection stores.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from collect_fixtures import do_trial, make_rig, mini_protocol, start
from PySide6.QtCore import Qt

from tactile_studio.playback import ANY_FLAG
from tactile_studio.protocol.trial_check import TrialVerdict, verdict
from tactile_studio.ui.research.player import SessionPlayer
from tactile_studio.ui.research.sessions_view import COLUMNS, SessionsView
from tactile_studio.ui.research.train_panel import TrainPanel


class TouchedOrNot:
    """Flags a trial the sensor was barely touched in: it 'looks like nothing'."""

    def __init__(self, gestures: list[str]) -> None:
        self.known = frozenset(gestures)
        self.labels = [*sorted(gestures), "nothing"]

    def describe(self) -> dict:
        return {"model": "touched", "version": "1", "top_k": 1, "threshold": 0.5}

    def check(self, layout, raw, baseline, rate_hz, prompted) -> TrialVerdict | None:  # noqa: ANN001
        touched = float((np.asarray(raw) < 0.985 * baseline).any(axis=1).mean()) >= 0.1
        probs = np.zeros(len(self.labels))
        probs[self.labels.index(prompted)] = 0.9 if touched else 0.2
        probs[-1] = 1.0 - probs[self.labels.index(prompted)]
        return verdict(self.labels, probs, prompted, top_k=1, threshold=0.5)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> Path:
    """One block of three gestures, the first nobody touched (flagged, by the signal and
    the model); and another session of two gestures without a check or flags."""
    folder = tmp_path_factory.mktemp("flags")
    protocol = mini_protocol(3, blocks=1)
    rig = make_rig(folder / "flagged", protocol, "P01",
                   trial_check=TouchedOrNot(protocol.gesture_names))
    try:
        start(rig)
        for k, g in enumerate(list(rig.runner.snapshot().remaining)):
            do_trial(rig, g, perform=k > 0)
    finally:
        rig.close()
    clean = mini_protocol(2, blocks=1)
    rig = make_rig(folder / "clean", clean, "P02")
    try:
        start(rig)
        for g in list(rig.runner.snapshot().remaining):
            do_trial(rig, g)
    finally:
        rig.close()
    return folder


def test_the_player_lists_all_flagged_or_one_flags_trials_with_their_reason(qtbot, recorded):
    path = next((recorded / "flagged").glob("*.h5"))
    player = SessionPlayer()
    qtbot.addWidget(player)
    assert player.open_session(str(path))
    trials = player.pb.trials
    flagged = [t.index for t in trials if t.flags]
    model = [t.index for t in trials if "model_mismatch" in t.flags]
    # a light Poke now and then reads as no contact on the simulator (and so to the
    # test's model): the expected lists come from the stored flags, not a fixed count
    none = [t.index for t in trials if "no_contact" in t.flags]
    assert trials[0].flags == ["no_contact", "model_mismatch"] and len(trials) == 3
    assert 1 not in flagged  # a touched trial that looks like its gesture
    labels = [player.flag_filter.itemText(k) for k in range(player.flag_filter.count())]
    assert labels == ["All trials (3)", f"Flagged ({len(flagged)})", f"no contact ({len(none)})",
                      f"does not look like the prompted gesture ({len(model)})"]
    assert player.listed_trials() == [0, 1, 2]
    player.set_flag_filter(ANY_FLAG)
    assert player.listed_trials() == flagged
    assert player.current_frame() == player.pb.trial(0).start  # it went to the first
    text = player.trial_box.itemText(0)
    gesture = trials[0].gesture
    assert text == (f"1: {gesture} (ok) \u2014 no contact, looks like nothing (0.80); "
                    f"{gesture} 0.20")
    player.set_flag_filter("no_contact")
    assert player.listed_trials() == none and none[0] == 0
    player.set_flag_filter("model_mismatch")
    assert player.listed_trials() == model
    player.set_flag_filter(None)
    assert player.listed_trials() == [0, 1, 2]


def test_the_sessions_view_can_list_only_sessions_with_flagged_trials(qtbot, recorded):
    view = SessionsView()
    qtbot.addWidget(view)
    view.show()
    view.set_folders([str(recorded / "flagged"), str(recorded / "clean")])

    def shown() -> list[str]:
        return sorted(view.table.item(r, COLUMNS.index("participant")).text()
                      for r in range(view.table.rowCount()) if not view.table.isRowHidden(r))
    assert shown() == ["P01", "P02"]
    qtbot.mouseClick(view.only_flagged, Qt.MouseButton.LeftButton)
    assert shown() == ["P01"]
    view.stop_checks(wait_s=5)


def test_the_train_tab_can_leave_flagged_trials_out(qtbot, recorded, tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    path = str(next((recorded / "flagged").glob("*.h5")))
    panel = TrainPanel(lambda: [path])
    qtbot.addWidget(panel)
    assert not panel.exclude_flagged.isChecked()  # off by default, as train's option
    assert panel.config().exclude_flagged is False
    panel.exclude_flagged.setChecked(True)
    assert panel.config().exclude_flagged is True
    assert "exclude-flagged" in panel.exclude_flagged.toolTip()
