"""A wellness check or calibration running in a background thread, for a GUI to poll.

The wizard stays responsive: it starts a :class:`HealthCheck`, polls :meth:`events` from a
timer, forwards Cancel and "the weight is on" to it, and reads ``result`` or ``error``
at the end. Qt-free, so the same object is tested without a display.
"""

from __future__ import annotations

import logging
import queue
import threading
from typing import Any

from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.health.bench import Bench, Placer, SimulatedPlacer, Timing
from tactile_studio.health.calibration import CalibrationSpec, run_calibration
from tactile_studio.health.events import Failed, HealthEvent, LogbookReplaced, Progress
from tactile_studio.health.wellness import WellnessSpec, run_wellness
from tactile_studio.jobs import CancelToken
from tactile_studio.output_faults import fault_line
from tactile_studio.storage.books.logbook import Logbook


class HealthCheck:
    """One procedure on its own device connection, in a thread."""

    def __init__(self, device: str, settings: dict[str, Any], spec: WellnessSpec | CalibrationSpec,
                 auto: bool = False, out: str | None = None, timing: Timing = Timing()) -> None:
        self.device = create_device(device, settings)  # bad settings raise here, at once
        self.placer: Placer = SimulatedPlacer(self.device) if auto else Placer()
        self.spec, self.out, self.timing = spec, out, timing
        self.cancel_token = CancelToken()
        self.result: dict[str, Any] | None = None
        self.error: str | None = None
        self.fraction = 0.0
        self.engine: LiveStream | None = None
        self._bench: Bench | None = None
        self._events: queue.Queue[HealthEvent] = queue.Queue()
        self._thread = threading.Thread(target=self._run, name="health-run", daemon=True)

    def start(self) -> HealthCheck:
        self._thread.start()
        return self

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def join(self, timeout: float | None = None) -> bool:
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def cancel(self) -> None:
        self.cancel_token.cancel()

    def confirm_placed(self) -> None:
        if self._bench is not None:
            self._bench.confirm_placed()

    def events(self) -> list[HealthEvent]:
        """Everything that happened since the last call (never blocks)."""
        out: list[HealthEvent] = []
        while True:
            try:
                out.append(self._events.get_nowait())
            except queue.Empty:
                return out

    # ---- the thread ------------------------------------------------------------------
    def _emit(self, event: HealthEvent) -> None:
        self._events.put(event)

    def _progress(self, fraction: float, message: str) -> None:
        self.fraction = fraction
        self._emit(Progress(fraction, message))

    def _run(self) -> None:
        engine = self.engine = open_stream(self.device)
        try:
            # what is measured is stored: a damaged logbook is set aside first, said here
            with Logbook(on_damage="replace") as book:
                if book.notice:
                    self._emit(LogbookReplaced(book.notice))
            engine.start()
            if not engine.wait_frames(1, timeout=10.0):
                raise UserError(engine.error or f"device {self.device.name}: no frames in 10 s")
            self._bench = Bench(engine, self.placer, self.timing, self.cancel_token,
                                self._emit)
            if isinstance(self.spec, WellnessSpec):
                self.result = run_wellness(self._bench, self.spec, progress=self._progress)
            else:
                self.result = run_calibration(engine, self.spec, self.out,
                                              progress=self._progress, bench=self._bench)
        except Cancelled:
            self.error = "cancelled: nothing was stored"
            self._emit(Failed(self.error))
        except UserError as exc:
            self.error = str(exc)
            self._emit(Failed(self.error))
        except Exception as exc:  # a bug: keep the traceback in the log, tell the user
            line = fault_line(exc)  # ... unless the place cannot be written: one line
            if line is None:
                logging.getLogger(__name__).exception("health procedure failed")
            self.error = line or f"internal error: {type(exc).__name__}: {exc}"
            self._emit(Failed(self.error))
        finally:
            engine.stop()
