"""How a finished recording ended: complete, or short of what was asked and why.

One function judges every recording the same way, so ``record``, ``collect``, the main
window and the collection console end a fault alike (docs/runner-api.md, "How a
recording ended"): the file's own summary (frames, events: a ``disconnect`` with a
reason and no ``reconnect`` after it is a device lost for good, ``overrun`` events are
frames the recorder lost, an engine ``error`` is a device that failed) plus what only the
live recorder knows (the write error that cut the file short, when it started and
stopped). The outcome is one line and an exit status: 0 when complete, 3
(:data:`~tactile_studio.errors.EXIT_INCOMPLETE`) when the user got less than asked;
what was recorded is kept either way.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tactile_studio.devices.engine_events import ConnectionLost, DeviceFailed, Reconnected
from tactile_studio.errors import EXIT_INCOMPLETE, EXIT_OK, IncompleteError, UserError
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_format import OVERRUN
from tactile_studio.storage.recording.recorder import Recorder


@dataclass(frozen=True)
class RecordingOutcome:
    """A finished recording judged: ``line`` is what the user is told."""

    path: str
    frames: int
    duration_s: float
    rate_hz: float
    malformed: int
    gaps: int
    problems: tuple[str, ...] = ()

    @property
    def complete(self) -> bool:
        return not self.problems

    @property
    def exit_code(self) -> int:
        return EXIT_OK if self.complete else EXIT_INCOMPLETE

    @property
    def summary_line(self) -> str:
        """``wrote x.h5: N frames, D s, R Hz, malformed M, gaps G``."""
        return (f"wrote {self.path}: {self.frames} frames, {self.duration_s:.2f} s, "
                f"{self.rate_hz:.1f} Hz, malformed {self.malformed}, gaps {self.gaps}")

    @property
    def line(self) -> str:
        """The one line: the summary when complete, else the file, every cause and what
        was kept."""
        if self.complete:
            return self.summary_line
        return (f"{self.path}: recording incomplete: {'; '.join(self.problems)}; kept "
                f"{self.frames} frames ({self.duration_s:.2f} s)")

    def raise_if_incomplete(self) -> None:
        """The CLI's ending: IncompleteError (exit 3) with :attr:`line`."""
        if not self.complete:
            raise IncompleteError(self.line)


def recording_outcome(summary: dict[str, Any], *, write_error: str | None = None,
                      started_at: float | None = None, ended_at: float | None = None,
                      reconnect_attempts: int | None = None) -> RecordingOutcome:
    """Judge a recording from its file's ``SessionFile.summary()`` and the live facts.

    ``started_at``/``ended_at`` are the recording's wall-clock start and stop (Unix s):
    a lost device is placed "N s into the recording" and "tried for M s" with them (else
    from its file row and the last event)."""
    path = str(summary.get("path", "?"))
    events = list(summary.get("events") or [])
    rate = float(summary.get("rate_hz") or 0.0)
    problems: list[str] = []
    if write_error:
        problems.append(_without_path(write_error, path))
    lost = _device_lost(events, rate, started_at, ended_at, reconnect_attempts)
    if lost:
        problems.append(lost)
    failed = [e for e in events if e.get("kind") == DeviceFailed.kind]
    if failed and not lost:
        problems.append(f"device failed: {failed[-1].get('message', '?')}")
    overruns = [e for e in events if e.get("kind") == OVERRUN]
    if overruns:
        n = sum(int(e.get("lost", 0)) for e in overruns)
        problems.append(f"{n} frames lost (the recorder fell a whole buffer behind "
                        f"{len(overruns)} time{'s' if len(overruns) != 1 else ''})")
    return RecordingOutcome(path=path, frames=int(summary.get("frames", 0)),
                            duration_s=float(summary.get("duration_s", 0.0)), rate_hz=rate,
                            malformed=int(summary.get("malformed", 0)),
                            gaps=int(summary.get("gaps", 0)), problems=tuple(problems))


def _without_path(line: str, path: str) -> str:
    """A one-line error without its leading file name (the outcome's line names it)."""
    for prefix in (f"{path}: ", f"{Path(path).name}: "):
        if line.startswith(prefix):
            return line[len(prefix):]
    return line


def _device_lost(events: list[dict[str, Any]], rate: float, started_at: float | None,
                 ended_at: float | None, attempts: int | None) -> str:
    """"device lost 8.0 s into the recording (why); tried to reconnect for 17.0 s (N
    attempts)" when the last loss (a ``disconnect`` with a reason) was never followed by
    a ``reconnect``; "" otherwise."""
    last = None
    for i, e in enumerate(events):
        if e.get("kind") == ConnectionLost.kind and e.get("reason"):
            last = i
    if last is None or any(e.get("kind") == Reconnected.kind for e in events[last + 1:]):
        return ""
    e = events[last]
    t = float(e.get("time") or 0.0)
    if started_at is not None and t:
        into = t - started_at
    else:
        into = int(e.get("frame", 0)) / rate if rate > 0 else 0.0
    end = ended_at if ended_at is not None else max(
        (float(x.get("time") or 0.0) for x in events[last:]), default=t)
    tried = max(0.0, end - t) if t else 0.0
    tries = f", {attempts} attempts" if attempts else ""
    return (f"device lost {into:.1f} s into the recording ({e['reason']}); tried to "
            f"reconnect for {tried:.1f} s{tries} without success")


def outcome_of(recorder: Recorder, reconnect_attempts: int | None = None) -> RecordingOutcome:
    """Judge a stopped recorder's recording (its file is opened and summarised)."""
    try:
        with SessionFile(recorder.path) as s:
            summary = s.summary()
    except UserError as exc:  # nothing readable was kept
        path = str(recorder.path)
        return RecordingOutcome(path, 0, 0.0, 0.0, 0, 0, problems=(
            _without_path(recorder.write_error or str(exc), path),))
    return recording_outcome(summary, write_error=recorder.write_error,
                             started_at=recorder.started_at, ended_at=recorder.stopped_at,
                             reconnect_attempts=reconnect_attempts)
