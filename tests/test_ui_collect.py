"""The collection screens, driven like an experimenter and a participant would.

Real engine, real simulated sensor (8x faster than real time), real session file, real
widgets (pytest-qt, offscreen). The participant "performs" a gesture through the
simulator's ``perform`` and presses its key; the experimenter clicks the console's
buttons. Budget: about 15 s for the file on 2 cores.
"""

from __future__ import annotations

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtGui import QColor, QImage
from PySide6.QtWidgets import QComboBox, QFileDialog

from tactile_studio.protocol.runner_events import StateChanged
from tactile_studio.protocol.snapshot import State
from tactile_studio.protocol.tone import tone_pcm, tone_samples
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.ui.collect.beep import QtBeeper
from tactile_studio.ui.collect.console import CollectConsole
from tactile_studio.ui.collect.log import FLAGGED_BG
from tactile_studio.ui.collect.participant import Card, ParticipantScreen, ParticipantView

MINI = """
name = "mini3"
title = "Mini 3 gestures"
description = "three gestures, short trials, a break after every block"
trial_s = 0.5
blocks = 3
free_play_s = 0.3

[breaks]
every_blocks = 1
min_s = 0.3

[beep]
frequency_hz = 880.0
length_s = 0.05

[[gestures]]
name = "Poke"
key = "p"
definition = "Press one fingertip firmly into the sensor and lift it again, once."
image = "pics/poke.png"

[[gestures]]
name = "Twist"
key = "t"
definition = "Press your fingertips onto the sensor and rotate your hand without sliding."

[[gestures]]
name = "Tickle"
key = "k"
definition = "Tickle the sensor with quick, light movements of your fingertips."
"""
# a participant who performs every gesture as asked (`easy`): these tests are the console's
# flows; how varied people are is test_population's (the default, `people`, is light
# enough in a 0.5 s trial to be flagged 'no contact' in about one trial in seven)
SIM = {"speed": "8", "gesture": "idle", "difficulty": "easy"}
WAIT_MS = 15_000
BUSY = (State.RECORDING, State.TRIAL_END)
SEEN_RECORDING: list[str] = []  # trials whose countdown screen the test saw
SEEN_PROMPTS: dict[str, str | None] = {}  # prompted gesture -> the image on its large card


MAGENTA = QColor(255, 0, 255)


def solid_png(path, width: int, height: int, color: QColor = MAGENTA) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    image = QImage(width, height, QImage.Format.Format_RGB32)
    image.fill(color)
    assert image.save(str(path))
    return str(path)


@pytest.fixture
def env(tmp_path, monkeypatch, qapp):
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    proto = tmp_path / "mini3.toml"
    proto.write_text(MINI)
    solid_png(tmp_path / "pics" / "poke.png", 60, 40)
    out = tmp_path / "data"
    out.mkdir()
    return proto, out


def make_console(qtbot) -> CollectConsole:
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    return console


def fill_device(qtbot, console: CollectConsole) -> None:
    s = console.setup
    s.device.setCurrentIndex(s.device.findData("simulated"))
    for name, value in SIM.items():  # typed into the plugin's generated form
        editor = s.device_form.fields[name].editor
        if isinstance(editor, QComboBox):
            editor.setCurrentText(value)
            assert editor.currentText() == value
            continue
        editor.clear()
        qtbot.keyClicks(editor, value)


def snap(console: CollectConsole):
    return console.runner.snapshot()


def click(qtbot, console: CollectConsole, name: str) -> None:
    button = console.buttons[name]
    assert button.isEnabled(), f"{name} is disabled"
    qtbot.mouseClick(button, Qt.MouseButton.LeftButton)


def settle(qtbot, console: CollectConsole, n_trials: int) -> None:
    """Wait until the runner has written ``n_trials`` and left the trial states."""
    qtbot.waitUntil(lambda: len(snap(console).trials) >= n_trials
                    and snap(console).state not in BUSY, timeout=WAIT_MS)


def perform_after_the_last(qtbot, console: CollectConsole, name: str) -> None:
    """The participant performs ``name`` once the previous gesture has ended, as a person
    does: a key-started trial that began during the last one's release is rightly flagged
    'release_overlap'. 0.8 s: a whole gesture (ramps in and out) around a 0.5 s trial."""
    device = console.engine.device
    qtbot.waitUntil(lambda: device.next_frame >= device.performing_until, timeout=WAIT_MS)
    device.perform(name, duration_s=0.8)


