"""A device plugin's settings as a form, generated from its ``settings_schema``.

One row per setting, by kind: int/float/str as a line edit, bool as a check box, choice
as a drop-down, path as a line edit with a file browser; the plugin's ``discover_setting``
(if any) gets the "Scan" drop-down of ui/device_discovery.py. Values are checked with
the schema's own ``Setting.parse`` as the user types, so the rules live in one place (the
core) and a bad value is highlighted with its one-line message before anything connects.
Used by the main window's device panel and the collection setup.
"""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLineEdit,
    QToolButton,
    QWidget,
)

from tactile_studio.devices.contract import DevicePlugin, Setting
from tactile_studio.errors import UserError
from tactile_studio.live import discover_setting
from tactile_studio.ui.device_discovery import DiscoverField


def one_line(text: object) -> str:
    return " ".join(str(text).split())


class SettingField:
    """One generated form row: the editor widget and how to read/write its text."""

    def __init__(self, setting: Setting, on_change: Any) -> None:
        self.setting = setting
        self.widget: QWidget
        default = "" if setting.default is None else str(setting.default)
        if setting.kind == "bool":
            self.editor = QCheckBox()
            self.editor.setChecked(bool(setting.default))
            self.editor.toggled.connect(on_change)
            self.widget = self.editor
        elif setting.kind == "choice":
            self.editor = QComboBox()
            self.editor.addItems(list(setting.choices))
            self.editor.setCurrentText(default)
            self.editor.currentTextChanged.connect(on_change)
            self.widget = self.editor
        else:
            self.editor = QLineEdit(default)
            self.editor.textChanged.connect(on_change)
            self.widget = self.editor
            if setting.kind == "path":
                browse = QToolButton(text="…")
                browse.clicked.connect(self._browse)
                row = QWidget()
                lay = QHBoxLayout(row)
                lay.setContentsMargins(0, 0, 0, 0)
                lay.addWidget(self.editor, 1)
                lay.addWidget(browse)
                self.widget = row
        tip = f"{setting.help or setting.name} (--set {setting.name}=\u2026)"
        if setting.minimum is not None or setting.maximum is not None:
            tip += f" (range {setting.minimum if setting.minimum is not None else ''}.."
            tip += f"{setting.maximum if setting.maximum is not None else ''})"
        self.widget.setToolTip(tip)

    def _browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self.widget, f"Choose {self.setting.name}",
                                              self.text())
        if path:
            self.set_text(path)

    def text(self) -> str:
        if isinstance(self.editor, QCheckBox):
            return "true" if self.editor.isChecked() else "false"
        if isinstance(self.editor, QComboBox):
            return self.editor.currentText()
        return self.editor.text().strip()

    def set_text(self, text: str) -> None:
        if isinstance(self.editor, QCheckBox):
            self.editor.setChecked(str(text).lower() in {"1", "true", "yes", "on"})
        elif isinstance(self.editor, QComboBox):
            self.editor.setCurrentText(str(text))
        else:
            self.editor.setText(str(text))

    def set_invalid(self, bad: bool) -> None:
        self.editor.setProperty("invalid", bad)
        self.editor.style().unpolish(self.editor)
        self.editor.style().polish(self.editor)


