"""The session file's format: its name and schema version, and the journal.

Everything that is not a frame (metadata updates, events, baselines, trials, counters)
is an append-only stream of JSON lines in ``/journal``; readers fold it into its current
state. Writer and reader both depend on this module, never on each other.
See docs/session-format.md.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import h5py

FORMAT = "tactile-studio-session"
SCHEMA_VERSION = 1
# the journal's kind for frames the recorder lost (it fell a whole buffer behind)
OVERRUN = "overrun"


@dataclass
class Journal:
    """The journal folded into its current state."""

    metadata: dict[str, Any] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    baselines: list[dict[str, Any]] = field(default_factory=list)
    trials: list[dict[str, Any]] = field(default_factory=list)
    counters: dict[str, Any] = field(default_factory=dict)
    closed: bool = False
    # records left out because they are not of their type's shape ("line 12: ..."):
    # a damaged or hand-made file; ``check`` names each
    skipped: list[str] = field(default_factory=list)


# The fields every reader relies on, by record type: a file from elsewhere may hold any
# JSON there, and one such record (a metadata update that is a number, a trial index
# "abc", an event kind that is a table, a count "x") ended info, check and export in a
# traceback. Such a record is left out, as a line cut by a crash is, and named.
_INT, _TEXT, _TABLE, _LIST = "a whole number", "text", "a table", "a list"
RECORD_FIELDS: dict[str, dict[str, str]] = {
    "event": {"kind": _TEXT, "frame": _INT, "lost": _INT, "missing": _INT},
    "baseline": {"frame": _INT, "values": _LIST},
    "trial": {"index": _INT, "block": _INT, "start_sample": _INT, "end_sample": _INT},
    "trial_update": {"index": _INT, "block": _INT, "start_sample": _INT,
                     "end_sample": _INT},
    "counters": {"malformed_by_kind": _TABLE, "gaps": _INT, "reconnects": _INT,
                 "dropped": _INT, "missing_frames": _INT},
    "truncate": {"rows": _INT},
}
REQUIRED = {"event": ("kind",), "baseline": ("frame", "values"), "trial": ("index",),
            "trial_update": ("index",), "truncate": ("rows",)}
# metadata keys readers take apart (``.get`` on a table, iterating a list)
METADATA_FIELDS = {"layout": _TABLE, "device": _TABLE, "protocol_spec": _TABLE,
                   "wellness": _TABLE, "gestures": _LIST, "block_order": _LIST,
                   "practice_order": _LIST, "unmapped_keys": _LIST, "other_sensor": _LIST}


def _is(value: Any, kind: str) -> bool:
    if kind == _INT:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, {_TEXT: str, _TABLE: dict, _LIST: list}[kind])


def _shape_problem(kind: Any, rec: dict[str, Any]) -> str | None:
    """Why a journal record of type ``kind`` cannot be folded, else None."""
    if kind == "metadata":
        return None if isinstance(rec.get("update", {}), dict) else \
            "a metadata update that is not a table"
    fields = RECORD_FIELDS.get(kind) if isinstance(kind, str) else None
    if fields is None:
        return None
    for key in REQUIRED.get(kind, ()):
        if key not in rec:
            return f"{kind} record without {key}"
    for key, want in fields.items():
        if key in rec and not (rec[key] is None and key not in REQUIRED.get(kind, ())) \
                and not _is(rec[key], want):
            return f"{kind} record whose {key} is {_shown(rec[key])}, not {want}"
    if kind == "counters" and not all(_is(v, _INT) for v in
                                      rec.get("malformed_by_kind", {}).values()):
        return "counters record whose malformed_by_kind counts are not whole numbers"
    return None


def _metadata_update(update: dict[str, Any], line: int, skipped: list[str]) -> dict[str, Any]:
    """``update`` without the keys whose values are not of the shape readers rely on."""
    bad = [k for k, want in METADATA_FIELDS.items() if k in update and update[k] is not None
           and not _is(update[k], want)]
    for k in bad:
        skipped.append(f"line {line}: metadata {k} is {_shown(update[k])}, not "
                       f"{METADATA_FIELDS[k]}")
    return {k: v for k, v in update.items() if k not in bad}


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def read_journal(f: h5py.File) -> Journal:
    """Fold ``/journal`` (JSON lines) into metadata, events, trials and counters.

    A line cut short by a crash is ignored; everything before it counts.
    """
    j = Journal()
    trials: dict[int, dict[str, Any]] = {}
    data = bytes(f["journal"][:]) if "journal" in f else b""
    for n, line in enumerate(data.split(b"\n"), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except ValueError:
            continue
        if not isinstance(rec, dict):
            j.skipped.append(f"line {n}: {_shown(rec)} is not a record")
            continue
        kind = rec.pop("type", None)
        why = _shape_problem(kind, rec)
        if why:
            j.skipped.append(f"line {n}: {why}")
            continue
        if kind == "metadata":
            j.metadata.update(_metadata_update(rec.get("update", {}), n, j.skipped))
        elif kind == "event":
            j.events.append(rec)
        elif kind == "baseline":
            j.baselines.append(rec)
        elif kind == "trial":
            trials[int(rec["index"])] = rec
        elif kind == "trial_update":
            idx = int(rec.pop("index"))
            if idx in trials:
                trials[idx].update(rec)
        elif kind == "counters":
            j.counters = rec
        elif kind == "closed":
            j.closed = True
        elif kind == "truncate":  # SessionWriter.truncate: rows past the end were cut
            last = max(0, int(rec["rows"]) - 1)
            for r in (*j.events, *j.baselines):
                if isinstance(r.get("frame"), int) and r["frame"] > last:
                    r["frame"] = last
    j.trials = [trials[k] for k in sorted(trials)]
    return j
