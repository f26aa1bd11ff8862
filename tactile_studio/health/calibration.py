"""The calibration procedure: known loads on each taxel (or a plate), fits, logbook.

Used by ``tactile-studio calibrate`` and the calibration wizard. Loads go on in
increasing order; each is placed, left to settle, recorded and lifted by the bench.
Only a complete calibration is stored (a new version in the logbook, made active) and
written to its JSON file; a cancelled or failed run leaves both untouched.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.errors import UserError
from tactile_studio.file_claims import written_whole
from tactile_studio.health.bench import Bench, EventFn, Placer, Timing
from tactile_studio.health.events import CalibrationDone, Warned
from tactile_studio.health.wellness import resolve_sensor
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.output_faults import (
    CALIBRATION_FILE,
    require_writable_file,
    stored_already,
)
from tactile_studio.sensor.calibration import (
    CalibrationError,
    calibration_data,
    check_loads,
    coverage,
    decode_calibrated,
    fit_taxel,
    measured_only,
)
from tactile_studio.sensor.decode import StressFrames, relative_change
from tactile_studio.sensor.layout import CENTRE
from tactile_studio.sensor.taxels import distinct_taxels
from tactile_studio.sensor.wellness import parse_taxel, stress_kpa, taxel_label
from tactile_studio.storage.books.calibration_store import store_calibration
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.storage.format.session_file import SessionFile


@dataclass(frozen=True)
class CalibrationSpec:
    sensor: str
    loads_g: tuple[float, ...]
    taxels: tuple[str, ...] | None = None   # None: every taxel
    plate: bool = False
    contact_mm: float = 14.0                # indenter side (per-taxel loads)
    plate_mm: float | None = None           # plate side (default: the array's extent)
    replace: bool = False                   # drop the active calibration's other taxels


def run_calibration(engine: LiveStream, spec: CalibrationSpec,
                    out: str | os.PathLike | None = None, placer: Placer | None = None,
                    timing: Timing = Timing(), progress: ProgressFn = no_progress,
                    cancel: CancelToken | None = None, on_event: EventFn | None = None,
                    bench: Bench | None = None) -> dict[str, Any]:
    """Measure, fit, store a new calibration version; returns it (with ``calibration_id``)."""
    lay = engine.layout
    loads = check_loads([float(v) for v in spec.loads_g])
    if not lay.has_shear or lay.calibration is None:
        raise UserError(f"calibration needs a calibrated shear+normal sensor, not {lay.name}")
    taxels = (list(range(lay.n_taxels)) if not spec.taxels
              else distinct_taxels(lay, [parse_taxel(lay, name) for name in spec.taxels]))
    if out is not None:  # before measuring: the file is written after the logbook's store
        require_writable_file(out, "the calibration", CALIBRATION_FILE)
    side = spec.plate_mm or lay.pitch_mm * max(lay.rows, lay.cols)
    kpa = np.array([stress_kpa(m, side if spec.plate else spec.contact_mm) for m in loads])
    # a calibration must be stored: a damaged logbook is moved aside (backup or new)
    with Logbook(on_damage="replace") as book:
        sensor = resolve_sensor(book, engine.device, spec.sensor, lay.name)
    bench = bench or Bench(engine, placer, timing, cancel, on_event)
    centre = np.array([lay.channel(t, CENTRE) for t in taxels])
    samples: list[list[np.ndarray]] = [[] for _ in taxels]  # per taxel, per load: frames
    progress(0.0, "rest")
    bench.rest()
    if spec.plate:
        for j, mass in enumerate(loads):
            progress(j / len(loads), f"plate {mass:g} g")
            raw = bench.load(mass, None, float(kpa[j]), recover=0.005)
            rel = relative_change(lay, raw, bench.baseline)[:, centre]
            for i in range(len(taxels)):
                samples[i].append(rel[:, i])
    else:
        steps = len(taxels) * len(loads)
        for i, t in enumerate(taxels):
            for j, mass in enumerate(loads):
                progress((i * len(loads) + j) / steps, f"{taxel_label(lay, t)} {mass:g} g")
                raw = bench.load(mass, t, float(kpa[j]), spec.contact_mm, recover=0.005)
                samples[i].append(relative_change(lay, raw, bench.baseline)[:, centre[i]])
    fits, skipped = [], []
    for i, t in enumerate(taxels):
        try:
            fits.append(fit_taxel(lay, t, kpa, samples[i]))
        except CalibrationError as exc:  # a dead taxel must not sink the other 35
            skipped.append({"taxel": taxel_label(lay, t), "reason": str(exc)})
            bench.emit(Warned(f"not calibrated: {exc}"))
    if not fits:
        raise CalibrationError(f"no taxel could be calibrated ({skipped[0]['reason']}); "
                               "nothing was stored")
    kind = "plate" if spec.plate else "per-taxel"
    data = calibration_data(lay, kind, loads, fits, {"skipped": skipped,
        "sensor": sensor, "contact_mm": spec.contact_mm, "plate_mm": side if spec.plate else None,
        "device": engine.device_info()})
    with Logbook() as book:
        data = store_calibration(book, sensor, kind, data, lay.n_taxels, spec.replace)
    if out is not None:
        with stored_already(f"calibration #{data['calibration_id']} of {sensor} is stored "
                            "in the logbook (active)"):
            _write_atomic(Path(out), data)
    progress(1.0, f"rms {data['rms_pct_max']:.2f}% of range")
    bench.emit(CalibrationDone(int(data["calibration_id"])))
    return data


def replace_instead(cal: dict[str, Any], out: str | os.PathLike | None = None
                    ) -> dict[str, Any]:
    """The calibration ``cal`` just stored merged, kept to the taxels it measured: the user
    chose (after seeing the merge) to replace the calibration it merged with. The same
    logbook version (and its CAL.json ``out``) is rewritten; it stays active."""
    if not cal.get("coverage", {}).get("kept"):
        return cal
    dropped = [f["taxel"] for f in cal["fits"] if f.get("from_calibration") is not None]
    new = measured_only(cal)
    new["coverage"] = coverage(cal["coverage"]["of"], new)
    new["replaced_calibration"], new["dropped"] = cal.get("merged_with"), dropped
    with Logbook() as book:
        book.update_calibration(cal["calibration_id"], new["rms_pct_max"], new)
    if out is not None:
        _write_atomic(Path(out), new)
    return new


def coverage_line(cal: dict[str, Any], replace_hint: str = "--replace drops them") -> str:
    """"covers 36 of 36 taxels: 4 measured now, 32 kept from calibration #1" (the CLI's
    and the wizard's words for what a new calibration covers)."""
    cov = cal["coverage"]
    line = f"covers {cov['taxels']} of {cov['of']} taxels"
    if cov["kept"]:
        kept = ", ".join(f"{len(v)} kept from calibration #{k}" for k, v in cov["kept"].items())
        line += f": {len(cov['measured'])} measured now, {kept} ({replace_hint})"
    elif cal.get("dropped"):
        line += (f" (replaced calibration #{cal['replaced_calibration']}: "
                 f"{len(cal['dropped'])} other taxels now read with the nominal curve)")
    return line


def _write_atomic(path: Path, data: dict[str, Any]) -> None:
    """Whole or absent, and one writer at a time (tactile_studio/file_claims.py): written
    to a temporary of this process's own and published under the file's claim (a full
    disk's half-written copy goes; a file another calibration is writing is refused)."""
    text = json.dumps(data, indent=1, default=str)
    written_whole(path, lambda tmp: tmp.write_text(text, encoding="utf-8"),
                  what="calibration file")


def decode_session(path: str | os.PathLike, calibration_id: int | None = None,
                   start: int = 0, stop: int | None = None) -> StressFrames:
    """Decode a recorded session to kPa with any calibration of its sensor.

    Default: the calibration the session was recorded with (``calibration_id`` in its
    metadata). The raw counts in the file are read, never changed.
    """
    with SessionFile(path) as s:
        meta, raw, base, layout = s.metadata, s.raw(start, stop), s.baseline(start), s.layout
    sensor = meta.get("sensor_id")
    cal_id = calibration_id if calibration_id is not None else meta.get("calibration_id")
    if cal_id is None:
        raise UserError(f"{path}: recorded without a calibration; name one to decode with")
    with Logbook() as book:
        cal = book.calibration(int(cal_id))
    if sensor and cal["sensor_id"] != sensor:
        raise UserError(f"{path}: calibration {cal_id} is for sensor {cal['sensor_id']}, "
                        f"the session was recorded with {sensor}")
    return decode_calibrated(layout, raw, base, cal)
