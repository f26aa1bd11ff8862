"""Playing a recorded session: frames ↔ time, trial spans, events, a play clock, and a
run's prediction over time. Qt-free; the session player widget only presents this.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.protocol.flag_summary import trial_reason
from tactile_studio.protocol.quality import FLAG_TEXT, FLAGS
from tactile_studio.sensor.decode import decode
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.trials import trial_number

ANY_FLAG = "*"  # the player's "flagged (any reason)" filter


def flag_filters(trials: list[TrialSpan]) -> list[tuple[str, str | None]]:
    """The player's trial filters for a session: all, flagged (any), then each flag its
    trials carry, in words, with counts: ("no contact (3)", "no_contact")."""
    flagged = [t for t in trials if t.flags]
    out: list[tuple[str, str | None]] = [(f"All trials ({len(trials)})", None),
                                         (f"Flagged ({len(flagged)})", ANY_FLAG)]
    present = {f for t in flagged for f in t.flags}
    for f in [*FLAGS, *sorted(present - set(FLAGS))]:
        if f in present:
            n = sum(f in t.flags for t in trials)
            out.append((f"{FLAG_TEXT.get(f, f)} ({n})", f))
    return out


@dataclass
class TrialSpan:
    index: int
    gesture: str
    status: str
    start: int
    end: int
    flags: list[str] = field(default_factory=list)
    reason: str = ""  # why it is flagged, in words (protocol/flag_summary.trial_reason)

    def shows(self, flag: str | None) -> bool:
        """True when the player's flag filter ``flag`` keeps this trial: None all trials,
        ``ANY_FLAG`` any flagged one, else trials with that flag."""
        return flag is None or (bool(self.flags) if flag == ANY_FLAG else flag in self.flags)

    @property
    def number(self) -> int:
        """The trial's number as people see it (from 1; ``index`` is the file's)."""
        return trial_number(self.index)


@dataclass
class EventMark:
    frame: int
    kind: str
    text: str


@dataclass
class AuxTrack:
    """An auxiliary signal's first channel on the frame axis (``frames``: fractional
    frame position of each sample), for drawing beside the touch."""

    name: str
    label: str
    unit: str
    frames: np.ndarray
    values: np.ndarray


def aux_tracks(session: SessionFile, n_frames: int) -> list[AuxTrack]:
    """Every auxiliary signal (storage/format/aux_signals.py) placed by its own timestamps on
    the frames' host clock; samples outside the recording are left out."""
    if n_frames < 1:
        return []
    host = session.column("host_time", 0, n_frames).astype(np.float64)
    rows = np.arange(n_frames, dtype=np.float64)
    out = []
    for sig in session.aux_signals():
        inside = (sig.time >= host[0]) & (sig.time <= host[-1])
        if not inside.any():
            continue
        out.append(AuxTrack(sig.name, sig.labels[0] if sig.labels else "", sig.unit,
                            np.interp(sig.time[inside], host, rows),
                            sig.values[inside, 0]))
    return out


