"""The connection status the device panel and the status bar show, as plain data."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class LiveStatus:
    """Everything the device panel and status bar show about the connection."""

    device: str | None
    state: str
    error: str | None
    frames: int = 0
    measured_rate_hz: float = 0.0
    device_rate_hz: float = 0.0
    malformed: int = 0
    malformed_by_kind: dict[str, int] = field(default_factory=dict)
    dropped: int = 0
    gaps: int = 0
    reconnects: int = 0
    reconnect_attempts: int = 0
    recording: str | None = None
    recorded_frames: int = 0

    def state_text(self) -> str:
        """One line such as 'serial: reconnecting (attempt 3)' or 'No device connected'."""
        if self.device is None:
            return "No device connected"
        state = self.state
        if state == "reconnecting":
            state += f" (attempt {self.reconnect_attempts})"
        return f"{self.device}: {state}"

    def malformed_text(self) -> str:
        """Dropped input by kind, most frequent first: "3 short, 1 non_numeric" (or "none")."""
        return format_malformed(self.malformed_by_kind)

    def detail_lines(self) -> list[str]:
        """The device panel's lines under the state (empty without a device)."""
        if self.device is None:
            return []
        return [f"{self.measured_rate_hz:.1f} Hz measured · {self.frames} frames",
                f"malformed: {self.malformed_text()}",
                f"dropped {self.dropped} · gaps {self.gaps} · reconnects {self.reconnects}"
                f" (attempts {self.reconnect_attempts})"]


def format_malformed(by_kind: dict[str, int]) -> str:
    """Counts by kind as '3 short, 1 non_numeric': most frequent first, ties by name;
    'none' when nothing was dropped."""
    counts = sorted(((int(n), str(k)) for k, n in by_kind.items() if n),
                    key=lambda nk: (-nk[0], nk[1]))
    return ", ".join(f"{n} {k}" for n, k in counts) or "none"
