"""Which stretch of a session the player's strip chart shows.

Live, the chart shows the last 10 s; a player knows what comes next, so a trial jumped to
is shown centred, with what came before and after it, and the chart then stands still
while the cursor runs up to its middle and scrolls with the cursor from there on (the
cursor never leaves the view and the view never jumps while playing). A cursor moved
outside the view (a click far along the timeline) is centred. The view stays inside the
session when the session is longer than the view.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class ChartWindow:
    """``seconds`` of session time starting at ``start`` (session seconds)."""

    seconds: float = 10.0
    duration: float = 0.0
    start: float = 0.0

    @property
    def span(self) -> tuple[float, float]:
        return self.start, self.start + self.seconds

    def _clamp(self, start: float) -> float:
        return float(min(max(start, 0.0), max(self.duration - self.seconds, 0.0)))

    def centre_on(self, first_s: float, last_s: float) -> tuple[float, float]:
        """Centre the stretch ``first_s..last_s`` (a trial) in the view; one too long to
        fit with room around it (a 12 s performance) starts a tenth into the view."""
        if last_s - first_s > 0.8 * self.seconds:
            self.start = self._clamp(first_s - 0.1 * self.seconds)
        else:
            self.start = self._clamp((first_s + last_s) / 2 - self.seconds / 2)
        return self.span

    def follow(self, cursor_s: float) -> tuple[float, float]:
        """The view for the cursor at ``cursor_s`` (see the module doc)."""
        t0, t1 = self.span
        if not t0 <= cursor_s <= t1 or cursor_s > t0 + self.seconds / 2:
            self.start = self._clamp(cursor_s - self.seconds / 2)
        return self.span
