"""Pilot mode (issue 47 item 13): rehearsing from the console on the simulator flooded
every trial with no_contact, since the virtual participant existed only headless. In a
pilot a virtual participant performs what the screen prompts while the experimenter runs
the session; the file is marked pilot everywhere and never mixed with real data.

Real console (pytest-qt), real engine and simulated sensor (8x real time), real files."""

from __future__ import annotations

import time
from pathlib import Path

from PySide6.QtCore import Qt, QTimer
from test_ui_collect import MINI, WAIT_MS, click, make_console, snap

from tactile_studio.cli import main
from tactile_studio.protocol.quality import QualitySettings
from tactile_studio.protocol.runner_events import RunnerEvent, TrialEnded
from tactile_studio.protocol.snapshot import State
from tactile_studio.sensor.decode import contact_taxels
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_set import select_sessions


def test_the_console_rehearses_with_a_virtual_participant_marked_pilot(
        qtbot, tmp_path: Path, monkeypatch, qapp) -> None:
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    proto = tmp_path / "mini3.toml"
    proto.write_text(MINI.replace('image = "pics/poke.png"\n', ""))
    console = make_console(qtbot)
    s = console.setup
    s.set_protocol_file(str(proto))
    s.blocks.setValue(2)  # a break between them: the experimenter continues it
    qtbot.keyClicks(s.participant, "P99")
    s.out_dir.setText(str(tmp_path / "data"))
    s.device.setCurrentIndex(s.device.findData("simulated"))
    s.set_device("simulated", {"speed": "8"})
    s.pilot.setChecked(True)
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert s.error.text() == "" and console.stack.currentIndex() == 1, s.error.text()
    assert console.pilot_banner.isVisibleTo(console)
    assert console.pilot_banner.text().startswith(
        "PILOT \u2013 a rehearsal: a virtual participant performs what the screen prompts.")
    assert console.windowTitle().endswith("PILOT")
    assert console.touches_label.text() == \
        "Touches: a virtual participant, on the simulated sensor"
    assert console.virtual is not None and snap(console).state == State.SETUP  # yours to start
    device = console.engine.device

    def pause_after_the_fourth(event: RunnerEvent) -> None:
        # the experimenter's Pause as trial 4 ends (it takes effect after the trial): a
        # poll of the state could miss the moment between trials on a loaded machine
        if isinstance(event, TrialEnded) and event.trial.index == 3:
            QTimer.singleShot(0, lambda: click(qtbot, console, "pause"))

    console.runner.add_listener(pause_after_the_fourth)
    click(qtbot, console, "primary")  # Start
    paused = False
    deadline = time.monotonic() + 4 * WAIT_MS / 1000  # a safety net, never a timing check
    while snap(console).state not in State.DONE:  # the experimenter's part, as with a person
        assert time.monotonic() < deadline, f"stuck in {snap(console).state}"
        now = snap(console)
        if now.state in (State.BREAK, State.REVIEW) and console.buttons["primary"].isEnabled():
            click(qtbot, console, "primary")  # (enabled by the console's own tick)
        elif not paused and now.state == State.PAUSED:  # a pause mid-block: it waits, goes on
            assert len(now.trials) == 4 and now.paused_state == State.WAITING
            frames = console.engine.frames
            qtbot.waitUntil(lambda: console.engine.frames > frames + 40, timeout=WAIT_MS)
            click(qtbot, console, "pause")  # Resume
            paused = True
        qtbot.wait(20)
        assert console.participant.view.pilot  # framed and tagged on the participant screen
    assert snap(console).state == State.FINISHED and paused
    path = Path(console._closed_session_path)
    assert path.name.startswith("PILOT_P99_mini3_")
    with SessionFile(path) as f:
        trials, meta = f.trials, f.metadata
    assert meta["pilot"] is True and len(trials) == 6
    for t in trials:  # someone touched, with the prompted gesture, during its trial
        middle = (t.start_sample + t.end_sample) // 2  # (the simulator's ground truth)
        assert device.gesture_at(middle) == t.gesture, t
    # ...and a trial is flagged no_contact only if its own rows hold no contact: the
    # participant reacts in real time, so which performances it draws depends on when it
    # saw the prompt, and a short Tickle of this style is too light to register in ~4% of
    # draws (a person's too), so "no trial flagged" was a lottery the load drew (the touch
    # and its trial coincided, the rows held no contact)
    with SessionFile(path) as f:
        for t in trials:
            rows = f.raw(t.start_sample, t.end_sample)
            touched = contact_taxels(console.engine.layout, rows, f.baseline(t.start_sample),
                                     QualitySettings().contact_rel).any()
            assert ("no_contact" in t.flags) == (not touched), t
    assert console.participant.view.pilot and console.pilot_banner.isVisibleTo(console)


def test_pilot_sessions_stay_out_of_datasets_unless_named(tmp_path: Path, capsys, qtbot,
                                                           monkeypatch) -> None:
    data = tmp_path / "data"
    made = {}
    for who, extra in (("P01", []), ("P02", []), ("P09", ["--pilot"])):
        assert main(["collect", "--protocol", "shear9", "--participant", who, "--blocks", "1",
                     "--virtual-participant", "--speed", "0", "--out", str(data),
                     *extra]) == 0
        made[who] = Path(capsys.readouterr().out.strip().splitlines()[-1])
    pilot = made["P09"]
    assert pilot.name.startswith("PILOT_P09_shear9_")
    assert main(["info", str(pilot)]) == 0
    assert "pilot:      yes: a rehearsal, not a participant's data" in capsys.readouterr().out
    assert main(["info", str(data)]) == 0
    out = capsys.readouterr().out
    assert "pilot (rehearsal; not counted)" in out
    assert "3 session file(s) under" in out and "; 1 pilot (rehearsals, not counted)" in out
    assert "participants: 2 (P01, P02)" in out
    chosen = select_sessions([data])  # what train, evaluate and the workspace read
    assert pilot not in chosen.files and len(chosen.files) == 2
    assert chosen.describe_skipped() == \
        "skipped 1 pilot session (rehearsals; name a file to use it)"
    assert pilot in select_sessions([data, pilot]).files  # named: used
    # the workspace lists it, marked, and leaves it out of the selection it trains on
    from tactile_studio.ui.research.sessions_view import SessionsView

    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    view = SessionsView()
    qtbot.addWidget(view)
    view.set_folders([str(data)])
    assert len(view.rows) == 3
    assert sorted(view.selected_paths()) == sorted(str(made[p]) for p in ("P01", "P02"))
    (row,) = [r for r in view.rows if r.pilot]
    assert row.problem == "pilot (a rehearsal): select it to train on it"
    assert "2 participants" in view.summary.text()
    view.stop_checks(wait_s=5.0)
    assert main(["collect", "--virtual-participant", "--pilot", "--resume",
                 str(made["P01"])]) == 1
    assert "is not a pilot session" in capsys.readouterr().err