def do_trial(qtbot, console: CollectConsole, name: str, key: str, perform: bool = True,
             via_participant: bool = True, accept_flagged: bool = True) -> dict:
    """The participant starts ``name``'s gesture and presses its key; returns the trial."""
    n = len(snap(console).trials)
    if perform:
        perform_after_the_last(qtbot, console, name)
    target = console.participant if via_participant else console.mirror
    prompt = console.participant.view.prompt
    if prompt is not None:
        assert prompt.name == name  # the test follows the prompt
        SEEN_PROMPTS[prompt.name] = prompt.image
    qtbot.keyClick(target, key)
    view = console.participant.view
    if snap(console).state == State.RECORDING:  # (a starved test thread may miss it)
        assert view.mode == "recording" and view.title == name
        assert view.countdown_s is not None and 0 < view.countdown_s <= 0.5
        assert console.mirror.view == view
        SEEN_RECORDING.append(name)
    settle(qtbot, console, n + 1)
    s = snap(console)
    if accept_flagged and s.state == State.REVIEW and s.can_continue:  # held: flagged
        click(qtbot, console, "primary")
    return s.trials[n]


def finish_block(qtbot, console: CollectConsole, via_participant: bool = True) -> None:
    s = snap(console)
    for g in s.gestures:
        if not g.done:
            trial = do_trial(qtbot, console, g.name, g.key, via_participant=via_participant)
            assert trial["gesture"] == g.name and trial["status"] == "ok"


def continue_after_break(qtbot, console: CollectConsole) -> None:
    qtbot.waitUntil(lambda: snap(console).state == State.BREAK, timeout=WAIT_MS)
    view = console.participant.view
    assert view.mode == "break" and view.title == "Break" and not view.cards
    qtbot.waitUntil(lambda: console.buttons["primary"].isEnabled(), timeout=WAIT_MS)
    click(qtbot, console, "primary")
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)


