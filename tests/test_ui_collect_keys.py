"""The collection console's keyboard and its first-day frictions, driven by key presses.

Real engine (the simulator, 8x real time), real session file, real widgets (pytest-qt,
offscreen). Every advertised shortcut is pressed in every state it applies to (labels
change between states: Start/Continue, Pause/Resume), letters typed outside the
participant screen and the focused mirror never start a trial, and a discarded trial's
gesture can be collected again at the end of its block.
"""

from __future__ import annotations

import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication
from test_ui_collect import (
    MINI,
    WAIT_MS,
    click,
    do_trial,
    make_console,
    open_mini,
    settle,
    snap,
    solid_png,
)

from tactile_studio.protocol.snapshot import State
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.ui.collect.beep import QtBeeper
from tactile_studio.ui.collect.console import CollectConsole

CTRL = Qt.KeyboardModifier.ControlModifier


@pytest.fixture
def env(tmp_path, monkeypatch, qapp):
    """test_ui_collect's protocol file (with its image) and an output folder."""
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    proto = tmp_path / "mini3.toml"
    proto.write_text(MINI)
    solid_png(tmp_path / "pics" / "poke.png", 60, 40)
    out = tmp_path / "data"
    out.mkdir()
    return proto, out


def press(qtbot, console: CollectConsole, key: Qt.Key) -> None:
    """Ctrl+key on the console window, as the experimenter types it (window shortcuts
    need the window active, as it is under the experimenter's hands)."""
    if QApplication.activeWindow() is not console:
        console.activateWindow()
        qtbot.waitUntil(lambda: QApplication.activeWindow() is console, timeout=2000)
    qtbot.keyClick(console, key, CTRL)


def test_every_shortcut_works_in_every_state_whatever_the_button_reads(qtbot, env):
    proto, out = env
    console = make_console(qtbot)
    s = console.setup
    s.set_protocol_file(str(proto))
    s.blocks.setValue(2)
    qtbot.keyClicks(s.participant, "P05")
    s.out_dir.setText(str(out))
    from test_ui_collect import fill_device
    fill_device(qtbot, console)
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert console.buttons["primary"].text() == "Start"
    press(qtbot, console, Qt.Key.Key_Return)  # Start
    qtbot.waitUntil(lambda: snap(console).state == State.FREE_PLAY, timeout=WAIT_MS)
    assert console.buttons["primary"].text() == "Continue"
    press(qtbot, console, Qt.Key.Key_Return)  # Continue (ends free play) under its new label
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)
    for _ in range(3):  # Pause, Resume, again and again: the label changes every time
        press(qtbot, console, Qt.Key.Key_P)
        assert snap(console).state == State.PAUSED and console.buttons["pause"].text() == "Resume"
        press(qtbot, console, Qt.Key.Key_P)
        assert snap(console).state == State.WAITING and console.buttons["pause"].text() == "Pause"
    # a trial without touching is flagged and held: Ctrl+Z redoes it
    g = snap(console).gestures[0] if snap(console).prompted is None else \
        next(x for x in snap(console).gestures if x.name == snap(console).prompted)
    do_trial(qtbot, console, g.name, g.key, perform=False, accept_flagged=False)
    assert snap(console).state == State.REVIEW and snap(console).can_continue
    press(qtbot, console, Qt.Key.Key_Z)
    assert snap(console).trials[0]["status"] == "redone"
    # again without touching: Ctrl+Return keeps it (Continue in the review state)
    do_trial(qtbot, console, g.name, g.key, perform=False, accept_flagged=False)
    assert snap(console).state == State.REVIEW
    press(qtbot, console, Qt.Key.Key_Return)
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)
    # Ctrl+D and Ctrl+N open their dialogs; Ctrl+F the participant screen
    press(qtbot, console, Qt.Key.Key_D)
    assert console.dialog is not None and console.dialog.windowTitle() == "Discard trial"
    console.dialog.reject()
    press(qtbot, console, Qt.Key.Key_N)
    assert console.dialog is not None and console.dialog.windowTitle() == "Session note"
    console.dialog.reject()
    press(qtbot, console, Qt.Key.Key_F)
    assert console.participant.isVisible()
    # Ctrl+B takes a break; Ctrl+Return ends it once its minimum is over
    press(qtbot, console, Qt.Key.Key_B)
    assert snap(console).state == State.BREAK
    qtbot.waitUntil(lambda: console.buttons["primary"].isEnabled(), timeout=WAIT_MS)
    press(qtbot, console, Qt.Key.Key_Return)
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)
    # paused in the break and out again: the state line says where it was paused
    press(qtbot, console, Qt.Key.Key_P)
    assert console.state.text() == ("Paused while waiting for the participant's key "
                                    "\u2014 Resume (Ctrl+P) to go on")
    press(qtbot, console, Qt.Key.Key_P)
    assert snap(console).state == State.WAITING
    console.close()


