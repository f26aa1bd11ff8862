"""Auxiliary signals: other instruments' streams (EDA, ECG, another sensor) kept in a
session beside the touch, each with its own timestamps.

Stored as ``/aux/<key>/time`` (f8, seconds on the clock of ``/frames/host_time``) and
``/aux/<key>/values`` (f8, (n, channels)), with attributes ``name`` (the stream's own
name), ``labels_json`` (channel labels), ``unit``, ``rate_hz`` (nominal, 0 = irregular),
``type`` and ``source_id``. Written before the file switches to SWMR (imports), so they
exist from the first flush; readers that predate them ignore the group.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import Any

import h5py
import numpy as np

GROUP = "aux"


@dataclass
class AuxSignal:
    """One auxiliary stream: ``time`` (n,) and ``values`` (n, channels)."""

    name: str
    time: np.ndarray
    values: np.ndarray
    labels: list[str] = field(default_factory=list)
    unit: str = ""
    rate_hz: float = 0.0
    type: str = ""
    source_id: str = ""

    def __post_init__(self) -> None:
        self.time = np.asarray(self.time, dtype=np.float64).reshape(-1)
        values = np.asarray(self.values, dtype=np.float64)
        self.values = values.reshape(len(self.time), -1)
        if not self.labels:
            self.labels = [f"ch{i + 1}" for i in range(self.values.shape[1])]

    @property
    def n_channels(self) -> int:
        return int(self.values.shape[1])


def aux_key(name: str, taken: set[str]) -> str:
    """An HDF5-safe, unique group name for a stream name."""
    base = re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_.") or "signal"
    key, k = base, 2
    while key in taken:
        key, k = f"{base}_{k}", k + 1
    taken.add(key)
    return key


def write_aux(f: h5py.File, signals: list[AuxSignal]) -> None:
    """Create ``/aux`` with one group per signal (before SWMR: see the module docstring)."""
    if not signals:
        return
    root = f.require_group(GROUP)
    taken = set(root.keys())
    for s in signals:
        g = root.create_group(aux_key(s.name, taken))
        g.create_dataset("time", data=s.time)
        g.create_dataset("values", data=s.values)
        g.attrs["name"] = s.name
        g.attrs["labels_json"] = json.dumps(list(s.labels))
        g.attrs["unit"] = s.unit
        g.attrs["rate_hz"] = float(s.rate_hz)
        g.attrs["type"] = s.type
        g.attrs["source_id"] = s.source_id


def _text(value: Any) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def read_aux(f: h5py.File) -> list[AuxSignal]:
    """Every auxiliary signal of an open session file, in group order."""
    if GROUP not in f:
        return []
    out = []
    for key, g in f[GROUP].items():
        a = g.attrs
        out.append(AuxSignal(
            name=_text(a.get("name", key)), time=g["time"][()], values=g["values"][()],
            labels=list(json.loads(_text(a.get("labels_json", "[]")))),
            unit=_text(a.get("unit", "")), rate_hz=float(a.get("rate_hz", 0.0)),
            type=_text(a.get("type", "")), source_id=_text(a.get("source_id", ""))))
    return out
