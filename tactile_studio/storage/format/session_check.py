"""The session validator behind ``tactile-studio check``: a file's facts agree with each other.

A wrong rate, an event at the wrong frame or a trial outside its rows is worse than a
crash, because nobody notices. This module states the invariants every session file must
hold (docs/session-format.md, "What check verifies") and names each violation with its
row, trial or event, so a test suite can run it on every file it writes and a user on any
file before analysing it. Groups it does not know (``/aux``...) are ignored.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.devices.ring import nearest_frame
from tactile_studio.storage.format.segments import is_segment_start, segment_starts
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_format import OVERRUN
from tactile_studio.storage.format.trial_checks import check_problems
from tactile_studio.storage.format.trials import TrialStatus

STATUSES = {s.value for s in TrialStatus}
# trial fields every trial carries (docs/session-format.md, the journal's `trial` record;
# readers take a missing block as 0 and a missing status as ok)
TRIAL_FIELDS = ("index", "gesture", "start_sample", "end_sample")
COUNTED_EVENTS = (("gaps", "gap"), ("reconnects", "reconnect"))
# the journal's times (docs/session-format.md): JSON as Python writes and reads it carries
# NaN and Infinity, and every comparison with NaN is false, so a time that is not a number
# passed every ordering rule unseen; ``t`` is a list of times (a load cell's samples)
EVENT_TIMES = ("time", "t", "lab_t", "lsl_time", "time_correction", "offset_s",
               "device_time_offset", "gap_s", "seconds", "silent_s")
TRIAL_TIMES = ("start_time", "end_time")
FRAME_COLUMNS = ("raw", "device_time", "host_time", "seq", "index")
METADATA_RATES = (("device", "nominal_rate_hz"), (None, "rate_hz"))


@dataclass
class CheckResult:
    """One file's verdict: ``violations`` empty when it holds every invariant."""

    path: str
    violations: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.violations

    def to_dict(self) -> dict[str, Any]:
        return {"path": self.path, "ok": self.ok, "violations": list(self.violations)}


def check_file(path: str | os.PathLike) -> CheckResult:
    """Open ``path`` and check it; an unreadable file raises ``SessionFileError``."""
    with SessionFile(path) as s:
        return CheckResult(str(Path(path)), check_session(s))


def check_session(s: SessionFile) -> list[str]:
    """Every violation of the session invariants in ``s``, one line each."""
    out: list[str] = [f"journal {why} (left out when read)" for why in s.journal.skipped]
    n = s.n_frames
    _check_times(s, segment_starts(s.events, n), out)
    trials = _check_trials(s, out)
    _check_events(s, trials, out)
    _check_numbers(s, out)
    _check_baselines(s, out)
    _check_markers(s, out)
    _check_metadata(s, out)
    _check_counters(s, out)
    return out


# ---- frames and clocks ----------------------------------------------------------------
def _first_backwards(t: np.ndarray, a: int, b: int) -> tuple[int, int]:
    """(row of the first frame whose time is below its predecessor's, how many) in a..b;
    times that are not finite are named on their own (``_not_finite_rows``)."""
    if b - a < 2:
        return -1, 0
    part = t[a:b]
    finite = np.isfinite(part)
    with np.errstate(invalid="ignore"):  # inf - inf: masked out just below
        steps = np.diff(part)
    back = np.flatnonzero((steps < 0) & finite[1:] & finite[:-1])
    return (int(back[0]) + a + 1, len(back)) if len(back) else (-1, 0)


def _s(seconds: float) -> str:
    """A time to the microsecond, trailing zeros dropped: two Unix times 23 ms apart
    must read apart (``.6g`` showed both as 1.7957e+09)."""
    return f"{float(seconds):.6f}".rstrip("0").rstrip(".")


def _check_times(s: SessionFile, segs: list[dict[str, Any]], out: list[str]) -> None:
    n = s.n_frames
    if n < 2:
        return
    # a reconnect may restart a device's own clock; a resume continues it (or says by how much)
    device_cuts = sorted({e["frame"] for e in segs} | {
        int(e["frame"]) for e in s.events if e.get("kind") == "reconnect"
        and isinstance(e.get("frame"), int) and 0 < e["frame"] < n})
    host_cuts = sorted({e["frame"] for e in segs})
    for name, cuts in (("device_time", device_cuts), ("host_time", host_cuts)):
        t = s.column(name)
        _not_finite_rows(name, t, out)
        bounds = [0, *cuts, n]
        for a, b in zip(bounds, bounds[1:]):
            row, count = _first_backwards(t, a, b)
            if row >= 0:
                more = f" ({count} times in rows {a}-{b - 1})" if count > 1 else ""
                out.append(f"{name} goes back at row {row}: {_s(t[row - 1])} -> "
                           f"{_s(t[row])} s ({_s(t[row - 1] - t[row])} s back){more}")
    dev = s.column("device_time")
    for e in segs:
        r = e["frame"]
        if dev[r] < dev[r - 1]:
            how = ("despite its device_time_offset" if "device_time_offset" in e
                   else "and the resume records no device_time_offset")
            out.append(f"device clock restarts at row {r} after a resume ({_s(dev[r - 1])} -> "
                       f"{_s(dev[r])} s) {how}")


