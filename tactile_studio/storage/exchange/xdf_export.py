"""A session as an XDF 1.0 file (``export --format xdf``), the file LabRecorder writes,
so pyxdf, MNE, EEGLAB and the rest of a lab's pipeline read the touch beside the rest.

Streams (ids in this order):

1. frames: ``TactileStudio-<device>``, type ``Tactile``, raw counts (int32; float32 for
   float layouts), one channel per raw channel labelled as on LSL (docs/lsl.md), the
   layout and device in ``desc/tactile_studio``, and in its ``session`` the protocol,
   condition, orders, seeds, sensor and calibration (storage/exchange/xdf_session_fields.py);
2. markers: ``<frames>-markers``, type ``Markers``, one JSON string per event and two per
   trial (``trial_start`` at its first frame, ``trial_end`` at its last with gesture,
   block, status...), the same JSON the live marker stream carries;
3. one stream per auxiliary signal (storage/format/aux_signals.py), double64.

Timestamps: when the session has ``lsl_clock`` events (it was recorded while streaming
to LSL), every time is on LSL's clock, ``host_time + offset_s`` with the offset in force
at that row, exactly the stamps the live outlet sent; otherwise host (Unix) time, paced
by the device clock when the recording ran faster or slower than real time (the
simulator's or replay's ``speed`` other than 1: ``paced_host``). Every
stream is on that one clock, so the ClockOffset chunks (one per stream every 10 s of
data, like LabRecorder's) all say 0. Every redone or discarded trial is written too,
with its status.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any

import numpy as np

from tactile_studio import __version__
from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.sensor.channels import RAW, frame_channels
from tactile_studio.storage.exchange.importers._common import (
    check_outputs,
    naming_the_file,
    write_through_part,
)
from tactile_studio.storage.exchange.xdf_session_fields import session_desc
from tactile_studio.storage.exchange.xdf_writer import XdfWriter
from tactile_studio.storage.format.session_file import SessionFile, measured_rate_hz

WINDOW_S = 10.0      # a Boundary chunk and ClockOffsets every WINDOW_S of data
MAX_CHUNK = 4096     # samples per Samples chunk at most
SKIPPED_EVENTS = frozenset({"lsl_clock"})
FRAME_TYPE, MARKER_TYPE = "Tactile", "Markers"


@dataclass
class XdfStream:
    """One stream's header fields and all its samples."""

    name: str
    type: str
    channel_format: str
    nominal_srate: float
    source_id: str
    stamps: np.ndarray
    values: Any  # (n, channels) array, or a list of [text] for strings
    desc: dict[str, Any] = field(default_factory=dict)

    @property
    def channel_count(self) -> int:
        return 1 if self.channel_format == "string" else int(np.shape(self.values)[1])


class Timeline:
    """Host time -> the file's clock: + the ``lsl_clock`` offset in force, else as is."""

    def __init__(self, host_time: np.ndarray, events: list[dict[str, Any]]) -> None:
        pts = sorted((int(e.get("frame") or 0), float(e["offset_s"])) for e in events
                     if e.get("kind") == "lsl_clock" and e.get("streaming")
                     and e.get("offset_s") is not None)
        self.lsl = bool(pts)
        self.rows = np.array([r for r, _ in pts] or [0], dtype=np.int64)
        self.offsets = np.array([o for _, o in pts] or [0.0], dtype=np.float64)
        n = len(host_time)
        self.starts = (host_time[np.clip(self.rows, 0, n - 1)] if n
                       else np.zeros(len(self.rows)))

    def rows_offset(self, rows: np.ndarray) -> np.ndarray:
        i = np.searchsorted(self.rows, rows, side="right") - 1
        return self.offsets[np.clip(i, 0, None)]

    def times_offset(self, times: np.ndarray) -> np.ndarray:
        i = np.searchsorted(self.starts, times, side="right") - 1
        return self.offsets[np.clip(i, 0, None)]


