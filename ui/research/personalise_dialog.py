"""Calibrate to this person: the live panel's one way to meet a new participant.

The experimenter picks K and the dialog prompts "Perform <gesture> now" for each of the
run's gestures K times on the live stream (one labelled window per prompt, taken once the
touch is there; Skip / Redo), then the run's fold model is retrained with those windows
off the GUI thread (``ui/background_job.py``: progress and Cancel; the live predictions
go on meanwhile) and the result says what was done and, with K >= 2, the held-out check
measured on the person's own touches (learn/deploy/personalise.py does all of it; this
dialog only shows it). "From an earlier recording…" is the statistics calibration of an
rf/knn (or fused) run trained with ``--adapt`` on a recording of the participant instead.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QDialog,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.personalise import HeldOutCheck, Personalised
from tactile_studio.learn.deploy.touch_prompts import TouchPrompts
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.learners.fused import display_name
from tactile_studio.ui.background_job import BackgroundJob
from tactile_studio.ui.file_dialogs import ask_open_file

STEPS = 1000  # the progress bar's resolution while retraining


class PersonaliseDialog(QDialog):
    personalised = Signal(object)  # learn.deploy.personalise.Personalised
    measured = Signal(object)  # the same Personalised, its held-out check now measured

    def __init__(self, model: WindowModel, engine: Callable[[], Any],
                 parent: QWidget | None = None,
                 calibrate: Callable[[str], tuple[bool, str]] | None = None) -> None:
        """``calibrate(path)``: the panel's statistics calibration on a recording,
        (done, one line to show)."""
        super().__init__(parent)
        self.setWindowTitle("Calibrate to this person")
        self.model, self.engine_fn, self.calibrate_fn = model, engine, calibrate
        self.prompts: TouchPrompts | None = None
        self.result: Personalised | None = None
        self.job: BackgroundJob | None = None
        self.job_kind = ""  # "retrain" or "check"
        self._layout: Any = None
        top = self._build_top(model, calibrate)
        intro = QLabel(f"The participant performs each of the {len(model.labels)} gestures "
                       f"of {model.name} when asked; "
                       f"{display_name(model.config.model, model.config.overrides)} is then "
                       "retrained with their touches.")
        intro.setWordWrap(True)
        self._build_prompt()
        buttons = self._build_buttons()
        lay = QVBoxLayout(self)
        lay.addWidget(intro)
        lay.addLayout(top)
        lay.addWidget(self.prompt)
        lay.addWidget(self.state)
        lay.addWidget(self.progress)
        lay.addLayout(buttons)
        self._connect()
        self._buttons()
        self.resize(600, 300)

    # ---- the dialog's parts -------------------------------------------------------------
    def _build_top(self, model: WindowModel,
                   calibrate: Callable[[str], tuple[bool, str]] | None) -> QHBoxLayout:
        """K, Start, and "From an earlier recording…" (only for a run that reads a
        person's feature statistics)."""
        self.k = QSpinBox()
        self.k.setRange(1, 2)
        self.k.setValue(2)
        self.k.setSuffix(" touch(es) per gesture")
        self.k.setToolTip("K labelled performances of every gesture: on virtual people K=1 "
                          "already lifts a new person's accuracy clearly "
                          "(docs/learning/figures.md); "
                          "K=2 also measures it, each round checked by the model of the other")
        self.start_button = QPushButton("Start")
        self.recording_button = QPushButton("From an earlier recording…")
        reads = model.reads_person_features and calibrate is not None
        self.recording_button.setEnabled(reads)
        self.recording_button.setToolTip(
            "Instead of prompting: standardise the run's features by the participant's own "
            "statistics from a recording of them (a session of every gesture, recorded "
            "before; no labels used), as --adapt person met each test person" if reads else
            "Only for an rf/knn (or fused) run trained with --adapt: it reads features "
            "standardised by each person's statistics. Prompted touches personalise any run.")
        top = QHBoxLayout()
        top.addWidget(QLabel("K"))
        top.addWidget(self.k)
        top.addWidget(self.start_button)
        top.addStretch(1)
        top.addWidget(self.recording_button)
        return top

    def _build_prompt(self) -> None:
        """The prompt (large), the state's lines and the progress."""
        self.prompt = QLabel("Pick K and press Start.")
        f = self.prompt.font()
        f.setPointSize(f.pointSize() + 6)
        f.setBold(True)
        self.prompt.setFont(f)
        self.prompt.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.prompt.setMinimumHeight(2 * self.prompt.fontMetrics().lineSpacing())
        self.state = QLabel("Start prompts each gesture K times; with K = 2 the result is "
                            "checked on their own touches, each round by the model of the "
                            "other.")
        self.state.setWordWrap(True)
        self.state.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop)
        self.state.setMinimumHeight(4 * self.state.fontMetrics().lineSpacing())
        self.progress = QProgressBar()

    def _build_buttons(self) -> QHBoxLayout:
        """Skip, Redo last, Retrain (shown after a cancelled or failed one), Cancel."""
        self.skip_button = QPushButton("Skip")
        self.skip_button.setToolTip("leave this gesture out (it keeps the run's training)")
        self.redo_button = QPushButton("Redo last")
        self.redo_button.setToolTip("record the last answered gesture again")
        self.retrain_button = QPushButton("Retrain")
        self.retrain_button.setToolTip("retrain with the touches recorded (kept after a "
                                       "cancelled or failed retraining)")
        self.retrain_button.hide()
        self.cancel_button = QPushButton("Cancel")
        buttons = QHBoxLayout()
        for b in (self.skip_button, self.redo_button, self.retrain_button):
            buttons.addWidget(b)
        buttons.addStretch(1)
        buttons.addWidget(self.cancel_button)
        return buttons

    def _connect(self) -> None:
        self.timer = QTimer(self)
        self.timer.setInterval(50)
        self.timer.timeout.connect(self.poll)
        self.start_button.clicked.connect(self.start)
        self.recording_button.clicked.connect(self._browse_recording)
        self.skip_button.clicked.connect(self.skip)
        self.redo_button.clicked.connect(self.redo)
        self.retrain_button.clicked.connect(self.retrain)
        self.cancel_button.clicked.connect(self.cancel)

    @property
    def retraining(self) -> bool:
        """A job is running: the retraining, or the held-out check after it."""
        return self.job is not None and self.job.running

    @property
    def checking(self) -> bool:
        return self.retraining and self.job_kind == "check"

    def cancel(self) -> None:
        """Cancel: stops a retraining (the touches stay for Retrain) or the held-out check
        (the personalised model stays), else closes."""
        if self.checking:
            self.job.cancel()
        elif self.retraining:
            self.job.cancel()
            self.state.setText("cancelling: the run's model stays in use…")
        else:
            self.reject()

    def done(self, result: int) -> None:  # Close / the window closed
        """Stops watching the stream; a retraining still running is cancelled, not used."""
        self.timer.stop()
        if self.job is not None:
            self.job.cancel()
            self.job = None
        super().done(result)

    def _engine(self) -> Any:
        engine = self.engine_fn()
        if engine is None:
            raise UserError("no device: connect one, then personalise")
        return engine

    def _browse_recording(self) -> None:
        path = ask_open_file(self, "Recording of the participant", "live_calibration",
                             "Session files (*.h5)")
        if path:
            self.from_recording(path)

    def from_recording(self, path: str) -> bool:
        """The statistics calibration on a recording of the participant (no prompts)."""
        if self.calibrate_fn is None or self.retraining:
            return False
        ok, text = self.calibrate_fn(path)
        self.prompt.setText("Calibrated" if ok else "Not calibrated")
        self.state.setText(text)
        if ok:
            self.timer.stop()
            self.prompts = None
            self.retrain_button.hide()
            self.cancel_button.setText("Close")
            self._buttons()
        return ok

    def start(self) -> bool:
        try:
            engine = self._engine()
        except UserError as exc:
            self.state.setText(str(exc))
            return False
        self.prompts = TouchPrompts(self.model, self.k.value())
        self.prompts.begin(engine)
        self.progress.setRange(0, len(self.prompts.prompts))
        self.retrain_button.hide()
        self.cancel_button.setText("Cancel")
        self._show()
        self.timer.start()
        return True

    def skip(self) -> None:
        if self.prompts is not None and not self.prompts.done:
            self.prompts.skip(self._engine())
            self._next()

    def redo(self) -> None:
        if self.prompts is not None and self.prompts.answers and not self.prompts.done:
            self.prompts.redo(self._engine())
            self._show()

    def poll(self) -> None:
        p = self.prompts
        engine = self.engine_fn()
        if p is None or engine is None:
            return
        try:
            answered = p.poll(engine)
        except UserError as exc:
            self.state.setText(str(exc))
            return
        if answered:
            self._next()
        elif p.touching:
            self.state.setText("touch seen: recording its window…")

    def _next(self) -> None:
        if self.prompts is not None and self.prompts.done:
            self.timer.stop()
            self._finish()
        else:
            self._show()

    def _show(self) -> None:
        p = self.prompts
        assert p is not None
        self.progress.setValue(p.pos)
        if p.gesture is not None:
            k = f" ({p.round} of {p.k})" if p.k > 1 else ""
            self.prompt.setText(f"Perform {p.gesture} now{k}")
            self.state.setText(f"prompt {p.pos + 1} of {len(p.prompts)} · "
                               f"{len(p.answers)} touch(es) recorded · waiting for the touch")
        self._buttons()

    def _buttons(self) -> None:
        p = self.prompts
        prompting = p is not None and not p.done
        # once the prompts are over (and not retraining) the experimenter may start again
        idle = not prompting and not self.retraining
        self.k.setEnabled(idle)
        self.start_button.setEnabled(idle)
        self.start_button.setText("Start again" if p is not None and idle else "Start")
        self.skip_button.setEnabled(prompting)
        self.redo_button.setEnabled(prompting and bool(p.answers))
        self.recording_button.setEnabled(
            not self.retraining and self.calibrate_fn is not None
            and self.model.reads_person_features)

    def _finish(self) -> None:
        p = self.prompts
        assert p is not None
        self.progress.setValue(len(p.prompts))
        self._buttons()
        if not p.answers:
            self.prompt.setText("No touches recorded")
            self.state.setText("every prompt was skipped: the run's model stays in use")
            self.cancel_button.setText("Close")
            return
        self.retrain()

    def retrain(self) -> bool:
        """Retrain the run's model with the answered prompts, off the GUI thread; once it
        is in use, the held-out check (K >= 2) is measured the same way."""
        p = self.prompts
        if p is None or not p.done or not p.answers or self.retraining:
            return False
        try:
            self._layout = self._engine().layout
        except UserError as exc:
            self.prompt.setText("Not personalised")
            self.state.setText(str(exc))
            return False
        self.prompt.setText("Retraining…")
        self.state.setText(f"{len(p.answers)} labelled touches; "
                           f"{self.model.config.model} is retrained with them")
        self.retrain_button.hide()
        layout = self._layout
        self._launch("retrain", lambda progress, cancel: p.personalise(
            layout, progress=progress, cancel=cancel))
        return True

    def _launch(self, kind: str, fn: Callable[[Any, Any], Any]) -> None:
        """Run ``fn(progress, cancel)`` as the dialog's one job ("retrain" or "check")."""
        job = BackgroundJob(fn, self)
        self.job, self.job_kind = job, kind
        self.progress.setRange(0, STEPS)
        self.progress.setValue(0)
        self.cancel_button.setText("Cancel" if kind == "retrain" else "Cancel check")
        job.progressed.connect(lambda f, msg: self._progressed(job, f, msg))
        if kind == "retrain":
            job.finished.connect(lambda result: self._retrained(job, result))
            job.failed.connect(lambda msg: self._stopped(job, msg))
            job.cancelled.connect(lambda: self._stopped(
                job, f"retraining cancelled: the run's model stays in use; the "
                f"{len(self.prompts.answers)} touches are kept (Retrain uses them)"))
        else:
            job.finished.connect(lambda check: self._measured(job, check))
            job.failed.connect(lambda msg: self._measured(
                job, None, f" The held-out check failed: {msg}"))
            job.cancelled.connect(lambda: self._measured(
                job, None, " Held-out check cancelled: nothing measured."))
        job.start()
        self._buttons()

    def _progressed(self, job: BackgroundJob, fraction: float, message: str) -> None:
        if job is not self.job:
            return
        self.progress.setValue(round(fraction * STEPS))
        if message and self.job_kind == "retrain":
            self.state.setText(message)
        elif message:  # the state line holds the result meanwhile
            self.progress.setFormat(f"{message} · %p%")

    def _stopped(self, job: BackgroundJob, message: str) -> None:
        if job is not self.job:  # closed meanwhile
            return
        self.prompt.setText("Not personalised")
        self.state.setText(message)
        self.retrain_button.show()
        self.cancel_button.setText("Close")
        self._buttons()

    def _retrained(self, job: BackgroundJob, result: Personalised) -> None:
        if job is not self.job:  # closed meanwhile: not used
            return
        self.result = result
        self.progress.setValue(STEPS)
        self.prompt.setText("Personalised")
        p = self.prompts
        measuring = len(set(p.rounds())) >= 2
        self.state.setText(result_text(result, self.model, " Measuring the held-out check "
                                       "on their own touches…" if measuring else None))
        self.cancel_button.setText("Close")
        if measuring:  # the personalised model is used meanwhile
            layout = self._layout
            self._launch("check", lambda progress, cancel: p.held_out_check(
                layout, progress=progress, cancel=cancel))
        self._buttons()
        self.personalised.emit(result)

    def _measured(self, job: BackgroundJob, check: HeldOutCheck | None,
                  note: str | None = None) -> None:
        if job is not self.job or self.result is None:  # closed meanwhile
            return
        self.progress.setFormat("%p%")
        self.progress.setValue(STEPS)
        self.result.check = check
        self.state.setText(result_text(self.result, self.model, note))
        self.cancel_button.setText("Close")
        self._buttons()
        if check is not None:
            self.measured.emit(self.result)


