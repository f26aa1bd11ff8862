"""XDF files (LabRecorder's, or our own export) -> sessions: ``import xdf``.

Read with pyxdf, clock synchronisation and jitter removal on, so every stream is on the
file's common clock. Each tactile stream becomes one session:

* a Tactile Studio frame stream (``desc/tactile_studio`` names its layout, raw content);
* else, a regular numeric stream of type Tactile/Touch/Pressure (or none) whose channel
  count implies a layout (180 -> shearsense-6x6, N*N with N >= 4 -> grid-NxN);
* or the stream named with ``stream`` (and ``layout``, else from its channel count).

Frames keep the file's timestamps as both ``device_time`` and ``host_time`` (metadata
``clock: xdf``). Every string stream is read as markers at the frame nearest each
timestamp: Tactile Studio's JSON markers become their own events, ``trial_start`` /
``trial_end`` pairs become trials (``redo`` / ``discard`` set statuses), a ``tare`` with
values a baseline; any other text is a ``marker`` event (``text``, ``stream``). Every
other numeric stream (EDA, ECG, ...) is kept as an auxiliary signal
(storage/aux_signals.py). Participant and session come from BIDS entities in the file
name (``sub-P01_ses-S1_task-T_run-1``), else ``participant``, else the stream's own.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

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
    import_session_id,
    run_jobs,
)
from tactile_studio.storage.input_files import check_input_file, file_sha256
from tactile_studio.storage.segments import is_segment_start
from tactile_studio.storage.session_writer import SessionWriter
from tactile_studio.storage.xdf_session import session_fields

# jitter removal fits a line per segment: a pause longer than max(BREAK_S, BREAK_SAMPLES
# sample intervals) starts a new one (pyxdf's default, 500 samples, would smooth a
# reconnect gap of seconds away)
BREAK_S, BREAK_SAMPLES = 0.2, 5
TACTILE_TYPES = frozenset({"tactile", "touch", "pressure", ""})
BIDS = {"sub": "participant", "ses": "session_label", "task": "task", "run": "run",
        "acq": "acquisition"}


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
        if not isinstance(d, dict) or not d.get(key):
            return None
        d = d[key][0]
    return d


def _stream_name(s: dict[str, Any]) -> str:
    return str(_first(s["info"], "name") or f"stream{s['info'].get('stream_id')}")


def _ours(s: dict[str, Any]) -> dict[str, Any]:
    return _first(s["info"], "desc", "tactile_studio") or {}


def tactile_layout(s: dict[str, Any], stream: str | None, layout: str | None) -> Layout | None:
    """The layout of a tactile stream, or None for any other stream."""
    info = s["info"]
    n = int(_first(info, "channel_count") or 0)
    fmt = _first(info, "channel_format")
    name = _stream_name(s)
    if stream is not None:
        if name != stream:
            return None
        lay = get_layout(layout) if layout else layout_for_channels(n)
        if lay is None or lay.n_channels != n:
            raise ImportFormatError(
                f"stream '{name}' has {n} channels, which "
                f"{'layout ' + lay.name + ' does not take' if lay else 'match no layout'}"
                " (name one with --layout L)")
        return lay
    if fmt == "string" or float(_first(info, "nominal_srate") or 0) <= 0:
        return None
    ours = _ours(s)
    if ours:
        lay_name = _first(ours, "layout", "name")
        if _first(ours, "content") not in (None, RAW) or not lay_name:
            return None
        lay = get_layout(str(lay_name))
        return lay if lay.n_channels == n else None
    if str(_first(info, "type") or "").lower() not in TACTILE_TYPES or n < 16:
        return None
    return layout_for_channels(n)


def _labels(s: dict[str, Any], n: int) -> tuple[list[str], str]:
    chans = (_first(s["info"], "desc", "channels") or {}).get("channel") or []
    labels = [str(_first(c, "label") or f"ch{i + 1}") for i, c in enumerate(chans)]
    unit = str(_first(chans[0], "unit") or "") if chans else ""
    return (labels if len(labels) == n else [f"ch{i + 1}" for i in range(n)]), unit


def aux_signal(s: dict[str, Any]) -> AuxSignal:
    values = np.asarray(s["time_series"], dtype=np.float64)
    n = int(_first(s["info"], "channel_count") or (values.shape[1] if values.ndim == 2 else 1))
    labels, unit = _labels(s, n)
    return AuxSignal(_stream_name(s), np.asarray(s["time_stamps"]), values.reshape(-1, n),
                     labels, unit, float(_first(s["info"], "nominal_srate") or 0.0),
                     str(_first(s["info"], "type") or ""),
                     str(_first(s["info"], "source_id") or ""))


class _Markers:
    """Marker streams -> events, trials and baselines at frame rows (see module doc)."""

    def __init__(self, times: np.ndarray) -> None:
        self.times = times
        self.events: list[tuple[str, int, float, dict[str, Any]]] = []
        self.trials: dict[int, dict[str, Any]] = {}
        self.baselines: list[tuple[int, list[float]]] = []
        self._starts: dict[int, int] = {}
        self._last_start: int | None = None

    def row(self, t: float) -> int:
        i = int(np.searchsorted(self.times, t))
        if i > 0 and (i == len(self.times) or t - self.times[i - 1] <= self.times[i] - t):
            i -= 1
        return min(i, len(self.times) - 1)

    def _after(self, row: int) -> float:
        """The time just after frame ``row`` (a trial's ``end_time``, as the runner
        writes it): the next frame's, or one frame step after the last."""
        times = self.times
        if row + 1 < len(times):
            return float(times[row + 1])
        step = float(times[-1] - times[-2]) if len(times) > 1 else 0.0
        return float(times[row]) + step

    def add(self, stream: str, text: str, t: float) -> None:
        row = self.row(t)
        try:
            m = json.loads(text)
        except ValueError:
            m = None
        if not (isinstance(m, dict) and "kind" in m and "source" in m):
            self.events.append(("marker", row, t, {"text": text, "stream": stream}))
            return
        kind = str(m.pop("kind"))
        m.pop("frame", None)
        m.pop("row", None)
        index = m.get("index")
        if kind == "trial_start":  # live markers name no index: the next end is its own
            if index is not None:
                self._starts[int(index)] = row
            self._last_start = row
        elif kind == "trial_end" and index is not None:
            start = self._starts.pop(int(index), None)
            if start is None and self._last_start is not None and self._last_start <= row:
                start = self._last_start
            self._last_start = None
            if start is None:
                start = row + 1 - (int(m.get("end_sample", 1)) - int(m.get("start_sample", 0)))
            keep = {k: v for k, v in m.items() if k not in ("source", "start_sample", "end_sample")}
            self.trials[int(index)] = {**keep, "index": int(index),
                                       "start_sample": max(start, 0), "end_sample": row + 1,
                                       "start_time": float(self.times[max(start, 0)]),
                                       "end_time": self._after(row),
                                       "status": m.get("status") or "ok"}
        elif kind in ("redo", "discard") and index is not None and int(index) in self.trials:
            self.trials[int(index)].update(status=m.get("status") or
                                           {"redo": "redone", "discard": "discarded"}[kind],
                                           reason=m.get("reason"))
        else:
            if kind == "tare" and isinstance(m.get("baseline"), list):
                self.baselines.append((row, [float(v) for v in m.pop("baseline")]))
            self.events.append((kind, row, t, {**m, "stream": stream}))


