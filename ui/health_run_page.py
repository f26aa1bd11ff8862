"""The wizard page that runs a check or calibration: prompt, array picture, progress."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
    QWizard,
    QWizardPage,
)

from tactile_studio.health.events import (
    Failed,
    LogbookReplaced,
    Misplaced,
    Phase,
    Progress,
    SpotMeasured,
    Warned,
)
from tactile_studio.health.health_check import HealthCheck
from tactile_studio.ui.array_picture import ArrayPicture

PHASE_TITLES = {"rest": "Rest: leave the sensor unloaded", "place": "Place the weight",
                "settle": "Settling (the skin relaxes over a few seconds)",
                "record": "Recording", "lift": "Lift the weight"}


class HealthRunPage(QWizardPage):
    """Starts a :class:`HealthCheck` from ``make_run`` when shown and follows its events.

    Complete (Next enabled) when the run ended with a result; an error is shown in words
    and the page offers Retry.
    """

    def __init__(self, title: str, make_run: Callable[[], HealthCheck]) -> None:
        super().__init__()
        self.setTitle(title)
        self.make_run = make_run
        self.run: HealthCheck | None = None
        self.phase = QLabel("")
        self.phase.setStyleSheet("font-size: 16pt; font-weight: bold")
        self.prompt = QLabel("")
        self.prompt.setWordWrap(True)
        self.prompt.setStyleSheet("font-size: 12pt")
        self.picture = ArrayPicture()
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.notice = QLabel("")  # the sensor logbook was damaged and set aside: one line
        self.notice.setWordWrap(True)
        self.notice.setStyleSheet("color: #b00020")
        self.notice.hide()
        self.placed_button = QPushButton("The weight is on (not detected)")
        self.placed_button.setToolTip("Use when the weight sits on a taxel that does not "
                                      "respond: the check records it as it is")
        self.placed_button.clicked.connect(self._confirm)
        self.cancel_button = QPushButton("Cancel check")
        self.cancel_button.clicked.connect(self.cancel)
        self.retry_button = QPushButton("Retry")
        self.retry_button.clicked.connect(self.start)
        buttons = QHBoxLayout()
        for b in (self.placed_button, self.cancel_button, self.retry_button):
            buttons.addWidget(b)
        buttons.addStretch(1)
        box = QVBoxLayout(self)
        box.addWidget(self.phase)
        box.addWidget(self.prompt)
        box.addWidget(self.picture, 1)
        box.addWidget(self.progress)
        box.addWidget(self.status)
        box.addWidget(self.notice)
        box.addLayout(buttons)
        self.timer = QTimer(self)
        self.timer.setInterval(50)
        self.timer.timeout.connect(self.poll)

    def initializePage(self) -> None:  # noqa: N802 - Qt name
        self.start()

    def cleanupPage(self) -> None:  # noqa: N802 - Qt name (Back pressed)
        self.cancel()

    def start(self) -> None:
        self.cancel()
        self.phase.setText("Starting…")
        self.prompt.setText("")
        self.status.setText("")
        self.status.setStyleSheet("")
        self.progress.setValue(0)
        self.retry_button.setVisible(False)
        self.cancel_button.setEnabled(True)
        self.placed_button.setEnabled(False)
        try:
            self.run = self.make_run().start()
        except Exception as exc:  # bad settings: say so on the page
            self.run = None
            self._failed(str(exc))
            return
        self.timer.start()
        self.completeChanged.emit()

    def cancel(self) -> None:
        if self.run is not None and self.run.running:
            self.run.cancel()
            self.run.join(10.0)
        self.timer.stop()

    def _confirm(self) -> None:
        if self.run is not None:
            self.run.confirm_placed()

    def poll(self) -> None:
        run = self.run
        if run is None:
            return
        for ev in run.events():
            match ev:
                case Phase(phase=phase, prompt=prompt, taxel=taxel):
                    self.phase.setText(PHASE_TITLES.get(phase, phase))
                    self.prompt.setText(prompt)
                    target = taxel if taxel and len(taxel) <= 3 else None
                    self.picture.mark(target=target, detected=None)
                    self.placed_button.setEnabled(phase == "place" and not run.placer.confirmed)
                case Misplaced(at=at, prompt=prompt):
                    self.prompt.setText(prompt)
                    self.picture.mark(target=self.picture.target, detected=at)
                case Warned(message=message):
                    self.status.setText(message)
                case LogbookReplaced(message=message):
                    self.notice.setText(message)
                    self.notice.show()
                case SpotMeasured(taxel=taxel):
                    verdicts = dict(self.picture.verdicts)
                    verdicts[taxel] = "measured"  # judged at the end
                    self.picture.mark(target=None, verdicts=verdicts)
                case Progress(fraction=fraction, message=message):
                    self.progress.setValue(int(fraction * 1000))
                    self.status.setText(message)
                case Failed(message=message):
                    self._failed(message)
        if not run.running:
            self.timer.stop()
            self.cancel_button.setEnabled(False)
            self.placed_button.setEnabled(False)
            if run.result is not None:
                self.phase.setText("Done")
                self.prompt.setText("Press Next for the results.")
                self.progress.setValue(1000)
            elif run.error is None:
                self._failed("the check stopped unexpectedly")
            self.completeChanged.emit()

    def _failed(self, message: str) -> None:
        self.phase.setText("Stopped")
        self.status.setText(message)
        self.status.setStyleSheet("color: #c0392b; font-weight: bold")
        self.retry_button.setVisible(True)

    def isComplete(self) -> bool:  # noqa: N802 - Qt name
        return self.run is not None and not self.run.running and self.run.result is not None


class HealthWizard(QWizard):
    """Set up → run → result on the wizard's own connection to a device; the wellness
    and calibration wizards differ only in their pages and the run they start."""

    def __init__(self, title: str, setup: QWizardPage,
                 result_page: Callable[[HealthRunPage], QWizardPage], size: tuple[int, int],
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle(title)
        self.setWizardStyle(QWizard.WizardStyle.ClassicStyle)
        self.setup = setup
        self.run_page = HealthRunPage(f"{title}: running", self._make_run)
        # "Cancel calibration", "Cancel wellness check": the button names what it stops
        self.run_page.cancel_button.setText(f"Cancel {title[0].lower()}{title[1:]}")
        self.result_page = result_page(self.run_page)
        for page in (self.setup, self.run_page, self.result_page):
            self.addPage(page)
        self.resize(*size)

    def _make_run(self) -> HealthCheck:
        raise NotImplementedError

    def done(self, code: int) -> None:
        self.run_page.cancel()
        super().done(code)
