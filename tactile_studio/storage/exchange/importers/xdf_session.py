"""One tactile stream of a loaded XDF file -> one session (exchange/importers/xdf.py plans which):
its frames kept only as the layout stores them (the rest left out and counted, never
cast), timestamps that no recording has refused, the file's markers at its rows
(exchange/importers/xdf_markers.py), its other numeric streams as auxiliary signals, and the
breaks pyxdf found as gaps."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.jobs import CancelToken, ProgressFn
from tactile_studio.sensor.layout import Layout
from tactile_studio.storage.exchange.importers._common import (
    ImportedSession,
    NoFramesError,
    import_session_id,
    write_session,
)
from tactile_studio.storage.exchange.importers.xdf_info import first, ours, stream_name, text
from tactile_studio.storage.exchange.importers.xdf_markers import MarkerReader
from tactile_studio.storage.exchange.input_files import unrepresentable_rows
from tactile_studio.storage.exchange.xdf_scan import MAX_RATE_HZ
from tactile_studio.storage.exchange.xdf_session_fields import session_fields
from tactile_studio.storage.format.aux_signals import AuxSignal
from tactile_studio.storage.format.segments import is_segment_start
from tactile_studio.terminal import shown


def _unnamed_breaks(segments: list[Any], events: list[tuple[str, int, float, dict[str, Any]]]
                    ) -> list[int]:
    """The rows where pyxdf's jitter segments start that no marker already names as a
    break (a ``gap`` or a resume's segment start, within a row): our own export's
    reconnects and resumes are gaps already, counted once (``info``'s gaps)."""
    named = {row for kind, row, _t, detail in events
             if kind == "gap" or is_segment_start({"kind": kind, **detail})}
    return [int(a) for a, _b in segments[1:]
            if not named & {int(a) - 1, int(a), int(a) + 1}]




@dataclass
class XdfReport:
    """What an import says beyond its sessions: tactile streams not imported (no
    samples, no frames it can store, timestamps no recording has), what was imported
    short of what the file recorded (cut, damaged, frames left out: the CLI exits 3) and
    notes (markers kept as text)."""

    skipped: list[str] = field(default_factory=list)
    short: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@dataclass
class _Frames:
    """A tactile stream's frames as the session stores them: rows the layout cannot
    hold as they are, or whose time is not finite or goes back, left out and counted."""

    raw: np.ndarray
    times: np.ndarray
    rows: np.ndarray          # the stream's sample number of each kept frame
    left_out: Counter[str]

    @classmethod
    def of(cls, s: dict[str, Any], lay: Layout) -> _Frames:
        values = s["time_series"]
        times = np.asarray(s["time_stamps"], dtype=np.float64)
        bad, kinds = unrepresentable_rows(np.asarray(values), lay.raw_dtype)
        finite = np.isfinite(times)
        ahead = np.maximum.accumulate(np.where(finite, times, -np.inf))
        back = finite & (times < np.concatenate(([-np.inf], ahead[:-1])))
        kinds.update(bad_time=int((~finite & ~bad).sum()), time_back=int((back & ~bad).sum()))
        keep = ~(bad | ~finite | back)
        rows = np.flatnonzero(keep)
        raw = np.asarray(values)[keep].astype(lay.raw_dtype) if len(rows) \
            else np.zeros((0, lay.n_channels), lay.raw_dtype)
        return cls(raw, times[keep], rows, +kinds)

    def rate_line(self) -> str:
        """Why these timestamps are no recording's ("" when they are plausible): frames
        closer than 1 / MAX_RATE_HZ apart (a nominal rate of 1e300 Hz squeezed 200
        frames into nothing)."""
        d = np.diff(self.times)
        d = d[d > 0]
        n = len(self.times)
        if n < 2:
            return ""
        rate = 1.0 / float(np.median(d)) if d.size else float("inf")
        if rate <= MAX_RATE_HZ:
            return ""
        span = float(self.times[-1] - self.times[0])
        return (f"its timestamps put {n:,} frames in {span:.3g} s ({rate:.3g} Hz), not a "
                f"plausible rate (at most {MAX_RATE_HZ:,.0f} Hz)")

    def left_out_line(self, total: int) -> str:
        if not self.left_out:
            return ""
        kinds = ", ".join(f"{KIND_WORDS.get(k, k)} {v:,}" for k, v in self.left_out.items())
        return (f"{sum(self.left_out.values()):,} of {total:,} frames left out: values or "
                f"times it cannot store as they are ({kinds})")


KIND_WORDS = {"not_finite": "NaN or infinite", "out_of_range": "beyond the layout's range",
              "not_whole": "not whole counts", "not_a_number": "not numbers",
              "bad_time": "time not finite", "time_back": "time going back"}


def _marker_stream_is_ours(m: dict[str, Any], frame_stream: str,
                           tactile_names: set[str]) -> bool | None:
    """Whether ``m``'s JSON is read as our markers for ``frame_stream``'s session: True
    for our marker stream (``desc/tactile_studio/format`` json) of this frame stream or
    of none named in the file; None: ours, but another tactile stream's (not added)."""
    desc = ours(m)
    if text(desc, "format") != "json":
        return False
    for_stream = text(desc, "frame_stream")
    if for_stream and for_stream != frame_stream and for_stream in tactile_names:
        return None
    return True


@dataclass(frozen=True)
class XdfStreamSource:
    """One tactile stream of an XDF file and what its session takes from the rest of
    the file: the file (``path``, its ``sha``, the file-wide ``meta``), the stream as
    pyxdf read it and its layout, the file's string streams (``markers``), the other
    instruments' signals (``aux``) and the names of the tactile streams imported."""

    path: Path
    sha: str
    meta: dict[str, Any]
    stream: dict[str, Any]
    layout: Layout
    markers: list[dict[str, Any]]
    aux: list[AuxSignal]
    tactile_names: set[str]


def session_job(source: XdfStreamSource, out: Path, report: XdfReport,
                cancel: CancelToken | None, force: bool = False
                ) -> Callable[[ProgressFn], Path]:
    """The job writing ``source``'s session to ``out``; what cannot be imported whole
    is said in ``report`` now, before any job runs."""
    path, sha, s, lay, meta = source.path, source.sha, source.stream, source.layout, source.meta
    others, aux, tactile_names = source.markers, source.aux, source.tactile_names
    name = stream_name(s)
    frames = _Frames.of(s, lay)
    said = f"{path}: stream '{shown(name)}'"
    why = frames.rate_line()
    if why:
        raise NoFramesError(f"{said}: {why}; nothing imported")
    if not len(frames.rows):
        raise NoFramesError(f"{said}: none of its {len(s['time_stamps']):,} frames can be "
                            f"stored ({frames.left_out_line(len(s['time_stamps']))}), "
                            "nothing imported")
    lost = frames.left_out_line(len(s["time_stamps"]))
    if lost:
        report.short.append(f"{said}: {lost}")
    times = frames.times
    markers = MarkerReader(times, lay.n_channels)
    for m in others:
        is_ours = _marker_stream_is_ours(m, name, tactile_names)
        if is_ours is None:
            continue
        for sample, t in zip(m["time_series"], m["time_stamps"]):
            markers.add(stream_name(m), list(sample), float(t), is_ours)
    trials = markers.trial_list()
    if markers.refused_line():
        report.notes.append(f"{said}: {markers.refused_line()}")
    rate = float(text(s["info"], "nominal_srate"))
    desc = ours(s)
    metadata = {
        "session_id": import_session_id("xdf", sha, name),
        # our own export's protocol, condition, orders, seeds, sensor and calibration,
        # each field checked (storage/exchange/xdf_session_fields.py); the BIDS entities win
        **session_fields(first(desc, "session")),
        "participant": meta.get("participant") or text(desc, "participant"),
        **{k: v for k, v in meta.items() if k != "participant"},
        "source": "import:xdf", "original_file": path.name, "stream": name,
        "clock": "xdf: device_time and host_time are the file's common clock (s)",
    }
    device = {"plugin": "import", "format": "xdf", "file": str(path), "stream": name,
              "nominal_rate_hz": rate, "rate_hz": rate,
              "source_id": text(s["info"], "source_id")}
    # pyxdf's segments are sample numbers of the stream; frames left out shift the rows
    segments = [(int(np.searchsorted(frames.rows, a)), b)
                for a, b in s["info"].get("segments") or []]

    def job(progress: ProgressFn) -> Path:
        n = len(times)
        gaps = [("gap", a, float(times[a]), {"cause": "xdf",
                                              "seconds": round(float(times[a] - times[a - 1]), 6)})
                for a in _unnamed_breaks(segments, markers.events) if 0 < a < n]
        session = ImportedSession(
            lay, device, metadata, frames.raw, times, trials,
            counters={"malformed_by_kind": dict(frames.left_out)} if frames.left_out else None,
            events=gaps + markers.events, baselines=markers.baselines, aux=aux)
        return write_session(out, session, progress, cancel, overwrite=force)

    return job
