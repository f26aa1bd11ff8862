"""What an XDF stream's header says, as pyxdf gives it ({key: [value]} dicts nested to
any depth: a foreign header may put anything anywhere, so every field is read as text or
a table, never trusted), which stream is tactile and with what layout, BIDS entities in
a file name, and a numeric stream kept as an auxiliary signal."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.sensor.channels import RAW, layout_for_channels
from tactile_studio.sensor.layout import Layout, get_layout
from tactile_studio.storage.exchange.importers._common import ImportFormatError
from tactile_studio.storage.format.aux_signals import AuxSignal
from tactile_studio.terminal import shown

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


def first(d: Any, *path: str) -> Any:
    """pyxdf's nested {key: [value]} dicts, one step per key; None when absent."""
    for key in path:
        if not isinstance(d, dict) or not isinstance(d.get(key), list) or not d[key]:
            return None
        d = d[key][0]
    return d


def text(d: Any, *path: str) -> str:
    """The text at ``path`` ("" when absent or not text: a foreign header may nest
    anything anywhere)."""
    v = first(d, *path)
    return v.strip() if isinstance(v, str) else ""


def node(d: Any, *path: str) -> dict[str, Any]:
    v = first(d, *path)
    return v if isinstance(v, dict) else {}


def stream_name(s: dict[str, Any]) -> str:
    return text(s["info"], "name") or f"stream{s['info'].get('stream_id')}"


def ours(s: dict[str, Any]) -> dict[str, Any]:
    return node(s["info"], "desc", "tactile_studio")


def tactile_layout(s: dict[str, Any], stream: str | None, layout: str | None) -> Layout | None:
    """The layout of a tactile stream, or None for any other stream."""
    info = s["info"]
    n = int(text(info, "channel_count"))  # xdf_scan checked the header
    fmt = text(info, "channel_format")
    name = stream_name(s)
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
    if fmt == "string" or float(text(info, "nominal_srate")) <= 0:
        return None
    desc = ours(s)
    if desc:
        lay_name = text(desc, "layout", "name")
        if text(desc, "content") not in ("", RAW) or not lay_name:
            return None
        lay = get_layout(lay_name)
        return lay if lay.n_channels == n else None
    if text(info, "type").lower() not in TACTILE_TYPES or n < 16:
        return None
    return layout_for_channels(n)


def _labels(s: dict[str, Any], n: int) -> tuple[list[str], str]:
    chans = node(s["info"], "desc", "channels").get("channel") or []
    labels = [text(c, "label") or f"ch{i + 1}" for i, c in enumerate(chans)]
    unit = text(chans[0], "unit") if chans else ""
    return (labels if len(labels) == n else [f"ch{i + 1}" for i in range(n)]), unit


def aux_signal(s: dict[str, Any]) -> AuxSignal:
    values = np.asarray(s["time_series"], dtype=np.float64)
    n = int(text(s["info"], "channel_count"))
    labels, unit = _labels(s, n)
    return AuxSignal(stream_name(s), np.asarray(s["time_stamps"]), values.reshape(-1, n),
                     labels, unit, float(text(s["info"], "nominal_srate")),
                     text(s["info"], "type"), text(s["info"], "source_id"))