def _not_finite_rows(name: str, t: np.ndarray, out: list[str]) -> None:
    bad = np.flatnonzero(~np.isfinite(t))
    if len(bad):
        more = f" ({len(bad)} rows, the last {int(bad[-1])})" if len(bad) > 1 else ""
        out.append(f"{name} is not a finite number at row {int(bad[0])} "
                   f"({t[bad[0]]}){more}")


# ---- numbers ------------------------------------------------------------------------------
def _not_a_time(value: Any) -> str | None:
    """Why ``value`` (a number, a list of numbers or null) is not a time, else None."""
    items = value if isinstance(value, list) else [value]
    for v in items:
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, int | float):
            return f"{v!r} is not a number"
        if not math.isfinite(v):
            return f"{v} is not a finite number"
    return None


def _check_numbers(s: SessionFile, out: list[str]) -> None:
    """Times in trials and events, rates and the calibration id in the metadata."""
    for t in s.journal.trials:  # the file's form: what is checked is what is stored
        for key in TRIAL_TIMES:
            why = _not_a_time(t.get(key))
            if why:
                out.append(f"trial {t.get('index', '?')}: {key} {why}")
    for e in s.events:
        for key in EVENT_TIMES:
            why = _not_a_time(e.get(key))
            if why:
                out.append(f"event {e.get('kind')} at frame {e.get('frame')}: {key} {why}")
    meta = s.metadata
    for table, key in METADATA_RATES:
        holder = meta.get(table) if table else meta
        value = holder.get(key) if isinstance(holder, dict) else None
        why = _not_a_time(value)
        if why is None and value is not None and value < 0:
            why = f"{value} is negative"
        if why:
            out.append(f"metadata {f'{table}.' if table else ''}{key} {why}")
    cal = meta.get("calibration_id")
    if cal is not None and (isinstance(cal, bool) or not isinstance(cal, int)):
        out.append(f"metadata calibration_id {cal!r} is not a whole number")


def _check_baselines(s: SessionFile, out: list[str]) -> None:
    """Each baseline: at a row of the frames, one finite value per channel."""
    n, width = s.n_frames, s.layout.n_channels
    for b in s.journal.baselines:
        f = _frame(b)
        where = f"baseline at frame {b.get('frame')}"
        if f is None or not 0 <= f <= n:
            out.append(f"{where}: not a row of the {n} frames")
        try:
            values = np.asarray(b.get("values"), dtype=np.float64)
        except (TypeError, ValueError):
            out.append(f"{where}: values are not numbers")
            continue
        if values.shape != (width,):
            out.append(f"{where}: {values.size} values for the layout's {width} channels")
        elif not np.isfinite(values).all():
            k = int(np.flatnonzero(~np.isfinite(values))[0])
            out.append(f"{where}: channel {k} is {values[k]}, not a finite number")


def _check_metadata(s: SessionFile, out: list[str]) -> None:
    meta = s.metadata
    width = int(s._f["frames/raw"].shape[1]) if s._f["frames/raw"].ndim == 2 else -1
    if width != s.layout.n_channels:
        out.append(f"frames/raw has {width} channels but layout {s.layout.name} has "
                   f"{s.layout.n_channels}")
    if s.closed_cleanly and not s.cut_short:  # a crash may leave them one flush apart
        rows = {name: int(s._f[f"frames/{name}"].shape[0]) for name in FRAME_COLUMNS}
        if len(set(rows.values())) > 1:
            out.append("frame columns differ in length: " + ", ".join(
                f"{name} {k}" for name, k in rows.items()))
    lay = meta.get("layout")
    if isinstance(lay, dict):
        try:
            channels = int(lay["rows"]) * int(lay["cols"]) * int(lay["channels_per_taxel"])
        except (KeyError, TypeError, ValueError):
            channels = None
        if channels is not None and channels != width:
            out.append(f"metadata layout {lay.get('name')} describes {channels} channels "
                       f"but frames/raw has {width}")
    attr = s._f.attrs.get("layout")
    if isinstance(attr, bytes):
        attr = attr.decode()
    if attr and str(attr) != s.layout.name:
        out.append(f"file attribute layout {attr} but metadata layout {s.layout.name}")
    device = meta.get("device")
    if isinstance(device, dict) and device.get("layout") and device["layout"] != s.layout.name:
        out.append(f"device delivers layout {device['layout']} but the session's is "
                   f"{s.layout.name}")
    sensor = meta.get("sensor_id")
    if meta.get("calibration_id") and not sensor:
        out.append(f"calibration_id {meta['calibration_id']} without a sensor_id")
    if isinstance(device, dict) and device.get("sensor_id") and sensor \
            and device["sensor_id"] != sensor:
        out.append(f"sensor_id {sensor} but the device says {device['sensor_id']}")
    wellness = meta.get("wellness")
    if isinstance(wellness, dict) and wellness.get("sensor_id") and sensor \
            and wellness["sensor_id"] != sensor:
        out.append(f"sensor_id {sensor} but the wellness check was of {wellness['sensor_id']}")


