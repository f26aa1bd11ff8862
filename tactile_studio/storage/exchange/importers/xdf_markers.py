"""An XDF file's marker streams -> events, trials and baselines at frame rows.

A marker is what a stranger says, so it is stored as content, never as the fields of our
records. Only a marker stream that declares itself ours (``desc/tactile_studio/format``
``json``: our export and our live marker outlet write it) is read as Tactile Studio
markers, and in it only a JSON object whose every field has the type we write
(:func:`why_not_ours`): ``trial_start`` / ``trial_end`` pairs become trials (``redo`` /
``discard`` set statuses), a ``tare`` with a baseline of the layout's channels a
baseline, any other kind its own event. Everything else (plain text, another program's
JSON, a marker claiming to be ours with a field we never write, a value of the wrong
type, a trial over another trial's rows) is a ``marker`` event holding what was sent
(``text``, ``stream``, and ``channels`` for a stream of several: foreign.marker_content),
and :attr:`MarkerReader.refused` counts why, for the import to say.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from typing import Any

import numpy as np

from tactile_studio.foreign import marker_content
from tactile_studio.storage.format.trials import TrialStatus
from tactile_studio.terminal import shown

# fields of our journal records that no marker of ours carries (``frame`` and ``row`` are
# ours too: the export writes them, the import places a marker by its time instead)
RECORD_FIELDS = ("type", "time")
MAX_INDEX = 10**9
STATUSES = frozenset(s.value for s in TrialStatus)


def _whole(v: Any, lo: int, hi: int = MAX_INDEX) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and lo <= v < hi


def _text_or_none(v: Any) -> bool:
    return v is None or isinstance(v, str)


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


# what each trial field of our markers holds (trials.TrialRecord), and how to say it
FIELD_TYPES: dict[str, tuple[Any, str]] = {
    "index": (lambda v: _whole(v, 0), "a trial number"),
    "block": (lambda v: _whole(v, -1), "a block number"),
    "gesture": (lambda v: isinstance(v, str), "a text"),
    "key": (_text_or_none, "a text"),
    "status": (lambda v: v in STATUSES, "one of " + ", ".join(sorted(STATUSES))),
    "reason": (_text_or_none, "a text"),
    "flags": (lambda v: isinstance(v, list) and all(isinstance(f, str) for f in v),
              "a list of texts"),
    "start_sample": (lambda v: _whole(v, 0), "a row"),
    "end_sample": (lambda v: _whole(v, 0), "a row"),
    "start_time": (_number, "a time"),
    "end_time": (_number, "a time"),
}


def why_not_ours(m: dict[str, Any], n_channels: int) -> str:
    """"" when ``m`` (a JSON object with ``kind`` and ``source``) is a marker as we
    write it, else why not (one phrase naming the field and its value)."""
    if not isinstance(m.get("kind"), str) or not isinstance(m.get("source"), str):
        return "its kind or source is not a text"
    for key in RECORD_FIELDS:
        if key in m:
            return f"it carries '{key}', a field of our own records"
    for key, (ok, what) in FIELD_TYPES.items():
        if key in m and not ok(m[key]):
            return f"its {key} {shown(json.dumps(m[key]), 40)} is not {what}"
    if m["kind"] == "tare" and "baseline" in m:
        base = m["baseline"]
        if not (isinstance(base, list) and len(base) == n_channels
                and all(_number(v) for v in base)):
            return f"its baseline is not {n_channels} finite numbers"
    return ""


class MarkerReader:
    """Markers -> events, trials and baselines at the rows of frames at ``times``."""

    def __init__(self, times: np.ndarray, n_channels: int) -> None:
        self.times = times
        self.n_channels = n_channels
        self.events: list[tuple[str, int, float, dict[str, Any]]] = []
        self.trials: dict[int, dict[str, Any]] = {}
        self.baselines: list[tuple[int, list[float]]] = []
        self.refused: Counter[str] = Counter()  # why markers that claimed to be ours are not
        self._starts: dict[int, int] = {}
        self._last_start: int | None = None
        self._texts: dict[int, tuple[str, dict[str, Any]]] = {}  # trial -> its end as text

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

    def add(self, stream: str, sample: list[Any], t: float, ours: bool) -> None:
        """One sample (its channels) of marker stream ``stream`` at time ``t``; ``ours``:
        the stream declares itself a Tactile Studio marker stream."""
        row = self.row(t)
        content = {**marker_content(sample), "stream": stream}
        m = None
        if ours and len(sample) == 1:
            try:
                m = json.loads(str(sample[0]))
            except ValueError:
                m = None
        if not (isinstance(m, dict) and "kind" in m and "source" in m):
            self.events.append(("marker", row, t, content))
            return
        why = why_not_ours(m, self.n_channels)
        if not why and m["kind"] == "trial_end" and m.get("index") in self.trials:
            why = "its index names a trial that already ended"
        if why:
            self.refused[why] += 1
            self.events.append(("marker", row, t, content))
            return
        self._ours(m, row, t, stream, content)

    def _ours(self, m: dict[str, Any], row: int, t: float, stream: str,
              content: dict[str, Any]) -> None:
        kind = m.pop("kind")
        m.pop("frame", None)
        m.pop("row", None)
        index = m.get("index")
        if kind == "trial_start":  # live markers name no index: the next end is its own
            if index is not None:
                self._starts[index] = row
            self._last_start = row
        elif kind == "trial_end" and index is not None:
            start = self._starts.pop(index, None)
            if start is None and self._last_start is not None and self._last_start <= row:
                start = self._last_start
            self._last_start = None
            if start is None or start > row:
                start = row + 1 - (m.get("end_sample", 1) - m.get("start_sample", 0))
                start = min(max(start, 0), row)
            keep = {k: v for k, v in m.items() if k not in ("source", "start_sample",
                                                            "end_sample")}
            self.trials[index] = {**keep, "index": index, "start_sample": start,
                                  "end_sample": row + 1,
                                  "start_time": float(self.times[start]),
                                  "end_time": self._after(row),
                                  "status": m.get("status") or "ok"}
            self._texts[index] = (stream, {"t": t, "row": row, **content})
        elif kind in ("redo", "discard") and index is not None and index in self.trials:
            self.trials[index].update(status=m.get("status") or
                                      {"redo": "redone", "discard": "discarded"}[kind],
                                      reason=m.get("reason"))
        else:
            if kind == "tare" and "baseline" in m:
                self.baselines.append((row, [float(v) for v in m.pop("baseline")]))
            self.events.append((kind, row, t, {**m, "stream": m.get("stream", stream)}))

    def trial_list(self) -> list[dict[str, Any]]:
        """The trials in index order, none over another's rows: a trial that starts
        before the previous one (by rows) ends stays a ``marker`` event, its text kept.
        Call once, after every marker; :attr:`events` are then in time order."""
        out: list[dict[str, Any]] = []
        end = 0
        for t in sorted(self.trials.values(), key=lambda t: (t["start_sample"], t["index"])):
            if t["start_sample"] < end:
                stream, where = self._texts[t["index"]]
                self.refused[f"its rows overlap trial {out[-1]['index']}"] += 1
                detail = {k: v for k, v in where.items() if k not in ("t", "row")}
                self.events.append(("marker", where["row"], where["t"], detail))
                continue
            out.append(t)
            end = t["end_sample"]
        self.events.sort(key=lambda e: (e[1], e[2]))  # in the file's order, as recorded
        return sorted(out, key=lambda t: t["index"])

    def refused_line(self) -> str:
        """One phrase: how many markers were kept as text although they claimed to be
        ours, and the most common reason ("" when none)."""
        n = sum(self.refused.values())
        if not n:
            return ""
        why, _ = self.refused.most_common(1)[0]
        return (f"{n} marker{'s' if n != 1 else ''} kept as text, not read as Tactile "
                f"Studio markers ({why}" + (", ..." if len(self.refused) > 1 else "") + ")")