def _frame_stream(s: SessionFile, host: np.ndarray, stamps: np.ndarray, lsl: bool) -> XdfStream:
    lay, meta = s.layout, s.metadata
    device = dict(meta.get("device") or {})
    plugin = str(device.get("plugin") or "session")
    rate = float(device.get("nominal_rate_hz") or 0.0) or round(measured_rate_hz(host), 6)
    integer = np.issubdtype(np.dtype(lay.raw_dtype), np.integer)
    # the session's own sensor (the logbook's, in the metadata), else what the device said
    sensor_id = meta.get("sensor_id") or device.get("sensor_id") or \
        (device.get("settings") or {}).get("sensor_id")
    desc = {
        "channels": {"channel": [{k: str(v) for k, v in ch.items()}
                                 for ch in frame_channels(lay, RAW)]},
        "acquisition": {"manufacturer": "Tactile Studio", "model": plugin,
                        "serial_number": sensor_id},
        "tactile_studio": {
            "version": __version__, "content": RAW, "device": plugin,
            "settings": json.dumps(_portable(device.get("settings") or {}), sort_keys=True,
                                   default=str),
            "sensor_id": sensor_id, "session_id": s.session_id,
            "participant": meta.get("participant"), "session_file": s.path.name,
            "layout": {"name": lay.name, "rows": lay.rows, "cols": lay.cols,
                       "channels_per_taxel": lay.channels_per_taxel,
                       "column_major": int(bool(lay.column_major)),
                       "pitch_mm": repr(lay.pitch_mm), "units": lay.units},
            # protocol, condition, gesture and block orders, seeds, sensor, calibration
            "session": session_desc(meta),
            "clock": {"timeline": "lsl" if lsl else "host",
                      "meaning": "lsl: host_time + offset_s of the lsl_clock event in force; "
                                 "host: host_time (Unix seconds)"},
        },
    }
    return XdfStream(f"TactileStudio-{plugin}", FRAME_TYPE, "int32" if integer else "float32",
                     rate, f"tactile-studio:{plugin}:{RAW}:{s.session_id}", stamps,
                     s.raw().astype(np.int32 if integer else np.float32), desc)


def _portable(settings: dict[str, Any]) -> dict[str, Any]:
    """The device's settings as a file shared with others may carry them: a path on the
    experimenter's machine (a replayed file's ``/home/<user>/...``) by its file name."""
    return {k: (PureWindowsPath(v).name if isinstance(v, str) and _is_path(v) else v)
            for k, v in settings.items()}


def _is_path(text: str) -> bool:
    return PurePosixPath(text).is_absolute() or PureWindowsPath(text).is_absolute()


def paced_host(s: SessionFile, host: np.ndarray) -> np.ndarray:
    """The host clock of a recording made faster or slower than real time (a simulator or
    replay ``speed`` other than 1: speed 0 writes a minute in a second, in bursts) follows
    the device clock from the first frame's host time, so an XDF reader sees the real rate
    and pyxdf's dejittering keeps every marker on its frame; other sessions keep theirs."""
    try:
        speed = float(((s.metadata.get("device") or {}).get("settings") or {}).get("speed"))
    except (TypeError, ValueError):
        return host
    dev = s.column("device_time")
    if speed == 1.0 or len(dev) != len(host) or not np.all(np.diff(dev) >= 0):
        return host
    return host[0] + (dev - dev[0])


def _on_clock(times: np.ndarray, recorded: np.ndarray, host: np.ndarray) -> np.ndarray:
    """Host times (events without a frame, auxiliary samples) on ``host``'s clock."""
    if host is recorded:
        return times
    return np.interp(times, recorded, host)


def session_markers(s: SessionFile, host: np.ndarray, index: np.ndarray,
                    recorded: np.ndarray | None = None) -> list[tuple[float, dict[str, Any]]]:
    """(host time, marker) of every event and trial boundary, in time order; ``recorded``:
    the file's own host times when ``host`` is paced (:func:`paced_host`)."""
    n = len(host)
    out: list[tuple[float, dict[str, Any]]] = []

    def at(row: int) -> tuple[float, int]:
        r = min(max(int(row), 0), n - 1)
        return float(host[r]), int(index[r])

    for e in s.events:
        if e.get("kind") in SKIPPED_EVENTS:
            continue
        detail = {k: v for k, v in e.items() if k not in ("kind", "frame", "time", "type")}
        row = e.get("frame")
        marker = {"kind": e["kind"], "source": detail.pop("source", "session"), **detail}
        if row is not None and 0 <= int(row) < n:
            t, marker["frame"] = at(int(row))
            marker["row"] = int(row)
        else:
            t = float(e.get("time") or (host[-1] if n else 0.0))
            if recorded is not None and e.get("time"):
                t = float(_on_clock(np.array([t]), recorded, host)[0])
        out.append((t, marker))
    for t in s.journal.trials:  # the file's columns, importers' extra ones too
        a, b = int(t["start_sample"]), min(int(t["end_sample"]), n)
        if not n or b <= a:
            continue
        common = {k: t[k] for k in ("index", "block", "gesture", "key") if k in t}
        ta, fa = at(a)
        out.append((ta, {"kind": "trial_start", "source": "collect", **common, "frame": fa,
                         "row": a}))
        tb, fb = at(b - 1)
        rest = {k: v for k, v in t.items() if k not in common and k not in ("type",)}
        out.append((tb, {"kind": "trial_end", "source": "collect", **common, **rest,
                         "frame": fb, "row": b - 1}))
    out.sort(key=lambda m: m[0])
    return out