# ---- trials -----------------------------------------------------------------------------
def _check_trials(s: SessionFile, out: list[str]) -> list[dict[str, Any]]:
    """The trials that are well formed (others are reported), in index order."""
    n = s.n_frames
    meta = s.metadata
    n_blocks = len(meta["block_order"]) if isinstance(meta.get("block_order"), list) else None
    good: list[dict[str, Any]] = []
    for t in s.journal.trials:
        name = f"trial {t.get('index', '?')}"
        missing = [k for k in TRIAL_FIELDS if k not in t]
        if missing:
            out.append(f"{name}: no {', '.join(missing)}")
            continue
        try:
            a, b, block = int(t["start_sample"]), int(t["end_sample"]), int(t.get("block", 0))
        except (TypeError, ValueError):
            out.append(f"{name}: rows or block not whole numbers")
            continue
        if "status" in t and t["status"] not in STATUSES:  # an absent status reads ok
            out.append(f"{name}: status {t['status']!r} (not {', '.join(sorted(STATUSES))})")
        if block < -1 or (n_blocks is not None and block >= n_blocks):
            out.append(f"{name}: block {block} outside the session's blocks "
                       f"(-1..{(n_blocks or 0) - 1})" if n_blocks is not None
                       else f"{name}: block {block} below -1 (practice)")
        flags = t.get("flags") or ()
        if not 0 <= a < b:
            out.append(f"{name}: rows {a}..{b} are not a range of frames")
        elif b > n and "dropped_frames" not in flags:
            out.append(f"{name}: rows {a}..{b} end past the {n} frames")
        st, et = t.get("start_time"), t.get("end_time")
        if isinstance(st, (int, float)) and isinstance(et, (int, float)) and et < st:
            out.append(f"{name}: ends ({_s(et)} s) before it starts ({_s(st)} s)")
        out.extend(f"{name}: {p}" for p in check_problems(t))  # its model check, decision
        good.append(t)
    by_index = sorted(good, key=lambda t: int(t["index"]))
    # in order along the frames: no two trials share a row, and their times follow
    # their rows (a clock that went back shows as a trial starting before the last)
    by_row = sorted(good, key=lambda t: (int(t["start_sample"]), int(t["index"])))
    for prev, t in zip(by_row, by_row[1:]):
        if int(t["start_sample"]) < int(prev["end_sample"]):
            out.append(f"trial {t['index']} (rows {t['start_sample']}..{t['end_sample']}) "
                       f"starts before trial {prev['index']} ends (row {prev['end_sample']})")
        st, pt = t.get("start_time"), prev.get("start_time")
        if isinstance(st, (int, float)) and isinstance(pt, (int, float)) and st < pt:
            out.append(f"trial {t['index']} starts at {_s(st)} s, before trial "
                       f"{prev['index']} ({_s(pt)} s): its time jumps back")
    return by_index


# ---- events -----------------------------------------------------------------------------
def _frame(e: dict[str, Any]) -> int | None:
    f = e.get("frame")
    return f if isinstance(f, int) and not isinstance(f, bool) else None


