"""The experimenter's trial log (a table of the runner's trial records) and the small
text dialog used for discard reasons and notes.

Rows are rebuilt only when the trial records change; flagged trials that still count
(status ok) are highlighted, so the experimenter sees at a glance what to redo.
"""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtGui import QBrush, QColor, QFont
from PySide6.QtWidgets import (
    QAbstractItemView,
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QHeaderView,
    QLabel,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.storage.format.trials import TrialRecord, TrialStatus, records
from tactile_studio.ui.collect.view import trial_row

COLUMNS = ("#", "Block", "Gesture", "Status", "Flags")
FLAGGED_BG = QColor("#ffe3b3")
DIMMED_FG = QColor("#8a8f98")


def _signature(trials: tuple[dict[str, Any], ...]) -> tuple:
    return tuple((t.get("index"), t.get("status"), t.get("reason"), tuple(t.get("flags") or ()),
                  repr(t.get("check")), t.get("decision")) for t in trials)


class TrialLog(QTableWidget):
    """One row per trial, newest at the bottom; flagged ok trials highlighted."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(0, len(COLUMNS), parent)
        self.setHorizontalHeaderLabels(COLUMNS)
        self.verticalHeader().setVisible(False)
        self.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        # clicking the log takes the keyboard from the mirror: a letter typed here never
        # starts a trial
        self.setFocusPolicy(Qt.FocusPolicy.ClickFocus)
        self.setAlternatingRowColors(True)
        h = self.horizontalHeader()
        for col, mode in enumerate((QHeaderView.ResizeMode.ResizeToContents,
                                    QHeaderView.ResizeMode.ResizeToContents,
                                    QHeaderView.ResizeMode.Stretch,
                                    QHeaderView.ResizeMode.ResizeToContents,
                                    QHeaderView.ResizeMode.Stretch)):
            h.setSectionResizeMode(col, mode)
        self._sig: tuple = ()
        self.trials: tuple[dict[str, Any], ...] = ()

    def set_trials(self, trials: tuple[dict[str, Any], ...]) -> bool:
        """Show these records; returns True if anything changed."""
        sig = _signature(trials)
        if sig == self._sig:
            return False
        selected = self.selected_index()
        grew = len(trials) > len(self.trials)
        self._sig, self.trials = sig, tuple(trials)
        self.setRowCount(len(trials))
        for row, trial in enumerate(trials):
            cells = trial_row(trial)
            rec = TrialRecord.from_dict(trial)
            flagged = rec.flagged
            for col, text in enumerate(cells):
                item = self.item(row, col)
                if item is None:
                    item = QTableWidgetItem()
                    self.setItem(row, col, item)
                item.setText(text)
                item.setData(Qt.ItemDataRole.UserRole, rec.index)
                item.setBackground(QBrush(FLAGGED_BG) if flagged else QBrush())
                item.setForeground(QBrush(DIMMED_FG) if not rec.ok else QBrush())
                f = QFont()
                f.setStrikeOut(rec.status == TrialStatus.DISCARDED)
                f.setItalic(rec.status == TrialStatus.REDONE)
                f.setBold(flagged and col == 4)
                item.setFont(f)
                item.setToolTip(f"flagged: {cells[4]} \u2014 consider a redo" if flagged else "")
        if selected is not None:
            self.select_index(selected)
        if grew:
            self.scrollToBottom()
        return True

    @property
    def signature(self) -> tuple:
        """What the rows show (changes exactly when a row would)."""
        return self._sig

    def selected_index(self) -> int | None:
        """The trial index of the selected row, or None."""
        rows = self.selectionModel().selectedRows()
        if not rows:
            return None
        item = self.item(rows[0].row(), 0)
        return None if item is None else item.data(Qt.ItemDataRole.UserRole)

    def select_index(self, index: int) -> None:
        for row in range(self.rowCount()):
            item = self.item(row, 0)
            if item is not None and item.data(Qt.ItemDataRole.UserRole) == index:
                self.selectRow(row)
                return

    def flagged_rows(self) -> list[int]:
        """Trial indices currently highlighted as flagged."""
        return [t.index for t in records(self.trials) if t.flagged]


class TextDialog(QDialog):
    """A one-line text prompt with suggestions (discard reason, note); opened with
    ``open()`` so the session timer keeps running while the experimenter types."""

    def __init__(self, title: str, prompt: str, suggestions: tuple[str, ...] = (),
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle(title)
        self.setMinimumWidth(420)
        self.label = QLabel(prompt)
        self.label.setWordWrap(True)
        self.edit = QComboBox()
        self.edit.setEditable(True)
        self.edit.addItems(list(suggestions))
        self.edit.setCurrentText("")
        self.buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok
                                        | QDialogButtonBox.StandardButton.Cancel)
        self.buttons.accepted.connect(self._accept_if_text)
        self.buttons.rejected.connect(self.reject)
        self.choice: QCheckBox | None = None  # see add_choice
        self.cost: QLabel | None = None
        box = QVBoxLayout(self)
        box.addWidget(self.label)
        box.addWidget(self.edit)
        box.addWidget(self.buttons)

    def text(self) -> str:
        return self.edit.currentText().strip()

    def add_choice(self, text: str, checked: bool, cost_on: str, cost_off: str) -> QCheckBox:
        """A checkbox under the text field with a line saying what either answer costs
        (the discard dialog's "collect again at the end of the block")."""
        box = QCheckBox(text)
        cost = QLabel()
        cost.setWordWrap(True)
        cost.setStyleSheet("color: #606770;")

        def say(on: bool) -> None:
            cost.setText(cost_on if on else cost_off)
        box.toggled.connect(say)
        box.setChecked(checked)
        say(checked)
        layout = self.layout()
        layout.insertWidget(layout.indexOf(self.buttons), box)
        layout.insertWidget(layout.indexOf(self.buttons), cost)
        self.choice, self.cost = box, cost
        return box

    def add_note(self, text: str) -> QLabel:
        """A grey line above the buttons (what a choice costs when there is no choice)."""
        label = QLabel(text)
        label.setWordWrap(True)
        label.setStyleSheet("color: #606770;")
        layout = self.layout()
        layout.insertWidget(layout.indexOf(self.buttons), label)
        self.cost = label
        return label

    def _accept_if_text(self) -> None:
        if self.text():
            self.accept()
