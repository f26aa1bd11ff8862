"""A sensor's history as series to plot: per-spot sensitivity and verdicts over hours of use.

Qt-free: the Sensors window only draws what this returns.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from tactile_studio.storage.logbook import Logbook


@dataclass
class SensorHistory:
    sensor: str
    summary: dict[str, Any]
    # per spot: (hours, ratio to reference) of every check that loaded it
    spot_series: dict[str, tuple[list[float], list[float]]] = field(default_factory=dict)
    verdicts: list[tuple[float, str, int]] = field(default_factory=list)  # hours, verdict, id
    calibrations: list[dict[str, Any]] = field(default_factory=list)
    notes: list[dict[str, Any]] = field(default_factory=list)


def sensor_history(sensor: str, book: Logbook | None = None) -> SensorHistory:
    """Collect what the Sensors window shows for one sensor (UnknownSensor if none)."""
    own = book is None
    book = book or Logbook()
    try:
        hist = book.history(sensor)
        out = SensorHistory(sensor, {k: hist[k] for k in (
            "id", "hours", "last_verdict", "last_check_at", "active_calibration", "created")})
        for c in hist["checks"]:
            out.verdicts.append((float(c["hours"]), c["verdict"], int(c["id"])))
            for s in c["spots"]:
                if s.get("ratio") is None:
                    continue
                hours, ratios = out.spot_series.setdefault(s["taxel"], ([], []))
                hours.append(float(c["hours"]))
                ratios.append(float(s["ratio"]))
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
