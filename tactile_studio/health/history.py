"""A sensor's history as series to plot: per-spot sensitivity and verdicts over hours of use.

Qt-free: the Sensors window only draws what this returns.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from tactile_studio.storage.books.logbook import Logbook


@dataclass
class SpotPoint:
    hours: float
    ratio: float
    reference: str   # what the ratio is against: "calibration #2", "check #1", "nominal"
    check_id: int


@dataclass
class SensorHistory:
    sensor: str
    summary: dict[str, Any]
    # per spot: (hours, ratio to reference) of every check that loaded it
    spot_series: dict[str, tuple[list[float], list[float]]] = field(default_factory=dict)
    # the same points with what each ratio is against (ratios to different references
    # are different scales: a calibration is not drift)
    spot_points: dict[str, list[SpotPoint]] = field(default_factory=dict)
    # (hours, check id, "nominal → calibration #1"): where the checks' reference changed
    reference_changes: list[tuple[float, int, str]] = field(default_factory=list)
    verdicts: list[tuple[float, str, int]] = field(default_factory=list)  # hours, verdict, id
    calibrations: list[dict[str, Any]] = field(default_factory=list)
    notes: list[dict[str, Any]] = field(default_factory=list)


def spot_reference(result: dict[str, Any], spot: dict[str, Any]) -> str:
    """What one spot's ratio was judged against; a check stored before spots carried it
    says so only for the whole check (then its check outranked its calibration)."""
    if spot.get("reference"):
        return str(spot["reference"])
    if result.get("reference_check") is not None:
        return f"check #{result['reference_check']}"
    if result.get("reference_calibration") is not None:
        return f"calibration #{result['reference_calibration']}"
    return "nominal"


def reference_words(references: set[str]) -> str:
    """"calibration #1" / "nominal curve" / "calibration #1 and check #2"."""
    names = sorted("nominal curve" if r == "nominal" else r for r in references)
    return " and ".join(names) or "nominal curve"


def sensor_history(sensor: str, book: Logbook | None = None) -> SensorHistory:
    """Collect what the Sensors window shows for one sensor (UnknownSensor if none)."""
    own = book is None
    book = book or Logbook()
    try:
        hist = book.history(sensor)
        out = SensorHistory(sensor, {k: hist[k] for k in (
            "id", "hours", "last_verdict", "last_check_at", "active_calibration", "created")})
        before: set[str] | None = None
        for c in hist["checks"]:
            out.verdicts.append((float(c["hours"]), c["verdict"], int(c["id"])))
            used: set[str] = set()
            for s in c["spots"]:
                if s.get("ratio") is None:
                    continue
                hours, ratios = out.spot_series.setdefault(s["taxel"], ([], []))
                hours.append(float(c["hours"]))
                ratios.append(float(s["ratio"]))
                ref = spot_reference(c, s)
                used.add(ref)
                out.spot_points.setdefault(s["taxel"], []).append(
                    SpotPoint(float(c["hours"]), float(s["ratio"]), ref, int(c["id"])))
            if used and before is not None and used != before:
                out.reference_changes.append((float(c["hours"]), int(c["id"]), (
                    f"{reference_words(before)} → {reference_words(used)}")))
            before = used or before
        out.calibrations = hist["calibrations"]
        out.notes = hist["notes"]
        return out
    finally:
        if own:
            book.close()


def covers_text(calibration: dict[str, Any]) -> str:
    """What one calibration (a ``Logbook.calibrations`` row) covers, in words: "36 of 36
    taxels (4 measured, 32 from #1)"; "" for a record that cannot say."""
    c = calibration
    if c.get("taxels") is None:
        return ""
    kept = "".join(f", {len(v)} from #{k}" for k, v in c.get("kept", {}).items())
    return f"{c['taxels']} of {c['of']} taxels ({len(c['measured'])} measured{kept})"
