"""Live inference overlay for the main window: load a finished run; the top-3 gestures
with probabilities, the smoothing window and the measured latency update as the live
engine streams (the model runs in learn/deploy/live_inference.py's worker thread).
"Calibrate to person…" is few-shot personalisation (``train --shots``) live: the
experimenter prompts each gesture K times and the run's model is retrained with those
labelled touches (personalise_dialog.py, learn/deploy/personalise.py); from the same
dialog, "From an earlier recording…" meets the participant as ``--adapt person`` met
each test person, from a recording of them (playback/predictions.py
``calibrate_to_session``; rf/knn or fused runs trained with ``--adapt``). "Adapt as they
touch" does that from their own last touches instead (learn/deploy/live_inference.py
``RunningCalibration``). "Forget personalisation" returns to the run's model."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from PySide6.QtCore import QSignalBlocker, Qt, QTimer
from PySide6.QtWidgets import (
    QCheckBox,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.live_inference import LiveInference, RunningCalibration
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.playback.predictions import calibrate_to_session
from tactile_studio.ui.file_dialogs import ask_folder
from tactile_studio.ui.research.personalise_dialog import PersonaliseDialog, describe
from tactile_studio.ui.settings import app_settings

RUNNING_KEY = "live/adapt_as_they_touch"


class LiveInferencePanel(QWidget):
    def __init__(self, engine: Callable[[], Any], recording: Callable[[], bool],
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.engine_fn, self.recording_fn = engine, recording
        self.model: WindowModel | None = None
        self.inference: LiveInference | None = None
        self.settings = app_settings()
        self.dialog: PersonaliseDialog | None = None
        self._build_buttons()
        self._build_labels()
        self._build_layout(self._build_prediction_rows())
        self._connect()

    # ---- the panel's parts ------------------------------------------------------------
    def _build_buttons(self) -> None:
        """Load run, Calibrate to person, Forget personalisation, Adapt as they touch."""
        self.load_button = QPushButton("Load run…")
        self.calibrate_button = QPushButton("Calibrate to person…")
        self.calibrate_button.setToolTip(
            "Few-shot personalisation (train --shots K, live): prompt the participant for "
            "each gesture K times; the run's model is retrained with their labelled "
            "touches (rf/knn refit with its training windows, a network's output layers "
            "fine-tuned, a fused model both) and predicts for them from then on; with K=2 "
            "the dialog measures it on their own touches. An rf/knn run trained with "
            "--adapt can instead take the person's statistics from an earlier recording "
            "of them (in the same dialog).")
        self.calibrate_button.setEnabled(False)
        self.forget_button = QPushButton("Forget personalisation")
        self.forget_button.setEnabled(False)
        self.running_box = QCheckBox("Adapt as they touch")
        self.running_box.setToolTip(
            "A run trained with --adapt meets the participant with the statistics of their "
            "own last 9 touches, the window being predicted among them, from the eighth "
            "touch on (no recording needed). On virtual people: cnn1d, cnn3d, sefusion "
            "2.6-3.6 points above their training statistics (cnn_transformer 1.9, mts3d "
            "-0.6); rf/knn level with the plain forest. A network stays as trained while "
            "over a third of the touches look like one gesture (one gesture repeated would "
            "be normalised away: cnn1d -24 points replayed unguarded, level with as trained "
            "guarded); rf/knn have no view as trained to judge by, so with them the "
            "participant must vary their gestures.")
        self.running_box.setEnabled(False)
        self.running_box.setChecked(self.settings.value(RUNNING_KEY, True, type=bool))

    def _build_labels(self) -> None:
        """The run's line, the calibration's lines and the smoothing."""
        self.run_label = QLabel("no run loaded")
        self.run_label.setWordWrap(True)
        self.calibration_label = QLabel("")
        self.calibration_label.setWordWrap(True)
        # three lines kept: its text changes with every touch, and a dock does not grow a
        # wrapped label (it clipped the guard's two lines), nor should the bars jump
        self.calibration_label.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop)
        self.calibration_label.setMinimumHeight(3 * self.fontMetrics().lineSpacing() + 4)
        self.smoothing = QSpinBox()
        self.smoothing.setRange(1, 50)
        self.smoothing.setValue(4)
        self.smoothing.setSuffix(" predictions")

    def _build_prediction_rows(self) -> QGridLayout:
        """The three most likely gestures, the first larger, each with its bar."""
        self.rows: list[tuple[QLabel, QProgressBar]] = []
        grid = QGridLayout()
        for i in range(3):
            name, bar = QLabel("—"), QProgressBar()
            bar.setRange(0, 100)
            bar.setFormat("%p%")
            f = name.font()
            f.setPointSize(f.pointSize() + (3 if i == 0 else 0))
            f.setBold(i == 0)
            name.setFont(f)
            name.setMinimumWidth(110)
            grid.addWidget(name, i, 0)
            grid.addWidget(bar, i, 1)
            self.rows.append((name, bar))
        return grid

    def _build_layout(self, grid: QGridLayout) -> None:
        """The buttons, the lines, the predictions, the latency and the message."""
        self.latency = QLabel("latency —")
        self.message = QLabel("")
        self.message.setWordWrap(True)
        # two short rows, not one long one: the dock stays narrow enough to leave the
        # device panel its width at the main window's default size
        top = QHBoxLayout()
        top.addWidget(self.load_button)
        top.addWidget(self.calibrate_button)
        top.addStretch(1)
        personal = QHBoxLayout()
        personal.addWidget(self.forget_button)
        personal.addStretch(1)
        smoothing = QHBoxLayout()
        smoothing.addWidget(QLabel("Smoothing"))
        smoothing.addWidget(self.smoothing)
        smoothing.addStretch(1)
        lay = QVBoxLayout(self)
        lay.addLayout(top)
        lay.addLayout(personal)
        lay.addWidget(self.running_box)
        lay.addLayout(smoothing)
        lay.addWidget(self.run_label)
        lay.addWidget(self.calibration_label)
        lay.addLayout(grid)
        lay.addWidget(self.latency)
        lay.addWidget(self.message)
        lay.addStretch(1)

    def _connect(self) -> None:
        self.timer = QTimer(self)
        self.timer.setInterval(100)
        self.timer.timeout.connect(self.refresh)
        self.load_button.clicked.connect(self._browse)
        self.calibrate_button.clicked.connect(self.open_personalise)
        self.forget_button.clicked.connect(self.forget_personalisation)
        self.running_box.toggled.connect(self._running_toggled)
        self.smoothing.valueChanged.connect(
            lambda n: self.inference.set_smoothing(n) if self.inference else None)

    def _browse(self) -> None:
        folder = ask_folder(self, "Run folder", "live_run")
        if folder:
            self.load_run(folder)

    def _running_toggled(self, on: bool) -> None:
        self.settings.setValue(RUNNING_KEY, on)
        self.stop()  # restarts with or without it on the next refresh
        if self.model is not None:  # ticked or not, it starts from the model as trained
            self.model.uncalibrate()
            self._describe_calibration()

    @property
    def adapts_as_they_touch(self) -> bool:
        return (self.model is not None and self.model.adapts_as_they_touch
                and self.running_box.isChecked())

    def calibrate(self, path: str) -> bool:
        """The loaded model adapted to the person recorded in session file ``path``."""
        if self.model is None:
            return False
        self.stop()  # restarts with the calibrated model on the next refresh
        if self.model.personalised is not None:  # the recording's statistics replace it
            self.model.forget_personalisation()
            self.forget_button.setEnabled(False)
        try:
            # features only: a network's batch norm re-estimated on a short earlier
            # recording lost points on virtual people (benchmarks/bench_calibration.py)
            samples = calibrate_to_session(self.model, path, batch_norm=False)
        except UserError as exc:
            self.message.setText(str(exc))
            return False
        self.message.setText("")
        with QSignalBlocker(self.running_box):  # the recording's statistics, fixed
            self.running_box.setChecked(False)
        self.settings.setValue(RUNNING_KEY, False)
        self.calibration_label.setText(f"calibrated to the person in {Path(path).name} "
                                       f"({samples} windows)")
        return True

    def _calibrate_line(self, path: str) -> tuple[bool, str]:
        """The dialog's "From an earlier recording…": (calibrated, one line)."""
        ok = self.calibrate(path)
        return ok, self.calibration_label.text() if ok else self.message.text()

    def open_personalise(self) -> PersonaliseDialog | None:
        """Calibrate to person…: the prompts dialog for the loaded run (non-modal: the
        predictions stay in view)."""
        if self.model is None:
            return None
        if self.dialog is not None:
            self.dialog.close()
        model = self.model
        self.dialog = PersonaliseDialog(model, self.engine_fn, self,
                                        calibrate=self._calibrate_line)
        # a run loaded meanwhile is not given another run's personalisation
        self.dialog.personalised.connect(
            lambda personal: self.use_personalised(personal) if self.model is model else None)
        self.dialog.measured.connect(  # its held-out check, measured while in use
            lambda personal: self.calibration_label.setText(describe(personal))
            if self.model is model and model.personalised is personal else None)
        self.dialog.show()
        return self.dialog

    def use_personalised(self, personal: Any) -> None:
        """Predict with the model retrained with the person's labelled touches."""
        if self.model is None:
            return
        self.stop()  # restarts with the personalised model on the next refresh
        self.model.personalise(personal)
        with QSignalBlocker(self.running_box):  # their labelled touches, fixed
            self.running_box.setChecked(False)
        self.forget_button.setEnabled(True)
        self.calibration_label.setText(describe(personal))

    def forget_personalisation(self) -> None:
        """Back to the run's own model, as trained."""
        if self.model is None or self.model.personalised is None:
            return
        self.stop()
        self.model.forget_personalisation()
        self.forget_button.setEnabled(False)
        self._describe_calibration()

    def load_run(self, path: str) -> bool:
        try:
            model = WindowModel(path)
        except UserError as exc:
            self.message.setText(str(exc))
            return False
        self.stop()
        if self.dialog is not None:  # its prompts were for the previous run
            self.dialog.close()
        self.model = model
        d = model.describe()
        self.run_label.setText(f"{model.name}: {d['model']} ({d['channels'] or 'all'}), fold "
                               f"{d['fold']}, window {d['window']} frames, "
                               f"{len(d['labels'])} gestures")
        self.message.setText("")
        self.calibrate_button.setEnabled(True)
        self.forget_button.setEnabled(False)
        self.running_box.setEnabled(model.adapts_as_they_touch)
        self._describe_calibration()
        self.timer.start()
        return True

    def _describe_calibration(self) -> None:
        m = self.model
        adapt, name = m.config.adapt, m.config.model
        self.calibration_label.setText(
            f"trained --adapt {adapt}: {name} adapts to the participant from their own last "
            "touches as they go" + ("" if m.needs_calibration else " (as trained until "
                                   "enough touches)") + "; they must vary their gestures"
            if self.adapts_as_they_touch else
            f"trained --adapt {adapt}: {name} needs the participant's own statistics; "
            "Calibrate to person… (their touches, or a recording of them) or tick Adapt as "
            "they touch" if m.needs_calibration else
            f"calibrated to the participant: {m.calibrated_on}" if m.reference is not None else
            "as trained, with the training people's statistics" if adapt == "none" else
            "as trained, with the training people's pooled feature statistics"
            + (" for its forest (about 2 points under a plain forest on virtual people)"
               if m.learner.kind == "fused" else
               " (about 5 points under a plain forest on virtual people)")
            + ": Calibrate to person… (their touches, or a recording of them) or tick Adapt "
            "as they touch"
            if m.reads_person_features else
            "as trained, with the training people's batch-norm statistics (re-estimated on "
            "a short earlier recording they cost points on virtual people)")

    def stop(self) -> None:
        if self.inference is not None:
            self.inference.stop()
            self.inference = None
        for name, bar in self.rows:  # no stale predictions of a model no longer running
            name.setText("—")
            bar.setValue(0)

    def refresh(self) -> None:
        engine = self.engine_fn()
        running = self.adapts_as_they_touch
        if self.model is None or (self.model.needs_calibration and not running):
            return
        if engine is None:
            self.message.setText("no device: connect one to predict")
            self.stop()
            return
        if self.inference is None or self.inference.engine is not engine:
            self.stop()
            self.inference = LiveInference(
                engine, self.model, smoothing=self.smoothing.value(),
                recording=self.recording_fn,
                adapting=RunningCalibration(self.model) if running else None).start()
        inf = self.inference
        if inf.error:
            self.message.setText(f"prediction stopped: {inf.error}")
            return
        p, touches = inf.latest, inf.adapting
        if touches is not None and touches.count:
            self.calibration_label.setText(self._touches_text(touches))
        if p is None:
            self.message.setText("waiting for the participant's first touches…"
                                 if touches is not None else
                                 "waiting for a full window and a baseline…")
            return
        self.message.setText("")
        for (name, bar), (label, prob) in zip(self.rows, p.top3):
            name.setText(label)
            bar.setValue(round(100 * prob))
        self.latency.setText(f"latency {p.latency_ms:.0f} ms (model {p.compute_ms:.0f} ms) · "
                             f"{inf.count} prediction{'' if inf.count == 1 else 's'}")

    def _touches_text(self, touches: RunningCalibration) -> str:
        n, alike = touches.count, touches.most_alike
        if n < touches.minimum:
            return (f"adapting to the participant: {n} of {touches.minimum} touches"
                    + (" before the first prediction" if self.model.needs_calibration else
                       ", as trained until then"))
        if not touches.guarded:
            return f"adapted to their last {n} touches (they must vary their gestures)"
        if not touches.ready:
            return (f"as trained: {alike} of their last {n} touches look like one gesture "
                    f"(adapts when no gesture is over {touches.alike:.0%} of them: one "
                    "gesture repeated would be normalised away)")
        return (f"adapted to their last {n} touches (varied: at most {alike} look like "
                "one gesture)")

    def top(self) -> str:
        return self.rows[0][0].text()
