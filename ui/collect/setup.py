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
from tactile_studio.paths import data_dir
from tactile_studio.protocol.collect import device_differences, read_resume_info, resume_device
from tactile_studio.storage.format.protocol_file import (
    CollectionProtocol,
    list_protocols,
    load_protocol,
)
from tactile_studio.ui.collect.qc_setup import QcChoice, QcModelField
from tactile_studio.ui.settings import get_json, set_json
from tactile_studio.ui.settings_form import SettingsForm

LIVE_DEVICE = "(the live device)"
KEY_OUT_DIR = "collect/out_dir"
KEY_LAST_DIR = "collect/last_dir"
KEY_DEVICE = "collect/device"
KEY_DEVICE_VALUES = "collect/device_values/"  # + plugin name: its non-default settings
KEY_PROTOCOL = "collect/protocol"
KEY_PROTOCOL_FILE = "collect/protocol_file"  # a protocol chosen "From file..."
DEFAULT_PROTOCOL = "shear9"
DEFAULT_DEVICE = "simulated"
_FROM_FILE = "From file\u2026"


def default_sessions_dir() -> Path:
    """Where sessions go until the experimenter picks a folder: the app's data folder,
    not wherever the app happened to be started."""
    return data_dir() / "sessions"


def _wrapped(style: str, text: str = "") -> QLabel:
    """A word-wrapped line of the form in its colour (notes grey, errors red)."""
    label = QLabel(text)
    label.setWordWrap(True)
    label.setStyleSheet(style)
    return label


def _row(first: QWidget, second: QWidget, wide: int = 0) -> QHBoxLayout:
    """Two widgets side by side, the ``wide``-th taking the room."""
    row = QHBoxLayout()
    row.addWidget(first, 1 - wide)
    row.addWidget(second, wide)
    return row


@dataclass
class SetupChoice:
    """Everything needed to open a session (protocol already loaded and overridden)."""

    protocol: CollectionProtocol
    participant: str
    out_dir: Path
    condition: str = ""
    seed: int = 0
    device: str | None = None          # None: use the console's shared live engine
    device_settings: dict[str, Any] = field(default_factory=dict)
    hold_flagged: bool = True          # a flagged trial waits for Redo or Keep
    auto_continue: bool = False        # breaks end by themselves after their minimum
    pilot: bool = False                # a rehearsal (protocol/collect.py: session_metadata)
    qc: QcChoice = field(default_factory=QcChoice)  # the trial check's model, if any


