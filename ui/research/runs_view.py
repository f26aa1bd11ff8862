"""Every run folder under a root, with its metrics, sortable; what two runs differ in."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.errors import UserError
from tactile_studio.learn.results.compare import config_difference
from tactile_studio.learn.results.workspace_index import RunRow, scan_runs
from tactile_studio.ui.file_dialogs import ask_folder
from tactile_studio.ui.research.tables import fill_row, make_table
from tactile_studio.ui.settings import app_settings

ROOT_KEY = "research/runs_root"

COLUMNS = ["run", "model", "channels", "evaluation", "preset", "accuracy", "trial acc.",
           "F1 macro", "bal. acc.", "few-shot (trial acc. per K)", "folds", "complete", "created",
           "problem"]


def _pct(v: float | None) -> str | None:
    return None if v is None else f"{100 * v:.1f}%"


class RunsView(QWidget):
    openRequested = Signal(str)
    compareRequested = Signal(str, str)
    error = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.rows: list[RunRow] = []
        self.root = QLineEdit()
        self.root.setPlaceholderText("folder holding run folders")
        browse, refresh = QPushButton("Browse…"), QPushButton("Refresh")
        self.open_button = QPushButton("Open confusion matrix")
        self.compare_button = QPushButton("Compare the two selected")
        self.table = make_table(COLUMNS)
        self.table.setSortingEnabled(True)
        self.difference = QLabel("Select one run to open it, two to compare them.")
        self.difference.setWordWrap(True)
        self.difference.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        top = QHBoxLayout()
        top.addWidget(QLabel("Runs under"))
        top.addWidget(self.root, 1)
        top.addWidget(browse)
        top.addWidget(refresh)
        buttons = QHBoxLayout()
        buttons.addWidget(self.open_button)
        buttons.addWidget(self.compare_button)
        buttons.addStretch(1)
        lay = QVBoxLayout(self)
        lay.addLayout(top)
        lay.addWidget(self.table, 1)
        lay.addWidget(self.difference)
        lay.addLayout(buttons)
        browse.clicked.connect(self._browse)
        refresh.clicked.connect(lambda: self.set_root(self.root.text()))
        self.root.returnPressed.connect(lambda: self.set_root(self.root.text()))
        self.table.itemSelectionChanged.connect(self._selection_changed)
        self.open_button.clicked.connect(self._open)
        self.compare_button.clicked.connect(self._compare)
        self._selection_changed()
        self.settings = app_settings()
        saved = str(self.settings.value(ROOT_KEY, "") or "")
        if saved and Path(saved).is_dir():  # where the last run of the app left it
            self.set_root(saved)

    def _browse(self) -> None:
        folder = ask_folder(self, "Folder with run folders", "runs_folder")
        if folder:
            self.set_root(folder)

    def set_root(self, root: str) -> None:
        self.root.setText(str(root))
        self.settings.setValue(ROOT_KEY, str(root))
        try:
            self.rows = scan_runs(root)
        except UserError as exc:
            self.rows = []
            self.error.emit(str(exc))
        self.table.setSortingEnabled(False)
        self.table.setRowCount(len(self.rows))
        for r, row in enumerate(self.rows):
            values = [row.name, row.model, row.channels, row.evaluation, row.preset, row.accuracy,
                      row.trial_accuracy, row.f1_macro, row.balanced_accuracy, row.shots,
                      row.folds,
                      "yes" if row.complete else "no", row.created, row.error]
            texts = [None] * 5 + [_pct(row.accuracy), _pct(row.trial_accuracy),
                                  _pct(row.f1_macro), _pct(row.balanced_accuracy)] + [None] * 5
            fill_row(self.table, r, values, texts, row.error)
        self.table.setSortingEnabled(True)
        self.table.sortItems(0, Qt.SortOrder.AscendingOrder)
        self._selection_changed()

    def selected(self) -> list[RunRow]:
        rows = sorted({i.row() for i in self.table.selectedIndexes()})
        return [self.rows[self.table.item(r, 0).data(Qt.ItemDataRole.UserRole)] for r in rows]

    def select_paths(self, *paths: str) -> None:
        self.table.clearSelection()
        mode = self.table.selectionMode()
        self.table.setSelectionMode(self.table.SelectionMode.MultiSelection)
        for r in range(self.table.rowCount()):
            if self.rows[self.table.item(r, 0).data(Qt.ItemDataRole.UserRole)].path in \
                    [str(p) for p in paths]:
                self.table.selectRow(r)
        self.table.setSelectionMode(mode)

    def _selection_changed(self) -> None:
        sel = self.selected()
        self.open_button.setEnabled(len(sel) == 1)
        self.compare_button.setEnabled(len(sel) == 2)
        if len(sel) == 2:
            diff = config_difference(sel[0].ran_config, sel[1].ran_config)
            self.difference.setText(f"{sel[0].name} → {sel[1].name}: " +
                                    ("; ".join(diff) if diff else "same settings"))
        elif len(sel) == 1:
            self.difference.setText(f"{sel[0].path}" + (f" — {sel[0].error}" if sel[0].error
                                                        else "")
                                    + (f" — few-shot curve (accuracy per trial with K "
                                       f"labelled performances per gesture of the test "
                                       f"person): {sel[0].shots}" if sel[0].shots else ""))
        else:
            self.difference.setText("Select one run to open it, two to compare them.")

    def _open(self) -> None:
        sel = self.selected()
        if len(sel) == 1:
            self.openRequested.emit(sel[0].path)

    def _compare(self) -> None:
        sel = self.selected()
        if len(sel) == 2:
            self.compareRequested.emit(sel[0].path, sel[1].path)