class SessionPlayback:
    """A session file opened for playing (kept open until :meth:`close`)."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.session = SessionFile(self.path)
        s = self.session
        self.layout = s.layout
        self.n_frames = s.n_frames
        if self.n_frames < 1:
            s.close()
            raise UserError(f"{self.path}: the session holds no frames")
        t = s.column("device_time", 0, self.n_frames).astype(np.float64)
        if self.n_frames > 1 and not np.all(np.diff(t) >= 0) or t[-1] <= t[0]:
            t = s.column("host_time", 0, self.n_frames).astype(np.float64)
        self.times = t - t[0]
        self.raw = s.raw()
        self.trials = sorted(
            (TrialSpan(tr.index, tr.gesture, tr.status.value, max(0, tr.start_sample),
                       min(self.n_frames, tr.end_sample), list(tr.flags), trial_reason(tr))
             for tr in s.trials),
            key=lambda sp: sp.start)
        self.events = [self._event(e) for e in s.events]
        self.metadata = s.metadata
        self.aux = aux_tracks(s, self.n_frames)

    def _event(self, e: dict[str, Any]) -> EventMark:
        frame = e.get("frame", e.get("index", e.get("sample")))
        if frame is None and "time" in e:
            frame = self.frame_at(float(e["time"]) - float(self._t0_host()))
        kind = str(e.get("kind") or e.get("type") or "event")
        text = str(e.get("text") or e.get("note") or e.get("message") or kind)
        return EventMark(int(min(max(int(frame or 0), 0), self.n_frames - 1)), kind, text)

    def _t0_host(self) -> float:
        return float(self.session.column("host_time", 0, 1)[0])

    def close(self) -> None:
        self.session.close()

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def gestures(self) -> list[str]:
        return sorted({t.gesture for t in self.trials if t.gesture})

    # --- time ------------------------------------------------------------------------------
    def time_of(self, frame: int) -> float:
        return float(self.times[int(np.clip(frame, 0, self.n_frames - 1))])

    def frame_at(self, seconds: float) -> int:
        """The last frame at or before ``seconds`` from the start."""
        i = int(np.searchsorted(self.times, seconds, side="right")) - 1
        return int(np.clip(i, 0, self.n_frames - 1))

    def trial_at(self, frame: int) -> TrialSpan | None:
        for t in self.trials:
            if t.start <= frame < t.end:
                return t
        return None

    def trial_near(self, frame: int) -> TrialSpan | None:
        """The trial ``frame`` is in, else the last one begun before it (what the
        player's trial box shows as the cursor moves); None before the first."""
        inside = self.trial_at(frame)
        if inside is not None:
            return inside
        begun = [t for t in self.trials if t.start <= frame]
        return begun[-1] if begun else None

    def trial(self, index: int) -> TrialSpan:
        for t in self.trials:
            if t.index == index:
                return t
        raise UserError(f"{self.path}: no trial {trial_number(index)}")

    # --- frames ----------------------------------------------------------------------------
    def frame(self, i: int, virtual: bool = False):
        """Decoded stress of frame ``i`` (normal, shear_x, shear_y; shear None without)."""
        i = int(np.clip(i, 0, self.n_frames - 1))
        frames = decode(self.layout, self.raw[i:i + 1], self.session.baseline(i), virtual)
        sx = None if frames.shear_x is None else frames.shear_x[0]
        sy = None if frames.shear_y is None else frames.shear_y[0]
        return frames.normal[0], sx, sy, frames.units


def session_history(pb: SessionPlayback, frame: int, taxels: list[tuple[int, int]],
                    quantity: str = "normal", seconds: float = 10.0, max_points: int = 600,
                    window: tuple[float, float] | None = None):
    """The strip chart's data (physical taxels) as the live view's
    :class:`~tactile_studio.live.view.History`: the ``seconds`` before ``frame`` (t <= 0,
    as live), or with ``window`` the frames of that stretch of session time, t in session
    seconds (the player's :class:`~tactile_studio.playback.chart.ChartWindow`)."""
    from tactile_studio.live.view import QUANTITIES, History

    if quantity not in QUANTITIES:
        raise ValueError(f"quantity {quantity!r} not in {QUANTITIES}")
    if window is None:
        end = int(np.clip(frame, 0, pb.n_frames - 1)) + 1
        start, zero = pb.frame_at(pb.time_of(end - 1) - seconds), pb.times[end - 1]
    else:
        start = pb.frame_at(window[0])
        end, zero = min(pb.frame_at(window[1]) + 1, pb.n_frames), 0.0
    step = max(1, (end - start) // max_points)
    rows = np.arange(start, end, step)
    fr = decode(pb.layout, pb.raw[rows], pb.session.baseline(start), False)
    if quantity == "normal" or fr.shear_x is None:
        q = fr.normal
    elif quantity == "shear_x":
        q = fr.shear_x
    elif quantity == "shear_y":
        q = fr.shear_y
    else:
        q = np.hypot(fr.shear_x, fr.shear_y)
    values = np.stack([q[:, r, c] for r, c in taxels], axis=1) if taxels else \
        np.zeros((len(rows), 0), np.float32)
    return History(t=pb.times[rows] - zero, values=values.astype(np.float32),
                   names=[pb.layout.taxel_name(r, c) for r, c in taxels], quantity=quantity,
                   units=fr.units)


class PlayClock:
    """Where playback is: advanced by wall-clock seconds × speed, optionally looping a span."""

    def __init__(self, playback: SessionPlayback) -> None:
        self.pb = playback
        self.frame = 0
        self.speed = 1.0
        self.playing = False
        self.loop: tuple[int, int] | None = None
        self._t = 0.0

    def seek(self, frame: int) -> int:
        self.frame = int(np.clip(frame, 0, self.pb.n_frames - 1))
        self._t = self.pb.time_of(self.frame)
        return self.frame

    def step(self, n: int = 1) -> int:
        return self.seek(self.frame + n)

    def loop_trial(self, span: TrialSpan | None) -> None:
        self.loop = None if span is None else (span.start, max(span.end - 1, span.start))
        if self.loop is not None:
            self.seek(self.loop[0])

    def advance(self, wall_seconds: float) -> int:
        """Move on by ``wall_seconds`` of real time at ``speed``; stops at the end (or wraps
        inside the looped span)."""
        if not self.playing:
            return self.frame
        self._t += wall_seconds * self.speed
        frame = self.pb.frame_at(self._t)
        if self.loop is not None:
            a, b = self.loop
            if frame > b:
                frame, self._t = a, self.pb.time_of(a)
        elif frame >= self.pb.n_frames - 1:
            self.playing = False
        self.frame = frame
        return frame
