"""XDF files (LabRecorder's, or our own export) -> sessions: ``import xdf``.

The file's chunks are checked first (storage/xdf_scan.py: what it claims against what it
holds, a cut or damaged file imported with what it holds and said), then read with pyxdf,
clock synchronisation and jitter removal on, so every stream is on the file's common
clock. Each tactile stream becomes one session:

* a Tactile Studio frame stream (``desc/tactile_studio`` names its layout, raw content);
* else, a regular numeric stream of type Tactile/Touch/Pressure (or none) whose channel
  count implies a layout (180 -> shearsense-6x6, N*N with N >= 4 -> grid-NxN);
* or the stream named with ``stream`` (and ``layout``, else from its channel count).

Frames keep the file's timestamps as both ``device_time`` and ``host_time`` (metadata
``clock: xdf``). A frame the layout cannot store as it is (NaN, 1e9 or 12.75 as 16-bit
counts) or whose time is not finite or goes back is left out and counted
(``malformed_by_kind``), never cast. Every string stream is read as markers at the frame
nearest each timestamp (importers/xdf_markers.py: only our own marker streams' JSON
becomes our events, trials and baselines; anything else is a ``marker`` event with its
text). Every other numeric stream (EDA, ECG, ...) is kept as an auxiliary signal
(storage/aux_signals.py). Participant and session come from BIDS entities in the file
name (``sub-P01_ses-S1_task-T_run-1``), else ``participant``, else the stream's own.
What the import could not take whole is said in :class:`XdfReport`; the session then
carries metadata ``source_incomplete`` (``info``: cut short).
"""

from __future__ import annotations

import logging
import os
import warnings
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.foreign import file_part, shown
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.sensor.channels import RAW, layout_for_channels
from tactile_studio.sensor.layout import Layout, get_layout
from tactile_studio.storage.aux_signals import AuxSignal
from tactile_studio.storage.importers._common import (
    ImportFormatError,
    NoFramesError,
    _discard,
    append_in_chunks,
    check_outputs,
    close_complete,
    distinct_paths,
    import_session_id,
    refuse_shared_outputs,
    run_jobs,
)
from tactile_studio.storage.importers.xdf_markers import MarkerReader
from tactile_studio.storage.input_files import check_input_file, file_sha256, unrepresentable_rows
from tactile_studio.storage.segments import is_segment_start
from tactile_studio.storage.session_writer import SessionWriter
from tactile_studio.storage.xdf_scan import MAX_RATE_HZ, XdfScan, checked_file, scan_xdf

# jitter removal fits a line per segment: a pause longer than max(BREAK_S, BREAK_SAMPLES
# sample intervals) starts a new one (pyxdf's default, 500 samples, would smooth a
# reconnect gap of seconds away)
BREAK_S, BREAK_SAMPLES = 0.2, 5
TACTILE_TYPES = frozenset({"tactile", "touch", "pressure", ""})
BIDS = {"sub": "participant", "ses": "session_label", "task": "task", "run": "run",
        "acq": "acquisition"}


@dataclass
class XdfReport:
    """What an import says beyond its sessions: tactile streams not imported (no
    samples), what was imported short of what the file recorded (cut, damaged, frames
    left out: the CLI exits 3) and notes (markers kept as text)."""

    skipped: list[str] = field(default_factory=list)
    short: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def bids_entities(name: str) -> dict[str, str]:
    """``sub-P01_ses-S1_task-T_run-1_...`` -> {participant: P01, session_label: S1, ...}."""
    out = {}
    for part in Path(name).stem.split("_"):
        key, sep, value = part.partition("-")
        if sep and key in BIDS and value:
            out[BIDS[key]] = value
    return out


def _first(d: Any, *path: str) -> Any:
    """pyxdf's nested {key: [value]} dicts, one step per key; None when absent."""
    for key in path:
        if not isinstance(d, dict) or not isinstance(d.get(key), list) or not d[key]:
            return None
        d = d[key][0]
    return d