def session_streams(s: SessionFile) -> list[XdfStream]:
    """What ``export --format xdf`` writes for a session (see the module docstring)."""
    host = s.column("host_time")
    if len(host) == 0:
        raise UserError(f"{s.path}: session has no frames to export")
    clock = Timeline(host, s.events)
    recorded = host
    if not clock.lsl:
        host = paced_host(s, host)
    stamps = host + clock.rows_offset(np.arange(len(host)))
    frames = _frame_stream(s, host, stamps, clock.lsl)
    markers = session_markers(s, host, s.column("index"), recorded)
    texts = [[json.dumps(m, separators=(",", ":"), default=str)] for _, m in markers]
    mtimes = np.array([t for t, _ in markers], dtype=np.float64)
    mdesc = {"tactile_studio": {"format": "json", "frame_stream": frames.name,
                                "frame_source_id": frames.source_id}}
    streams = [frames, XdfStream(f"{frames.name}-markers", MARKER_TYPE, "string", 0.0,
                                 f"{frames.source_id}:markers",
                                 mtimes + clock.times_offset(mtimes), texts, mdesc)]
    for aux in s.aux_signals():
        chans = [{"label": label, "unit": aux.unit} for label in aux.labels]
        streams.append(XdfStream(aux.name, aux.type or "Misc", "double64", aux.rate_hz,
                                 aux.source_id or f"tactile-studio:aux:{aux.name}",
                                 _on_clock(aux.time, recorded, host)
                                 + clock.times_offset(aux.time), aux.values,
                                 {"channels": {"channel": chans}}))
    return streams


def write_xdf(path: Path, streams: list[XdfStream], progress: ProgressFn | None = None,
              cancel: CancelToken | None = None) -> Path:
    """Write ``streams`` as one XDF file, interleaved in windows of WINDOW_S."""
    progress = progress or no_progress
    all_t = np.concatenate([st.stamps for st in streams if len(st.stamps)] or [np.zeros(1)])
    t0, t1 = float(all_t.min()), float(all_t.max())
    edges = np.arange(t0, t1 + WINDOW_S, WINDOW_S)
    edges[-1] = np.inf
    offsets: list[list[tuple[float, float]]] = [[] for _ in streams]
    with open(path, "wb") as fh:
        w = XdfWriter(fh)
        w.file_header()
        for sid, st in enumerate(streams, 1):
            w.stream_header(sid, st.name, st.type, st.channel_count, st.nominal_srate,
                            st.channel_format, st.source_id, t0, st.desc)
        cuts = [np.searchsorted(st.stamps, edges, side="left") for st in streams]
        for k in range(len(edges) - 1):
            if cancel is not None:
                cancel.check()
            when = t0 + k * WINDOW_S
            for sid, st in enumerate(streams, 1):
                w.clock_offset(sid, when, 0.0)
                offsets[sid - 1].append((when, 0.0))
                a, b = int(cuts[sid - 1][k]), int(cuts[sid - 1][k + 1])
                for i in range(a, b, MAX_CHUNK):
                    j = min(b, i + MAX_CHUNK)
                    w.samples(sid, st.channel_format, st.stamps[i:j], st.values[i:j])
            w.boundary()
            progress(min((k + 1) / (len(edges) - 1), 0.99), f"{path.name}: {when - t0:.0f} s")
        for sid, st in enumerate(streams, 1):
            w.clock_offset(sid, t1, 0.0)
            offsets[sid - 1].append((t1, 0.0))
            n = len(st.stamps)
            first = float(st.stamps[0]) if n else 0.0
            last = float(st.stamps[-1]) if n else 0.0
            w.stream_footer(sid, first, last, n, offsets[sid - 1])
    return path


def export_xdf(path: str | os.PathLike, out_dir: str | os.PathLike,
               progress: ProgressFn | None = None, cancel: CancelToken | None = None,
               force: bool = False) -> Path:
    """``<session>.xdf`` in ``out_dir``; a cancelled export leaves no file."""
    progress = progress or no_progress
    with SessionFile(path) as s:
        out = Path(out_dir) / f"{s.path.stem}.xdf"
        check_outputs([out], force)
        streams = session_streams(s)
    shown = naming_the_file(progress)  # the file, not its temporary
    write_through_part(out, lambda tmp: write_xdf(tmp, streams, shown, cancel))
    progress(1.0, f"{out.name}: {len(streams)} streams, {len(streams[0].stamps)} frames")
    return out