def test_letters_start_a_trial_only_from_the_participant_screen_or_the_focused_mirror(
        qtbot, env):
    proto, out = env
    console = make_console(qtbot)
    open_mini(qtbot, console, proto, out, blocks=1)
    key = next(g.key for g in snap(console).gestures if g.name == snap(console).prompted)
    console.log.setFocus()
    for target in (console, console.log, console.state, console.buttons["primary"]):
        qtbot.keyClick(target, key)  # the console, the trial log, a label, a button
        assert snap(console).state == State.WAITING and not snap(console).trials
    assert "Click the mirror" in console.mirror_hint.text()
    qtbot.mouseClick(console.mirror, Qt.MouseButton.LeftButton)  # the explicit focus
    assert console.mirror.hasFocus() and "go to the session" in console.mirror_hint.text()
    qtbot.keyClick(console.mirror, " ")  # Space is not a gesture key: nothing, no hint
    assert snap(console).state == State.WAITING and not snap(console).hint
    console.engine.device.perform(snap(console).prompted, duration_s=1.0)
    qtbot.keyClick(console.mirror, key)
    settle(qtbot, console, 1)
    assert len(snap(console).trials) == 1
    qtbot.mouseClick(console.log.viewport(), Qt.MouseButton.LeftButton)  # focus leaves
    assert not console.mirror.hasFocus() and "Click the mirror" in console.mirror_hint.text()
    console.close()


def test_a_discarded_gesture_is_collected_again_at_the_end_of_its_block(qtbot, env):
    proto, out = env
    console = make_console(qtbot)
    open_mini(qtbot, console, proto, out, blocks=1)
    order = list(console.runner.orders[0])
    keys = {g.name: g.key for g in console.protocol.gestures}
    first = do_trial(qtbot, console, order[0], keys[order[0]])
    click(qtbot, console, "discard")  # the last trial
    dialog = console.dialog
    assert f"trial 1 ({order[0]}, block 1)" in dialog.label.text()
    assert dialog.choice is not None and dialog.choice.isChecked()
    assert "at the end of block 1" in dialog.choice.text()
    assert "replaces this one" in dialog.cost.text()
    dialog.choice.setChecked(False)  # the dialog says what not collecting it costs
    assert f"no usable {order[0]} trial" in dialog.cost.text()
    dialog.choice.setChecked(True)
    qtbot.keyClicks(dialog.edit.lineEdit(), "started late")
    qtbot.mouseClick(dialog.buttons.buttons()[0], Qt.MouseButton.LeftButton)
    s = snap(console)
    assert s.trials[0]["status"] == "discarded" and s.trials[0]["collected_again"]
    assert s.trials[0]["reason"] == "started late"
    assert console.log.item(0, 3).text() == "discarded (started late; collected again)"
    assert list(s.remaining) == [*order[1:], order[0]]  # the discarded one comes last
    for name in [*order[1:], order[0]]:
        do_trial(qtbot, console, name, keys[name])
    qtbot.waitUntil(lambda: snap(console).state == State.FINISHED, timeout=WAIT_MS)
    path = console._closed_session_path
    with SessionFile(path) as f:
        trials = f.journal.trials
        events = [e for e in f.events if e.get("kind") == "discard"]
    assert [t["gesture"] for t in trials] == [*order, order[0]]
    assert trials[-1]["status"] == "ok" and trials[-1]["reason"] == "collected again for trial 1"
    assert events and events[0]["again"] is True and events[0]["trial"] == first["index"]
    assert {t["gesture"] for t in trials if t["status"] == "ok"} == set(order)
    assert console.log.item(3, 0).text() == "4"  # numbered from 1, as blocks are
    assert "collected again for trial 1" in console.log.item(3, 3).text()