def describe(p: Personalised) -> str:
    """"personalised to this person with 1 touch per gesture (rf refit ...)"."""
    how = {"refit": "refit on its training windows plus theirs",
           "fine-tuned": "its output layers fine-tuned on theirs",
           "refit and fine-tuned": "forest refit, network's output layers fine-tuned"}[p.how]
    text = (f"personalised to this person with {p.per_gesture} touch"
            f"{'' if p.per_gesture == 1 else 'es'} per gesture ({p.windows} labelled "
            f"windows; {how})")
    c = p.check
    if c is not None:
        text += ("; held-out check " + (f"{c.before:.2f} as trained → " if c.before is not None
                                        else "") + f"{c.after:.2f} personalised")
    return text


def result_text(p: Personalised, model: WindowModel, note: str | None = None) -> str:
    """What was done, and what was measured (every number shown is measured); ``note``
    in place of the check while it has none."""
    name = display_name(model.config.model, model.config.overrides)
    n = f"their {p.windows} labelled windows ({p.per_gesture} per gesture at least)"
    done = {
        "refit": f"{name} refit on the fold's training windows plus {n}, as train --shots "
                 "trains.",
        "fine-tuned": f"{name}'s output layers fine-tuned on {n}, the rest as trained (live "
                      "fine-tunes for speed; train --shots joins the touches to the "
                      "training instead).",
        "refit and fine-tuned": f"{name}: the forest refit on the fold's training windows "
                                f"plus {n}, the network's output layers fine-tuned on them, "
                                "fused again with the same weight."}[p.how]
    c = p.check
    if c is None:
        return done + (note or " Nothing measured: a held-out check needs a second round "
                       "of touches (K = 2) to test each round on.")
    before = (f"as trained {c.before:.2f}, " if c.before is not None else
              "(the run has no view as trained to compare) ")
    return done + (f" Held-out check on their {c.touches} touches, each round predicted "
                   f"by the model personalised with the other{'s' if c.rounds > 2 else ''}: "
                   f"accuracy {before}personalised {c.after:.2f}.")
