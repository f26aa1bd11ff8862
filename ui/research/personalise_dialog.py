"""Personalise to this person: the experimenter picks K, the dialog prompts "Perform
<gesture> now" for each of the run's gestures K times on the live stream (one labelled
window per prompt, taken once the touch is there; Skip / Redo), then the run's fold model
is retrained with those windows (learn/deploy/personalise.py: the prompts and the retraining
are there; this dialog only shows them)."""

from __future__ import annotations

import threading
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
from tactile_studio.learn.deploy.personalise import Personalised, TouchPrompts
from tactile_studio.learn.deploy.window_model import WindowModel


class PersonaliseDialog(QDialog):
    personalised = Signal(object)  # learn.deploy.personalise.Personalised

    def __init__(self, model: WindowModel, engine: Callable[[], Any],
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Personalise to this person")
        self.model, self.engine_fn = model, engine
        self.prompts: TouchPrompts | None = None
        self.result: Personalised | None = None
        self.k = QSpinBox()
        self.k.setRange(1, 2)
        self.k.setSuffix(" touch(es) per gesture")
        self.k.setToolTip("K labelled performances of every gesture: on virtual people K=1 "
                          "already lifts a new person's accuracy clearly (docs/learning.md)")
        self.start_button = QPushButton("Start")
        intro = QLabel(f"The participant performs each of the {len(model.labels)} gestures "
                       f"of {model.name} when asked; {model.config.model} is then retrained "
                       "with their touches.")
        intro.setWordWrap(True)
        self.prompt = QLabel("Pick K and press Start.")
        f = self.prompt.font()
        f.setPointSize(f.pointSize() + 6)
        f.setBold(True)
        self.prompt.setFont(f)
        self.prompt.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.prompt.setMinimumHeight(2 * self.prompt.fontMetrics().lineSpacing())
        self.state = QLabel("")
        self.state.setWordWrap(True)
        self.progress = QProgressBar()
        self.skip_button = QPushButton("Skip")
        self.skip_button.setToolTip("leave this gesture out (it keeps the run's training)")
        self.redo_button = QPushButton("Redo last")
        self.redo_button.setToolTip("record the last answered gesture again")
        self.cancel_button = QPushButton("Cancel")
        top = QHBoxLayout()
        top.addWidget(QLabel("K"))
        top.addWidget(self.k)
        top.addWidget(self.start_button)
        top.addStretch(1)
        buttons = QHBoxLayout()
        for b in (self.skip_button, self.redo_button):
            buttons.addWidget(b)
        buttons.addStretch(1)
        buttons.addWidget(self.cancel_button)
        lay = QVBoxLayout(self)
        lay.addWidget(intro)
        lay.addLayout(top)
        lay.addWidget(self.prompt)
        lay.addWidget(self.state)
        lay.addWidget(self.progress)
        lay.addLayout(buttons)
        self.timer = QTimer(self)
        self.timer.setInterval(50)
        self.timer.timeout.connect(self.poll)
        # the retraining runs in a thread (a network's fine-tuning can take a minute on a
        # busy CPU): the window stays responsive, this timer picks up its result
        self.retrain_timer = QTimer(self)
        self.retrain_timer.setInterval(100)
        self.retrain_timer.timeout.connect(self._retrained)
        self._retrain: dict[str, Any] = {}
        self.start_button.clicked.connect(self.start)
        self.skip_button.clicked.connect(self.skip)
        self.redo_button.clicked.connect(self.redo)
        self.cancel_button.clicked.connect(self.reject)
        self._buttons()
        self.resize(520, 260)

    def done(self, result: int) -> None:  # Cancel / Close / the window closed
        """Stops watching the stream; a retraining still running is not used."""
        self.timer.stop()
        self.retrain_timer.stop()
        self._retrain = {}
        super().done(result)

    def _engine(self) -> Any:
        engine = self.engine_fn()
        if engine is None:
            raise UserError("no device: connect one, then personalise")
        return engine

    def start(self) -> bool:
        try:
            engine = self._engine()
        except UserError as exc:
            self.state.setText(str(exc))
            return False
        self.prompts = TouchPrompts(self.model, self.k.value())
        self.prompts.begin(engine)
        self.progress.setRange(0, len(self.prompts.prompts))
        self.k.setEnabled(False)
        self.start_button.setEnabled(False)
        self._show()
        self.timer.start()
        return True

    def skip(self) -> None:
        if self.prompts is not None and not self.prompts.done:
            self.prompts.skip(self._engine())
            self._next()

    def redo(self) -> None:
        if self.prompts is not None and self.prompts.answers:
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
        running = p is not None and not p.done
        self.skip_button.setEnabled(running)
        self.redo_button.setEnabled(running and bool(p.answers))

    def _finish(self) -> None:
        p = self.prompts
        assert p is not None
        self.progress.setValue(len(p.prompts))
        self._buttons()
        if not p.answers:
            self.prompt.setText("No touches recorded")
            self.state.setText("every prompt was skipped: the run's model stays in use")
            return
        self.prompt.setText("Retraining…")
        self.state.setText(f"{len(p.answers)} labelled touches; {self.model.config.model} "
                           "is retrained with them")
        try:
            layout = self._engine().layout
        except UserError as exc:
            self.prompt.setText("Not personalised")
            self.state.setText(str(exc))
            return
        job: dict[str, Any] = {}
        self._retrain = job

        def work() -> None:
            try:
                job["result"] = p.personalise(layout)
            except UserError as exc:
                job["error"] = str(exc)

        job["thread"] = threading.Thread(target=work, name="personalise", daemon=True)
        job["thread"].start()
        self.retrain_timer.start()

    def _retrained(self) -> None:
        job = self._retrain
        if not job or job["thread"].is_alive():
            return
        self.retrain_timer.stop()
        self._retrain = {}
        if "result" not in job:
            self.prompt.setText("Not personalised")
            self.state.setText(job.get("error") or "the retraining failed (see the log)")
            return
        self.result = job["result"]
        self.prompt.setText("Personalised")
        self.state.setText(describe(self.result))
        self.personalised.emit(self.result)
        self.cancel_button.setText("Close")


def describe(p: Personalised) -> str:
    """"personalised to this person with 1 touch per gesture (rf refit ...)"."""
    how = ("refit on its training windows plus theirs" if p.how == "refit" else
           "its output layers fine-tuned on theirs")
    return (f"personalised to this person with {p.per_gesture} touch"
            f"{'' if p.per_gesture == 1 else 'es'} per gesture ({p.windows} labelled "
            f"windows; {how})")
