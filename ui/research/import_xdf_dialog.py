"""Import XDF recordings (LabRecorder's files) from the research workspace: what
``tactile-studio import xdf`` does (storage/importers/xdf.py), with its progress shown
and Cancel keeping the finished sessions. The imported folder joins the Sessions tab."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.storage.importers.xdf import import_xdf
from tactile_studio.ui.background_job import BackgroundJob
from tactile_studio.ui.file_dialogs import ask_folder, ask_open_files
from tactile_studio.ui.settings import app_settings

KEY = "import_xdf/"


class XdfImportDialog(QDialog):
    imported = Signal(str)  # the folder the sessions were written to

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Import XDF recordings (LabRecorder)")
        self.settings = app_settings()
        self.job: BackgroundJob | None = None
        self.written: list[str] = []
        self.files = QListWidget()
        self.files.setMinimumHeight(90)
        add, clear = QPushButton("Add XDF files…"), QPushButton("Clear")
        self.participant = QLineEdit()
        self.participant.setPlaceholderText("from the file name (sub-P01_...), else this")
        self.stream = QLineEdit()
        self.stream.setPlaceholderText("found automatically; or a stream's name")
        self.layout_name = QLineEdit()
        self.layout_name.setPlaceholderText("from the stream; or e.g. grid-8x8")
        self.out = QLineEdit(str(self.settings.value(KEY + "out", "")))
        self.out.setPlaceholderText("folder for the session files")
        browse = QPushButton("Browse…")
        self.force = QCheckBox("Replace sessions already in the folder")
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.status = QLabel("Add the XDF files to import. Each tactile stream becomes a "
                             "session; markers become events and trials; EDA, ECG and "
                             "other streams are kept beside the touch.")
        self.status.setWordWrap(True)
        self.import_button, self.cancel_button = QPushButton("Import"), QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        close = QPushButton("Close")

        file_buttons = QHBoxLayout()
        file_buttons.addWidget(add)
        file_buttons.addWidget(clear)
        file_buttons.addStretch(1)
        out_row = QHBoxLayout()
        out_row.addWidget(self.out, 1)
        out_row.addWidget(browse)
        form = QFormLayout()
        form.addRow("Participant", self.participant)
        form.addRow("Tactile stream", self.stream)
        form.addRow("Its layout", self.layout_name)
        form.addRow("Into folder", out_row)
        form.addRow("", self.force)
        buttons = QHBoxLayout()
        buttons.addWidget(self.progress, 1)
        for b in (self.import_button, self.cancel_button, close):
            buttons.addWidget(b)
        lay = QVBoxLayout(self)
        lay.addWidget(QLabel("XDF files (LabRecorder's, or exported by Tactile Studio)"))
        lay.addWidget(self.files, 1)
        lay.addLayout(file_buttons)
        lay.addLayout(form)
        lay.addLayout(buttons)
        lay.addWidget(self.status)
        self.resize(680, 460)

        add.clicked.connect(lambda: self.add_files(ask_open_files(
            self, "XDF files", "import_xdf", "XDF (*.xdf *.xdfz);;All files (*)")))
        clear.clicked.connect(self.files.clear)
        browse.clicked.connect(self._browse_out)
        self.import_button.clicked.connect(self.start)
        self.cancel_button.clicked.connect(self.cancel)
        close.clicked.connect(self.close)

    def add_files(self, paths: list[str]) -> None:
        known = {self.files.item(i).text() for i in range(self.files.count())}
        for path in dict.fromkeys(paths):
            if path not in known:
                self.files.addItem(path)
        self.status.setText(f"{self.files.count()} file(s) to import.")

    def _browse_out(self) -> None:
        folder = ask_folder(self, "Folder for the session files", "import_out")
        if folder:
            self.out.setText(folder)

    def start(self) -> bool:
        """Import the listed files; False (with the reason shown) when it cannot start."""
        files = [self.files.item(i).text() for i in range(self.files.count())]
        out = self.out.text().strip()
        if not files or not out:
            self.status.setText("Add XDF files and choose a folder for the sessions."
                                if not files else "Choose a folder for the sessions.")
            return False
        self.settings.setValue(KEY + "out", out)
        Path(out).mkdir(parents=True, exist_ok=True)
        participant = self.participant.text().strip() or None
        stream = self.stream.text().strip() or None
        layout = self.layout_name.text().strip() or None
        force = self.force.isChecked()
        self.written = []
        skipped: list[str] = []  # tactile streams without samples (no session written)
        self.job = BackgroundJob(lambda progress, cancel: import_xdf(
            files, out, participant, stream, layout, progress, cancel, force,
            lambda path: self.written.append(str(path)), skipped), self)
        self.job.progressed.connect(self._progressed)
        self.job.finished.connect(lambda paths: self._stopped(
            f"Imported {len(paths)} session(s) into {out}; they are listed in the "
            "Sessions tab." + "".join(f"\nNot imported: {line}" for line in skipped),
            out, done=True))
        self.job.failed.connect(self._failed)
        self.job.cancelled.connect(lambda: self._stopped(
            f"Cancelled: the {len(self.written)} session(s) finished are kept in {out}.", out))
        self._set_running(True)
        self.status.setText(f"Importing {len(files)} file(s)…")
        self.job.start()
        return True

    def cancel(self) -> None:
        if self.job is not None:
            self.job.cancel()
            self.status.setText("Cancelling after the session being written…")

    def _set_running(self, on: bool) -> None:
        self.import_button.setEnabled(not on)
        self.cancel_button.setEnabled(on)

    def _progressed(self, fraction: float, message: str) -> None:
        self.progress.setValue(round(fraction * 1000))
        if message:
            self.status.setText(message)

    def _failed(self, message: str) -> None:
        message = message.replace("(use --force to overwrite)",
                                  f"(tick \u201c{self.force.text()}\u201d to overwrite)")
        message = message.replace("--stream NAME --layout L", "Tactile stream and Its layout")
        self._stopped(message, self.out.text().strip() if self.written else None)

    def _stopped(self, text: str, out: str | None, done: bool = False) -> None:
        self._set_running(False)
        if done:
            self.progress.setValue(1000)
        self.status.setText(text)
        if out is not None:
            self.imported.emit(out)

    def closeEvent(self, event) -> None:  # noqa: ANN001, N802 - Qt name and signature
        if self.job is not None and self.job.running:
            self.job.cancel()
            self.job.wait(10.0)
        super().closeEvent(event)
