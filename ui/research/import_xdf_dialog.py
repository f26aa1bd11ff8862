"""Import XDF recordings (LabRecorder's files) from the research workspace: what
``tactile-studio import xdf`` does (storage/exchange/importers/xdf.py), with its progress shown
and Cancel keeping the finished sessions. The imported folder joins the Sessions tab."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from PySide6.QtWidgets import QFormLayout, QLineEdit, QWidget

from tactile_studio.storage.exchange.importers.xdf import XdfChoice, XdfReport, import_xdf
from tactile_studio.ui.research.import_base import ImportDialogBase, ImportJob


class XdfImportDialog(ImportDialogBase):
    TITLE = "Import XDF recordings (LabRecorder)"
    KEY = "import_xdf/"
    FILES_LABEL = "XDF files (LabRecorder's, or exported by Tactile Studio)"
    FILE_NOUN = "XDF files"
    ADD_TEXT = "Add XDF files…"
    FILE_KIND = "import_xdf"
    FILE_FILTER = "XDF (*.xdf *.xdfz);;All files (*)"
    IDLE_TEXT = ("Add the XDF files to import. Each tactile stream becomes a session; "
                 "markers become events and trials; EDA, ECG and other streams are kept "
                 "beside the touch.")
    CANCEL_TEXT = "Cancelling after the session being written…"
    CLI_WORDS = (("--stream NAME --layout L", "Tactile stream and Its layout"),)

    def __init__(self, parent: QWidget | None = None) -> None:
        self.said = XdfReport()  # streams not imported, imported short, notes
        super().__init__(parent)

    def add_fields(self, form: QFormLayout) -> None:
        self.participant = QLineEdit()
        self.participant.setPlaceholderText("from the file name (sub-P01_...), else this")
        self.stream = QLineEdit()
        self.stream.setPlaceholderText("found automatically; or a stream's name")
        self.layout_name = QLineEdit()
        self.layout_name.setPlaceholderText("from the stream; or e.g. grid-8x8")
        form.addRow("Participant", self.participant)
        form.addRow("Tactile stream", self.stream)
        form.addRow("Its layout", self.layout_name)

    def make_job(self, files: list[str], out: str, force: bool,
                 written: Callable[[Path], None]) -> ImportJob:
        Path(out).mkdir(parents=True, exist_ok=True)
        choice = XdfChoice(self.participant.text().strip() or None,
                           self.stream.text().strip() or None,
                           self.layout_name.text().strip() or None)
        self.said = XdfReport()
        return lambda progress, cancel: import_xdf(
            files, out, choice, progress, cancel, force, written, self.said)

    def finished_text(self, out: str, result: Any) -> str:
        return (f"Imported {len(result)} session(s) into {out}; they are listed in the "
                "Sessions tab." + "".join(f"\nNot imported: {line}" for line in self.said.skipped)
                + "".join(f"\nImported short: {line}" for line in self.said.short)
                + "".join(f"\nNote: {line}" for line in self.said.notes))
