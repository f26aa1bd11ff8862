"""Session browser: pick folders, filter, select; the selection is a run's dataset.

A folder is listed at once from the files' journals; ``check`` (which reads every file's
clocks) runs on a background job and its column fills in as each file's result arrives
("checking…" until then), so a folder of long sessions does not freeze the tab."""

from __future__ import annotations

import queue
from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QCheckBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.learn.results.workspace_index import (
    SessionRow,
    check_sessions,
    chosen_rows,
    scan_sessions,
)
from tactile_studio.storage.format.study_summary import study_counts
from tactile_studio.ui.background_job import BackgroundJob
from tactile_studio.ui.file_dialogs import ask_folder
from tactile_studio.ui.research.tables import fill_row, make_table
from tactile_studio.ui.settings import app_settings, get_json, set_json

FOLDERS_KEY = "research/session_folders"

COLUMNS = ["session", "folder", "participant", "condition", "protocol", "sensor", "date",
           "ok trials", "flagged", "discarded", "per gesture", "note", "problem"]
LEFT_OUT = QColor(120, 120, 120)  # a backup or a copy: listed, not counted twice
CHECKING = "checking…"


def per_gesture_text(per: dict[str, int]) -> str:
    """"9 gestures × 2" when balanced, else each gesture's count (full list in the tooltip)."""
    counts = set(per.values())
    if len(counts) == 1:
        return f"{len(per)} gestures × {counts.pop()}"
    return ", ".join(f"{g} {n}" for g, n in sorted(per.items()))


def left_out_text(reasons: list[str]) -> str:
    """"2 not counted: a resume backup, a copy of a recording" (``choose``'s reasons)."""
    words = {"resume backup": "resume backup", "duplicate session": "copy of a session",
             "same recording": "copy of a recording"}
    named = [f"{n} {words[why]}s" if n > 1 else f"a {words[why]}"
             for why in words if (n := reasons.count(why))]
    return f"{len(reasons)} not counted: " + ", ".join(named)