def _text(d: Any, *path: str) -> str:
    """The text at ``path`` ("" when absent or not text: a foreign header may nest
    anything anywhere)."""
    v = _first(d, *path)
    return v.strip() if isinstance(v, str) else ""


def _node(d: Any, *path: str) -> dict[str, Any]:
    v = _first(d, *path)
    return v if isinstance(v, dict) else {}


def _stream_name(s: dict[str, Any]) -> str:
    return _text(s["info"], "name") or f"stream{s['info'].get('stream_id')}"


def _ours(s: dict[str, Any]) -> dict[str, Any]:
    return _node(s["info"], "desc", "tactile_studio")


def tactile_layout(s: dict[str, Any], stream: str | None, layout: str | None) -> Layout | None:
    """The layout of a tactile stream, or None for any other stream."""
    info = s["info"]
    n = int(_text(info, "channel_count"))  # xdf_scan checked the header
    fmt = _text(info, "channel_format")
    name = _stream_name(s)
    if stream is not None:
        if name != stream:
            return None
        if fmt == "string":
            raise ImportFormatError(f"stream '{shown(name)}' is a text (marker) stream, "
                                    "not a tactile one: name a numeric stream with --stream")
        lay = get_layout(layout) if layout else layout_for_channels(n)
        if lay is None or lay.n_channels != n:
            raise ImportFormatError(
                f"stream '{shown(name)}' has {n} channels, which "
                f"{'layout ' + lay.name + ' does not take' if lay else 'match no layout'}"
                " (name one with --layout L)")
        return lay
    if fmt == "string" or float(_text(info, "nominal_srate")) <= 0:
        return None
    ours = _ours(s)
    if ours:
        lay_name = _text(ours, "layout", "name")
        if _text(ours, "content") not in ("", RAW) or not lay_name:
            return None
        lay = get_layout(lay_name)
        return lay if lay.n_channels == n else None
    if _text(info, "type").lower() not in TACTILE_TYPES or n < 16:
        return None
    return layout_for_channels(n)


def _labels(s: dict[str, Any], n: int) -> tuple[list[str], str]:
    chans = _node(s["info"], "desc", "channels").get("channel") or []
    labels = [_text(c, "label") or f"ch{i + 1}" for i, c in enumerate(chans)]
    unit = _text(chans[0], "unit") if chans else ""
    return (labels if len(labels) == n else [f"ch{i + 1}" for i in range(n)]), unit


def aux_signal(s: dict[str, Any]) -> AuxSignal:
    values = np.asarray(s["time_series"], dtype=np.float64)
    n = int(_text(s["info"], "channel_count"))
    labels, unit = _labels(s, n)
    return AuxSignal(_stream_name(s), np.asarray(s["time_stamps"]), values.reshape(-1, n),
                     labels, unit, float(_text(s["info"], "nominal_srate")),
                     _text(s["info"], "type"), _text(s["info"], "source_id"))


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
    desc = _ours(m)
    if _text(desc, "format") != "json":
        return False
    for_stream = _text(desc, "frame_stream")
    if for_stream and for_stream != frame_stream and for_stream in tactile_names:
        return None
    return True