def test_a_missing_speaker_is_said_once_in_the_console_and_by_test_sound(qtbot, env):
    proto, out = env
    console = CollectConsole(beeper=QtBeeper(audio=False))
    qtbot.addWidget(console)
    console.show()
    console.setup.set_protocol_file(str(proto))
    qtbot.mouseClick(console.setup.test_sound_button, Qt.MouseButton.LeftButton)
    assert "No sound (audio disabled)" in console.setup.sound_result.text()
    assert console.beeper.requests[-1].frequency_hz == 880.0  # the protocol's own beep
    open_mini(qtbot, console, proto, out, blocks=1)
    assert console.sound_notice.isVisible()
    assert console.sound_notice.text().startswith("No sound (audio disabled)")
    console.close()


def test_setup_clears_a_fixed_error_and_remembers_a_protocol_file(qtbot, env, tmp_path,
                                                                  monkeypatch):
    proto, out = env
    data = tmp_path / "appdata"
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(data))
    console = make_console(qtbot)
    s = console.setup
    assert s.out_dir.text() == str(data / "sessions")  # not the folder the app started in
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert "participant" in s.error.text()
    qtbot.keyClicks(s.participant, "P0")
    assert s.error.text() == ""  # the message went with the fix
    s.set_protocol_file(str(proto))
    assert s.blocks.value() == 3  # the protocol's own count
    from test_ui_collect import fill_device
    fill_device(qtbot, console)
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert console.stack.currentIndex() == 1 and (data / "sessions").is_dir()
    assert console.session.path.parent == data / "sessions"
    console.close()
    again = make_console(qtbot)  # the next session starts from the last one's protocol
    assert again.setup.blocks.value() == 3 and "mini3.toml" in again.setup.protocol.currentText()
    again.close()


def test_resume_form_hides_what_the_file_decides(qtbot, env, monkeypatch):
    from PySide6.QtWidgets import QFileDialog
    console = make_console(qtbot)
    s = console.setup
    assert s.participant.isVisible() and not s.resume_file.isVisible()
    monkeypatch.setattr(QFileDialog, "getOpenFileName", staticmethod(lambda *a, **k: ("", "")))
    qtbot.mouseClick(s.resume_button, Qt.MouseButton.LeftButton)  # cancelled: back to new
    assert s.participant.isVisible() and s.title.text() == "New collection session"
    junk = env[1] / "junk.h5"
    junk.write_bytes(b"not hdf5")
    monkeypatch.setattr(QFileDialog, "getOpenFileName",
                        staticmethod(lambda *a, **k: (str(junk), "")))
    qtbot.mouseClick(s.resume_button, Qt.MouseButton.LeftButton)
    assert s.title.text() == "Resume a collection session" and s.resume_file.isVisible()
    for hidden in (s.protocol, s.participant, s.condition, s.blocks, s.seed, s.out_dir,
                   s.start_button):
        assert not hidden.isVisible()
    assert s.device.isVisible() and s.hold_flagged.isVisible() and s.continue_button.isVisible()
    assert str(junk) in s.error.text()  # the failed resume says why, under the resume form
    qtbot.mouseClick(s.new_button, Qt.MouseButton.LeftButton)
    assert s.participant.isVisible() and not s.resume_file.isVisible()


LONG = "Twist slowly with the whole flat hand, then hold it still"


def test_the_mirror_fills_its_pane_and_long_lines_wrap_in_the_left_pane(qtbot, env, tmp_path):
    """Issue 47 item 15: the mirror filled a third of its pane (the rest empty around
    it), and the left pane widened whenever the state line or a hint grew."""
    proto, out = env
    long_proto = tmp_path / "long.toml"
    long_proto.write_text(MINI.replace('name = "Twist"', f'name = "{LONG}"'))
    console = make_console(qtbot)
    console.resize(1500, 900)
    open_mini(qtbot, console, long_proto, out, blocks=1)
    settle_ui = lambda: QApplication.processEvents()  # noqa: E731 - layouts run on events
    settle_ui()
    m = console.mirror
    painted_w = min(m.width(), m.height() * m.aspect)  # its 16:9 screen, letterboxed
    assert painted_w >= 0.97 * m.width(), (m.width(), m.height())
    widths, said = [], []
    keys = {g.name: g.key for g in console.protocol.gestures}
    for name in console.runner.orders[0]:
        qtbot.keyClick(console.participant, "z")  # refused: a hint naming the prompt
        settle_ui()
        said += [console.state.text(), console.hint_label.text()]
        widths.append(console.page_splitter.sizes()[0])
        do_trial(qtbot, console, name, keys[name], perform=name != LONG)
        settle_ui()
        widths.append(console.page_splitter.sizes()[0])
    assert f"next is {LONG} (T)" in " ".join(said)  # the long lines were shown
    assert len(set(widths)) == 1, widths
