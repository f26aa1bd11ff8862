"""Choose a device plugin, edit its settings, connect, tare and record.

The settings form (ui/settings_form.py, shared with the collection setup) is generated
from the plugin's ``settings_schema`` and validated with the schema's own
``Setting.parse`` as the user types, so an invalid value shows its one-line message
before anything connects. A plugin with a ``discover`` hook gets a "Scan" drop-down for
its ``discover_setting`` (ui/device_discovery.py); serial ports are listed as soon as the
plugin is chosen.
"""

from __future__ import annotations

import os
import time
from typing import Any

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSizePolicy,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.acquisition import LiveAcquisition, LiveStatus
from tactile_studio.acquisition.events import AcquisitionEvent, RecordingStarted, RecordingStopped
from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.devices.registry import available_plugins
from tactile_studio.errors import UserError
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.ui.device_discovery import DiscoverField, ElidedLabel
from tactile_studio.ui.file_dialogs import ask_save_file
from tactile_studio.ui.settings_form import SettingField, SettingsForm, one_line
from tactile_studio.ui.write_faults import fault_text


class DevicePanel(QWidget):
    """Device chooser + generated settings form + connect/tare/record + live state.

    Handed the main window's session (:class:`LiveAcquisition`): it forwards the verbs
    and shows what the session reports; the session decides when a recording stops (its
    events drive the Record button). Emits ``engineChanged`` after connect or disconnect
    so the owner can point its live view at the new engine, ``recordingChanged(path)``
    ("" when a recording stops) and ``deviceChosen(name)`` when another plugin is picked.
    """

    engineChanged = Signal()
    recordingChanged = Signal(str)
    deviceChosen = Signal(str)

    def __init__(self, acquisition: LiveAcquisition, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.acquisition = acquisition
        acquisition.add_listener(self._on_session_event)
        self.plugins = available_plugins()
        self._form_error: str | None = None
        self._build_device_choice()
        self._build_settings()
        buttons = self._build_buttons()
        self._build_state_lines()
        self._build_layout(buttons)
        self._rebuild_form()
        self._update_buttons(LiveStatus(None, "disconnected", None))

    # ---- the panel's parts, top to bottom -----------------------------------------------
    def _build_device_choice(self) -> None:
        """Every device plugin (one that failed to load shown greyed, its error as the
        tip) and the chosen one's description."""
        self.device_box = QComboBox()
        for name, cls in self.plugins.items():
            if isinstance(cls, Exception):
                self.device_box.addItem(f"{name} (failed to load)", name)
                item = self.device_box.model().item(self.device_box.count() - 1)
                item.setEnabled(False)
                item.setToolTip(one_line(cls))
            else:
                self.device_box.addItem(name, name)
        self.device_box.currentIndexChanged.connect(self._rebuild_form)
        self.device_box.currentIndexChanged.connect(
            lambda *_: self.deviceChosen.emit(self.device_name() or ""))
        self.description = QLabel()
        self.description.setWordWrap(True)
        self.description.setObjectName("hint")

    def _build_settings(self) -> None:
        """The device's settings form, the settings it holds, the sensor id, the error."""
        self.form_box = SettingsForm("Settings")
        self.form_box.changed.connect(self._validate)
        # a setting the device changed while connected (a collection session quiets the
        # simulator): shown as it is now, locked, and said; name -> the form's own text
        self._connected: dict[str, Any] = {}
        self._held: dict[str, str] = {}
        self.held_label = QLabel()
        self.held_label.setObjectName("detail")
        self.held_label.setWordWrap(True)
        self.held_label.hide()

        self.sensor_box = sensor_id_box()

        self.error_label = ElidedLabel()
        self.error_label.setObjectName("error")
        self.error_label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)
        self.error_label.hide()

    def _build_buttons(self) -> tuple[QHBoxLayout, QHBoxLayout]:
        """Connect and Disconnect; Tare and Record."""
        self.connect_button = QPushButton("Connect")
        self.connect_button.setObjectName("primary")
        self.connect_button.clicked.connect(self.connect_device)
        self.disconnect_button = QPushButton("Disconnect")
        self.disconnect_button.clicked.connect(self.disconnect_device)
        self.tare_button = QPushButton("Tare")
        self.tare_button.setToolTip("Take a new baseline from the next frames (hands off!)")
        self.tare_button.clicked.connect(self.tare)
        self.record_button = QPushButton("Record…")
        self.record_button.setCheckable(True)
        self.record_button.clicked.connect(self.toggle_recording)
        buttons = QHBoxLayout()
        for b in (self.connect_button, self.disconnect_button):
            buttons.addWidget(b)
        buttons2 = QHBoxLayout()
        for b in (self.tare_button, self.record_button):
            buttons2.addWidget(b)
        return buttons, buttons2

    def _build_state_lines(self) -> None:
        """The connection's state, its detail and the recording's line."""
        self.state_label = QLabel("disconnected")
        self.state_label.setObjectName("state")
        self.detail_label = QLabel()
        self.detail_label.setObjectName("detail")
        self.detail_label.setWordWrap(True)
        self.record_label = QLabel()
        self.record_label.setWordWrap(True)
        self.record_label.setObjectName("recording")
        self.record_label.hide()

    def _build_layout(self, buttons: tuple[QHBoxLayout, QHBoxLayout]) -> None:
        box = QVBoxLayout(self)
        box.addWidget(self.device_box)
        box.addWidget(self.description)
        box.addWidget(self.form_box)
        box.addWidget(self.held_label)
        box.addWidget(self.sensor_box)
        box.addWidget(self.error_label)
        box.addLayout(buttons[0])
        box.addLayout(buttons[1])
        box.addWidget(self._build_lsl_row())
        box.addSpacing(8)
        box.addWidget(self.state_label)
        box.addWidget(self.detail_label)
        box.addWidget(self.record_label)
        box.addStretch(1)

    # ---- the form --------------------------------------------------------------------
    def plugin(self) -> type[DevicePlugin] | None:
        cls = self.plugins.get(self.device_name() or "")
        return None if cls is None or isinstance(cls, Exception) else cls

    def device_name(self) -> str | None:
        data = self.device_box.currentData()
        return None if data is None else str(data)

    def set_device(self, name: str, values: dict[str, Any] | None = None) -> bool:
        """Select a plugin and fill its form; False if the plugin is not available."""
        i = self.device_box.findData(name)
        if i < 0 or isinstance(self.plugins.get(name), Exception):
            return False
        if i != self.device_box.currentIndex():
            self.device_box.setCurrentIndex(i)
        else:
            self._rebuild_form()
        self.form_box.set_values(values or {})
        self._validate()
        return True

    @property
    def _fields(self) -> dict[str, SettingField | DiscoverField]:
        return self.form_box.fields

    @property
    def discover_field(self) -> DiscoverField | None:
        return self.form_box.discover_field

    def _rebuild_form(self) -> None:
        self._held.clear()  # new rows: nothing of the old ones is held
        self.held_label.hide()
        cls = self.plugin()
        self.description.setText(getattr(cls, "description", "") or "")
        self.description.setVisible(bool(self.description.text()))
        self.form_box.set_plugin(cls)
        self._validate()

    def values(self) -> dict[str, str]:
        """The form as text, as ``--set key=value`` would give it (empty = default); a
        setting the device holds for a session keeps the user's own value here."""
        return {**self.form_box.values(), **self._held}

    def _validate(self, *_: object) -> bool:
        first = self.form_box.first_error()
        self._form_error = first
        self.show_error(first)
        self.connect_button.setEnabled(self.plugin() is not None and first is None)
        return first is None

    def is_valid(self) -> bool:
        """True when every field of the form parses."""
        return self._form_error is None

    def show_error(self, message: str | None) -> None:
        """Show one line of error text under the form (None hides it)."""
        if message:
            self.error_label.setText(one_line(message))
            self.error_label.setToolTip(message)
        self.error_label.setVisible(bool(message))

    def error_text(self) -> str:
        return self.error_label.text() if self.error_label.isVisible() else ""

    # ---- verbs -----------------------------------------------------------------------
    def connect_device(self) -> bool:
        """Connect with the form's settings; False (and an inline error) if refused."""
        name = self.device_name()
        if name is None or not self._validate():
            return False
        try:
            self.acquisition.connect(name, self.values())
        except UserError as exc:
            self.show_error(one_line(exc))
            return False
        self.show_error(None)
        self._release_held()
        engine = self.acquisition.engine
        self._connected = dict(getattr(engine.device, "settings", None) or {})
        self.engineChanged.emit()
        self.refresh(self.acquisition.status())
        return True

    def disconnect_device(self) -> None:
        self.acquisition.disconnect("disconnect")  # a recording stops with it (an event)
        self.engineChanged.emit()
        self.refresh(self.acquisition.status())

    def tare(self) -> None:
        self.acquisition.tare()

    def ask_record_path(self) -> str | None:
        """Ask where to record, starting in the folder the user last recorded to."""
        path = ask_save_file(self, "Record to", "record",
                             time.strftime("session-%Y%m%d-%H%M%S.h5"),
                             "Tactile Studio session (*.h5)")
        if not path:
            return None
        return path if path.endswith((".h5", ".hdf5")) else path + ".h5"

    def toggle_recording(self) -> None:
        """The Record button (and File > Record): stop, or ask where and start."""
        if self.acquisition.recorder is not None:
            self.stop_recording()
            return
        path = self.ask_record_path()
        if path:
            self.start_recording(path)
        self.record_button.setChecked(self.acquisition.recorder is not None)

    def start_recording(self, path: str) -> bool:
        """Record to ``path``, replacing a file there (the save dialog asked first); a
        file another recording or program is writing is refused (its one line shown)."""
        try:
            sensor = self.sensor_box.currentText().strip()
            self.acquisition.start_recording(path, {"sensor_id": sensor} if sensor else None,
                                             overwrite=True)
        except (UserError, OSError) as exc:
            text = fault_text(exc)
            if text is None:
                raise
            self.show_error(text)
            self.record_button.setChecked(False)
            return False
        self.show_error(None)
        self.refresh(self.acquisition.status())
        return True

    def stop_recording(self) -> str | None:
        return self.acquisition.stop_recording()

    def _on_session_event(self, event: AcquisitionEvent) -> None:
        """The session started or stopped a recording (asked here, or on its own: the
        stream ended, a limit was reached)."""
        if isinstance(event, RecordingStarted):
            self.record_button.setChecked(True)
            self.record_button.setText("Stop recording")
            self.recordingChanged.emit(event.path)
        elif isinstance(event, RecordingStopped):
            self.record_button.setChecked(False)
            self.record_button.setText("Record…")
            self.recordingChanged.emit("")
            if event.reason != "disconnect":
                self.record_label.setText(f"Saved {event.path}")
                self.record_label.show()
            if event.message:  # incomplete: write failed, device lost, frames lost
                self.show_error(event.message)

    # ---- Lab Streaming Layer ------------------------------------------------------------
    def _build_lsl_row(self) -> QWidget:
        """The "Stream to LSL" toggle and its one-line status (the core does the work)."""
        row = QWidget()
        lay = QVBoxLayout(row)
        lay.setContentsMargins(0, 0, 0, 0)
        self.lsl_toggle = QCheckBox("Stream to LSL")
        self.lsl_toggle.setToolTip("Publish the frames and a marker stream on the Lab "
                                   "Streaming Layer (LabRecorder, other LSL apps)")
        self.lsl_toggle.toggled.connect(self.set_lsl)
        self.lsl_label = QLabel()
        self.lsl_label.setObjectName("detail")
        self.lsl_label.setWordWrap(True)
        self.lsl_label.hide()
        lay.addWidget(self.lsl_toggle)
        lay.addWidget(self.lsl_label)
        return row

    def set_lsl(self, on: bool) -> bool:
        """Forward the toggle to the core; False (toggle off, error shown) if refused."""
        try:
            self.acquisition.set_lsl(on)
        except UserError as exc:
            self.show_error(one_line(exc))
            on = False
        if self.lsl_toggle.isChecked() != on:
            self.lsl_toggle.blockSignals(True)
            self.lsl_toggle.setChecked(on)
            self.lsl_toggle.blockSignals(False)
        self._show_lsl()
        return on

    def _show_lsl(self) -> None:
        text = self.acquisition.lsl_status() if self.lsl_toggle.isChecked() else ""
        self.lsl_label.setText(text)
        self.lsl_label.setToolTip(text)
        self.lsl_label.setVisible(bool(text))

    # ---- live state --------------------------------------------------------------------
    def refresh(self, st: LiveStatus) -> None:
        """Show the connection state; called a few times a second by the owner."""
        self.state_label.setText(st.state_text())
        self.state_label.setProperty("state", st.state)
        self.state_label.style().unpolish(self.state_label)
        self.state_label.style().polish(self.state_label)
        self.detail_label.setText("\n".join(st.detail_lines()))
        if st.error:
            prefixed = st.error.startswith(f"{st.device}:")
            self.show_error(st.error if prefixed else f"{st.device}: {st.error}")
        elif self._form_error is None and st.state != "disconnected" and self.error_text() \
                and self.error_text().startswith(f"{st.device}:"):
            self.show_error(None)
        if st.recording:
            self.record_label.setText(
                f"Recording {os.path.basename(st.recording)} · {st.recorded_frames} frames")
            self.record_label.show()
        self._show_lsl()
        self._show_device_settings(st)
        self._update_buttons(st)

    def _show_device_settings(self, st: LiveStatus) -> None:
        """A setting the connected device now has other than it was connected with (a
        collection session sets the simulator idle: its touches must be the
        participant's) is shown as it is, locked, with a line saying why; it goes back
        when the device does. The form never claims gesture=auto while it is idle."""
        engine = self.acquisition.engine
        live = st.state in ("connecting", "running", "reconnecting") and engine is not None
        now = dict(getattr(engine.device, "settings", None) or {}) if live else {}
        lines = []
        for name, field in self.form_box.fields.items():
            was = self._connected.get(name)
            if name in now and name in self._connected and now[name] != was:
                if name not in self._held:
                    self._held[name] = field.text()
                    field.set_text(str(now[name]))
                    field.widget.setEnabled(False)
                lines.append(f"{field.setting.label or name}: {now[name]} while a collection "
                             f"session uses this device (it was {was}; back when the session "
                             "closes)")
            elif name in self._held:
                self._release_held(name)
        self.held_label.setText("\n".join(lines))
        self.held_label.setVisible(bool(lines))

    def _release_held(self, *names: str) -> None:
        """The form's own value back in the rows the device held (all when none named)."""
        for name in names or list(self._held):
            text = self._held.pop(name)
            field = self.form_box.fields.get(name)
            if field is not None:
                field.set_text(text)
                field.widget.setEnabled(True)
        if not self._held:
            self.held_label.hide()

    def _update_buttons(self, st: LiveStatus) -> None:
        live = st.state in ("connecting", "running", "reconnecting")
        self.connect_button.setText("Restart" if live else "Connect")
        self.connect_button.setToolTip("Restart the device with the settings above" if live
                                       else "Start streaming from the device")
        self.disconnect_button.setEnabled(st.device is not None and st.state != "stopped")
        self.tare_button.setEnabled(live)
        self.record_button.setEnabled(live or st.recording is not None)


def sensor_id_box() -> QComboBox:
    """Pick or type the sensor's ID for recordings (empty: the device's own, if any)."""
    box = QComboBox()
    box.setEditable(True)
    box.setToolTip("The sensor's ID goes into every recording and the sensor logbook")
    hint = "sensor ID (empty: the device's own)"
    try:
        with Logbook() as book:
            box.addItems(book.sensor_ids())
    except UserError as exc:  # unreadable or damaged (left as it is): typing an ID works
        box.setToolTip(f"{box.toolTip()}\n{exc}")
        hint = "sensor logbook unavailable (see tooltip): type the ID"
    box.setCurrentText("")
    box.lineEdit().setPlaceholderText(hint)
    return box
