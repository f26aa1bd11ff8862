"""A collection never records a simulator performing by itself: on the main window's
simulated device (gesture ``auto``, its demo cycle) the console's session sets it idle,
says who makes the touches, and a trial where nobody touched comes out without load."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt

from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.plugins.simulated import SimulatedSensor
from tactile_studio.protocol.snapshot import State
from tactile_studio.sensor.decode import decode
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.ui.collect.console import CollectConsole

MINI = """
name = "mini2"
title = "Mini 2 gestures"
trial_s = 1.0
blocks = 1
free_play_s = 0.0

[beep]
frequency_hz = 880.0
length_s = 0.05

[[gestures]]
name = "Poke"
key = "p"
definition = "Poke it."

[[gestures]]
name = "Twist"
key = "t"
definition = "Twist on it."
"""


def test_a_console_on_the_live_demo_simulator_records_only_touches(qtbot, tmp_path,
                                                                    monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    (tmp_path / "mini2.toml").write_text(MINI)
    out = tmp_path / "data"
    out.mkdir()
    device = SimulatedSensor(speed=8)  # the main window's default: the demo cycle
    assert device.settings["gesture"] == "auto"
    engine = AcquisitionEngine(device)
    engine.start()
    try:
        console = CollectConsole(engine=engine, live_device="simulated")
        qtbot.addWidget(console)
        console.show()
        s = console.setup
        s.set_protocol_file(str(tmp_path / "mini2.toml"))
        qtbot.keyClicks(s.participant, "P03")
        s.out_dir.setText(str(out))
        assert s.device.currentData() is None  # the live device
        qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
        assert s.error.text() == "" and console.engine is engine
        assert console.touches_label.text().startswith(
            "Touches: simulated sensor, idle until a virtual participant or a person touches")
        assert device.settings["gesture"] == "idle"
        # the demo's last touch relaxes off the skin over seconds (tau ~3 s): the trial
        # starts once 15 s of stream have passed, not when a loaded or idle machine gets
        # there (a trial right away saw 1.04 kPa of it, now and then)
        settled = engine.frames + round(15 * engine.nominal_rate_hz)
        qtbot.waitUntil(lambda: engine.frames >= settled, timeout=15000)
        qtbot.mouseClick(console.buttons["primary"], Qt.MouseButton.LeftButton)  # Start
        snap = console.runner.snapshot
        qtbot.waitUntil(lambda: snap().state == State.WAITING, timeout=15000)
        prompt = console.participant.view.prompt
        qtbot.keyClick(console.participant, prompt.key)  # nobody touches the sensor
        qtbot.waitUntil(lambda: len(snap().trials) == 1 and snap().state not in
                        (State.RECORDING, State.TRIAL_END), timeout=15000)
        trial = snap().trials[0]
        assert "no_contact" in trial["flags"]
        path = console.session.path
        console.close()
        assert device.settings["gesture"] == "auto"  # the live demo goes on afterwards
    finally:
        engine.stop()
    with SessionFile(path) as sess:
        assert sess.metadata["device"]["settings"]["gesture"] == "idle"
        t = sess.journal.trials[0]
        raw = sess.raw(t["start_sample"], t["end_sample"])
        load = decode(sess.layout, raw, sess.baseline(t["start_sample"])).normal
        assert float(np.abs(load).max()) < 1.0  # kPa: noise, no gesture


def test_the_device_panel_says_the_simulator_is_idle_while_a_collection_uses_it(
        qtbot, tmp_path, monkeypatch):
    """Issue 47 item 14: the device panel listed the simulator's settings as raw names
    without units ("noise 20.0, drift 0.002") and showed gesture=auto while the
    collection forced it idle."""
    from tactile_studio.ui.collect.app import open_console
    from tactile_studio.ui.main_window import MainWindow
    from tactile_studio.ui.settings import SETTINGS_ENV

    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    (tmp_path / "mini2.toml").write_text(MINI)
    w = MainWindow(device="simulated", settings={"rate": "200", "speed": "4"})
    qtbot.addWidget(w)
    w.show()
    try:
        form = w.panel.form_box
        label = form.form.labelForField(form.fields["noise"].widget)
        assert label.text() == "Noise (counts rms)"
        assert form.form.labelForField(form.fields["drift"].widget).text() == \
            "Baseline drift (fraction of baseline)"
        assert form.form.labelForField(form.fields["rate"].widget).text() == "Frame rate (Hz)"
        assert "--set noise=" in form.fields["noise"].widget.toolTip()
        assert form.more.text() == "More settings (14)" and not form.more.isChecked()
        assert not form.fields["noise"].widget.isVisibleTo(w)  # folded: not the default set
        assert form.fields["rate"].widget.isVisibleTo(w)
        gesture = form.fields["gesture"]
        assert w.panel.connect_device() and gesture.text() == "auto"
        engine = w.acquisition.engine
        qtbot.waitUntil(lambda: engine.baseline is not None, timeout=15000)
        console = open_console(lambda: (engine, "simulated"))
        qtbot.addWidget(console)
        s = console.setup
        s.set_protocol_file(str(tmp_path / "mini2.toml"))
        qtbot.keyClicks(s.participant, "P03")
        s.out_dir.setText(str(tmp_path / "data"))
        qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
        assert s.error.text() == "" and console.engine is engine
        qtbot.waitUntil(lambda: gesture.text() == "idle", timeout=5000)  # the panel's timer
        assert not gesture.widget.isEnabled()
        assert w.panel.held_label.text() == ("Touches by itself: idle while a collection "
                                             "session uses this device (it was auto; back "
                                             "when the session closes)")
        assert w.panel.values()["gesture"] == "auto"  # a Restart keeps the user's choice
        console.close()
        qtbot.waitUntil(lambda: gesture.text() == "auto", timeout=5000)
        assert gesture.widget.isEnabled() and not w.panel.held_label.isVisibleTo(w)
    finally:
        w.shutdown()
