"""The "Stream to LSL" toggles: the device panel's and the collection console's forward
to the core, which publishes real LSL streams; without liblsl the toggle says why."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest
from collect_fixtures import mini_protocol
from lsl_fixtures import Collector

from tactile_studio.ui.collect.console import CollectConsole
from tactile_studio.ui.collect.setup import SetupChoice
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.settings import SETTINGS_ENV

# screenshots go to a temporary folder; TACTILE_STUDIO_SHOTS=docs/screenshots refreshes the docs
SHOTS_ENV = "TACTILE_STUDIO_SHOTS"
WAIT_MS = 10_000


@pytest.fixture(autouse=True)
def isolated_settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


@pytest.fixture
def window(qtbot):
    w = MainWindow(device="simulated", settings={"rate": "200", "seed": "21"}, connect=True,
                   persist=False)
    qtbot.addWidget(w)
    w.show()
    yield w
    w.shutdown()


def _shots(tmp_path: Path) -> Path:
    return Path(os.environ.get(SHOTS_ENV) or tmp_path)


def test_device_panel_toggle_streams_and_follows_a_restart(qtbot, window, tmp_path) -> None:
    panel = window.panel
    qtbot.waitUntil(lambda: window.acquisition.status().state == "running", timeout=WAIT_MS)
    panel.lsl_toggle.click()  # as the user does
    streamer = window.acquisition.lsl
    assert panel.lsl_toggle.isChecked() and streamer is not None and streamer.running
    got = Collector(f"source_id='{streamer.source_id}'")
    got.wait_connected()
    qtbot.waitUntil(lambda: len(got.stamps) > 50, timeout=WAIT_MS)
    window.refresh_status()
    assert panel.lsl_label.isVisible()
    assert panel.lsl_label.text().startswith("LSL TactileStudio-simulated (raw)\n")
    window.resize(1280, 800)
    qtbot.wait(300)
    window.refresh_status()
    assert panel.grab().save(str(_shots(tmp_path) / "lsl-device-panel.png"))

    assert panel.connect_device()  # "Restart": a new engine, the stream follows it
    assert window.acquisition.lsl is not None and window.acquisition.lsl is not streamer
    assert not streamer.running and window.acquisition.lsl.engine is window.acquisition.engine
    panel.lsl_toggle.click()
    assert window.acquisition.lsl is None and not panel.lsl_toggle.isChecked()
    got.stop()
    assert got.array().shape[1] == 180


def test_device_panel_without_liblsl_shows_one_line_and_unchecks(qtbot, window,
                                                                  monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "pylsl", None)
    window.panel.lsl_toggle.click()
    assert not window.panel.lsl_toggle.isChecked()
    assert window.panel.error_text().startswith("Lab Streaming Layer is not available")
    assert window.acquisition.lsl is None and window.acquisition.engine.running


def test_console_toggle_streams_the_session_markers(qtbot, tmp_path) -> None:
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    console.lsl_toggle.setChecked(True)  # before the session: streams once it is open
    assert console._lsl is None  # noqa: SLF001
    choice = SetupChoice(mini_protocol(3, blocks=1), "P07", tmp_path, seed=3,
                         device="simulated", device_settings={"speed": 8, "gesture": "idle"})
    assert console.start_session(choice)
    streamer = console._lsl  # noqa: SLF001
    assert streamer is not None and streamer.engine is console.engine
    got = Collector(f"name='{streamer.marker_name}'")
    got.wait_connected()
    console.primary_action()  # Start
    qtbot.waitUntil(lambda: any(json.loads(m[0]).get("source") == "collect"
                                for m in list(got.samples)), timeout=WAIT_MS)
    console.resize(1400, 860)
    qtbot.wait(200)
    assert console.grab().save(str(_shots(tmp_path) / "lsl-collect-console.png"))
    console.lsl_toggle.setChecked(False)
    assert console._lsl is None and not streamer.running  # noqa: SLF001
    got.stop()
    console.close_session()
    states = [json.loads(m[0]) for m in got.samples]
    assert {"kind": "state", "source": "collect", "state": "waiting_for_key"} in states


def test_collect_lsl_option_pre_checks_the_console_toggle(qtbot, tmp_path) -> None:
    from tactile_studio.cli import build_parser
    from tactile_studio.cli.collect import console_options
    from tactile_studio.ui.collect.app import build_console

    args = build_parser().parse_args(["collect", "--protocol", "shear9", "--participant", "P01",
                                      "--out", str(tmp_path), "--lsl"])
    console = build_console(console_options(args))
    qtbot.addWidget(console)
    assert console.lsl_toggle.isChecked() and console._lsl is None  # noqa: SLF001 - no session yet
    args = build_parser().parse_args(["collect", "--protocol", "shear9", "--participant", "P01",
                                      "--out", str(tmp_path)])
    plain = build_console(console_options(args))
    qtbot.addWidget(plain)
    assert not plain.lsl_toggle.isChecked()
