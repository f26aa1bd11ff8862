"""The console's setup step: protocol, participant, output folder, device; or resume a file.

It only collects choices and hands them on (``startRequested`` / ``resumeRequested``);
loading and validating the protocol is the core's ``load_protocol`` (its one-line
errors are shown under the form). Folders and files are remembered in QSettings so
the dialogs open where the experimenter last was.

The device defaults to the main window's live device when there is one, else the one
last used for a session, else ``simulated``. Its settings are the plugin's own form
(ui/settings_form.py, as in the device panel), checked as they are typed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from PySide6.QtCore import QSettings, Signal
from PySide6.QtGui import QRegularExpressionValidator
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.devices.registry import available_plugins
from tactile_studio.errors import UserError
from tactile_studio.storage.protocol_file import Protocol, list_protocols, load_protocol
from tactile_studio.ui.settings import get_json, set_json
from tactile_studio.ui.settings_form import SettingsForm

LIVE_DEVICE = "(the live device)"
KEY_OUT_DIR = "collect/out_dir"
KEY_LAST_DIR = "collect/last_dir"
KEY_DEVICE = "collect/device"
KEY_DEVICE_VALUES = "collect/device_values/"  # + plugin name: its non-default settings
KEY_PROTOCOL = "collect/protocol"
DEFAULT_PROTOCOL = "shear9"
DEFAULT_DEVICE = "simulated"
_FROM_FILE = "From file\u2026"


@dataclass
class SetupChoice:
    """Everything needed to open a session (protocol already loaded and overridden)."""

    protocol: Protocol
    participant: str
    out_dir: Path
    condition: str = ""
    seed: int = 0
    device: str | None = None          # None: use the console's shared live engine
    device_settings: dict[str, Any] = field(default_factory=dict)
    hold_flagged: bool = True          # a flagged trial waits for Redo or Continue
    auto_continue: bool = False        # breaks end by themselves after their minimum


class CollectSetup(QWidget):
    """The form shown before a session starts."""

    startRequested = Signal(object)   # SetupChoice
    resumeRequested = Signal(str)     # session file path

    def __init__(self, settings: QSettings, live_device: str | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.settings = settings
        self._protocol_file: str | None = None
        title = QLabel("New collection session")
        title.setStyleSheet("font-size: 20px; font-weight: 600;")

        self.protocol = QComboBox()
        for name in list_protocols():
            self.protocol.addItem(name, name)
        self.protocol.addItem(_FROM_FILE, None)
        self.protocol_info = QLabel()
        self.protocol_info.setWordWrap(True)
        self.protocol_info.setStyleSheet("color: #606770;")
        self.participant = QLineEdit()
        self.participant.setPlaceholderText("e.g. P01")
        self.participant.setValidator(QRegularExpressionValidator(r"[A-Za-z0-9_\-]{0,32}"))
        self.condition = QLineEdit()
        self.condition.setPlaceholderText("optional, e.g. FLAT or PILLOW")
        self.blocks = QSpinBox()
        self.blocks.setRange(1, 999)
        self.seed = QSpinBox()
        self.seed.setRange(0, 2**31 - 1)
        self.out_dir = QLineEdit(str(settings.value(KEY_OUT_DIR, str(Path.cwd()))))
        browse = QPushButton("Browse\u2026")
        browse.clicked.connect(self.choose_out_dir)
        out_row = QHBoxLayout()
        out_row.addWidget(self.out_dir, 1)
        out_row.addWidget(browse)
        self.plugins = {name: cls for name, cls in available_plugins().items()
                        if not isinstance(cls, Exception) and name != "replay"}
        self.device = QComboBox()
        if live_device:
            self.device.addItem(f"{LIVE_DEVICE} {live_device}", None)
        for name in self.plugins:
            self.device.addItem(name, name)
        self.device_form = SettingsForm("Device settings")
        self.device_form.changed.connect(self._check_device)
        self.device_error = QLabel()
        self.device_error.setWordWrap(True)
        self.device_error.setStyleSheet("color: #c0392b;")
        self.device_error.hide()
        self.device.currentIndexChanged.connect(self._on_device_changed)
        saved = settings.value(KEY_DEVICE)
        if not live_device:
            default = saved if self.device.findData(saved) >= 0 else DEFAULT_DEVICE
            self.device.setCurrentIndex(max(0, self.device.findData(default)))
        self._on_device_changed()
        self.hold_flagged = QCheckBox("Hold a flagged trial until I choose Redo or Continue")
        self.hold_flagged.setChecked(True)
        self.auto_continue = QCheckBox("End breaks automatically after their minimum")

        form = QFormLayout()
        form.addRow("Protocol", self.protocol)
        form.addRow("", self.protocol_info)
        form.addRow("Participant", self.participant)
        form.addRow("Condition", self.condition)
        form.addRow("Blocks", self.blocks)
        form.addRow("Order seed", self.seed)
        form.addRow("Output folder", out_row)
        form.addRow("Device", self.device)
        form.addRow(self.device_form)
        form.addRow("", self.device_error)
        form.addRow("", self.hold_flagged)
        form.addRow("", self.auto_continue)

        self.error = QLabel()
        self.error.setWordWrap(True)
        self.error.setStyleSheet("color: #c0392b; font-weight: 600;")
        self.start_button = QPushButton("Open session")
        self.start_button.setDefault(True)
        self.start_button.clicked.connect(self._on_start)
        self.resume_button = QPushButton("Resume session\u2026")
        self.resume_button.clicked.connect(self.choose_resume_file)
        buttons = QHBoxLayout()
        buttons.addStretch(1)
        buttons.addWidget(self.resume_button)
        buttons.addWidget(self.start_button)

        card = QWidget()
        card.setMaximumWidth(760)
        inner = QVBoxLayout(card)
        inner.addWidget(title)
        inner.addSpacing(8)
        inner.addLayout(form)
        inner.addWidget(self.error)
        inner.addSpacing(8)
        inner.addLayout(buttons)
        row = QHBoxLayout()
        row.addStretch(1)
        row.addWidget(card, 4)
        row.addStretch(1)
        box = QVBoxLayout(self)
        box.addStretch(1)
        box.addLayout(row)
        box.addStretch(2)

        self.protocol.currentIndexChanged.connect(self._on_protocol_changed)
        saved_p = settings.value(KEY_PROTOCOL) or DEFAULT_PROTOCOL
        if self.protocol.findData(saved_p) >= 0:
            self.protocol.setCurrentIndex(self.protocol.findData(saved_p))
        self._on_protocol_changed()

    # ---- protocol ---------------------------------------------------------------------
    def _protocol_source(self) -> str | None:
        data = self.protocol.currentData()
        return data if data is not None else self._protocol_file

    def set_protocol_file(self, path: str) -> None:
        """Use a protocol file from disk (what "From file..." picks)."""
        self._protocol_file = path
        self.protocol.blockSignals(True)
        self.protocol.setCurrentIndex(self.protocol.count() - 1)
        self.protocol.setItemText(self.protocol.count() - 1, f"{Path(path).name} (file)")
        self.protocol.blockSignals(False)
        self._on_protocol_changed()

    def _on_protocol_changed(self) -> None:
        if self.protocol.currentData() is None and self._protocol_file is None:
            path, _ = QFileDialog.getOpenFileName(self, "Protocol file", self._last_dir(),
                                                  "Protocols (*.toml)")
            if not path:
                self.protocol.setCurrentIndex(0)
                return
            self._remember_dir(Path(path).parent)
            self.set_protocol_file(path)
            return
        try:
            p = load_protocol(self._protocol_source())
        except UserError as exc:
            self.protocol_info.setText("")
            self.error.setText(str(exc))
            return
        self.error.setText("")
        self.blocks.setValue(p.blocks)
        self.seed.setValue(p.seed)
        brk = (f"break \u2265 {p.break_min_s:g} s every {p.break_every} blocks"
               if p.break_every else "no breaks")
        self.protocol_info.setText(
            f"{p.title}: {len(p.gestures)} gestures, {p.trial_s:g} s trials, {brk}, "
            f"{p.free_play_s:g} s free play; "
            + ("the screen prompts each block's random order" if p.order == "prompted"
               else "free order within a block (any gesture not done yet)"))

    # ---- folders ----------------------------------------------------------------------
    def _last_dir(self) -> str:
        return str(self.settings.value(KEY_LAST_DIR, self.out_dir.text() or str(Path.cwd())))

    def _remember_dir(self, folder: Path) -> None:
        self.settings.setValue(KEY_LAST_DIR, str(folder))

    def choose_out_dir(self) -> None:
        start = self.out_dir.text() or self._last_dir()
        folder = QFileDialog.getExistingDirectory(self, "Output folder", start)
        if folder:
            self.out_dir.setText(folder)
            self._remember_dir(Path(folder))

    def choose_resume_file(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Resume session", self._last_dir(),
                                              "Sessions (*.h5)")
        if path:
            self._remember_dir(Path(path).parent)
            self.resumeRequested.emit(path)

    # ---- choices ----------------------------------------------------------------------
    # ---- device -----------------------------------------------------------------------
    def _on_device_changed(self) -> None:
        """The chosen plugin's form, with the settings last used with it."""
        name = self.device.currentData() or ""
        self.device_form.set_plugin(self.plugins.get(name))
        if name:
            saved = get_json(self.settings, KEY_DEVICE_VALUES + name, {})
            self.device_form.set_values(saved if isinstance(saved, dict) else {})
        self._check_device()

    def _check_device(self) -> str | None:
        error = self.device_form.first_error()
        self.device_error.setText(error or "")
        self.device_error.setVisible(bool(error))
        return error

    def set_device(self, name: str, values: dict[str, Any] | None = None) -> bool:
        """Choose plugin ``name`` with exactly ``values`` over its defaults (what the
        ``collect`` command passes); False if it cannot run a session."""
        i = self.device.findData(name)
        if i < 0:
            return False
        if i != self.device.currentIndex():
            self.device.setCurrentIndex(i)
        self.device_form.set_plugin(self.plugins[name])
        self.device_form.set_values(values or {})
        self._check_device()
        return True

    def device_choice(self) -> tuple[str | None, dict[str, Any]]:
        """The chosen plugin (None = the shared live engine) and the settings that differ
        from its defaults; a bad value is a one-line UserError."""
        name = self.device.currentData()
        error = self._check_device()
        if error:
            raise UserError(f"device {name}: {error}")
        return name, self.device_form.changed_values() if name else {}

    def choice(self) -> SetupChoice:
        """The form's values, validated (UserError with a one-line message)."""
        participant = self.participant.text().strip()
        if not participant:
            raise UserError("enter a participant id (e.g. P01)")
        out = Path(self.out_dir.text().strip() or ".").expanduser()
        if not out.is_dir():
            raise UserError(f"{out}: output folder does not exist")
        p = load_protocol(self._protocol_source())
        if self.blocks.value() != p.blocks:
            p = p.with_overrides(blocks=self.blocks.value())
        device, dev_settings = self.device_choice()
        return SetupChoice(p, participant, out, self.condition.text().strip(),
                           self.seed.value(), device, dev_settings,
                           self.hold_flagged.isChecked(), self.auto_continue.isChecked())

    def show_error(self, text: str) -> None:
        """The one-line message under the form ("" clears it)."""
        self.error.setText(text)

    def run_options(self) -> tuple[bool, bool]:
        """(hold flagged trials, auto-continue after breaks): a resume's options."""
        return self.hold_flagged.isChecked(), self.auto_continue.isChecked()

    def prefill(self, protocol: str | None = None, participant: str = "",
                device: str | None = None, device_values: dict[str, str] | None = None,
                out_dir: str | None = None, blocks: int | None = None,
                seed: int | None = None, condition: str = "") -> None:
        """Fill the form (the ``collect`` command's options); it stays editable. A
        device that cannot run a session is a one-line UserError."""
        if device and self.device.findData(device) < 0:
            usable = [self.device.itemData(i) for i in range(self.device.count())]
            raise UserError(f"device {device!r} cannot run a collection session "
                            f"(usable: {', '.join(str(u) for u in usable if u)})")
        if protocol is not None:
            if self.protocol.findData(protocol) >= 0:
                self.protocol.setCurrentIndex(self.protocol.findData(protocol))
            else:
                self.set_protocol_file(str(Path(protocol).resolve()))
        if participant:
            self.participant.setText(participant)
        if condition:
            self.condition.setText(condition)
        if device:
            self.set_device(device, device_values)
        if out_dir is not None:
            self.out_dir.setText(out_dir)
        if blocks is not None:
            self.blocks.setValue(int(blocks))
        if seed is not None:
            self.seed.setValue(int(seed))

    def _on_start(self) -> None:
        try:
            choice = self.choice()
        except UserError as exc:
            self.error.setText(str(exc))
            return
        self.error.setText("")
        self.settings.setValue(KEY_OUT_DIR, str(choice.out_dir))
        self.settings.setValue(KEY_PROTOCOL, self.protocol.currentData() or "")
        if choice.device:
            self.settings.setValue(KEY_DEVICE, choice.device)
            set_json(self.settings, KEY_DEVICE_VALUES + choice.device, choice.device_settings)
        self.startRequested.emit(choice)