def test_session_end_to_end_with_redo_discard_break_and_resume(qtbot, env, monkeypatch):
    proto, out = env
    SEEN_RECORDING.clear()
    SEEN_PROMPTS.clear()
    console = make_console(qtbot)
    s = console.setup
    # protocol from a file, through the "From file..." entry and its dialog
    monkeypatch.setattr(QFileDialog, "getOpenFileName",
                        staticmethod(lambda *a, **k: (str(proto), "")))
    s.protocol.setCurrentIndex(s.protocol.count() - 1)
    assert "Mini 3 gestures" in s.protocol_info.text() and s.blocks.value() == 3
    qtbot.keyClicks(s.participant, "P07")
    s.out_dir.clear()
    qtbot.keyClicks(s.out_dir, str(out))
    fill_device(qtbot, console)
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert s.error.text() == "" and console.stack.currentIndex() == 1
    path = console.session.path
    states: list[str] = []
    console.runner.add_listener(lambda e: isinstance(e, StateChanged) and states.append(e.state))
    assert console.participant.view.mode == "setup"
    click(qtbot, console, "screen")
    assert console.participant.isVisible()
    assert console.mirror.aspect == pytest.approx(16 / 9)

    click(qtbot, console, "primary")  # Start
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)
    assert "free_play" in states
    view = console.participant.view
    assert view.block_label == "Block 1 of 3" and len(view.cards) == 3
    # the protocol's image (relative to the protocol file) reaches the participant's card
    images = {"Poke": str(proto.parent / "pics" / "poke.png"), "Twist": None, "Tickle": None}
    assert {g.name: g.image for g in snap(console).gestures} == images
    assert view.prompt.image == images[view.prompt.name]  # on the large prompted card
    first = snap(console).gestures[0]

    # 1. a trial without touching: flagged, held, highlighted, prompted; then redone
    trial = do_trial(qtbot, console, first.name, first.key, perform=False, accept_flagged=False)
    assert "no_contact" in trial["flags"]
    assert snap(console).state == State.REVIEW and console.redo_banner.isVisible()
    assert "no contact" in console.redo_banner.text()
    assert console.log.flagged_rows() == [0]
    assert console.log.item(0, 4).background().color() == FLAGGED_BG
    other = snap(console).gestures[1]
    qtbot.keyClick(console.participant, other.key)  # refused while the experimenter decides
    assert snap(console).state == State.REVIEW and console.participant.view.hint
    click(qtbot, console, "redo")
    s1 = snap(console)
    assert s1.trials[0]["status"] == "redone" and first.name in s1.remaining
    assert not console.redo_banner.isVisible() and console.log.flagged_rows() == []

    # 2. block 1 by key presses (alternating windows); a done gesture's key is refused
    do_trial(qtbot, console, first.name, first.key)
    qtbot.keyClick(console.mirror, first.key)
    assert "already done" in console.participant.view.hint
    assert snap(console).state == State.WAITING
    finish_block(qtbot, console, via_participant=False)

    # 3. the break; the experimenter continues once its minimum is over
    continue_after_break(qtbot, console)
    assert console.participant.view.block_label == "Block 2 of 3"

    # 4. discard trial 1 with a reason, from the log's selection and the dialog
    console.log.select_index(1)
    click(qtbot, console, "discard")
    dialog = console.dialog
    assert dialog is not None and "trial 2 (" in dialog.label.text()  # shown 1-based
    assert dialog.choice is None and "block 1 is over" in dialog.cost.text().lower()
    qtbot.keyClicks(dialog.edit.lineEdit(), "participant sneezed")
    qtbot.mouseClick(dialog.buttons.buttons()[0], Qt.MouseButton.LeftButton)
    t1 = snap(console).trials[1]
    assert t1["status"] == "discarded" and t1["reason"] == "participant sneezed"

    # 5. one trial of block 2, then the console is closed mid-block
    g = snap(console).gestures[0]
    mid = do_trial(qtbot, console, g.name, g.key)
    assert mid["block"] == 1
    beeps_before = list(console.beeper.requests)
    console.close()
    with SessionFile(path) as sess:
        assert sess.n_frames > 0 and len(sess.journal.trials) == 5

    # 6. a new console resumes the file and the session runs to the end
    console2 = make_console(qtbot)
    fill_device(qtbot, console2)
    monkeypatch.setattr(QFileDialog, "getOpenFileName",
                        staticmethod(lambda *a, **k: (str(path), "")))
    qtbot.mouseClick(console2.setup.resume_button, Qt.MouseButton.LeftButton)
    assert console2.setup.error.text() == "" and console2.stack.currentIndex() == 1
    s2 = snap(console2)
    assert s2.block_number == 2 and [x.name for x in s2.gestures if x.done] == [g.name]
    click(qtbot, console2, "primary")  # Start (no free play again)
    qtbot.waitUntil(lambda: snap(console2).state == State.WAITING, timeout=WAIT_MS)
    finish_block(qtbot, console2)
    continue_after_break(qtbot, console2)
    finish_block(qtbot, console2)
    qtbot.waitUntil(lambda: console2.session is None, timeout=WAIT_MS)  # closed when finished
    assert snap(console2).state == State.FINISHED
    assert console2.participant.view.mode == "finished"
    assert console2.file_label.text().startswith("Saved:")

    # the file: every completed trial exactly once, with the right statuses
    with SessionFile(path) as sess:
        trials = sess.journal.trials
        meta = sess.metadata
        n_rows = sess.n_frames
    assert [t["index"] for t in trials] == list(range(len(trials)))
    statuses = [t["status"] for t in trials]
    assert statuses.count("redone") == 1 and trials[0]["status"] == "redone"
    assert statuses.count("discarded") == 1 and trials[1]["reason"] == "participant sneezed"
    counted = [(t["block"], t["gesture"]) for t in trials if t["status"] != "redone"]
    assert len(counted) == len(set(counted)) == 9
    orders = meta["block_order"]
    for b in range(3):
        assert sorted(gg for bb, gg in counted if bb == b) == sorted(orders[b])
    lengths = {t["end_sample"] - t["start_sample"] for t in trials}
    assert len(lengths) == 1 and lengths.pop() == round(0.5 * 43.0)
    assert all(0 <= t["start_sample"] < t["end_sample"] <= n_rows for t in trials)
    assert meta["participant"] == "P07" and meta.get("resumes") == 1
    # one beep per finished trial, as the protocol asks, across both windows
    beeps = beeps_before + console2.beeper.requests
    assert len(beeps) == len(trials) == 10
    assert {(b.frequency_hz, b.length_s) for b in beeps} == {(880.0, 0.05)}
    assert len(SEEN_RECORDING) >= 5  # the countdown was on screen during the trials
    assert SEEN_PROMPTS == images  # every gesture was prompted, with its image


