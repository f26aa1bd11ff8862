"""What a frame stream carries, written into (and read back from) its LSL XML metadata.

Channels follow the XDF meta-data convention (``desc/channels/channel`` with ``label``,
``type``, ``unit``) plus ``taxel``, ``row`` and ``col``, so a recipient can rebuild the
grid without Tactile Studio. ``desc/tactile_studio`` says what the stream is: ``content``
(raw | decoded), the layout (name and geometry), the device, its settings, the sensor ID
when known, the calibration in use and the host->LSL clock offset at the start.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import asdict
from typing import Any

import numpy as np

from tactile_studio import __version__
from tactile_studio.sensor.channels import (  # noqa: F401 - re-exported
    DECODED,
    DECODED_ROLES,
    RAW,
    ROLE_NAMES,
    frame_channels,
)
from tactile_studio.sensor.decode import decode
from tactile_studio.sensor.layout import Layout
from tactile_studio.streams.clock import ClockOffset

FRAME_TYPE, MARKER_TYPE = "Tactile", "Markers"


def decoded_channels(layout: Layout, raw: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """(n, channels) float32 in :func:`frame_channels` order for decoded content."""
    st = decode(layout, raw, baseline)
    n = st.normal.shape[0]
    parts = [st.normal.reshape(n, -1)]
    if layout.has_shear:
        parts += [st.shear_x.reshape(n, -1), st.shear_y.reshape(n, -1)]
    return np.ascontiguousarray(np.concatenate(parts, axis=1), dtype=np.float32)


def stable_source_id(device: str, content: str, settings: dict[str, Any],
                     sensor_id: str | None) -> str:
    """Same device, settings and content -> same source_id, so LSL recipients recover
    the stream after a restart instead of seeing a new one."""
    if sensor_id:
        ident = str(sensor_id)
    else:
        blob = json.dumps(settings, sort_keys=True, default=str).encode()
        ident = hashlib.sha1(blob).hexdigest()[:10]
    return f"tactile-studio:{device}:{content}:{ident}"


def public_settings(settings: dict[str, Any]) -> dict[str, Any]:
    """The device settings as a stream may publish them: a path (a replayed file, a
    serial port) by its last part only, so the stream's metadata, which anyone on the
    network can read, says nothing about the host's folders or user names."""
    def public(value: Any) -> Any:
        if isinstance(value, os.PathLike):
            value = os.fspath(value)
        if isinstance(value, str) and ("/" in value or "\\" in value or value[:1] == "~"):
            return re.split(r"[\\/]", value.rstrip("/\\"))[-1]
        return value
    return {k: public(v) for k, v in settings.items()}


def _append(elem: Any, values: dict[str, Any]) -> None:
    for key, value in values.items():
        if isinstance(value, dict):
            _append(elem.append_child(key), value)
        elif value is not None:
            elem.append_child_value(key, value if isinstance(value, str) else json.dumps(value))


def frame_stream_info(pylsl: Any, layout: Layout, device_info: dict[str, Any], content: str,
                      name: str, source_id: str, offset: ClockOffset) -> Any:
    """A ``pylsl.StreamInfo`` for a frame stream, with the full description."""
    channels = frame_channels(layout, content)
    integer = content == RAW and np.issubdtype(np.dtype(layout.raw_dtype), np.integer)
    fmt = pylsl.cf_int32 if integer else pylsl.cf_float32
    info = pylsl.StreamInfo(name, FRAME_TYPE, len(channels),
                            float(device_info.get("nominal_rate_hz") or 0.0), fmt, source_id)
    desc = info.desc()
    chans = desc.append_child("channels")
    for ch in channels:
        _append(chans.append_child("channel"), {k: str(v) for k, v in ch.items()})
    sensor_id = device_info.get("sensor_id") or device_info.get("settings", {}).get("sensor_id")
    _append(desc.append_child("acquisition"), {
        "manufacturer": "Tactile Studio", "model": str(device_info.get("plugin", "")),
        "serial_number": str(sensor_id) if sensor_id else None})
    cal = layout.calibration
    _append(desc.append_child("tactile_studio"), {
        "version": __version__, "content": content,
        "device": str(device_info.get("plugin", "")),
        "settings": json.dumps(public_settings(device_info.get("settings", {})),
                               sort_keys=True, default=str),
        "sensor_id": str(sensor_id) if sensor_id else None,
        "layout": {"name": layout.name, "rows": str(layout.rows), "cols": str(layout.cols),
                   "channels_per_taxel": str(layout.channels_per_taxel),
                   "column_major": "1" if layout.column_major else "0",
                   "pitch_mm": repr(layout.pitch_mm), "units": layout.units},
        "calibration": json.dumps(asdict(cal)) if (cal and content == DECODED) else None,
        "baseline": "the latest 'tare' marker of the marker stream" if content == DECODED
        else None,
        "clock": {"offset_s": repr(offset.offset_s),
                  "uncertainty_s": repr(offset.uncertainty_s),
                  "meaning": "lsl_time = host_time + offset_s"},
    })
    return info


def read_tactile_desc(info: Any) -> dict[str, str]:
    """``desc/tactile_studio`` of a stream as flat text (empty if not one of ours)."""
    node = info.desc().child("tactile_studio")
    if node.empty():
        return {}
    out = {k: node.child_value(k) for k in ("content", "device", "sensor_id", "version")}
    out["layout"] = node.child("layout").child_value("name")
    return {k: v for k, v in out.items() if v}