def _check_events(s: SessionFile, trials: list[dict[str, Any]], out: list[str]) -> None:
    n = s.n_frames
    for e in s.events:
        f = _frame(e)
        if f is None:
            out.append(f"event {e.get('kind')}: no frame")
        elif not 0 <= f <= n:
            out.append(f"event {e.get('kind')} at frame {f}, outside the {n} frames")
    blocks: dict[int, list[dict[str, Any]]] = {}
    for t in trials:
        blocks.setdefault(int(t.get("block", 0)), []).append(t)
    starts = [e for e in s.events if e.get("kind") == "block_start" and _frame(e) is not None]
    first_start: dict[int, int] = {}
    last_start: dict[int, int] = {}
    for e in starts:
        try:
            b = int(e["block"])
        except (KeyError, TypeError, ValueError):
            out.append(f"block_start at frame {e['frame']}: no block number")
            continue
        first_start[b] = min(first_start.get(b, e["frame"]), e["frame"])
        last_start[b] = max(last_start.get(b, e["frame"]), e["frame"])
    # a redo may reopen an earlier block after this one began: the runner then starts
    # this block again, so its last block_start follows every trial of earlier blocks
    for b, frame in sorted(last_start.items()):
        before = [t for t in trials if int(t.get("block", 0)) < b]
        if before:
            last = max(before, key=lambda t: int(t["end_sample"]))
            if frame < int(last["end_sample"]):
                out.append(f"block_start of block {b} at frame {frame} is before trial "
                           f"{last['index']} of block {last.get('block', 0)} ends (row "
                           f"{last['end_sample']})")
    if starts:
        for b, ts in sorted(blocks.items()):
            first = min(ts, key=lambda t: int(t["start_sample"]))
            if b in first_start and first_start[b] > int(first["start_sample"]):
                out.append(f"block_start of block {b} at frame {first_start[b]} is after its "
                           f"first trial {first['index']} starts (row {first['start_sample']})")
    if trials:
        last = max(trials, key=lambda t: int(t["end_sample"]))
        first = min(trials, key=lambda t: int(t["start_sample"]))
        for e in s.events:
            f = _frame(e)
            if f is None:
                continue
            if e.get("kind") == "session_end" and f < int(last["end_sample"]):
                out.append(f"session_end at frame {f} is before trial {last['index']} ends "
                           f"(row {last['end_sample']})")
            if e.get("kind") in ("session_start", "free_play") and \
                    f > int(first["start_sample"]) and not _after_resume(s, f):
                out.append(f"{e['kind']} at frame {f} is after trial {first['index']} starts "
                           f"(row {first['start_sample']})")


def _check_markers(s: SessionFile, out: list[str]) -> None:
    """Another program's LSL marker (``--markers``) is at the frame whose host time is
    nearest its own (streams/marker_inlet.py; one stamped before the first frame at row
    0), never at a later row when an earlier one is nearer. (An earlier row is allowed:
    a marker that waited over a second for its frame, the device silent, takes the
    newest frame there was.) Imports place markers by their own rule: not checked."""
    n = s.n_frames
    if n == 0 or str(s.metadata.get("source") or "").startswith("import:"):
        return
    marks = [e for e in s.events if e.get("kind") == "marker" and e.get("source") == "lsl"
             and _frame(e) is not None and 0 < e["frame"] < n
             and isinstance(e.get("time"), (int, float))]
    if not marks:
        return
    host = s.column("host_time", 0, n)
    for e in marks:
        row, t = e["frame"], float(e["time"])
        if abs(host[row - 1] - t) < abs(host[row] - t):
            near = nearest_frame(host, t)
            out.append(f"marker {str(e.get('text'))[:40]!r} at row {row} is "
                       f"{t - host[row]:+.3f} s from its frame, but row {near} is nearer "
                       f"({t - host[near]:+.3f} s)")


def _after_resume(s: SessionFile, frame: int) -> bool:
    """A resumed run starts its session again: its session_start follows earlier trials."""
    return any(is_segment_start(e) and _frame(e) is not None and e["frame"] <= frame
               for e in s.events)


def _check_counters(s: SessionFile, out: list[str]) -> None:
    counters = s.journal.counters
    if not counters:
        return
    for key, kind in COUNTED_EVENTS:
        if key not in counters:
            continue
        events = sum(1 for e in s.events if e.get("kind") == kind)
        if int(counters[key]) != events:
            out.append(f"counters say {counters[key]} {key} but the journal has {events} "
                       f"{kind} events")
    if "dropped" in counters:
        lost = sum(int(e.get("lost") or 0) for e in s.events if e.get("kind") == OVERRUN)
        if int(counters["dropped"]) != lost:
            out.append(f"counters say {counters['dropped']} dropped frames but the overrun "
                       f"events lost {lost}")


def summary_line(result: CheckResult, shown: int = 3) -> str:
    """``FILE: 2 violations: first; second`` (the first ``shown``)."""
    v = result.violations
    if not v:
        return f"{result.path}: ok"
    more = f"; {len(v) - shown} more" if len(v) > shown else ""
    return (f"{result.path}: {len(v)} violation{'s' if len(v) != 1 else ''}: "
            + "; ".join(v[:shown]) + more)


def verdict_text(violations: list[str]) -> str:
    """The one line a window shows for a file (the player's badge, the Sessions tab's
    problem column): "passes check", or "fails check: 3 problems: <the first>"."""
    if not violations:
        return "passes check"
    n = len(violations)
    return f"fails check: {n} problem{'s' if n != 1 else ''}: {violations[0]}"


__all__ = ["CheckResult", "check_file", "check_session", "summary_line", "verdict_text"]
