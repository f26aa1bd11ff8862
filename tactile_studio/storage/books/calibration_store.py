"""Storing a new calibration as a sensor's active one, for every path that makes one
(``calibrate``, the calibration wizard, ``characterise --save-calibration``).

A calibration of some taxels merges with the sensor's active calibration (the taxels it
measured take their new curves, the others keep theirs: sensor/calibration.py
``merge_calibration``) unless ``replace``: a 4-taxel calibration must not silently drop
the other 32 taxels of a plate calibration back to the nominal curve. The stored record
says what it covers (``coverage``) and which calibration a replacement dropped taxels of.
"""

from __future__ import annotations

from typing import Any

from tactile_studio.sensor.calibration import coverage, merge_calibration
from tactile_studio.storage.books.logbook import Logbook


def store_calibration(book: Logbook, sensor: str, kind: str, data: dict[str, Any],
                      n_taxels: int, replace: bool = False,
                      rms_pct: float | None = None) -> dict[str, Any]:
    """Store ``data`` (merged with the active calibration unless ``replace``) as the
    sensor's new active version; returns what was stored, with ``calibration_id``.
    ``rms_pct``: the logbook's summary figure (default: the stored worst rms)."""
    active = book.active_calibration(sensor)
    dropped: list[str] = []
    if active is not None:
        old = book.calibration(active)
        measured = {f["taxel"] for f in data["fits"]}
        if replace:
            dropped = [f["taxel"] for f in old.get("fits", []) if f["taxel"] not in measured]
        else:
            data = merge_calibration(data, old, active)
    data = {**data, "coverage": coverage(n_taxels, data),
            "replaced_calibration": active if dropped else None, "dropped": dropped}
    rms = data["rms_pct_max"] if rms_pct is None or data.get("merged") else rms_pct
    data["calibration_id"] = book.add_calibration(sensor, kind, rms, data)
    return data
