"""The collection setup form: its device default and the plugin-schema settings form.

Real widgets (pytest-qt, offscreen) and the real plugin registry; nothing connects, the
form's ``startRequested`` signal carries what "Open session" would open.
"""

from __future__ import annotations

import pytest
from PySide6.QtCore import QSettings, Qt
from PySide6.QtWidgets import QCheckBox, QComboBox, QLineEdit, QToolButton

from tactile_studio.devices.registry import plugin_class
from tactile_studio.errors import UserError
from tactile_studio.ui.collect.setup import KEY_DEVICE, CollectSetup
from tactile_studio.ui.settings_form import SettingsForm


@pytest.fixture
def settings(tmp_path) -> QSettings:
    return QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)


def make_setup(qtbot, settings: QSettings, live_device: str | None = None) -> CollectSetup:
    setup = CollectSetup(settings, live_device=live_device)
    qtbot.addWidget(setup)
    setup.show()
    return setup


def retype(qtbot, setup: CollectSetup, name: str, text: str) -> None:
    editor = setup.device_form.fields[name].editor
    editor.clear()
    qtbot.keyClicks(editor, text)


def test_device_defaults_to_the_live_one_else_the_last_used_else_simulated(qtbot, settings):
    setup = make_setup(qtbot, settings)
    assert setup.device.itemData(0) == "ble"  # the first one alphabetically is not chosen
    assert setup.device.currentData() == "simulated"
    names = [s.name for s in plugin_class("simulated").settings_schema]
    assert list(setup.device_form.fields) == names and setup.device_form.isVisibleTo(setup)
    assert setup.device_choice() == ("simulated", {})  # all defaults: nothing to say
    settings.setValue(KEY_DEVICE, "serial")
    assert make_setup(qtbot, settings).device.currentData() == "serial"
    live = make_setup(qtbot, settings, live_device="serial")
    assert live.device.currentData() is None and "serial" in live.device.currentText()
    assert not live.device_form.fields and not live.device_form.isVisibleTo(live)
    assert live.device_choice() == (None, {})


def test_a_ble_name_with_a_space_reaches_the_session(qtbot, settings, tmp_path):
    setup = make_setup(qtbot, settings)
    setup.device.setCurrentIndex(setup.device.findData("ble"))
    assert list(setup.device_form.fields) == [s.name for s in plugin_class("ble").settings_schema]
    retype(qtbot, setup, "name", "Shear Sense 2")
    retype(qtbot, setup, "scan_timeout", "2.5")
    assert not setup.device_error.isVisibleTo(setup)
    qtbot.keyClicks(setup.participant, "P01")
    setup.out_dir.setText(str(tmp_path))
    with qtbot.waitSignal(setup.startRequested, timeout=2000) as sig:
        qtbot.mouseClick(setup.start_button, Qt.MouseButton.LeftButton)
    choice = sig.args[0]
    assert choice.device == "ble"
    assert choice.device_settings == {"name": "Shear Sense 2", "scan_timeout": "2.5"}
    plugin_class("ble").validate_settings(dict(choice.device_settings))  # the core accepts it
    assert settings.value(KEY_DEVICE) == "ble"
    # the next session's form starts with that device and those settings
    again = make_setup(qtbot, settings)
    assert again.device_choice() == ("ble", {"name": "Shear Sense 2", "scan_timeout": "2.5"})
    again.device.setCurrentIndex(again.device.findData("simulated"))
    assert again.device_choice() == ("simulated", {})
    # the collect command's settings replace the remembered ones
    assert again.set_device("ble", {"scan_timeout": "9"})
    assert again.device_choice() == ("ble", {"scan_timeout": "9"})


def test_a_bad_value_is_named_highlighted_and_nothing_starts(qtbot, settings, tmp_path):
    setup = make_setup(qtbot, settings)
    qtbot.keyClicks(setup.participant, "P01")
    setup.out_dir.setText(str(tmp_path))
    retype(qtbot, setup, "rate", "fast")
    field = setup.device_form.fields["rate"]
    assert field.editor.property("invalid") is True
    assert setup.device_error.isVisibleTo(setup)
    assert setup.device_error.text() == "rate: 'fast' is not a valid float"
    started = []
    setup.startRequested.connect(started.append)
    qtbot.mouseClick(setup.start_button, Qt.MouseButton.LeftButton)
    assert not started
    assert setup.error.text() == "device simulated: rate: 'fast' is not a valid float"
    with pytest.raises(UserError):
        setup.device_choice()
    retype(qtbot, setup, "rate", "1e9")  # a number, but out of the schema's range
    assert "above the maximum" in setup.device_error.text()
    retype(qtbot, setup, "rate", "100")
    assert field.editor.property("invalid") is False and not setup.device_error.isVisibleTo(setup)
    fault = setup.device_form.fields["fault"].editor  # a choice is a drop-down of its choices
    assert isinstance(fault, QComboBox)
    assert [fault.itemText(i) for i in range(fault.count())] == \
        list(next(s for s in plugin_class("simulated").settings_schema
                  if s.name == "fault").choices)
    fault.setCurrentText("stuck_channel")
    assert setup.device_choice() == ("simulated", {"rate": "100", "fault": "stuck_channel"})
    qtbot.mouseClick(setup.start_button, Qt.MouseButton.LeftButton)
    assert len(started) == 1 and started[0].device_settings["fault"] == "stuck_channel"


def test_the_shared_form_builds_every_kind(qtbot):
    form = SettingsForm()
    qtbot.addWidget(form)
    form.set_plugin(plugin_class("replay"))  # path and bool settings
    path, loop = form.fields["path"], form.fields["loop"]
    assert isinstance(path.editor, QLineEdit) and path.widget.findChild(QToolButton) is not None
    assert isinstance(loop.editor, QCheckBox) and not loop.editor.isChecked()
    loop.editor.setChecked(True)
    path.set_text("/data/my session.h5")
    assert form.first_error() is None
    assert form.changed_values() == {"path": "/data/my session.h5", "loop": "true"}
    form.set_plugin(None)
    assert form.fields == {} and form.values() == {}


def test_the_collect_command_prefills_the_form_with_a_spaced_name(qtbot, tmp_path, monkeypatch):
    from tactile_studio.protocol.console_options import ConsoleOptions
    from tactile_studio.ui.collect.app import build_console

    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    console = build_console(ConsoleOptions(
        "shear9", "P01", device="ble",
        device_settings={"name": "Shear Sense 2", "scan_timeout": 2.0}, out_dir=str(tmp_path)))
    qtbot.addWidget(console)
    s = console.setup
    assert s.device.currentData() == "ble"
    assert s.device_form.fields["name"].text() == "Shear Sense 2"
    assert s.device_choice() == ("ble", {"name": "Shear Sense 2", "scan_timeout": "2"})
    assert console.session is None  # nothing connects before "Open session"