def open_mini(qtbot, console: CollectConsole, proto, out, blocks: int) -> None:
    s = console.setup
    s.set_protocol_file(str(proto))
    s.blocks.setValue(blocks)
    qtbot.keyClicks(s.participant, "P05")
    s.out_dir.setText(str(out))
    fill_device(qtbot, console)
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert s.error.text() == "" and console.stack.currentIndex() == 1
    click(qtbot, console, "primary")  # Start
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)


def test_prompted_order_is_enforced_by_key_presses(qtbot, env):
    proto, out = env
    console = make_console(qtbot)
    open_mini(qtbot, console, proto, out, blocks=1)
    order = console.runner.orders[0]
    keys = {g.name: g.key for g in console.protocol.gestures}
    for i, name in enumerate(order):
        view = console.participant.view
        # the prompted gesture is shown large, the block's cards marked done/next/upcoming
        assert view.mode == "waiting" and view.prompt is not None
        assert view.prompt.name == name and view.prompt.key == keys[name]
        assert view.title == f"Next: {name}" and console.mirror.view == view
        assert [c.note for c in view.cards] == \
            ["done"] * i + ["next"] + ["upcoming"] * (len(order) - i - 1)
        assert f"next is {name} ({keys[name].upper()})" in console.state.text()
        refusal = f"Next is {name} \u2013 press {keys[name].upper()}"
        for wrong in [*order[:i], *order[i + 1:]]:  # done or upcoming: refused, named
            qtbot.keyClick(console.participant, keys[wrong])
            assert snap(console).state == State.WAITING and len(snap(console).trials) == i
            assert console.participant.view.hint.endswith(refusal)
            assert console.hint_label.text().endswith(refusal)
        qtbot.keyClick(console.participant, "x")  # not a gesture key: named too
        assert console.participant.view.hint == f"'x' is not a gesture key. {refusal}"
        trial = do_trial(qtbot, console, name, keys[name])  # the prompted key starts it
        assert trial["gesture"] == name and trial["status"] == "ok"
    qtbot.waitUntil(lambda: snap(console).state == State.FINISHED, timeout=WAIT_MS)
    assert [t["gesture"] for t in snap(console).trials] == order


def test_free_order_protocol_takes_any_remaining_key(qtbot, env):
    proto, out = env
    proto.write_text(MINI.replace('free_play_s = 0.3', 'free_play_s = 0.3\norder = "free"'))
    console = make_console(qtbot)
    open_mini(qtbot, console, proto, out, blocks=1)
    order = console.runner.orders[0]
    keys = {g.name: g.key for g in console.protocol.gestures}
    assert console.participant.view.prompt is None
    assert "free order" in console.state.text() and "free order" in console.progress_label.text()
    for name in reversed(order):  # any remaining gesture's key starts its trial
        assert do_trial(qtbot, console, name, keys[name])["gesture"] == name
    qtbot.waitUntil(lambda: snap(console).state == State.FINISHED, timeout=WAIT_MS)
    assert [t["gesture"] for t in snap(console).trials] == order[::-1]
    with SessionFile(console.session.path if console.session
                     else console._closed_session_path) as f:
        assert f.metadata["trial_order"] == "free"


def test_setup_errors_are_one_line_and_nothing_opens(qtbot, env, tmp_path):
    _, out = env
    console = make_console(qtbot)
    s = console.setup
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert "participant" in s.error.text() and console.stack.currentIndex() == 0
    qtbot.keyClicks(s.participant, "P01")
    in_the_way = tmp_path / "a-file"  # (a missing folder is made: tests/test_out_folders)
    in_the_way.write_text("not a folder")
    s.out_dir.setText(str(in_the_way))
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert s.error.text() == f"{in_the_way}: not a folder; choose a folder for the sessions"
    bad = tmp_path / "bad.toml"
    bad.write_text(MINI.replace("trial_s = 0.5", "trial_s = -1"))
    s.set_protocol_file(str(bad))
    assert "trial_s" in s.error.text() and "\n" not in s.error.text()
    assert console.stack.currentIndex() == 0 and console.session is None


