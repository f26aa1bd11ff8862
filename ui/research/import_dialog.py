"""Import old recordings (the old collection software's ShearSense CSVs) from the
research workspace: what ``tactile-studio import shearsense`` does, with its maps typed
the same way, its progress shown and Cancel keeping the finished sessions. The imported
folder joins the Sessions tab."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from PySide6.QtWidgets import QFormLayout, QLineEdit, QPlainTextEdit, QWidget

from tactile_studio.storage.exchange.importers.shearsense import import_shearsense_study
from tactile_studio.ui.research.import_base import ImportDialogBase, ImportJob

GESTURES_HINT = "shear9's keys; or cost14, a protocol or map .toml, or key=Name,…"
PEOPLE_HINT = "as the file names say; or old=new,… or a .toml file"


class ImportDialog(ImportDialogBase):
    TITLE = "Import old recordings (ShearSense CSV)"
    KEY = "import_shearsense/"
    FILES_LABEL = ("CSV files (one per recording; P<number> and FLAT/PILLOW in the name "
                   "give participant and surface)")
    FILE_NOUN = "CSV files"
    ADD_TEXT = "Add CSV files…"
    FILE_KIND = "import_csv"
    FILE_FILTER = "ShearSense CSV (*.csv *.csv.xz *.csv.gz *.csv.bz2);;All files (*)"
    IDLE_TEXT = "Add the CSV files to import."
    SIZE = (760, 560)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.summary = QPlainTextEdit()
        self.summary.setReadOnly(True)
        self.summary.setPlaceholderText("What the import did is listed here: participants, "
                                        "keys without a gesture name, empty files.")
        self.main_layout.addWidget(self.summary, 1)

    def add_fields(self, form: QFormLayout) -> None:
        self.gestures = QLineEdit(str(self.settings.value(self.KEY + "gestures", "")))
        self.gestures.setPlaceholderText(GESTURES_HINT)
        self.gestures.setToolTip("pressed key -> gesture name, as import shearsense --gestures")
        self.people = QLineEdit(str(self.settings.value(self.KEY + "participants", "")))
        self.people.setPlaceholderText(PEOPLE_HINT)
        form.addRow("Gesture keys", self.gestures)
        form.addRow("Participants", self.people)

    def remember(self) -> None:
        for key, edit in (("gestures", self.gestures), ("participants", self.people)):
            self.settings.setValue(self.KEY + key, edit.text().strip())

    def make_job(self, files: list[str], out: str, force: bool,
                 written: Callable[[Path], None]) -> ImportJob:
        gestures, people = self.gestures.text().strip(), self.people.text().strip()
        self.summary.clear()
        return lambda progress, cancel: import_shearsense_study(
            files, out, gestures or None, people or None, progress, cancel, force, written)

    def finished_text(self, out: str, result: Any) -> str:
        paths, report = result
        self.summary.setPlainText("\n".join(report.lines()))
        skipped = (f" {len(report.no_frames)} file(s) had no frames and were not imported "
                   "(listed below).") if report.no_frames else ""
        return (f"Imported {len(paths)} session(s) into {out}; they are listed in "
                f"the Sessions tab.{skipped}")
