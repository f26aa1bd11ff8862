"""The session facts an exported XDF carries beside its frames, and reading them back.

A session's frames alone do not make it the same recording for a researcher: the
protocol (and its full spec: trial length, gestures, keys), the condition, the gesture
order, the sensor and the calibration it was decoded with, the randomisation seed and
each block's gesture order. ``export --format xdf`` writes them in the frame stream's
``desc/tactile_studio/session``, one element per field whose text is the value as JSON;
``import xdf`` reads them back into the new session's metadata.

What an XDF file says is a stranger's data (anyone can write one): only the fields
below are read, each checked against its kind and size, and a field that fails is
left out rather than trusted. Nothing read here becomes a key of our own records (the
imported session keeps the importer's ``session_id``).
"""

from __future__ import annotations

import json
from typing import Any

from tactile_studio.errors import UserError

TEXT_MAX = 200            # characters in a name or a text field
LIST_MAX = 10_000         # names in a list (shear9: 52 blocks x 9 gestures)
SPEC_MAX = 64 * 1024      # bytes of JSON in the protocol's spec

# metadata key -> kind (see _valid)
CARRIED: dict[str, str] = {
    "protocol": "text", "protocol_spec": "protocol", "condition": "text",
    "gestures": "names", "trial_order": "text", "seed": "int", "order_seed": "int",
    "block_order": "blocks", "practice_order": "names",
    "sensor_id": "text", "calibration_id": "id",
}


def session_desc(meta: dict[str, Any]) -> dict[str, str]:
    """The carried fields a session's metadata has, each as its JSON text (the XML
    element ``session`` in the frame stream's ``desc/tactile_studio``)."""
    return {k: json.dumps(meta[k], sort_keys=True, default=str)
            for k in CARRIED if meta.get(k) is not None}


def _text(v: Any) -> bool:
    return isinstance(v, str) and len(v) <= TEXT_MAX and v.isprintable()


def _names(v: Any) -> bool:
    return isinstance(v, list) and len(v) <= LIST_MAX and all(_text(x) for x in v)


def _valid(kind: str, v: Any) -> bool:
    if kind == "text":
        return _text(v)
    if kind == "int":
        return isinstance(v, int) and not isinstance(v, bool)
    if kind == "id":
        return _valid("int", v) or _text(v)
    if kind == "names":
        return _names(v)
    if kind == "blocks":
        return isinstance(v, list) and len(v) <= LIST_MAX and all(_names(b) for b in v)
    raise ValueError(f"unknown kind {kind!r}")


def _protocol(v: Any) -> dict[str, Any] | None:
    """A protocol's spec as the protocol parser accepts it (its flat form), else None:
    a training later reads the trial length from it."""
    from tactile_studio.storage.format.protocol_file import protocol_from_dict

    if not isinstance(v, dict):
        return None
    try:
        return protocol_from_dict(v, "XDF protocol_spec", check_images=False).to_dict()
    except (UserError, TypeError, ValueError):
        return None


def session_fields(element: Any) -> dict[str, Any]:
    """The carried fields from a ``session`` element as pyxdf reads XML (``{name:
    [text]}``; anything else is no element): those that parse and pass their check."""
    out: dict[str, Any] = {}
    if not isinstance(element, dict):
        return out
    for key, kind in CARRIED.items():
        texts = element.get(key)
        text = texts[0] if isinstance(texts, list) and texts else None
        if not isinstance(text, str) or len(text) > (SPEC_MAX if kind == "protocol" else
                                                       LIST_MAX * (TEXT_MAX + 4)):
            continue
        try:
            value = json.loads(text)
        except (ValueError, RecursionError):  # not JSON, or nested past Python's stack
            continue
        if kind == "protocol":
            value = _protocol(value)
            if value is not None:
                out[key] = value
        elif _valid(kind, value):
            out[key] = value
    return out