def test_resume_of_a_non_session_is_refused(qtbot, env, tmp_path):
    console = make_console(qtbot)
    fill_device(qtbot, console)
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5")
    assert not console.resume_from(junk)
    assert str(junk) in console.setup.error.text() and console.stack.currentIndex() == 0
    assert console.engine is None or not console.engine.running


def test_tone_is_the_requested_frequency_and_length():
    rate = 44_100
    samples = tone_samples(880.0, 0.25, rate, volume=0.5)
    assert samples.dtype == np.int16 and len(samples) == round(0.25 * rate)
    spectrum = np.abs(np.fft.rfft(samples.astype(float)))
    peak_hz = np.argmax(spectrum) * rate / len(samples)
    assert abs(peak_hz - 880.0) < 5
    assert abs(int(samples[0])) < 50 and abs(int(samples[-1])) < 50  # faded: no click
    assert np.max(np.abs(samples)) <= 0.5 * 32767 + 1
    assert len(tone_pcm(880.0, 0.25, rate)) == 2 * len(samples)
    with pytest.raises(ValueError):
        tone_samples(0, 1)


def test_beeper_records_requests_and_falls_back_with_a_flash(qtbot):
    beeper = QtBeeper(audio=False)
    screen = ParticipantScreen()
    qtbot.addWidget(screen)
    beeper.flash.connect(screen.flash)
    with qtbot.waitSignal(beeper.flash, timeout=1000):
        req = beeper.beep(1000.0, 0.2)
    assert (req.frequency_hz, req.length_s, req.via) == (1000.0, 0.2, "fallback")
    assert beeper.requests == [req] and beeper.fallback_reason
    qtbot.waitUntil(lambda: screen.flash_level > 0, timeout=1000)
    qtbot.waitUntil(lambda: screen.flash_level == 0, timeout=3000)
    beeper.play(500.0, 0.1)  # the runner's name for it
    assert [r.frequency_hz for r in beeper.requests] == [1000.0, 500.0]


@pytest.mark.parametrize("size", [(1600, 900), (480, 270)])
def test_participant_screen_draws_every_mode_at_any_size(qtbot, size):
    screen = ParticipantScreen()
    qtbot.addWidget(screen)
    screen.resize(*size)
    cards = [Card(k, n, "A definition long enough to wrap over two lines of text.", i == 0,
                  i == 1) for i, (k, n) in enumerate(zip("abcdefghijklmn", "ABCDEFGHIJKLMN"))]
    blank = screen.grab().toImage()
    for mode, countdown in (("waiting", None), ("recording", 1.2), ("break", 95.0),
                            ("finished", None)):
        screen.show_view(ParticipantView(mode, "Title", "Subtitle", "Block 2 of 52", 1, 14,
                                         cards if mode in ("waiting", "recording") else [],
                                         countdown, 2.0 if mode == "recording" else 120.0,
                                         hint="K is already done" if mode == "waiting" else ""))
        image = screen.grab().toImage()
        assert image.width() == size[0] and image != blank
    # prompted order: the next gesture large above the block's compact cards
    strip = [Card(c.key, c.name, c.definition, c.done, i == 1, note="next" if i == 1 else "")
             for i, c in enumerate(cards)]
    screen.show_view(ParticipantView("waiting", "Next: B", "Press B as you start it.",
                                     "Block 2 of 52", 1, 14, strip, hint="Next is B",
                                     prompt=Card("b", "B", "A long definition. " * 8)))
    prompted = screen.grab().toImage()
    assert prompted != image and prompted != blank


