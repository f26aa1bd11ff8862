"""Marker strings of the marker stream: one JSON object per marker (docs/lsl.md).

Every marker has ``kind`` and ``source`` (``engine`` | ``collect`` | ``inference`` |
``app``) and, where known, ``frame`` (the engine frame index it refers to). The rest is the
event's own detail. The LSL timestamp of a marker is the host time it refers to (the
event's time, or the host arrival time of the frame it names) on LSL's clock.
"""

from __future__ import annotations

import json
import math
from typing import Any, Protocol

import numpy as np

SKIPPED_ENGINE_KINDS = frozenset({"lsl_clock"})  # bookkeeping for the session file only
_RUNNER_KINDS = {"hint": "refused", "trial_started": "trial_start", "trial_ended": "trial_end"}


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def to_json(marker: dict[str, Any]) -> str:
    """Compact, key-ordered JSON (kind and source first)."""
    head = {"kind": marker["kind"], "source": marker["source"]}
    body = {k: v for k, v in marker.items() if k not in head}
    return json.dumps(_plain({**head, **body}), separators=(",", ":"), default=str)


def engine_marker(event: dict[str, Any]) -> dict[str, Any] | None:
    """An engine event (connect, disconnect, reconnect, gap, tare, error...) as a marker;
    None for events that are not for the marker stream."""
    if event["kind"] in SKIPPED_ENGINE_KINDS:
        return None
    detail = {k: v for k, v in event.items() if k not in ("kind", "time", "frame")}
    return {"kind": event["kind"], "source": "engine", "frame": event.get("frame"), **detail}


class RecordedEvent(Protocol):
    """A typed event with a plain form (protocol/runner_events.py; protocol is a layer above
    streams, so the marker stream knows the runner's events by their plain form only)."""

    def to_record(self) -> dict[str, Any]: ...


def runner_marker(event: RecordedEvent) -> dict[str, Any]:
    """A collection-runner event (``TrialRunner.add_listener``) as a marker."""
    detail = event.to_record()
    kind = detail.pop("kind")
    if kind == "trial_started":
        detail["frame"] = detail.pop("start_frame", None)
    elif kind in ("trial_ended", "trial_updated"):
        trial = detail.pop("trial", {})
        keep = ("index", "block", "gesture", "key", "status", "reason", "flags",
                "start_sample", "end_sample")
        detail.update({k: trial[k] for k in keep if k in trial})
        if kind == "trial_updated":
            status = trial.get("status")
            kind = {"redone": "redo", "discarded": "discard"}.get(status, kind)
    return {"kind": _RUNNER_KINDS.get(kind, kind), "source": "collect", **detail}


def prediction_marker(label: str, probability: float | None = None,
                      scores: dict[str, float] | None = None, frame: int | None = None,
                      model: str | None = None) -> dict[str, Any]:
    """A live-inference prediction as a marker."""
    out: dict[str, Any] = {"kind": "prediction", "source": "inference", "label": str(label)}
    if probability is not None:
        out["probability"] = round(float(probability), 6)
    if scores:
        out["scores"] = {str(k): round(float(v), 6) for k, v in scores.items()}
    if frame is not None:
        out["frame"] = int(frame)
    if model:
        out["model"] = str(model)
    return out
