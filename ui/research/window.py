"""The research workspace window: Sessions, Train, Sweep, Runs, Confusion matrix, Compare
and Session player tabs.

Every failure to read a run or a session is shown in the window's message line; the
window stays usable.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QLabel, QMainWindow, QTabWidget, QWidget

from tactile_studio.errors import UserError
from tactile_studio.learn.results.compare import compare_runs as compare_run_folders
from tactile_studio.learn.results.trialpreds import load_predictions
from tactile_studio.ui.file_dialogs import SESSION_KIND, ask_open_file, ask_save_file
from tactile_studio.ui.research.compare_view import CompareView
from tactile_studio.ui.research.confusion_view import ConfusionView
from tactile_studio.ui.research.import_dialog import ImportDialog
from tactile_studio.ui.research.import_xdf_dialog import XdfImportDialog
from tactile_studio.ui.research.player import SessionPlayer
from tactile_studio.ui.research.runs_view import RunsView
from tactile_studio.ui.research.sessions_view import SessionsView
from tactile_studio.ui.research.sweep_panel import SweepPanel
from tactile_studio.ui.research.train_panel import TrainPanel
from tactile_studio.ui.write_faults import fault_text


class ResearchWindow(QMainWindow):
    trialOpened = Signal(object)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Tactile Studio — research workspace")
        self.tabs = QTabWidget()
        self.sessions = SessionsView()
        self.runs = RunsView()
        self.confusion = ConfusionView()
        self.compare = CompareView()
        self.player = SessionPlayer()
        self.train = TrainPanel(self.sessions.selected_paths)
        self.sweep = SweepPanel(self.sessions.selected_paths)
        for w, name in ((self.sessions, "Sessions"), (self.train, "Train"),
                        (self.sweep, "Sweep"), (self.runs, "Runs"),
                        (self.confusion, "Confusion matrix"), (self.compare, "Compare"),
                        (self.player, "Session player")):
            self.tabs.addTab(w, name)
        self.setCentralWidget(self.tabs)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.statusBar().addWidget(self.message, 1)
        self.runs.openRequested.connect(self.open_run)
        self.runs.compareRequested.connect(self.compare_runs)
        self.runs.error.connect(self.show_error)
        self.confusion.export_png.clicked.connect(lambda: self._export("PNG image (*.png)"))
        self.confusion.export_svg.clicked.connect(lambda: self._export("SVG drawing (*.svg)"))
        self.confusion.export_csv.clicked.connect(lambda: self._export("CSV table (*.csv)"))
        self.confusion.trialActivated.connect(self.play_trial)
        self.player.error.connect(self.show_error)
        self.train.error.connect(self.show_error)
        self.train.runFinished.connect(self._run_finished)
        self.train.ablationFinished.connect(
            lambda runs: self.compare_runs(runs[0], runs[-1]))
        self.sweep.error.connect(self.show_error)
        self.sweep.sweepFinished.connect(self._sweep_finished)
        self.sweep.openRequested.connect(self.open_run)
        self.train.sweepRequested.connect(self._to_sweep)
        file_menu = self.menuBar().addMenu("&File")
        file_menu.addAction("&Open session…").triggered.connect(self._browse_session)
        file_menu.addAction("&Import old recordings (ShearSense CSV)…").triggered.connect(
            self.open_import)
        file_menu.addAction("Import &XDF recordings (LabRecorder)…").triggered.connect(
            self.open_import_xdf)
        self.sessions.importRequested.connect(self.open_import)
        self.import_dialog: ImportDialog | None = None
        self.import_xdf_dialog: XdfImportDialog | None = None
        self.resize(1200, 760)

    def open_import(self) -> ImportDialog:
        """The import dialog (one, kept); what it imports joins the Sessions tab."""
        if self.import_dialog is None:
            self.import_dialog = ImportDialog(self)
            self.import_dialog.imported.connect(self._imported)
        self.import_dialog.show()
        self.import_dialog.raise_()
        return self.import_dialog

    def open_import_xdf(self) -> XdfImportDialog:
        """The XDF import dialog (one, kept); what it imports joins the Sessions tab."""
        if self.import_xdf_dialog is None:
            self.import_xdf_dialog = XdfImportDialog(self)
            self.import_xdf_dialog.imported.connect(self._imported)
        self.import_xdf_dialog.show()
        self.import_xdf_dialog.raise_()
        return self.import_xdf_dialog

    def _imported(self, folder: str) -> None:
        # listed once; rescanned either way, since a re-import may replace sessions
        self.sessions.set_folders(list(dict.fromkeys([*self.sessions.folders, folder])))
        self.tabs.setCurrentWidget(self.sessions)
        self.show_info(f"imported sessions in {folder} are listed in the Sessions tab")

    def show_error(self, text: str) -> None:
        self.message.setStyleSheet("color: #a00000")
        self.message.setText(text)

    def show_info(self, text: str) -> None:
        self.message.setStyleSheet("")
        self.message.setText(text)

    def open_run(self, path: str) -> bool:
        try:
            run = load_predictions(path)
        except UserError as exc:
            self.show_error(str(exc))
            return False
        self.confusion.set_run(run)
        self.tabs.setCurrentWidget(self.confusion)
        ks = run.shot_counts  # a few-shot run scores each test trial once per K
        tested = len(run.at_shots(ks[0]).trials) if ks else len(run.trials)
        self.show_info(f"opened {path}: {tested} test trials" + (
            f", each scored at K = {', '.join(map(str, ks))} (the header's K is shown)"
            if ks else ""))
        return True

    def compare_runs(self, a: str, b: str) -> bool:
        try:
            result = compare_run_folders(a, b)  # few-shot runs: per K, never mixed
        except UserError as exc:
            self.show_error(str(exc))
            return False
        self.compare.set_result(result)
        self.tabs.setCurrentWidget(self.compare)
        self.show_info(result["sentence"])
        return True

    def closeEvent(self, event) -> None:  # noqa: ANN001, N802 - Qt name and signature
        self.sessions.stop_checks(wait_s=5.0)  # nothing left reading the user's files
        if self.train.job is not None and self.train.job.running:
            self.train.cancel()  # the worker stops after its epoch; folds are kept
        if self.import_dialog is not None:
            self.import_dialog.close()  # a running import stops; finished sessions stay
        if self.import_xdf_dialog is not None:
            self.import_xdf_dialog.close()
        if self.sweep.job is not None and self.sweep.job.running:
            self.sweep.cancel()  # workers are ended; finished tasks are kept
            self.sweep.job.wait(10.0)
        super().closeEvent(event)

    def _run_finished(self, out: str) -> None:
        root = str(Path(out).parent)
        if not self.runs.root.text():
            self.runs.set_root(root)
        else:
            self.runs.set_root(self.runs.root.text())
        self.show_info(f"run finished: {out}")

    def _to_sweep(self, model: str, channels: str) -> None:
        """The Train tab's model and channel set join the Sweep tab's ticks."""
        self.sweep.set_models(sorted({*self.sweep.checked_models(), model}))
        self.sweep.set_channels([*self.sweep.checked_channels(), channels])
        self.sweep.preset.setCurrentText(self.train.preset.currentText())
        self.sweep.evaluation.setCurrentText(self.train.evaluation.currentText())
        self.tabs.setCurrentWidget(self.sweep)

    def _sweep_finished(self, out: str) -> None:
        """The sweep's runs (one per model x channel set) join the Runs tab."""
        self.runs.set_root(out)
        n = len(self.runs.rows)
        self.show_info(f"sweep saved in {out}: {n} run(s) listed in the Runs tab")

    def _browse_session(self) -> None:
        path = ask_open_file(self, "Open session", SESSION_KIND, "Sessions (*.h5)")
        if path:
            self.open_session(path)

    def open_session(self, path: str) -> bool:
        ok = self.player.open_session(path)
        if ok:
            self.tabs.setCurrentWidget(self.player)
            self.show_info(f"playing {path}")
        return ok

    def play_trial(self, trial) -> bool:
        """Open a confusion-cell trial in the player at its start, with the run's
        prediction over time."""
        if not trial.path or not self.open_session(trial.path):
            if not trial.path:
                self.show_error(f"{trial.uid}: the run does not say where its session is")
            return False
        run = self.confusion.run
        if run is not None:
            self.player.load_run_predictions(str(run.path))
        self.player.jump_to_trial(trial.trial)
        self.trialOpened.emit(trial)
        return True

    def _export(self, kind: str) -> None:
        run = self.confusion.run
        stem = f"{Path(run.path).name}-confusion" if run is not None else "confusion"
        extension = kind.rsplit("*", 1)[-1].rstrip(")")  # "PNG image (*.png)" -> ".png"
        path = ask_save_file(self, "Export confusion matrix", "export", stem + extension, kind)
        if path:
            self.export_confusion(path)

    def export_confusion(self, path: str | Path) -> bool:
        """Write the confusion matrix (PNG, SVG or CSV by suffix); a place that cannot
        be written is one line in the status bar."""
        try:
            self.confusion.export(path)
        except (OSError, UserError) as exc:
            text = fault_text(exc)
            if text is None:
                raise
            self.show_error(text)
            return False
        self.show_info(f"exported {path}")
        return True
