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


@dataclass
class Journal:
    """The journal folded into its current state."""

    metadata: dict[str, Any] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    baselines: list[dict[str, Any]] = field(default_factory=list)
    trials: list[dict[str, Any]] = field(default_factory=list)
    counters: dict[str, Any] = field(default_factory=dict)
    closed: bool = False


def read_journal(f: h5py.File) -> Journal:
    """Fold ``/journal`` (JSON lines) into metadata, events, trials and counters.

    A line cut short by a crash is ignored; everything before it counts.
    """
    j = Journal()
    trials: dict[int, dict[str, Any]] = {}
    data = bytes(f["journal"][:]) if "journal" in f else b""
    for line in data.split(b"\n"):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except ValueError:
            continue
        kind = rec.pop("type", None)
        if kind == "metadata":
            j.metadata.update(rec.get("update", {}))
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