def test_main_window_menu_opens_a_console_on_the_live_engine(qtbot, env):
    from tactile_studio.ui.main_window import MainWindow

    _, out = env
    window = MainWindow(device="simulated", settings={"speed": "8", "gesture": "idle"},
                        connect=True, persist=False)
    qtbot.addWidget(window)
    qtbot.waitUntil(lambda: window.acquisition.engine is not None
                    and window.acquisition.engine.running, timeout=WAIT_MS)
    action = next(a for a in window.menuBar().actions()[0].menu().actions()
                  if a.text().startswith("New &collection"))
    action.trigger()
    console = window._collect_consoles[-1]
    qtbot.addWidget(console)
    s = console.setup
    assert s.device.currentData() is None and "simulated" in s.device.currentText()
    qtbot.keyClicks(s.participant, "P02")
    s.out_dir.setText(str(out))
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert console.engine is window.acquisition.engine
    path = console.session.path
    console.close()
    assert window.acquisition.engine.running  # the live engine is not the console's to stop
    with SessionFile(path) as sess:
        assert sess.metadata["participant"] == "P02"
    window.shutdown()


def _magenta_box(image: QImage) -> tuple[int, int, int, int] | None:
    """Bounding box (left, top, width, height) of the pure magenta pixels."""
    arr = np.frombuffer(image.convertToFormat(QImage.Format.Format_RGB32).constBits(),
                        np.uint8).reshape(image.height(), image.width(), 4)
    hit = (arr[..., 2] > 240) & (arr[..., 1] < 15) & (arr[..., 0] > 240)  # BGRA
    if not hit.any():
        return None
    ys, xs = np.nonzero(hit)
    return int(xs.min()), int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1


@pytest.mark.parametrize("size", [(1600, 900), (800, 450)])
def test_card_image_is_scaled_to_fit_with_its_aspect(qtbot, tmp_path, size):
    wide = solid_png(tmp_path / "wide.png", 300, 100)   # 3:1
    screen = ParticipantScreen()
    qtbot.addWidget(screen)
    screen.resize(*size)

    def grab(image: str | None, done: bool = False, mode: str = "waiting") -> QImage:
        cards = [Card("a", "Alpha", "Do alpha to the sensor, gently.", done, False, image),
                 Card("b", "Beta", "Do beta.")]
        screen.show_view(ParticipantView(mode, "Title", "", "Block 1 of 2", 0, 2, cards))
        return screen.grab().toImage()

    left, top, w, h = _magenta_box(grab(wide))
    assert w / h == pytest.approx(3.0, rel=0.08)  # aspect kept
    assert w >= 0.15 * size[0] / 2  # grows with the screen, at the card's right
    assert left > 0.25 * size[0] and left + w < size[0] / 2
    # the same size while recording (compact cards), since it fits the card's width
    assert _magenta_box(grab(wide, mode="recording"))[2] <= w + 1
    assert _magenta_box(grab(wide, done=True)) is None  # a done card's image is dimmed
    tall = solid_png(tmp_path / "tall.png", 50, 100)   # 1:2 fits the height instead
    _, _, tw, th = _magenta_box(grab(tall))
    assert th / tw == pytest.approx(2.0, rel=0.08) and th > tw
    # an unreadable or missing image is left out: the card looks as if it had none
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"not a png")
    plain = grab(None)
    assert grab(str(junk)) == plain and grab(str(tmp_path / "gone.png")) == plain
    assert grab(wide) != plain


def test_console_numbers_blocks_from_one_and_names_practice(qtbot, env, tmp_path):
    proto, out = env
    proto.write_text(MINI.replace("free_play_s = 0.3", "free_play_s = 0.0\npractice_trials = 1"))
    console = make_console(qtbot)
    open_mini(qtbot, console, proto, out, blocks=1)
    s = snap(console)
    assert s.practice and console.participant.view.block_label == "Practice"
    assert "practice \u00b7" in console.progress_label.text()
    assert "block 0" not in console.progress_label.text()
    g = next(x for x in s.gestures if x.name == s.prompted)
    do_trial(qtbot, console, g.name, g.key)
    qtbot.waitUntil(lambda: not snap(console).practice, timeout=WAIT_MS)
    assert console.log.item(0, 1).text() == "practice"
    s = snap(console)
    assert console.participant.view.block_label == "Block 1 of 1"
    assert "block 1 of 1" in console.progress_label.text()
    g = next(x for x in s.gestures if x.name == s.prompted)
    do_trial(qtbot, console, g.name, g.key)
    assert console.log.item(1, 1).text() == "1"  # stored 0-based, shown 1-based
