"""One lifecycle for the research tabs that run a job (Train, Sweep): start -> poll ->
cancel -> finished, written once so a new job panel cannot forget to stop its timer,
re-enable Start, or read a job's last event differently from the others.

A subclass makes ``start_button``, ``cancel_button`` and ``status`` and implements
:meth:`on_event` (each typed :mod:`~tactile_studio.learn.experiments.job_events` event) and
:meth:`on_finished`; it starts a job with :meth:`launch`. The job is any object with
``poll()``, ``cancel()``, ``running`` and ``finished`` (TrainJob, SweepJob).
"""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QWidget

from tactile_studio.learn.experiments.job_events import JobEvent


class JobPanel(QWidget):
    CANCELLING = "cancelling…"  # the message line after Cancel (a subclass says what stays)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.job: Any = None
        self.timer = QTimer(self)
        self.timer.setInterval(100)
        self.timer.timeout.connect(self.poll)

    # --- for subclasses ----------------------------------------------------------------
    def on_event(self, job: Any, event: JobEvent) -> None:
        """One event of the running job (progress, epochs, tasks…)."""

    def after_events(self, job: Any) -> None:
        """After each poll's events (counters that change with time)."""

    def on_finished(self, job: Any) -> None:
        """The job ended: ``job.finished`` is its Done, Cancelled or Failed event."""

    def before_cancel(self) -> None:
        """Cancel was asked for (e.g. drop queued runs)."""

    # --- the lifecycle -----------------------------------------------------------------
    def launch(self, job: Any, message: str) -> None:
        """Show ``job`` (already started) as running and poll it until it ends."""
        self.job = job
        self.status.setText(message)
        self._set_running(True)
        self.timer.start()

    def cancel(self) -> None:
        if self.job is not None and self.job.running:
            self.before_cancel()
            self.job.cancel()
            self.status.setText(self.CANCELLING)

    def _set_running(self, on: bool) -> None:
        self.start_button.setEnabled(not on)
        self.cancel_button.setEnabled(on)

    def poll(self) -> None:
        job = self.job
        if job is None:
            return
        for event in job.poll():
            self.on_event(job, event)
        self.after_events(job)
        if job.finished is not None:
            self.timer.stop()
            self.on_finished(job)
