"""A core long job (``fn(progress, cancel)``, see ``tactile_studio.jobs``) run on a thread
while the window stays responsive.

The job's progress is read by a timer on the GUI thread (Qt objects are never touched
from the worker), so a job may report as often as it likes. A user error ends it with its
one-line message; a programming error prints its traceback and shows its type and text.
"""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable
from functools import partial
from typing import Any

from PySide6.QtCore import QObject, QTimer, Signal

from tactile_studio.errors import Cancelled, UserError
from tactile_studio.jobs import CancelToken, ProgressFn
from tactile_studio.output_faults import fault_line


class BackgroundJob(QObject):
    progressed = Signal(float, str)
    finished = Signal(object)  # the job's return value
    failed = Signal(str)  # one line for the user
    cancelled = Signal()

    def __init__(self, fn: Callable[[ProgressFn, CancelToken], Any],
                 parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.token = CancelToken()
        self._fn = fn
        self._lock = threading.Lock()
        self._progress: tuple[float, str] | None = None
        # how the job ended: the signal to emit, on the GUI thread (set by the worker)
        self._outcome: Callable[[], None] | None = None
        self._thread = threading.Thread(target=self._run, name="background-job", daemon=True)
        self._timer = QTimer(self)
        self._timer.setInterval(100)
        self._timer.timeout.connect(self._deliver)

    @property
    def running(self) -> bool:
        return self._thread.is_alive() or self._timer.isActive()

    def start(self) -> None:
        self._thread.start()
        self._timer.start()

    def cancel(self) -> None:
        """Ask the job to stop at its next check; what it finished stays."""
        self.token.cancel()

    def wait(self, seconds: float) -> bool:
        """Block until the worker ends (tests, closing a window); True when it has."""
        self._thread.join(seconds)
        self._deliver()
        return not self._thread.is_alive()

    def _report(self, fraction: float, message: str = "") -> None:
        with self._lock:
            self._progress = (fraction, message)

    def _run(self) -> None:
        try:
            outcome: Callable[[], None] = partial(self.finished.emit,
                                                  self._fn(self._report, self.token))
        except Cancelled:
            outcome = self.cancelled.emit
        except UserError as exc:
            outcome = partial(self.failed.emit, str(exc))
        except Exception as exc:  # a bug: the traceback goes where developers look
            line = fault_line(exc)  # ... unless the place cannot be written: one line
            if line is None:
                traceback.print_exc()
            outcome = partial(self.failed.emit, line or f"{type(exc).__name__}: {exc}")
        with self._lock:
            self._outcome = outcome

    def _deliver(self) -> None:
        with self._lock:
            progress, self._progress = self._progress, None
            outcome = self._outcome if not self._thread.is_alive() else None
            if outcome is not None:
                self._outcome = None
        if progress is not None:
            self.progressed.emit(*progress)
        if outcome is None:
            return
        self._timer.stop()
        outcome()
