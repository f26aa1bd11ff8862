"""The main window's status bar: device state, rates, error counts and paint latency."""

from __future__ import annotations

from PySide6.QtWidgets import QLabel, QStatusBar, QWidget

from tactile_studio.acquisition import LiveAcquisition, LiveStatus
from tactile_studio.acquisition.events import (
    AcquisitionEvent,
    Health,
    RecordingStarted,
    RecordingStopped,
)


class LiveStatusBar(QStatusBar):
    """Permanent fields; ``update_status`` is called a few times a second."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.state = QLabel("disconnected")
        self.state.setObjectName("state")
        self.rate = QLabel()
        self.fps = QLabel()
        self.malformed = QLabel()
        self.dropped = QLabel()
        self.latency = QLabel()
        self.latency.setToolTip("Device-to-paint latency: paint time minus the newest "
                                "frame's host arrival time (median of the last second)")
        self.warning = QLabel()  # a device gone silent while recording (stream health)
        self.warning.setObjectName("healthWarning")
        self.warning.setStyleSheet("QLabel#healthWarning { background: #f5c542; color: #222;"
                                   " font-weight: bold; padding: 1px 6px; }")
        self.warning.hide()
        # a recording that ended short (write failed, device lost, frames lost): its one
        # line (acquisition/outcome.py), until the next recording starts
        self.fault = QLabel()
        self.fault.setObjectName("recordingFault")
        self.fault.setStyleSheet("QLabel#recordingFault { background: #c62828; color: white;"
                                 " font-weight: bold; padding: 1px 6px; }")
        self.fault.hide()
        self.remote = QLabel()  # "remote :22345" while experiment scripts may drive us
        self.remote.hide()
        self.addWidget(self.state, 1)
        self.addWidget(self.warning)
        self.addWidget(self.fault)
        for w in (self.remote, self.rate, self.fps, self.malformed, self.dropped, self.latency):
            self.addPermanentWidget(w)

    def follow(self, session: LiveAcquisition) -> None:
        """Show ``session``'s stream-health warnings (acquisition/stream_health.py) until the
        device sends again or the next recording starts, and a recording that ended short
        of what was asked (red, its one line) until the next one starts."""
        def on_event(event: AcquisitionEvent) -> None:
            match event:
                case Health(message=message, silent=silent):
                    self.warning.setText(f"\u26a0 {message}")
                    self.warning.setToolTip(message)
                    self.warning.setVisible(silent)
                case RecordingStarted():
                    self.warning.hide()
                    self.fault.hide()
                case RecordingStopped(message=message) if message:
                    self.warning.hide()
                    self.fault.setText(f"\u26a0 {message}")
                    self.fault.setToolTip(message)
                    self.fault.show()
        session.add_listener(on_event)

    def set_remote(self, text: str, tip: str = "") -> None:
        """The remote control's port (empty: off)."""
        self.remote.setText(text)
        self.remote.setToolTip(tip)
        self.remote.setVisible(bool(text))

    def update_status(self, st: LiveStatus, display_fps: float,
                      latency_ms: float | None) -> None:
        text = st.state_text()
        if st.error:
            text += f" — {st.error}"
        if st.recording:
            text += f" · recording {st.recorded_frames} frames"
        self.state.setText(text)
        self.state.setToolTip(text)
        self.state.setProperty("state", st.state)
        self.state.style().unpolish(self.state)
        self.state.style().polish(self.state)
        self.rate.setText(f"{st.measured_rate_hz:6.1f} Hz")
        self.fps.setText(f"display {display_fps:4.0f} fps")
        self.malformed.setText(f"malformed {st.malformed}")
        self.malformed.setToolTip(f"Malformed input dropped, by kind: {st.malformed_text()}")
        self.dropped.setText(f"dropped {st.dropped}")
        self.latency.setText("latency –" if latency_ms is None
                             else f"latency {latency_ms:5.1f} ms")
