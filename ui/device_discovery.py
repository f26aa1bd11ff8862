"""The device panel's "Scan" field: an editable drop-down of ports or peripherals found.

Discovery blocks (a BLE scan listens for seconds), so it runs in a plain daemon thread
that hands its answer back through a queued Qt signal: the GUI thread never waits, and
closing the window never waits for a scan either. The emitter is one module-level
object that lives as long as the application, so a worker finishing after its panel is
gone emits into no one rather than into a deleted object.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, QSize, Qt, Signal, Slot
from PySide6.QtGui import QPainter
from PySide6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QLabel,
    QSizePolicy,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.devices.contract import DevicePlugin, Setting
from tactile_studio.live import discover_is_instant, run_discovery


class ElidedLabel(QLabel):
    """One line of text, cut with "…" to the width it gets; the full text is the tooltip."""

    def paintEvent(self, event) -> None:  # noqa: ANN001, N802 - Qt signature
        painter = QPainter(self)
        rect = self.contentsRect()
        text = self.fontMetrics().elidedText(self.text(), Qt.TextElideMode.ElideRight,
                                             rect.width())
        painter.setPen(self.palette().color(self.foregroundRole()))
        painter.drawText(rect, int(self.alignment()), text)

    def minimumSizeHint(self) -> QSize:  # noqa: N802 - Qt name
        return QSize(10, super().minimumSizeHint().height())


class _ScanSignals(QObject):
    done = Signal(int, object, object)  # request id, [(value, label)], error or None


_signals: _ScanSignals | None = None
_next_request = 0


def _scan_signals() -> _ScanSignals:
    global _signals
    if _signals is None:  # created in the GUI thread, on first use
        _signals = _ScanSignals()
    return _signals


class DiscoverField(QObject):
    """Form row for a plugin's ``discover_setting``: editable combo + "Scan" + a status line.

    The list shows the plugin's labels (port, description, VID:PID / name, address,
    RSSI); choosing one puts its value in the edit, and any text can still be typed.
    Same interface as the panel's plain fields (``text``/``set_text``/``set_invalid``).
    A QObject child of its row widget, so scan results reach it in the GUI thread and
    stop reaching it when the form is rebuilt.
    """

    def __init__(self, setting: Setting, plugin: type[DevicePlugin],
                 on_change: Callable[..., Any], form_texts: Callable[[], dict[str, str]]) -> None:
        super().__init__()
        self.setting, self.plugin, self._form_texts = setting, plugin, form_texts
        self._request = -1
        self.editor = QComboBox()
        self.editor.setEditable(True)
        self.editor.setInsertPolicy(QComboBox.InsertPolicy.NoInsert)
        self.editor.setCompleter(None)  # inline completion would paste a whole label
        self.editor.setSizeAdjustPolicy(
            QComboBox.SizeAdjustPolicy.AdjustToMinimumContentsLengthWithIcon)
        self.editor.setMinimumContentsLength(8)
        self.editor.lineEdit().setPlaceholderText("type, or Scan and choose")
        self.editor.setEditText("" if setting.default is None else str(setting.default))
        self.editor.currentIndexChanged.connect(self._use_item)
        self.editor.activated.connect(self._use_item)
        self.editor.editTextChanged.connect(on_change)
        self.scan_button = QToolButton()
        self.scan_button.setText("Scan")
        self.scan_button.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        self.scan_button.setToolTip(f"Look for devices and list them under {setting.name}")
        self.scan_button.clicked.connect(self.scan)
        self.status = ElidedLabel()
        self.status.setObjectName("hint")
        self.status.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)
        self.status.hide()

        self.widget = QWidget()
        row = QHBoxLayout()
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(self.editor, 1)
        row.addWidget(self.scan_button)
        box = QVBoxLayout(self.widget)
        box.setContentsMargins(0, 0, 0, 0)
        box.setSpacing(2)
        box.addLayout(row)
        box.addWidget(self.status)
        self.editor.setToolTip(setting.help or setting.name)
        self.setParent(self.widget)
        _scan_signals().done.connect(self._on_done)

    # ---- the field interface ---------------------------------------------------------
    def text(self) -> str:
        return self.editor.currentText().strip()

    def set_text(self, text: str) -> None:
        self.editor.setEditText(str(text))
        self.editor.lineEdit().setCursorPosition(0)  # a long path shows its start

    def set_invalid(self, bad: bool) -> None:
        edit = self.editor.lineEdit()
        edit.setProperty("invalid", bad)
        edit.style().unpolish(edit)
        edit.style().polish(edit)

    # ---- scanning --------------------------------------------------------------------
    @property
    def instant(self) -> bool:
        """True when listing is immediate (serial ports): done when the plugin is chosen."""
        return discover_is_instant(self.plugin)

    def is_scanning(self) -> bool:
        return self._request >= 0

    def choices(self) -> list[tuple[str, str]]:
        """(value, label) of every listed item."""
        return [(str(self.editor.itemData(i)), self.editor.itemText(i))
                for i in range(self.editor.count())]

    def status_text(self) -> str:
        return "" if self.status.isHidden() else self.status.text()

    def scan(self) -> None:
        """Start a scan in a worker thread; the list and status line update when it ends."""
        global _next_request
        _next_request += 1
        self._request = request = _next_request
        self.scan_button.setEnabled(False)
        self._set_status("scanning…", error=False)
        plugin, texts, signals = self.plugin, dict(self._form_texts()), _scan_signals()

        def work() -> None:
            found, error = run_discovery(plugin, texts)
            signals.done.emit(request, found, error)

        threading.Thread(target=work, name=f"scan-{plugin.name}", daemon=True).start()

    def forget(self) -> None:
        """Ignore any scan still running (the form is being rebuilt)."""
        self._request = -1

    @Slot(int, object, object)
    def _on_done(self, request: int, found: list[tuple[str, str]], error: str | None) -> None:
        if request != self._request:
            return  # an older scan, or another panel's
        self._request = -1
        self.scan_button.setEnabled(True)
        if error:
            self._set_status(error, error=True)
            return
        text, cursor = self.editor.currentText(), self.editor.lineEdit().cursorPosition()
        self.editor.blockSignals(True)
        self.editor.clear()
        for value, label in found:
            self.editor.addItem(label, value)
            self.editor.setItemData(self.editor.count() - 1, label, Qt.ItemDataRole.ToolTipRole)
        self.editor.setCurrentIndex(-1)
        self.editor.setEditText(text)  # never replace what the user typed
        self.editor.lineEdit().setCursorPosition(cursor)
        self.editor.blockSignals(False)
        view = self.editor.view()
        view.setMinimumWidth(view.sizeHintForColumn(0) + 24 if found else 0)
        n = len(found)
        self._set_status(f"{n} found: see the list" if n
                         else f"none found: type the {self.setting.name}", error=False)

    def _use_item(self, index: int) -> None:
        if index >= 0:
            value = self.editor.itemData(index)
            if value is not None and self.editor.currentText() != value:
                self.editor.setEditText(str(value))

    def _set_status(self, text: str, error: bool) -> None:
        self.status.setObjectName("error" if error else "hint")
        self.status.setText(text)
        self.status.setToolTip(text)
        self.status.style().unpolish(self.status)
        self.status.style().polish(self.status)
        self.status.show()
