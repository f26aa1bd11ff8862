"""Opening a collection session in the console as an experimenter does: the setup form
filled in by keystrokes, a simulated device, "Open session" clicked."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt


def open_console_session(qtbot, console, out_dir: Path, participant: str,  # noqa: ANN001
                         device_settings: dict[str, str] | None = None,
                         make_folder: bool = True) -> Path:
    """Fill the shown ``console``'s setup (the first protocol, the simulated device with
    ``device_settings`` typed in) and open the session; returns its file. With
    ``make_folder`` False a missing ``out_dir`` is left for the console to make."""
    s = console.setup
    s.protocol.setCurrentIndex(0)
    qtbot.keyClicks(s.participant, participant)
    s.out_dir.clear()
    if make_folder:
        out_dir.mkdir(parents=True, exist_ok=True)
    qtbot.keyClicks(s.out_dir, str(out_dir))
    s.device.setCurrentIndex(s.device.findData("simulated"))
    for name, value in (device_settings or {}).items():
        editor = s.device_form.fields[name].editor
        editor.clear()
        qtbot.keyClicks(editor, value)
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert s.error.text() == "" and console.stack.currentIndex() == 1, s.error.text()
    return Path(console.session.path)


def fill_setup(qtbot, console, protocol_file: Path, out_dir: Path, participant: str,  # noqa: ANN001
               blocks: int) -> None:
    """The setup form of a shown ``console``: a protocol file, its first ``blocks``, the
    participant typed in, the folder, and test_ui_collect's simulated device (8x real
    time, idle); "Open session" is left to the test."""
    from test_ui_collect import fill_device

    s = console.setup
    s.set_protocol_file(str(protocol_file))
    s.blocks.setValue(blocks)
    qtbot.keyClicks(s.participant, participant)
    s.out_dir.setText(str(out_dir))
    fill_device(qtbot, console)