def _unnamed_breaks(segments: list[Any], events: list[tuple[str, int, float, dict[str, Any]]]
                    ) -> list[int]:
    """The rows where pyxdf's jitter segments start that no marker already names as a
    break (a ``gap`` or a resume's segment start, within a row): our own export's
    reconnects and resumes are gaps already, counted once (``info``'s gaps)."""
    named = {row for kind, row, _t, detail in events
             if kind == "gap" or is_segment_start({"kind": kind, **detail})}
    return [int(a) for a, _b in segments[1:]
            if not named & {int(a) - 1, int(a), int(a) + 1}]


def _session_job(path: Path, out: Path, sha: str, s: dict[str, Any], lay: Layout,
                 others: list[dict[str, Any]], aux: list[AuxSignal], meta: dict[str, Any],
                 cancel: CancelToken | None) -> Callable[[ProgressFn], Path]:
    name = _stream_name(s)
    times = np.asarray(s["time_stamps"], dtype=np.float64)
    raw = np.asarray(s["time_series"])
    if np.issubdtype(np.dtype(lay.raw_dtype), np.integer):
        lim = np.iinfo(lay.raw_dtype)
        raw = np.clip(raw, lim.min, lim.max)
    raw = raw.astype(lay.raw_dtype)
    markers = _Markers(times)
    for m in others:
        for text, t in zip(m["time_series"], m["time_stamps"]):
            markers.add(_stream_name(m), str(text[0] if isinstance(text, list) else text), float(t))
    rate = float(_first(s["info"], "nominal_srate") or 0.0)
    ours = _ours(s)
    metadata = {
        "session_id": import_session_id("xdf", sha, name),
        # our own export's protocol, condition, orders, seeds, sensor and calibration,
        # each field checked (storage/xdf_session.py); the file name's BIDS entities win
        **session_fields(_first(ours, "session")),
        "participant": meta.get("participant") or _first(ours, "participant") or "",
        **{k: v for k, v in meta.items() if k != "participant"},
        "source": "import:xdf", "original_file": path.name, "stream": name,
        "clock": "xdf: device_time and host_time are the file's common clock (s)",
    }
    device = {"plugin": "import", "format": "xdf", "file": str(path), "stream": name,
              "nominal_rate_hz": rate, "rate_hz": rate,
              "source_id": str(_first(s["info"], "source_id") or "")}
    segments = s["info"].get("segments") or []

    def job(progress: ProgressFn) -> Path:
        n = len(times)
        writer = SessionWriter(out, lay, device, metadata, flush_interval=1e9, aux=aux)
        try:
            for row, values in markers.baselines:
                if len(values) == lay.n_channels:
                    writer.add_baseline(np.asarray(values), row)
            append_in_chunks(writer, raw, times, out.name, progress, cancel)
            for a in _unnamed_breaks(segments, markers.events):
                writer.add_event("gap", a, float(times[a]), cause="xdf",
                                 seconds=round(float(times[a] - times[a - 1]), 6))
            for kind, row, t, detail in markers.events:
                writer.add_event(kind, row, t, **detail)
            for index in sorted(markers.trials):
                writer.add_trial(markers.trials[index])
            close_complete(writer)
        except BaseException:
            _discard(writer, out)
            raise
        progress(1.0, f"{out.name}: {n} frames, {len(markers.trials)} trials")
        return out

    return job


