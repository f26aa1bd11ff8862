"""Starting the GUI and rendering it offscreen; the CLI's ``gui`` and ``snapshot`` call these."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication

from tactile_studio.errors import UserError
from tactile_studio.jobs import signals_handled
from tactile_studio.ui.application import ensure_app
from tactile_studio.ui.main_window import MainWindow, wait_for
from tactile_studio.ui.write_faults import write_image


def run_gui(device: str, settings: dict[str, Any], connect: bool = True,
            lsl: bool = False, markers: list[str] | None = None,
            silence_warning_s: float | None = None) -> int:
    """Show the main window connected to ``device`` and run until it is closed;
    ``lsl`` switches "Stream to LSL" on; ``markers``: LSL marker streams every recording
    takes in (acquisition/marker_recording.py); ``silence_warning_s``: how long a device
    may be silent while recording before it is said (acquisition/stream_health.py)."""
    app = ensure_app()
    window = MainWindow(device=device, settings=settings, connect=connect)
    window.acquisition.marker_streams = tuple(markers or ())
    if silence_warning_s is not None:
        window.acquisition.silence_warning_s = silence_warning_s
    if lsl and not window.panel.set_lsl(True):
        window.shutdown()
        raise UserError(window.panel.error_text() or "cannot stream to LSL")
    window.show()
    with close_on_signals(app):
        return int(app.exec())


@contextmanager
def close_on_signals(app: QApplication) -> Iterator[None]:
    """While active, Ctrl-C in the terminal or SIGTERM (a ``kill``, a logout) closes every
    window as its close button does: a recording or a collection session is finished and
    its file closed, not cut off mid-write."""

    def close_all() -> None:
        app.closeAllWindows()
        app.quit()

    def handler(signum: int, frame: object) -> None:
        QTimer.singleShot(0, close_all)

    # Python runs a signal handler only between bytecodes: this lets it in while Qt idles
    wake = QTimer(app)
    wake.timeout.connect(lambda: None)
    wake.start(200)
    try:
        with signals_handled(handler, signal.SIGINT, signal.SIGTERM):
            yield
    finally:
        wake.stop()
        wake.deleteLater()


TOUCH_KPA = 2.0        # a snapshot waits this long for a touch this firm...
TOUCH_WAIT_S = 4.0     # ...after its seconds of live data: an untouched map is a blank picture
TOUCH_PEAK_S = 0.8     # then the firmest frame of that touch is the picture


def _wait_for_touch(window: MainWindow) -> Any:
    """Up to TOUCH_WAIT_S more for a frame with a touch, painted at once (the simulator's
    demo begins after 3 s of idle for the tare, so ``--seconds 3`` caught an empty map);
    returns that frame (None: no touch came, the picture shows the map as it is)."""
    deadline = time.monotonic() + TOUCH_WAIT_S
    while time.monotonic() < deadline:
        frame = window.live.latest()
        if frame is not None and not frame.provisional_baseline \
                and float(np.nanmax(frame.normal)) >= TOUCH_KPA:
            frame = _firmest(window, frame, time.monotonic() + TOUCH_PEAK_S)
            window.hold_frame(frame)  # the picture shows this touch, not a later gap
            return frame
        wait_for(0.02)
    return None


def _firmest(window: MainWindow, best: Any, until: float) -> Any:
    """The firmest frame of a touch that has begun (its peak, not its first instant)."""
    while time.monotonic() < until:
        wait_for(0.02)
        frame = window.live.latest()
        if frame is not None and float(np.nanmax(frame.normal)) > float(np.nanmax(best.normal)):
            best = frame
    return best


def snapshot(device: str, settings: dict[str, Any], seconds: float, out: str | os.PathLike,
             virtual: bool = False, size: tuple[int, int] = (1280, 800),
             hover: str | None = None) -> Path:
    """Render the main window after ``seconds`` of live data and save it as a PNG.

    ``hover`` names a taxel (e.g. "C3") whose readout is shown as if the pointer
    rested on it.
    """
    out = Path(out)
    if not out.parent.is_dir():
        raise UserError(f"{out}: folder {out.parent} does not exist")
    ensure_app()
    window = MainWindow(device=device, settings=settings, connect=False, persist=False)
    try:
        window.resize(*size)
        window.set_virtual(virtual)
        window.show()
        if not window.panel.connect_device():
            raise UserError(window.panel.error_text() or f"cannot connect to {device}")
        if hover:
            window.hover_taxel(hover)
        wait_for(seconds)
        touch = _wait_for_touch(window)
        st = window.acquisition.status()
        if st.error:
            raise UserError(f"device {device}: {st.error}")
        window.refresh_status()
        if touch is None:  # else the touch is painted: a newer frame may be a gap
            window.tick()
        wait_for(0.05)
        write_image(window.grab(), out)  # an unwritable place: its OSError, one line
    finally:
        window.shutdown()
        window.close()
        window.deleteLater()
    return out
