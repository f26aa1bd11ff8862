"""What every import dialog of the research workspace shares: the files to import, the
folder the sessions go to, the replace tick box, progress, Cancel that keeps the finished
sessions, and the one line a failure ends in. A subclass adds its own fields (the maps of
old CSVs, an XDF file's stream and layout) and names the core function that imports."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

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

from tactile_studio.output_faults import kept_when_full
from tactile_studio.ui.background_job import BackgroundJob
from tactile_studio.ui.file_dialogs import ask_folder, ask_open_files
from tactile_studio.ui.settings import app_settings

ImportJob = Callable[[Any, Any], Any]  # fn(progress, cancel) -> result


class ImportDialogBase(QDialog):
    """The shared frame; subclasses set the class attributes and implement
    :meth:`add_fields`, :meth:`make_job` and :meth:`finished_text`."""

    imported = Signal(str)  # the folder the sessions were written to

    TITLE = "Import"
    KEY = "import/"              # settings prefix
    FILES_LABEL = "Files"
    ADD_TEXT = "Add files…"
    FILE_NOUN = "files"          # "Add <noun> and choose a folder…"
    FILE_KIND = "import"         # file_dialogs' remembered folder
    FILE_FILTER = "All files (*)"
    IDLE_TEXT = "Add the files to import."
    CANCEL_TEXT = "Cancelling after the file being read…"
    # what the core says in command-line words -> what this dialog calls it
    CLI_WORDS: tuple[tuple[str, str], ...] = ()
    SIZE = (680, 460)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle(self.TITLE)
        self.settings = app_settings()
        self.job: BackgroundJob | None = None
        self.written: list[str] = []  # sessions the current import has finished
        self.files = QListWidget()
        self.files.setMinimumHeight(100)
        add, clear = QPushButton(self.ADD_TEXT), QPushButton("Clear")
        self.out = QLineEdit(str(self.settings.value(self.KEY + "out", "")))
        self.out.setPlaceholderText("folder for the session files")
        browse = QPushButton("Browse…")
        self.force = QCheckBox("Replace sessions already in the folder")
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.status = QLabel(self.IDLE_TEXT)
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
        self.add_fields(form)
        form.addRow("Into folder", out_row)
        form.addRow("", self.force)
        buttons = QHBoxLayout()
        buttons.addWidget(self.progress, 1)
        for b in (self.import_button, self.cancel_button, close):
            buttons.addWidget(b)
        self.main_layout = QVBoxLayout(self)
        self.main_layout.addWidget(QLabel(self.FILES_LABEL))
        self.main_layout.addWidget(self.files, 1)
        self.main_layout.addLayout(file_buttons)
        self.main_layout.addLayout(form)
        self.main_layout.addLayout(buttons)
        self.main_layout.addWidget(self.status)
        self.resize(*self.SIZE)

        add.clicked.connect(lambda: self.add_files(ask_open_files(
            self, self.FILES_LABEL, self.FILE_KIND, self.FILE_FILTER)))
        clear.clicked.connect(self.files.clear)
        browse.clicked.connect(self._browse_out)
        self.import_button.clicked.connect(self.start)
        self.cancel_button.clicked.connect(self.cancel)
        close.clicked.connect(self.close)

    # ---- what a subclass says ----------------------------------------------------------
    def add_fields(self, form: QFormLayout) -> None:
        """Rows of this import's own options, above "Into folder"."""

    def remember(self) -> None:
        """Store this import's own options in the settings when an import starts."""

    def make_job(self, files: list[str], out: str, force: bool,
                 written: Callable[[Path], None]) -> ImportJob:
        """The core import as ``fn(progress, cancel)``; ``written(path)`` for each
        session it finishes (kept when cancelled)."""
        raise NotImplementedError

    def finished_text(self, out: str, result: Any) -> str:
        raise NotImplementedError

    # ---- the shared frame ----------------------------------------------------------------
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
            self.status.setText(f"Add {self.FILE_NOUN} and choose a folder for the sessions."
                                if not files else "Choose a folder for the sessions.")
            return False
        self.settings.setValue(self.KEY + "out", out)
        self.remember()
        self.written = []
        work = self.make_job(files, out, self.force.isChecked(),
                             lambda path: self.written.append(str(path)))

        def fn(progress, cancel):  # noqa: ANN001, ANN202 - the job's two arguments
            # a full disk part way: the cut session is removed, those before it kept
            with kept_when_full(self.written, "session", "imported"):
                return work(progress, cancel)

        self.job = BackgroundJob(fn, self)
        self.job.progressed.connect(self._progressed)
        self.job.finished.connect(lambda result: self._stopped(
            self.finished_text(out, result), out, done=True))
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
            self.status.setText(self.CANCEL_TEXT)

    def _set_running(self, on: bool) -> None:
        self.import_button.setEnabled(not on)
        self.cancel_button.setEnabled(on)

    def _progressed(self, fraction: float, message: str) -> None:
        self.progress.setValue(round(fraction * 1000))
        if message:
            self.status.setText(message)

    def _failed(self, message: str) -> None:
        # the core names the command-line switches; here they are this dialog's fields
        message = message.replace("(use --force to overwrite)",
                                  f"(tick \u201c{self.force.text()}\u201d to overwrite)")
        for cli, here in self.CLI_WORDS:
            message = message.replace(cli, here)
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
            self.job.cancel()  # the file being read is dropped, finished sessions stay
            self.job.wait(10.0)
        super().closeEvent(event)
