"""The main window's remote control for experiment scripts (LabRecorder's commands,
streams/remote_control.py): a File menu tick box, off by default and remembered, the
port in the status bar while it listens.

Commands arrive on socket threads and are carried out here on the GUI thread by a timer
(``RemoteControl.process``), on the window's own acquisition session: a script's
``start`` records the device the window shows, into the folder chosen here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject, QTimer
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QMenu, QMessageBox, QWidget

from tactile_studio.errors import UserError
from tactile_studio.paths import data_dir
from tactile_studio.streams.remote_control import DEFAULT_PORT, LOOPBACK, RemoteControl
from tactile_studio.ui.settings import app_settings

KEY = "remote_control/"
PROCESS_MS = 50


def recordings_folder() -> Path:
    """Where a script's recordings go unless its ``{root:...}`` is absolute."""
    stored = str(app_settings().value(KEY + "folder", "") or "")
    return Path(stored) if stored else data_dir() / "recordings"


class RemoteControlToggle(QObject):
    """Owns the listener while the tick box is on (see the module docstring)."""

    def __init__(self, window: QWidget, session: Any, status_bar: Any) -> None:
        super().__init__(window)
        self.window, self.session, self.status_bar = window, session, status_bar
        self.control: RemoteControl | None = None
        s = app_settings()
        self.port = int(s.value(KEY + "port", DEFAULT_PORT) or DEFAULT_PORT)
        self.action = QAction(f"Remote control for experiment scripts (port {self.port})",
                              window)
        self.action.setCheckable(True)
        self.action.setToolTip("Let an experiment script start and stop recordings with "
                               "LabRecorder's commands on 127.0.0.1 (docs/lsl.md)")
        self.timer = QTimer(self)
        self.timer.setInterval(PROCESS_MS)
        self.timer.timeout.connect(self._process)
        self.action.toggled.connect(self.set_on)
        if str(s.value(KEY + "enabled", "false")).lower() == "true":
            self.action.setChecked(True)

    def set_on(self, on: bool) -> bool:
        """Listen or stop listening; False (with the reason shown) when it cannot."""
        if on and self.control is None:
            control = RemoteControl(self.session, recordings_folder(), self.port, LOOPBACK,
                                    metadata={"notes": "started by an experiment script"})
            try:
                control.listen()
            except UserError as exc:
                self.action.blockSignals(True)
                self.action.setChecked(False)
                self.action.blockSignals(False)
                QMessageBox.warning(self.window, "Remote control", str(exc))
                return False
            self.control = control
            self.timer.start()
            self.status_bar.set_remote(f"remote :{control.port}",
                                       f"Experiment scripts may start and stop recordings "
                                       f"on {LOOPBACK}:{control.port}; recordings go to "
                                       f"{control.out_dir}")
        elif not on and self.control is not None:
            self.timer.stop()
            self.control.close()
            self.control = None
            self.status_bar.set_remote("")
        app_settings().setValue(KEY + "enabled", "true" if on else "false")
        return True

    def _process(self) -> None:
        if self.control is not None:
            self.control.process()

    def close(self) -> None:
        """At shutdown: stop listening, keep the setting as the user left it."""
        if self.control is not None:
            self.timer.stop()
            self.control.close()
            self.control = None


def add_remote_control(window: Any, menu: QMenu) -> RemoteControlToggle:
    """The File menu's tick box for ``window`` (its ``controller`` and ``status``)."""
    toggle = RemoteControlToggle(window, window.acquisition, window.status)
    menu.addAction(toggle.action)
    return toggle