class SettingsForm(QGroupBox):
    """The settings rows of one plugin; ``changed`` fires on every edit.

    Rows are labelled in words with their unit (``Setting.title``: "Noise (counts rms)";
    the name ``--set`` takes is in the tooltip). Settings the plugin marks ``advanced``
    fold under "More settings (N)", shown at once when one of them is not its default
    or is wrong, so nothing that matters is ever hidden."""

    changed = Signal()

    def __init__(self, title: str = "Settings", parent: QWidget | None = None) -> None:
        super().__init__(title, parent)
        self.form = QFormLayout(self)
        self.form.setFieldGrowthPolicy(QFormLayout.FieldGrowthPolicy.AllNonFixedFieldsGrow)
        # a label in words with its unit goes above its field where the two do not fit
        # side by side (the main window's device dock), never squeezing the field
        self.form.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        self.plugin: type[DevicePlugin] | None = None
        self.fields: dict[str, SettingField | DiscoverField] = {}
        self.discover_field: DiscoverField | None = None
        self.more: QToolButton | None = None  # "More settings (N)"
        self._advanced: list[str] = []

    def set_plugin(self, cls: type[DevicePlugin] | None) -> None:
        """Rebuild the rows for ``cls`` (None: no rows), filled with its defaults."""
        if self.discover_field is not None:
            self.discover_field.forget()
            self.discover_field = None
        while self.form.rowCount():
            self.form.removeRow(0)
        self.fields.clear()
        self.more = None
        self.plugin = cls
        scan_name = discover_setting(cls)
        schema = cls.settings_schema if cls else ()
        self._advanced = [s.name for s in schema if s.advanced and s.name != scan_name]
        first_advanced = self._advanced[0] if self._advanced else None
        for setting in sorted(schema, key=lambda s: s.name in self._advanced):
            if setting.name == first_advanced:
                self._add_more_row()
            if setting.name == scan_name:
                field = DiscoverField(setting, cls, self._changed, self.values)
                self.discover_field = field
            else:
                field = SettingField(setting, self._changed)
            self.fields[setting.name] = field
            self.form.addRow(setting.title, field.widget)
        self.show_advanced(False)
        self.setVisible(bool(self.fields))
        if self.discover_field is not None and self.discover_field.instant:
            self.discover_field.scan()

    def _add_more_row(self) -> None:
        self.more = QToolButton()
        self.more.setCheckable(True)
        self.more.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.more.setArrowType(Qt.ArrowType.RightArrow)
        self.more.setAutoRaise(True)
        self.more.setText(f"More settings ({len(self._advanced)})")
        self.more.toggled.connect(self.show_advanced)
        self.form.addRow(self.more)

    def show_advanced(self, on: bool) -> None:
        """Unfold (or fold) the advanced settings' rows."""
        if self.more is None:
            return
        if self.more.isChecked() != on:
            self.more.setChecked(on)  # toggled: comes back here
            return
        self.more.setArrowType(Qt.ArrowType.DownArrow if on else Qt.ArrowType.RightArrow)
        for name in self._advanced:
            self.form.setRowVisible(self.fields[name].widget, on)

    def _unfold_if_needed(self) -> None:
        """An advanced setting that is not its default, or is wrong, is shown."""
        if self.more is None or self.more.isChecked():
            return
        device = self.plugin.name if self.plugin else ""
        for name in self._advanced:
            field = self.fields[name]
            try:
                if field.text() != "" and field.setting.parse(field.text(), device) \
                        != field.setting.default:
                    break
            except UserError:
                break
        else:
            return
        self.show_advanced(True)

    def _changed(self, *_: object) -> None:
        self._unfold_if_needed()
        self.changed.emit()

    def values(self) -> dict[str, str]:
        """The form as text, as ``--set key=value`` would give it (empty = default)."""
        return {name: f.text() for name, f in self.fields.items() if f.text() != ""}

    def set_values(self, values: dict[str, Any]) -> None:
        """Fill the rows named in ``values`` (unknown names are ignored)."""
        for key, value in values.items():
            if key in self.fields and value is not None:
                self.fields[key].set_text(str(value))
        self._unfold_if_needed()

    def changed_values(self) -> dict[str, str]:
        """Only the values that differ from the plugin's defaults (what a session or a
        command line needs to say)."""
        device = self.plugin.name if self.plugin else ""
        out = {}
        for name, text in self.values().items():
            setting = self.fields[name].setting
            try:
                same = setting.parse(text, device) == setting.default
            except UserError:
                same = False
            if not same:
                out[name] = text
        return out

    def first_error(self) -> str | None:
        """Check every row, highlight the bad ones; the first one's message or None."""
        device, first = self.plugin.name if self.plugin else "", None
        for field in self.fields.values():
            text = field.text()
            try:
                if text != "":
                    field.setting.parse(text, device)
                field.set_invalid(False)
            except UserError as exc:
                field.set_invalid(True)
                # the row is highlighted, so "device x: setting " need not be repeated
                first = first or one_line(exc).replace(f"device {device}: setting ", "", 1)
        return first