def load_xdf(path: Path) -> list[dict[str, Any]]:
    """pyxdf's streams of ``path`` (clocks synchronised, jitter removed), or one line."""
    check_input_file(path, "XDF file", ImportFormatError)
    import pyxdf

    try:
        streams, _ = pyxdf.load_xdf(str(path), synchronize_clocks=True,
                                    dejitter_timestamps=True,
                                    jitter_break_threshold_seconds=BREAK_S,
                                    jitter_break_threshold_samples=BREAK_SAMPLES)
    except Exception as exc:  # noqa: BLE001 - pyxdf raises anything on a bad file
        raise ImportFormatError(f"{path}: not a readable XDF file ({exc})") from None
    return streams


def import_xdf(paths: Sequence[str | os.PathLike], out_dir: str | os.PathLike,
               participant: str | None = None, stream: str | None = None,
               layout: str | None = None, progress: ProgressFn | None = None,
               cancel: CancelToken | None = None, force: bool = False,
               on_done: Callable[[Path], None] | None = None,
               skipped: list[str] | None = None) -> list[Path]:
    """Each tactile stream of each file -> ``<file>[_<stream>].h5`` in ``out_dir``.

    A tactile stream without samples writes no session: with a ``skipped`` list its line
    goes there and the other streams are imported (``NoFramesError`` when none had any);
    without one its ``NoFramesError`` is raised before anything is written."""
    progress = progress or no_progress
    jobs: list[Callable[[ProgressFn], Path]] = []
    for k, p in enumerate(paths):
        path = Path(p)
        streams = load_xdf(path)
        progress(0.5 * (k + 1) / len(paths), f"{path.name}: {len(streams)} streams read")
        tactile = [(s, lay) for s in streams
                   if (lay := tactile_layout(s, stream, layout)) is not None]
        if not tactile:
            names = ", ".join(f"{_stream_name(s)} "
                              f"({int(_first(s['info'], 'channel_count') or 0)} ch)"
                              for s in streams) or "none"
            what = f"no stream named '{stream}'" if stream else "no tactile stream"
            raise ImportFormatError(f"{path}: {what} (streams: {names}); name one with "
                                    "--stream NAME --layout L")
        chosen = {id(s) for s, _ in tactile}
        markers = [s for s in streams if _first(s["info"], "channel_format") == "string"]
        aux = [aux_signal(s) for s in streams
               if id(s) not in chosen and _first(s["info"], "channel_format") != "string"
               and len(s["time_stamps"])]
        meta = bids_entities(path.name)
        if not meta.get("participant") and participant:
            meta["participant"] = participant
        sha = file_sha256(path)
        outs = [Path(out_dir) / (f"{path.stem}.h5" if len(tactile) == 1 else
                                 f"{path.stem}_"
                                 f"{re.sub(r'[^A-Za-z0-9.-]+', '-', _stream_name(s))}.h5")
                for s, _ in tactile]
        check_outputs(outs, force)
        for (s, lay), out in zip(tactile, outs):
            if not len(s["time_stamps"]):
                line = f"{path}: stream '{_stream_name(s)}' has no samples, nothing imported"
                if skipped is None:
                    raise NoFramesError(line)
                skipped.append(line)
                continue
            jobs.append(_session_job(path, out, sha, s, lay, markers, aux, meta, cancel))
    if not jobs and skipped:
        raise NoFramesError(skipped[0] if len(skipped) == 1 else
                            f"nothing imported: none of the {len(skipped)} tactile streams "
                            "has samples (" + ", ".join(Path(p).name for p in paths) + ")")
    return run_jobs(jobs, progress, 0.5, 1.0, on_done)