class CollectSetup(QWidget):
    """The form shown before a session starts."""

    startRequested = Signal(object)   # SetupChoice
    resumeRequested = Signal(str)     # session file path
    otherSensorRequested = Signal(str)  # resume this file on the form's other sensor
    testSoundRequested = Signal()     # the console plays the protocol's beep

    def __init__(self, settings: QSettings, live_device: str | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.settings = settings
        self._protocol_file: str | None = None
        self._device_file: str | None = None  # the resume file the device form was set from
        self._resume_info: dict[str, Any] | None = None  # that file's read_resume_info
        self.other_sensor_why: str | None = None  # why the device is not the file's
        self.resuming = False
        out_row = self._build_session_fields()
        self._build_device_fields(live_device)
        sound_row = self._build_options()
        resume_row = self._build_resume_fields()
        self._build_form(resume_row, out_row, sound_row)
        self._build_page(self._build_buttons())
        self._restore_protocol()

    # ---- the form's parts, top to bottom ---------------------------------------------
    def _build_session_fields(self) -> QHBoxLayout:
        """Title, protocol, participant, condition, blocks, seed, the output folder's row."""
        self.title = QLabel("New collection session")
        self.title.setStyleSheet("font-size: 20px; font-weight: 600;")
        self.protocol = QComboBox()
        for name in list_protocols():
            self.protocol.addItem(name, name)
        self.protocol.addItem(_FROM_FILE, None)
        self.protocol_info = _wrapped("color: #606770;")
        self.participant = QLineEdit()
        self.participant.setPlaceholderText("e.g. P01")
        self.participant.setValidator(QRegularExpressionValidator(r"[A-Za-z0-9_\-]{0,32}"))
        self.condition = QLineEdit()
        self.condition.setPlaceholderText("optional, e.g. FLAT or PILLOW")
        self.blocks = QSpinBox()
        self.blocks.setRange(1, 999)
        self.seed = QSpinBox()
        self.seed.setRange(0, 2**31 - 1)
        self.out_dir = QLineEdit(str(self.settings.value(KEY_OUT_DIR)
                                     or default_sessions_dir()))
        browse = QPushButton("Browse\u2026")
        browse.clicked.connect(self.choose_out_dir)
        out_row = _row(self.out_dir, browse)
        self.out_note = _wrapped("color: #606770;")  # a folder that does not exist: made
        return out_row

    def _build_device_fields(self, live_device: str | None) -> None:
        """The device (the live one first), its settings form, resuming on another sensor."""
        self.plugins = {name: cls for name, cls in available_plugins().items()
                        if not isinstance(cls, Exception) and name != "replay"}
        self.device = QComboBox()
        if live_device:
            self.device.addItem(f"{LIVE_DEVICE} {live_device}", None)
        for name in self.plugins:
            self.device.addItem(name, name)
        self.device_form = SettingsForm("Device settings")
        self.device_form.changed.connect(self._check_device)
        self.device_form.changed.connect(self._check_other_sensor)
        self.device_error = _wrapped("color: #c0392b;")
        self.device_error.hide()
        # a resume on another device or sensor than the file's: said, and chosen explicitly
        self.other_sensor_info = _wrapped("color: #a15c00; font-weight: 600;")
        self.other_sensor_button = QPushButton("Resume on this other sensor\u2026")
        self.other_sensor_button.setToolTip(
            "continue the session on the device chosen here, not the file's; asks why "
            "(the note is kept in the session, as collect --allow-other-sensor)")
        self.other_sensor_button.clicked.connect(
            lambda: self.otherSensorRequested.emit(self.resume_path()))
        self.device.currentIndexChanged.connect(self._on_device_changed)
        saved = self.settings.value(KEY_DEVICE)
        if not live_device:
            default = saved if self.device.findData(saved) >= 0 else DEFAULT_DEVICE
            self.device.setCurrentIndex(max(0, self.device.findData(default)))
        self._on_device_changed()

    def _build_options(self) -> QHBoxLayout:
        """Pilot, hold-flagged, auto-continue, trial check; returns the beep's row."""
        self.hold_flagged = QCheckBox("Hold a flagged trial until I choose Redo or Keep")
        self.hold_flagged.setChecked(True)
        self.auto_continue = QCheckBox("End breaks automatically after their minimum")
        self.pilot = QCheckBox("Pilot: rehearse the protocol (on the simulated sensor a "
                               "virtual participant performs)")
        self.pilot.setToolTip("The file is marked pilot and named PILOT_...; datasets, "
                              "train and info's study leave it out unless the file is named")
        self.qc = QcModelField(self.settings)
        self.test_sound_button = QPushButton("Test sound")
        self.test_sound_button.setToolTip("Play the protocol's end-of-trial beep now")
        self.test_sound_button.clicked.connect(self.testSoundRequested)
        self.sound_result = QLabel()
        self.sound_result.setWordWrap(True)
        return _row(self.test_sound_button, self.sound_result, wide=1)

    def _build_resume_fields(self) -> QHBoxLayout:
        """The resume form's file line and what it keeps; returns the file's row."""
        self.resume_file = QLineEdit()
        self.resume_file.setPlaceholderText("the session file to continue (.h5)")
        resume_browse = QPushButton("Browse\u2026")
        resume_browse.clicked.connect(self.choose_resume_file)
        resume_row = _row(self.resume_file, resume_browse)
        self.resume_info = _wrapped("color: #606770;", "The protocol, participant, blocks "
                                    "and order come from the file; the session continues "
                                    "at its next trial.")
        return resume_row

    def _build_form(self, resume_row: QHBoxLayout, out_row: QHBoxLayout,
                    sound_row: QHBoxLayout) -> None:
        """One form for both modes: ``set_resume_mode`` shows the rows of one."""
        self.form = form = QFormLayout()
        form.addRow("Session file", resume_row)
        form.addRow("", self.resume_info)
        form.addRow("Protocol", self.protocol)
        form.addRow("", self.protocol_info)
        form.addRow("Participant", self.participant)
        form.addRow("Condition", self.condition)
        form.addRow("Blocks", self.blocks)
        form.addRow("Order seed", self.seed)
        form.addRow("Output folder", out_row)
        form.addRow("", self.out_note)
        form.addRow("Device", self.device)
        form.addRow(self.device_form)
        form.addRow("", self.device_error)
        form.addRow("", self.other_sensor_info)
        form.setRowVisible(self.other_sensor_info, False)
        self.other_sensor_button.hide()
        form.addRow("", self.pilot)
        form.addRow("", self.hold_flagged)
        form.addRow("", self.auto_continue)
        form.addRow("Trial check", self.qc)
        form.addRow("Beep", sound_row)

    def _build_buttons(self) -> QHBoxLayout:
        """The error line and the row of buttons below the form (both modes')."""
        self.error = _wrapped("color: #c0392b; font-weight: 600;")
        self.start_button = QPushButton("Open session")
        self.start_button.setDefault(True)
        self.start_button.clicked.connect(self._on_start)
        self.resume_button = QPushButton("Resume session\u2026")
        self.resume_button.clicked.connect(self.choose_resume_file)
        self.new_button = QPushButton("New session instead")
        self.new_button.clicked.connect(lambda: self.set_resume_mode(False))
        self.continue_button = QPushButton("Resume")
        self.continue_button.clicked.connect(self._on_resume)
        buttons = QHBoxLayout()
        buttons.addWidget(self.new_button)
        buttons.addStretch(1)
        buttons.addWidget(self.resume_button)
        buttons.addWidget(self.start_button)
        buttons.addWidget(self.other_sensor_button)
        buttons.addWidget(self.continue_button)
        self.participant.textEdited.connect(self._clear_error)
        self.out_dir.textEdited.connect(self._clear_error)
        self.out_dir.textChanged.connect(self._say_out_dir)
        return buttons

    def _build_page(self, buttons: QHBoxLayout) -> None:
        """The form in a card of bounded width, centred on the page."""
        card = QWidget()
        card.setMaximumWidth(760)
        inner = QVBoxLayout(card)
        inner.addWidget(self.title)
        inner.addSpacing(8)
        inner.addLayout(self.form)
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

    def _restore_protocol(self) -> None:
        """The last session's protocol (or protocol file), then the new-session form."""
        settings = self.settings
        self.protocol.currentIndexChanged.connect(self._on_protocol_changed)
        saved_p = settings.value(KEY_PROTOCOL) or DEFAULT_PROTOCOL
        saved_file = str(settings.value(KEY_PROTOCOL_FILE) or "")
        if not settings.value(KEY_PROTOCOL) and saved_file and Path(saved_file).is_file():
            self.set_protocol_file(saved_file)  # the protocol file of the last session
        else:
            if self.protocol.findData(saved_p) >= 0:
                self.protocol.setCurrentIndex(self.protocol.findData(saved_p))
            self._on_protocol_changed()
        self.set_resume_mode(False)

    # ---- new session or resume -----------------------------------------------------------
    def set_resume_mode(self, on: bool) -> None:
        """Show the resume form (file, device, options) or the new-session form; the
        fields that a resume takes from the file are hidden, not left to mislead."""
        self.resuming = on
        self.title.setText("Resume a collection session" if on else "New collection session")
        for widget in (self.protocol, self.protocol_info, self.participant, self.condition,
                       self.blocks, self.seed, self.pilot):
            self.form.setRowVisible(widget, not on)
        self._set_row_visible(self.out_dir, not on)
        self._say_out_dir()
        self.form.setRowVisible(self.resume_info, on)
        self._set_row_visible(self.resume_file, on)
        self.start_button.setVisible(not on)
        self.resume_button.setVisible(not on)
        self.new_button.setVisible(on)
        self.continue_button.setVisible(on)
        self.continue_button.setDefault(on)
        self.start_button.setDefault(not on)
        self.error.setText("")
        self._check_other_sensor()

    def _set_row_visible_widget(self, widget: QWidget, on: bool) -> None:
        """Show or hide the row of a label (never in the resume form, which has no folder)."""
        self.form.setRowVisible(widget, on and not self.resuming)

    def _set_row_visible(self, widget: QWidget, on: bool) -> None:
        """Show or hide the form row holding ``widget`` (also inside a row's layout)."""
        for row in range(self.form.rowCount()):
            item = self.form.itemAt(row, QFormLayout.ItemRole.FieldRole)
            layout = item.layout() if item is not None else None
            if layout is not None and layout.indexOf(widget) >= 0:
                self.form.setRowVisible(row, on)
                return

    def resume_participant(self) -> str:
        """The participant of the file being resumed ("" when unknown): the trial check
        uses the fold that never saw them."""
        info = self._resume_info if self.resume_path() == self._device_file else None
        return str((info or {}).get("participant") or "")

    def resume_path(self) -> str:
        """The resume form's file ("" when none)."""
        path = self.resume_file.text().strip()
        return str(Path(path).expanduser()) if path else ""

    def _on_resume(self) -> None:
        path = self.resume_path()
        if not path:
            self.choose_resume_file()
            return
        self._remember_dir(Path(path).parent)
        if path != self._device_file:  # a device chosen after the file is left as chosen
            self.device_from_file(path)
        self.resumeRequested.emit(path)

    def _clear_error(self, *_: object) -> None:
        """A message about a field goes once the field is edited."""
        self.error.setText("")

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
        self.qc.set_study(p.name, p.gesture_names)  # its model, remembered per study
        self.blocks.setMaximum(p.blocks)  # its first N blocks; never more than it has
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

    def out_path(self) -> Path:
        """The output folder the form names (the app's sessions folder when empty)."""
        return Path(self.out_dir.text().strip() or default_sessions_dir()).expanduser()

    def _say_out_dir(self, *_: object) -> None:
        """Say, before anything is written, that a folder that does not exist will be
        made (the rule of every output folder, ``paths.make_out_dir``): a mistyped one
        shows here, not as a stray folder found later."""
        out = self.out_path()
        missing = not out.exists()
        self.out_note.setText(f"{out} does not exist yet: it will be made when the "
                              "session opens." if missing else "")
        self._set_row_visible_widget(self.out_note, missing)

    def choose_out_dir(self) -> None:
        start = self.out_dir.text() or self._last_dir()
        folder = QFileDialog.getExistingDirectory(self, "Output folder", start)
        if folder:
            self.out_dir.setText(folder)
            self._remember_dir(Path(folder))

    def choose_resume_file(self) -> None:
        """Switch to the resume form and pick the file; cancelled with no file chosen,
        the form goes back to a new session."""
        was = self.resuming
        self.set_resume_mode(True)
        path, _ = QFileDialog.getOpenFileName(self, "Resume session", self._last_dir(),
                                              "Sessions (*.h5)")
        if path:
            self.resume_file.setText(path)
            self._remember_dir(Path(path).parent)
            self.device_from_file(path)
            self.resumeRequested.emit(path)
        elif not self.resume_file.text().strip() and not was:
            self.set_resume_mode(False)

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
        self._check_other_sensor()

    def _check_device(self) -> str | None:
        error = self.device_form.first_error()
        self.device_error.setText(error or "")
        self.device_error.setVisible(bool(error))
        return error

    def device_from_file(self, path: str) -> None:
        """A resume runs on the file's device and sensor (its plugin and settings, e.g.
        the simulator's seed): the form shows them. A file that cannot be read keeps the
        form as it is (the resume then says why in one line)."""
        try:
            info = read_resume_info(path)
        except UserError:
            return
        name, values = resume_device(info)
        self._resume_info, self._device_file = info, path
        if name is not None:
            self.set_device(name, values)
        self._check_other_sensor()

    def keep_resume_file(self, path: str) -> None:
        """The resume form for ``path`` with the device the form shows now (the console
        resuming a file it was given): a refusal can then offer the other-sensor choice."""
        if not self.resuming:
            self.set_resume_mode(True)
        self.resume_file.setText(path)
        if path != self._device_file:
            try:
                self._resume_info = read_resume_info(path)
            except UserError:
                self._resume_info = None
            self._device_file = path
        self._check_other_sensor()

    def _check_other_sensor(self, *_: object) -> None:
        """In the resume form, say when the chosen device is not the file's (the core's
        ``device_differences``) and offer to resume on it with a note."""
        if not self.resuming and self.other_sensor_why is None:
            return  # nothing shown, nothing to say (also while the form is being built)
        why = None
        if self.resuming and self._resume_info is not None \
                and self.resume_path() == self._device_file:
            why = device_differences(self._resume_info, self.device.currentData(),
                                     self.device_form.values())
        self.offer_other_sensor(why)

    def offer_other_sensor(self, why: str | None) -> None:
        """Show (or with None hide) that the device is another sensor than the file's and
        the explicit choice to resume on it; the console calls it when a resume is
        refused for that reason."""
        self.other_sensor_why = why
        self.other_sensor_info.setText(
            f"\u26a0 {why[:1].upper()}{why[1:]}. A resume on another sensor is refused "
            "unless you say why: \u201cResume on this other sensor\u2026\u201d asks for a "
            "note, kept in the session." if why else "")
        self.form.setRowVisible(self.other_sensor_info, bool(why))
        self.other_sensor_button.setVisible(bool(why) and self.resuming)

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
        self._check_other_sensor()
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
        out = self.out_path()  # made when the session opens, if it does not exist
        if out.exists() and not out.is_dir():
            raise UserError(f"{out}: not a folder; choose a folder for the sessions")
        p = load_protocol(self._protocol_source())
        if self.blocks.value() != p.blocks:
            p = p.with_overrides(blocks=self.blocks.value())
        device, dev_settings = self.device_choice()
        return SetupChoice(p, participant, out, self.condition.text().strip(),
                           self.seed.value(), device, dev_settings,
                           self.hold_flagged.isChecked(), self.auto_continue.isChecked(),
                           self.pilot.isChecked(), self.qc.choice())

    def show_sound(self, text: str, ok: bool) -> None:
        """The result of "Test sound" beside its button."""
        self.sound_result.setText(text)
        self.sound_result.setStyleSheet("color: #606770;" if ok else "color: #c0392b;")

    def current_protocol(self) -> CollectionProtocol | None:
        """The chosen protocol, or None if it cannot be loaded."""
        try:
            return load_protocol(self._protocol_source())
        except UserError:
            return None

    def show_error(self, text: str) -> None:
        """The one-line message under the form ("" clears it)."""
        self.error.setText(text)

    def run_options(self) -> tuple[bool, bool]:
        """(hold flagged trials, auto-continue after breaks): a resume's options."""
        return self.hold_flagged.isChecked(), self.auto_continue.isChecked()

    def prefill(self, protocol: str | None = None, participant: str = "",
                device: str | None = None, device_values: dict[str, str] | None = None,
                out_dir: str | None = None, blocks: int | None = None,
                seed: int | None = None, condition: str = "", pilot: bool = False) -> None:
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
        self.pilot.setChecked(pilot)

    def _on_start(self) -> None:
        try:
            choice = self.choice()
        except UserError as exc:
            self.error.setText(str(exc))
            return
        self.error.setText("")
        self.settings.setValue(KEY_OUT_DIR, str(choice.out_dir))
        self.settings.setValue(KEY_PROTOCOL, self.protocol.currentData() or "")
        self.settings.setValue(KEY_PROTOCOL_FILE,
                               "" if self.protocol.currentData() else self._protocol_file or "")
        if choice.device:
            self.settings.setValue(KEY_DEVICE, choice.device)
            set_json(self.settings, KEY_DEVICE_VALUES + choice.device, choice.device_settings)
        self.startRequested.emit(choice)
