"""Session browser: pick folders, filter, select; the selection is a run's dataset."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.learn.experiments.workspace_index import SessionRow, scan_sessions
from tactile_studio.storage.study_summary import study_counts
from tactile_studio.ui.file_dialogs import ask_folder
from tactile_studio.ui.research.tables import fill_row, make_table
from tactile_studio.ui.settings import app_settings, get_json, set_json

FOLDERS_KEY = "research/session_folders"

COLUMNS = ["session", "participant", "condition", "protocol", "sensor", "date", "ok trials",
           "flagged", "discarded", "per gesture", "problem"]


def per_gesture_text(per: dict[str, int]) -> str:
    """"9 gestures × 2" when balanced, else each gesture's count (full list in the tooltip)."""
    counts = set(per.values())
    if len(counts) == 1:
        return f"{len(per)} gestures × {counts.pop()}"
    return ", ".join(f"{g} {n}" for g, n in sorted(per.items()))


class SessionsView(QWidget):
    selectionChanged = Signal()
    importRequested = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.folders: list[str] = []
        self.rows: list[SessionRow] = []
        add, clear = QPushButton("Add folder…"), QPushButton("Clear")
        import_csv = QPushButton("Import old CSVs…")
        import_csv.setToolTip("the old collection software's ShearSense CSVs, as sessions")
        self.filter = QLineEdit()
        self.filter.setPlaceholderText("filter: participant, condition, protocol, sensor…")
        self.table = make_table(COLUMNS)
        self.table.setSortingEnabled(True)
        self.summary = QLabel("Add a folder of session files.")
        top = QHBoxLayout()
        top.addWidget(add)
        top.addWidget(clear)
        top.addWidget(import_csv)
        top.addWidget(QLabel("Filter"))
        top.addWidget(self.filter, 1)
        lay = QVBoxLayout(self)
        lay.addLayout(top)
        lay.addWidget(self.table, 1)
        lay.addWidget(self.summary)
        add.clicked.connect(self._browse)
        clear.clicked.connect(lambda: self.set_folders([]))
        import_csv.clicked.connect(self.importRequested.emit)
        self.filter.textChanged.connect(self._apply_filter)
        self.table.itemSelectionChanged.connect(self._selection_changed)
        self.settings = app_settings()
        # the folders of the last run of the app, those that still exist
        saved = [f for f in get_json(self.settings, FOLDERS_KEY, []) if Path(f).is_dir()]
        if saved:
            self.set_folders(saved)

    def _browse(self) -> None:
        folder = ask_folder(self, "Folder of session files", "session_folder")
        if folder:
            self.set_folders([*self.folders, folder])

    def set_folders(self, folders: list[str]) -> None:
        self.folders = [str(f) for f in folders]
        set_json(self.settings, FOLDERS_KEY, self.folders)
        self.rows = scan_sessions(self.folders)
        self.table.setSortingEnabled(False)
        self.table.setRowCount(0)  # no selected row may point at a row of the last scan
        self.table.setRowCount(len(self.rows))
        for r, row in enumerate(self.rows):
            values = [row.path.rsplit("/", 1)[-1], row.participant, row.condition, row.protocol,
                      row.sensor, row.date, row.ok, row.flagged, row.discarded,
                      per_gesture_text(row.per_gesture), row.problem]
            fill_row(self.table, r, values, [None] * len(values), row.error)
            self.table.item(r, 0).setToolTip(row.path)
            self.table.item(r, 9).setToolTip("\n".join(
                f"{g}: {n}" for g, n in sorted(row.per_gesture.items())))
            if row.violations and not row.error:  # readable, but its facts disagree
                self._flag_failed_check(r, row.violations)
        self.table.setSortingEnabled(True)
        self.table.sortItems(0, Qt.SortOrder.AscendingOrder)
        # the column only when a file could not be read or fails the check: otherwise it
        # is empty and wide
        self.table.setColumnHidden(COLUMNS.index("problem"),
                                   not any(r.problem for r in self.rows))
        self._apply_filter()
        self.table.selectAll()
        self._selection_changed()

    def _flag_failed_check(self, r: int, violations: list[str]) -> None:
        """Amber name and problem cell, every violation in their tooltip (``check``'s list)."""
        tip = f"tactile-studio check finds {len(violations)} problem(s):\n" + "\n".join(
            f"• {v}" for v in violations)
        for c in (0, COLUMNS.index("problem")):
            item = self.table.item(r, c)
            item.setForeground(QColor(170, 95, 0))
            item.setToolTip(tip if c else f"{self.rows[r].path}\n{tip}")

    def _apply_filter(self) -> None:
        text = self.filter.text()
        for r in range(self.table.rowCount()):
            row = self.rows[self.table.item(r, 0).data(Qt.ItemDataRole.UserRole)]
            self.table.setRowHidden(r, not row.matches(text))

    def selected(self) -> list[SessionRow]:
        rows = sorted({i.row() for i in self.table.selectedIndexes()
                       if not self.table.isRowHidden(i.row())})
        return [self.rows[self.table.item(r, 0).data(Qt.ItemDataRole.UserRole)] for r in rows]

    def selected_paths(self) -> list[str]:
        """The dataset of a run: the selected sessions that can be read."""
        return [r.path for r in self.selected() if not r.error]

    def _selection_changed(self) -> None:
        sel = self.selected()
        ok = sum(r.ok for r in sel)
        people = len({r.participant for r in sel})
        gaps = study_counts((r.participant, r.condition, r.per_gesture)
                            for r in sel if not r.error).missing_text()
        failing = sum(1 for r in sel if r.violations and not r.error)
        self.summary.setText(f"{len(sel)} of {len(self.rows)} sessions selected: {people} "
                             f"participants, {ok} ok trials" +
                             (" — no ok trials to train on" if sel and not ok else "") +
                             (f" — {gaps}" if gaps else "") +
                             (f" — {failing} fail{'s' if failing == 1 else ''} check "
                              "(see the problem column)" if failing else ""))
        self.selectionChanged.emit()
