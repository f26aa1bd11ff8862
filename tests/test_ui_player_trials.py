"""The session player around a trial (issue 47, items 2 and 8): jumping to a trial shows
it centred in the strip chart with what came before and after it (it showed the 10 s
before the trial, the trial itself off the right edge), the trial box follows the cursor
(it stayed on the first trial while the cursor played trial 7), and trial numbers count
from 1 as the console's do."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from learn_fixtures import write_participant
from PySide6.QtWidgets import QApplication

from tactile_studio.playback import SessionPlayback
from tactile_studio.playback.chart import ChartWindow
from tactile_studio.ui.research.player import SessionPlayer

GESTURES = ("Poke", "Heavy Pat", "Back & Forth Rub", "Tickle")
SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())


def test_the_chart_window_centres_a_trial_and_then_follows_the_cursor_without_jumps():
    w = ChartWindow(seconds=10.0, duration=60.0)
    assert w.centre_on(20.0, 22.0) == (16.0, 26.0)  # the trial's middle in the middle
    # playing from the trial's start: still until the cursor reaches the middle, then
    # the view moves with it, never leaving it behind and never jumping
    starts, t = [], 20.0
    while t < 40.0:
        a, b = w.follow(t)
        assert a <= t <= b
        starts.append(a)
        t += 0.05
    steps = np.diff(starts)
    assert starts[0] == 16.0 and np.all(steps >= 0) and steps.max() <= 0.05 + 1e-9
    assert w.follow(55.0) == (50.0, 60.0)  # a click far away: centred, inside the session
    assert w.centre_on(0.5, 2.5) == (0.0, 10.0)  # the first trial: the view starts at 0
    assert ChartWindow(10.0, 60.0).centre_on(20.0, 32.0) == (19.0, 29.0)  # a 12 s one
    assert ChartWindow(10.0, 4.0).follow(3.0) == (0.0, 10.0)  # a session shorter


@pytest.fixture
def session(tmp_path):
    return write_participant(tmp_path / "P01.h5", "P01", 101, GESTURES, blocks=3)


def test_jump_to_trial_centres_it_and_the_trial_box_follows_the_cursor(session, qtbot):
    player = SessionPlayer()
    qtbot.addWidget(player)
    player.resize(1300, 760)
    player.show()
    assert player.open_session(str(session))
    pb: SessionPlayback = player.pb
    # the trial box counts from 1, as the console ("Trial 1" is index 0)
    assert [player.trial_box.itemText(k).split(":")[0] for k in range(3)] == ["1", "2", "3"]
    six = pb.trial(5)
    player.jump_to_trial(5)
    assert player.current_frame() == six.start  # plays from the trial's start
    a, b = player.strip._x
    first, last = pb.time_of(six.start), pb.time_of(six.end - 1)
    assert (a + b) / 2 == pytest.approx((first + last) / 2, abs=1e-6)  # centred
    assert a < first - 3 and last + 3 < b  # with what came before and after it
    assert player.strip.cursor_line.value() == pytest.approx(first)
    shown = player.strip.line_data(player.strip.curve_names()[0])[0]
    assert shown.min() <= first - 3 and shown.max() >= last + 3  # the lines span it
    assert f"6: {six.gesture}" in player.strip.span_names()
    assert player.trial_box.currentText().startswith(f"6: {six.gesture}")
    assert player.position.text().endswith(f"trial 6 {six.gesture}")
    SHOTS.mkdir(parents=True, exist_ok=True)
    QApplication.processEvents()  # the labels laid out for their new texts
    player.grab().save(str(SHOTS / "research_player_trial.png"))
    # the cursor moved by the timeline into trial 8, then between 8 and 9: the box follows
    eight, nine = pb.trial(7), pb.trial(8)
    player.seek((eight.start + eight.end) // 2)
    assert player.trial_box.currentText().startswith(f"8: {eight.gesture}")
    assert player.strip._x[0] <= pb.time_of(player.current_frame()) <= player.strip._x[1]
    if nine.start > eight.end:
        player.seek(eight.end)  # after trial 8's last frame: still trial 8
        assert player.trial_box.currentText().startswith("8: ")
        assert player.position.text().endswith("between trials")
