"""Import old recordings (the old collection software's ShearSense CSVs) from the
research workspace: what ``tactile-studio import shearsense`` does, with its maps typed
the same way, its progress shown and Cancel keeping the finished sessions. The imported
folder joins the Sessions tab."""

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
    QPlainTextEdit,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.storage.importers.shearsense import import_shearsense_study
from tactile_studio.ui.background_job import BackgroundJob
from tactile_studio.ui.file_dialogs import ask_folder, ask_open_files
from tactile_studio.ui.settings import app_settings

KEY = "import_shearsense/"
GESTURES_HINT = "shear9's keys; or cost14, a protocol or map .toml, or key=Name,…"
PEOPLE_HINT = "as the file names say; or old=new,… or a .toml file"


class ImportDialog(QDialog):
    imported = Signal(str)  # the folder the sessions were written to

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Import old recordings (ShearSense CSV)")
        self.settings = app_settings()
        self.job: BackgroundJob | None = None
        self.written: list[str] = []  # sessions the current import has finished
        self.files = QListWidget()
        self.files.setMinimumHeight(110)
        add, clear = QPushButton("Add CSV files…"), QPushButton("Clear")
        self.gestures = QLineEdit(str(self.settings.value(KEY + "gestures", "")))
        self.gestures.setPlaceholderText(GESTURES_HINT)
        self.gestures.setToolTip("pressed key -> gesture name, as import shearsense --gestures")
        self.people = QLineEdit(str(self.settings.value(KEY + "participants", "")))
        self.people.setPlaceholderText(PEOPLE_HINT)
        self.out = QLineEdit(str(self.settings.value(KEY + "out", "")))
        self.out.setPlaceholderText("folder for the session files")
        browse = QPushButton("Browse…")
        self.force = QCheckBox("Replace sessions already in the folder")
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.status = QLabel("Add the CSV files to import.")
        self.status.setWordWrap(True)
        self.summary = QPlainTextEdit()
        self.summary.setReadOnly(True)
        self.summary.setPlaceholderText("What the import did is listed here: participants, "
                                        "keys without a gesture name, empty files.")
        self.import_button = QPushButton("Import")
        self.cancel_button = QPushButton("Cancel")
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
        form.addRow("Gesture keys", self.gestures)
        form.addRow("Participants", self.people)
        form.addRow("Into folder", out_row)
        form.addRow("", self.force)
        buttons = QHBoxLayout()
        buttons.addWidget(self.progress, 1)
        buttons.addWidget(self.import_button)
        buttons.addWidget(self.cancel_button)
        buttons.addWidget(close)
        lay = QVBoxLayout(self)
        lay.addWidget(QLabel("CSV files (one per recording; P<number> and FLAT/PILLOW in "
                             "the name give participant and surface)"))
        lay.addWidget(self.files, 1)
        lay.addLayout(file_buttons)
        lay.addLayout(form)
        lay.addLayout(buttons)
        lay.addWidget(self.status)
        lay.addWidget(self.summary, 1)
        self.resize(760, 560)

        add.clicked.connect(self._add_files)
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

    def _add_files(self) -> None:
        self.add_files(ask_open_files(self, "ShearSense CSV files", "import_csv",
                                      "ShearSense CSV (*.csv);;All files (*)"))

    def _browse_out(self) -> None:
        folder = ask_folder(self, "Folder for the session files", "import_out")
        if folder:
            self.out.setText(folder)

    def start(self) -> bool:
        """Import the listed files; False (with the reason shown) when it cannot start."""
        files = [self.files.item(i).text() for i in range(self.files.count())]
        out = self.out.text().strip()
        if not files or not out:
            self.status.setText("Add CSV files and choose a folder for the sessions."
                                if not files else "Choose a folder for the sessions.")
            return False
        for key, edit in (("gestures", self.gestures), ("participants", self.people),
                          ("out", self.out)):
            self.settings.setValue(KEY + key, edit.text().strip())
        gestures, people = self.gestures.text().strip(), self.people.text().strip()
        force = self.force.isChecked()
        self.written = []
        self.job = BackgroundJob(lambda progress, cancel: import_shearsense_study(
            files, out, gestures or None, people or None, progress, cancel, force,
            lambda path: self.written.append(str(path))), self)
        self.job.progressed.connect(self._progressed)
        self.job.finished.connect(lambda result: self._finished(out, *result))
        self.job.failed.connect(self._failed)
        self.job.cancelled.connect(lambda: self._stopped(
            f"Cancelled: the {len(self.written)} session(s) finished are kept in {out}.", out))
        self._set_running(True)
        self.summary.clear()
        self.status.setText(f"Importing {len(files)} file(s)…")
        self.job.start()
        return True

    def cancel(self) -> None:
        if self.job is not None:
            self.job.cancel()
            self.status.setText("Cancelling after the file being read…")

    def _set_running(self, on: bool) -> None:
        self.import_button.setEnabled(not on)
        self.cancel_button.setEnabled(on)

    def _progressed(self, fraction: float, message: str) -> None:
        self.progress.setValue(round(fraction * 1000))
        if message:
            self.status.setText(message)

    def _finished(self, out: str, paths: list[Path], report) -> None:  # noqa: ANN001
        self.progress.setValue(1000)
        self.summary.setPlainText("\n".join(report.lines()))
        skipped = (f" {len(report.no_frames)} file(s) had no frames and were not imported "
                   "(listed below).") if report.no_frames else ""
        self._stopped(f"Imported {len(paths)} session(s) into {out}; they are listed in "
                      f"the Sessions tab.{skipped}", out)

    def _failed(self, message: str) -> None:
        # the core names the command-line switch; here the switch is the tick box
        message = message.replace("(use --force to overwrite)",
                                  f"(tick \u201c{self.force.text()}\u201d to overwrite)")
        self._stopped(message, self.out.text().strip() if self.written else None)

    def _stopped(self, text: str, out: str | None) -> None:
        self._set_running(False)
        self.status.setText(text)
        if out is not None:
            self.imported.emit(out)

    def closeEvent(self, event) -> None:  # noqa: ANN001, N802 - Qt name and signature
        if self.job is not None and self.job.running:
            self.job.cancel()  # the file being read is dropped, finished sessions stay
            self.job.wait(10.0)
        super().closeEvent(event)