class SessionsView(QWidget):
    selectionChanged = Signal()
    importRequested = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.folders: list[str] = []
        self.rows: list[SessionRow] = []
        self.check_job: BackgroundJob | None = None  # checks the rows of this listing
        add, clear = QPushButton("Add folder…"), QPushButton("Clear")
        import_csv = QPushButton("Import old CSVs…")
        import_csv.setToolTip("the old collection software's ShearSense CSVs, as sessions")
        self.filter = QLineEdit()
        self.filter.setPlaceholderText("filter: participant, condition, protocol, sensor…")
        self.only_flagged = QCheckBox("With flagged trials")
        self.only_flagged.setToolTip("list only the sessions with flagged trials (quality "
                                     "flags or the model's check); the player lists a "
                                     "session's flagged trials")
        self.table = make_table(COLUMNS)
        self.table.setSortingEnabled(True)
        self.summary = QLabel("Add a folder of session files.")
        top = QHBoxLayout()
        top.addWidget(add)
        top.addWidget(clear)
        top.addWidget(import_csv)
        top.addWidget(QLabel("Filter"))
        top.addWidget(self.filter, 1)
        top.addWidget(self.only_flagged)
        lay = QVBoxLayout(self)
        lay.addLayout(top)
        lay.addWidget(self.table, 1)
        lay.addWidget(self.summary)
        add.clicked.connect(self._browse)
        clear.clicked.connect(lambda: self.set_folders([]))
        import_csv.clicked.connect(self.importRequested.emit)
        self.filter.textChanged.connect(self._apply_filter)
        self.only_flagged.toggled.connect(self._apply_filter)
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
        self.stop_checks()  # the last listing's checks: no longer wanted
        self.rows = scan_sessions(self.folders, check=False)
        self.table.setSortingEnabled(False)
        self.table.setRowCount(0)  # no selected row may point at a row of the last scan
        self.table.setRowCount(len(self.rows))
        for r, row in enumerate(self.rows):
            values = [row.path.rsplit("/", 1)[-1], row.folder, row.participant, row.condition,
                      row.protocol, row.sensor, row.date, row.ok, row.flagged, row.discarded,
                      per_gesture_text(row.per_gesture), row.note, row.problem or CHECKING]
            fill_row(self.table, r, values, [None] * len(values), row.error)
            self.table.item(r, 0).setToolTip(row.path)
            self.table.item(r, COLUMNS.index("per gesture")).setToolTip("\n".join(
                f"{g}: {n}" for g, n in sorted(row.per_gesture.items())))
            if row.left_out and not row.error:
                for c in range(len(COLUMNS)):
                    self.table.item(r, c).setForeground(LEFT_OUT)
                self.table.item(r, COLUMNS.index("note")).setToolTip(
                    f"{row.note}: its trials are that file's (re-imported from an export, or "
                    "copied).\nA dataset reads one file per "
                    "session and per recording: train and the Train tab skip this one when "
                    "the other is selected too.")
        self.table.setSortingEnabled(True)
        self.table.sortItems(0, Qt.SortOrder.AscendingOrder)
        self.table.setColumnHidden(COLUMNS.index("note"), not any(r.note for r in self.rows))
        self._show_problem_column()
        self._apply_filter()
        self.table.selectAll()
        self._deselect_copies_and_pilots()
        self._selection_changed()
        self._start_checks()

    def _deselect_copies_and_pilots(self) -> None:
        """A resume backup, another copy of a listed recording or a pilot session (a
        rehearsal) starts unselected: the selection is then what a run reads, never mixed
        with a rehearsal unless chosen by hand (a copy selected anyway is counted once)."""
        model = self.table.selectionModel()
        for r in range(self.table.rowCount()):
            row = self.rows[self.table.item(r, 0).data(Qt.ItemDataRole.UserRole)]
            if row.left_out or row.pilot:
                model.select(self.table.model().index(r, 0),
                             model.SelectionFlag.Deselect | model.SelectionFlag.Rows)

    def stop_checks(self, wait_s: float = 0.0) -> None:
        """Cancel the listing's checks (they stop between files; a file being read is
        finished, up to ``wait_s``): a new listing, or the window closing."""
        job, self.check_job = self.check_job, None
        if job is not None:
            job.cancel()
            if wait_s > 0:
                job.wait(wait_s)

    @property
    def checking(self) -> bool:
        """Some rows' check results are still to come."""
        return self.check_job is not None

    def _start_checks(self) -> None:
        todo = [i for i, row in enumerate(self.rows) if not row.error]
        if not todo:
            return
        paths = [self.rows[i].path for i in todo]
        results: queue.SimpleQueue[tuple[int, list[str], str]] = queue.SimpleQueue()

        def run(progress, cancel) -> int:  # on the worker: only the queue is touched
            return check_sessions(paths, lambda k, v, e: results.put((todo[k], v, e)),
                                  progress, cancel)

        job = BackgroundJob(run, self)
        job.progressed.connect(lambda *_: self._take_results(job, results))
        job.finished.connect(lambda _: self._checks_ended(job, results))
        job.failed.connect(lambda line: self._checks_ended(job, results, line))
        self.check_job = job
        job.start()

    def _take_results(self, job: BackgroundJob, results: queue.SimpleQueue) -> None:
        """Show the check results that have arrived (the GUI thread, the job's timer)."""
        if job is not self.check_job:
            return  # a listing since replaced
        by_index = {self.table.item(r, 0).data(Qt.ItemDataRole.UserRole): r
                    for r in range(self.table.rowCount())}
        self.table.setSortingEnabled(False)  # no re-sort under our feet while rows change
        while True:
            try:
                i, violations, error = results.get_nowait()
            except queue.Empty:
                break
            row = self.rows[i]
            row.violations, row.error, row.checked = violations, error, True
            self._show_check(by_index[i], row)
        self.table.setSortingEnabled(True)
        self._selection_changed()

    def _checks_ended(self, job: BackgroundJob, results: queue.SimpleQueue,
                      failure: str = "") -> None:
        self._take_results(job, results)
        if job is not self.check_job:
            return
        self.check_job = None
        for r in range(self.table.rowCount()):  # a check that failed: say so, not "checking"
            row = self.rows[self.table.item(r, 0).data(Qt.ItemDataRole.UserRole)]
            if not row.checked and not row.error:
                self.table.item(r, COLUMNS.index("problem")).setText(
                    f"not checked: {failure}" if failure else "")
        self._show_problem_column()
        self._selection_changed()

    def _show_check(self, r: int, row: SessionRow) -> None:
        """One file's check result in table row ``r``."""
        cell = self.table.item(r, COLUMNS.index("problem"))
        cell.setText(row.problem)
        cell.value = row.problem
        if row.error:  # it could not be read after all: red, and not trained on
            for c in range(self.table.columnCount()):
                self.table.item(r, c).setForeground(QColor(170, 0, 0))
                self.table.item(r, c).setToolTip(row.error)
        elif row.violations:  # readable, but its facts disagree
            self._flag_failed_check(r, row.violations)

    def _show_problem_column(self) -> None:
        """The column only while checking or when a file could not be read or fails the
        check: otherwise it is empty and wide."""
        self.table.setColumnHidden(COLUMNS.index("problem"), not (
            self.checking or any(r.problem for r in self.rows)
            or any(not r.checked and not r.error for r in self.rows)))

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
            self.table.setRowHidden(r, not row.matches(text)
                                    or (self.only_flagged.isChecked() and not row.flagged))

    def selected(self) -> list[SessionRow]:
        rows = sorted({i.row() for i in self.table.selectedIndexes()
                       if not self.table.isRowHidden(i.row())})
        return [self.rows[self.table.item(r, 0).data(Qt.ItemDataRole.UserRole)] for r in rows]

    def selected_paths(self) -> list[str]:
        """The dataset of a run: the selected sessions that can be read."""
        return [r.path for r in self.selected() if not r.error]

    def _selection_changed(self) -> None:
        sel = self.selected()
        read, left = chosen_rows(sel)  # what a run on the selection reads, as train does
        ok = sum(r.ok for r in read)
        people = len({r.participant for r in read})  # a junk file is nobody
        gaps = study_counts((r.participant, r.condition, r.per_gesture)
                            for r in read).missing_text()
        failing = sum(1 for r in sel if r.violations and not r.error)
        unpicked = sum(1 for r in self.rows if r.left_out) - sum(1 for r in sel if r.left_out)
        self.summary.setText(f"{len(sel)} of {len(self.rows)} sessions selected: {people} "
                             f"participants, {ok} ok trials" +
                             (f" ({left_out_text(left)})" if left else "") +
                             (f" — {unpicked} listed cop{'ies' if unpicked != 1 else 'y'} "
                              "not selected (see the note column)" if unpicked else "") +
                             (" — no ok trials to train on" if sel and not ok else "") +
                             (f" — {gaps}" if gaps else "") +
                             (f" — {failing} fail{'s' if failing == 1 else ''} check "
                              "(see the problem column)" if failing else ""))
        self.selectionChanged.emit()