def _session_job(path: Path, out: Path, sha: str, s: dict[str, Any], lay: Layout,
                 others: list[dict[str, Any]], aux: list[AuxSignal], meta: dict[str, Any],
                 tactile_names: set[str], report: XdfReport,
                 cancel: CancelToken | None) -> Callable[[ProgressFn], Path]:
    name = _stream_name(s)
    frames = _Frames.of(s, lay)
    said = f"{path}: stream '{shown(name)}'"
    why = frames.rate_line()
    if why:
        raise ImportFormatError(f"{said}: {why}")
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
        ours = _marker_stream_is_ours(m, name, tactile_names)
        if ours is None:
            continue
        for sample, t in zip(m["time_series"], m["time_stamps"]):
            markers.add(_stream_name(m), list(sample), float(t), ours)
    trials = markers.trial_list()
    if markers.refused_line():
        report.notes.append(f"{said}: {markers.refused_line()}")
    rate = float(_text(s["info"], "nominal_srate"))
    ours = _ours(s)
    metadata = {
        "session_id": import_session_id("xdf", sha, name),
        "participant": meta.get("participant") or _text(ours, "participant"),
        **{k: v for k, v in meta.items() if k != "participant"},
        "source": "import:xdf", "original_file": path.name, "stream": name,
        "clock": "xdf: device_time and host_time are the file's common clock (s)",
    }
    device = {"plugin": "import", "format": "xdf", "file": str(path), "stream": name,
              "nominal_rate_hz": rate, "rate_hz": rate,
              "source_id": _text(s["info"], "source_id")}
    # pyxdf's segments are sample numbers of the stream; frames left out shift the rows
    segments = [(int(np.searchsorted(frames.rows, a)), b)
                for a, b in s["info"].get("segments") or []]

    def job(progress: ProgressFn) -> Path:
        n = len(times)
        writer = SessionWriter(out, lay, device, metadata, flush_interval=1e9, aux=aux)
        try:
            if frames.left_out:
                writer.set_counters({"malformed_by_kind": dict(frames.left_out)})
            for row, values in markers.baselines:
                writer.add_baseline(np.asarray(values), row)
            append_in_chunks(writer, frames.raw, times, out.name, progress, cancel)
            for a in _unnamed_breaks(segments, markers.events):
                if 0 < a < n:
                    writer.add_event("gap", a, float(times[a]), cause="xdf",
                                     seconds=round(float(times[a] - times[a - 1]), 6))
            for kind, row, t, detail in markers.events:
                writer.add_event(kind, row, t, **detail)
            for trial in trials:
                writer.add_trial(trial)
            close_complete(writer)
        except BaseException:
            _discard(writer, out)
            raise
        progress(1.0, f"{out.name}: {n} frames, {len(trials)} trials")
        return out

    return job


@contextmanager
def _pyxdf_quiet() -> Iterator[None]:
    """pyxdf logs what it finds odd (segments and clock segments differ, ...) and
    numpy warns of its divisions by zero, on stderr: what matters is said in our own
    lines, once (a time that came out NaN is a frame left out and counted)."""
    logs = [logging.getLogger(name) for name in ("pyxdf", "pyxdf.pyxdf")]
    was = [log.disabled for log in logs]
    for log in logs:
        log.disabled = True
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            yield
    finally:
        for log, state in zip(logs, was):
            log.disabled = state


def load_xdf(path: Path) -> tuple[list[dict[str, Any]], XdfScan]:
    """pyxdf's streams of ``path`` (clocks synchronised, jitter removed) read from the
    chunks that hold what they claim (storage/xdf_scan.py), and that scan; or one line."""
    check_input_file(path, "an XDF file", ImportFormatError)
    import pyxdf

    try:
        scan = scan_xdf(path)
    except ValueError as exc:
        raise ImportFormatError(f"{path}: {exc}") from None
    try:
        with _pyxdf_quiet(), checked_file(scan) as fh:
            streams, _ = pyxdf.load_xdf(fh, synchronize_clocks=True,
                                        dejitter_timestamps=True,
                                        jitter_break_threshold_seconds=BREAK_S,
                                        jitter_break_threshold_samples=BREAK_SAMPLES)
    except MemoryError:
        raise ImportFormatError(f"{path}: its streams do not fit in memory") from None
    except Exception as exc:  # noqa: BLE001 - pyxdf raises anything on a bad file
        why = shown(str(exc).strip() or type(exc).__name__, 120)
        raise ImportFormatError(f"{path}: not a readable XDF file ({why})") from None
    return streams, scan


def _output_name(path: Path, s: dict[str, Any], several: bool) -> str:
    return f"{path.stem}_{file_part(_stream_name(s))}.h5" if several else f"{path.stem}.h5"


def import_xdf(paths: Sequence[str | os.PathLike], out_dir: str | os.PathLike,
               participant: str | None = None, stream: str | None = None,
               layout: str | None = None, progress: ProgressFn | None = None,
               cancel: CancelToken | None = None, force: bool = False,
               on_done: Callable[[Path], None] | None = None,
               report: XdfReport | None = None) -> list[Path]:
    """Each tactile stream of each file -> ``<file>[_<stream>].h5`` in ``out_dir``.

    A tactile stream without samples writes no session: with a ``report`` its line goes
    to ``report.skipped`` and the other streams are imported (``NoFramesError`` when none
    had any); without one its ``NoFramesError`` is raised before anything is written.
    What was imported short of the file (cut, damaged, frames left out) goes to
    ``report.short``, and each such session carries ``source_incomplete``."""
    progress = progress or no_progress
    said = report or XdfReport()
    jobs: list[Callable[[ProgressFn], Path]] = []
    sources: list[tuple[Path, Path]] = []  # (input, output) of every file so far
    for k, p in enumerate(paths):
        path = Path(p)
        streams, scan = load_xdf(path)
        progress(0.5 * (k + 1) / len(paths), f"{path.name}: {len(streams)} streams read")
        refused = scan.refused_name(stream) if stream else ""
        if refused:
            raise ImportFormatError(f"{path}: {refused}")
        tactile = [(s, lay) for s in streams
                   if (lay := tactile_layout(s, stream, layout)) is not None]
        if not tactile:
            names = ", ".join(f"{shown(_stream_name(s))} "
                              f"({int(_text(s['info'], 'channel_count'))} ch)"
                              for s in streams) or "none"
            what = f"no stream named '{shown(stream)}'" if stream else "no tactile stream"
            why = "".join(f"; {line}" for line in scan.refused.values())
            raise ImportFormatError(f"{path}: {what} (streams: {names}{why}); name one with "
                                    "--stream NAME --layout L")
        chosen = {id(s) for s, _ in tactile}
        markers = [s for s in streams if _text(s["info"], "channel_format") == "string"]
        aux = [aux_signal(s) for s in streams
               if id(s) not in chosen and _text(s["info"], "channel_format") != "string"
               and len(s["time_stamps"])]
        meta = bids_entities(path.name)
        if not meta.get("participant") and participant:
            meta["participant"] = participant
        problems = scan.problems()
        if problems:
            meta["source_incomplete"] = "; ".join(line.removeprefix(f"{path}: ")
                                                  for line in problems)
            said.short.extend(problems)
        sha = file_sha256(path)
        outs = distinct_paths([Path(out_dir) / _output_name(path, s, len(tactile) > 1)
                               for s, _ in tactile])
        sources += [(path, out) for out in outs]
        refuse_shared_outputs(sources)
        check_outputs(outs, force)
        names = {_stream_name(s) for s, _ in tactile}
        for (s, lay), out in zip(tactile, outs):
            if not len(s["time_stamps"]):
                why = "; ".join(line.removeprefix(f"{path}: ") for line in problems)
                line = (f"{path}: stream '{shown(_stream_name(s))}' has no samples, "
                        "nothing imported" + (f" ({why})" if why else ""))
                if report is None:
                    raise NoFramesError(line)
                said.skipped.append(line)
                continue
            try:
                jobs.append(_session_job(path, out, sha, s, lay, markers, aux, meta, names,
                                         said, cancel))
            except NoFramesError as exc:
                if report is None:
                    raise
                said.skipped.append(str(exc))
    if not jobs and said.skipped:
        raise NoFramesError(said.skipped[0] if len(said.skipped) == 1 else
                            f"nothing imported: none of the {len(said.skipped)} tactile "
                            "streams has frames to store ("
                            + ", ".join(Path(p).name for p in paths) + ")")
    return run_jobs(jobs, progress, 0.5, 1.0, on_done)
