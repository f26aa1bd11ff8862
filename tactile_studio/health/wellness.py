"""The wellness check procedure: rest, then a known weight on each spot, then verdicts.

Used by ``tactile-studio wellness`` and the wellness wizard. The maths is in
:mod:`tactile_studio.sensor.wellness`; this module drives the bench, picks the sensor's
reference from the logbook and stores the result there (only a complete check is
stored: a cancelled or failed run leaves the logbook untouched).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.health.bench import Bench
from tactile_studio.health.events import CheckDone, SpotMeasured
from tactile_studio.jobs import ProgressFn, no_progress
from tactile_studio.sensor.calibration import expected_nominal_kpa
from tactile_studio.sensor.layout import Layout
from tactile_studio.sensor.wellness import (
    DEFAULT_SPOTS,
    PASS,
    Thresholds,
    analyse_rest,
    judge_spots,
    measure_spot,
    parse_taxel,
    stress_kpa,
    taxel_label,
    worst,
)
from tactile_studio.storage.books.logbook import Logbook, check_sensor_id


@dataclass(frozen=True)
class WellnessSpec:
    """What to check: which sensor, which weight, where."""

    sensor: str
    weight_g: float
    spots: tuple[str, ...] = DEFAULT_SPOTS
    contact_mm: float = 14.0


def resolve_sensor(book: Logbook, device: Any, sensor: str, layout_name: str) -> str:
    """The sensor to check: the device's own ID must agree; an ID neither the device nor
    the logbook knows is refused (a typo would otherwise start a new history)."""
    sensor = check_sensor_id(sensor)
    own = device.sensor_id() if hasattr(device, "sensor_id") else None
    if own and own != sensor:
        raise UserError(f"device {device.name} reports sensor {own}, not {sensor}")
    if own:
        book.ensure_sensor(own, layout_name)
        return own
    return book.require(sensor)


# The one rule for what a check's ratios are against, said by the CLI, the wizard, the
# report and the docs alike. The calibration first: it is the engineer's statement of
# how this sensor responds (a check before it no longer is); a spot it does not cover
# falls to the next source, spot by spot.
REFERENCE_RULE = ("each spot against the sensor's active calibration, else its first "
                  "passing check with this weight, else the nominal curve")


def reference_for(book: Logbook, sensor: str, spec: WellnessSpec,
                  layout: Layout) -> dict[str, Any]:
    """The sensor's reference per spot, by :data:`REFERENCE_RULE`: what its active
    calibration predicts for this weight; for spots it does not cover, its first passing
    check with the same weight and contact; else nothing (the nominal curve). The rest
    phase's baseline is that first passing check's. ``source`` says, per spot, which."""
    out: dict[str, Any] = {"check_id": None, "baseline": None, "spots": {},
                           "calibration_id": None, "source": {}, "active_calibration": None}
    first: dict[str, Any] | None = None
    for check in book.checks(sensor):
        res = check["result"]
        if (check["verdict"] == PASS and res.get("weight_g") == spec.weight_g
                and res.get("contact_mm") == spec.contact_mm):
            first = check
            out["baseline"] = res.get("baseline")
            break
    cal_id = out["active_calibration"] = book.active_calibration(sensor)
    fits = {}
    if cal_id is not None and layout.calibration is not None:
        fits = {f["taxel"]: f for f in book.calibration(cal_id).get("fits", [])}
    expected = stress_kpa(spec.weight_g, spec.contact_mm)
    checked = {s["taxel"]: s["normal_kpa"] for s in first["result"].get("spots", [])} \
        if first is not None else {}
    for taxel in spec.spots:
        if taxel in fits:
            out["spots"][taxel] = expected_nominal_kpa(layout, fits[taxel], expected)
            out["calibration_id"] = cal_id
            out["source"][taxel] = f"calibration #{cal_id}"
        elif taxel in checked:
            out["spots"][taxel] = checked[taxel]
            out["check_id"] = first["id"]  # type: ignore[index]
            out["source"][taxel] = f"check #{first['id']}"  # type: ignore[index]
    return out


def spot_taxels(layout: Layout, spots: tuple[str, ...]) -> list[int]:
    """The taxels a check loads: the named spots, or every taxel for ``all``."""
    if [s.strip().lower() for s in spots] == ["all"]:
        return list(range(layout.n_taxels))
    taxels = [parse_taxel(layout, s) for s in spots]
    if not taxels:
        raise UserError("no spots to check (give taxels such as B2,E5, or all)")
    if len(set(taxels)) != len(taxels):
        raise UserError(f"spots repeat a taxel: {', '.join(spots)}")
    return taxels


def tested_line(layout: Layout, taxels: list[str]) -> str:
    """"5 of 36 taxels tested: B2, B5, E2, E5, C3": a pass speaks only for these."""
    n = layout.n_taxels
    if len(taxels) == n:
        return f"{n} of {n} taxels tested (all)"
    return (f"{len(taxels)} of {n} taxels tested: {', '.join(taxels)} "
            "(spots 'all' tests every taxel)")


def judged_against(ref: dict[str, Any], spots: tuple[str, ...]) -> str:
    """What the spots' ratios are relative to, in words: an uncalibrated sensor is read
    against the nominal curve, from which a healthy one may differ by some 10%."""
    groups: dict[str, list[str]] = {}
    for taxel in spots:
        groups.setdefault(ref["source"].get(taxel, "nominal"), []).append(taxel)
    parts = []
    for source, taxels in groups.items():
        which = "" if len(groups) == 1 else f" ({', '.join(taxels)})"
        if source == "nominal":
            parts.append(f"the nominal curve{which}: no calibration or earlier passing check "
                         "with this weight covers "
                         + ("them" if len(taxels) > 1 else "it")
                         + "; a healthy sensor may differ from it by some 10%: calibrate it "
                         "first for a reference of its own")
        elif source.startswith("calibration"):
            parts.append(f"{source}, the sensor's active calibration{which}")
        else:
            parts.append(f"{source}, its first passing check with this weight{which}"
                         + ("" if len(groups) > 1 else " (no calibration covers "
                            + ("them" if len(taxels) > 1 else "it") + ")"))
    return "; ".join(parts)


def run_wellness(bench: Bench, spec: WellnessSpec, thresholds: Thresholds = Thresholds(),
                 progress: ProgressFn = no_progress, store: bool = True) -> dict[str, Any]:
    """Run a whole check on ``bench`` (a started engine, its placer, timing, cancel token
    and event sink); returns the result (with ``check_id``)."""
    engine = bench.engine
    lay = engine.layout
    if not lay.has_shear or lay.calibration is None:
        raise UserError(f"wellness checks need a calibrated shear+normal sensor, not {lay.name}")
    spots = spot_taxels(lay, spec.spots)
    spec = replace(spec, spots=tuple(taxel_label(lay, t) for t in spots))
    expected = stress_kpa(spec.weight_g, spec.contact_mm)
    # a check must be stored: a damaged logbook is moved aside (its backup or a new one)
    with Logbook(on_damage="replace") as book:
        sensor = resolve_sensor(book, engine.device, spec.sensor, lay.name)
        ref = reference_for(book, sensor, spec, lay)
    steps = 1 + len(spots)
    progress(0.0, "rest")
    rest_raw = bench.rest()
    ref_base = np.asarray(ref["baseline"]) if ref["baseline"] is not None else None
    rest = analyse_rest(lay, rest_raw, bench.rate, ref_base, thresholds)
    results = []
    for i, taxel in enumerate(spots):
        progress((1 + i) / steps, f"spot {taxel_label(lay, taxel)}")
        raw = bench.load(spec.weight_g, taxel, expected, spec.contact_mm)
        spot = measure_spot(lay, raw, bench.baseline, taxel, expected)
        spot.reference_kpa = ref["spots"].get(spot.taxel)
        results.append(spot)
        bench.emit(SpotMeasured(spot.taxel, spot.normal_kpa))
    judge_spots(lay, results, thresholds)
    dead = sorted(set(rest.dead) | {c for s in results for c in s.dead_channels})
    reasons = [words for _, words in rest.reasons] + [r for s in results for r in s.reasons]
    verdict = worst([rest.verdict] + [s.verdict for s in results])
    result = {
        "sensor": sensor, "verdict": verdict,
        "tested": {"taxels": [s.taxel for s in results], "of": lay.n_taxels,
                   "line": tested_line(lay, [s.taxel for s in results])},
        "judged_against": judged_against(ref, spec.spots),
        "weight_g": spec.weight_g,
        "contact_mm": spec.contact_mm, "expected_kpa": round(expected, 4),
        "spots": [{**s.to_dict(), "reference": ref["source"].get(s.taxel, "nominal")}
                  for s in results],
        "active_calibration": ref["active_calibration"],
        "channels": {"dead": dead, "stuck": rest.stuck, "noisy": rest.noisy,
                     "saturated": rest.saturated},
        "rest": {"noise_counts_median": round(float(np.median(rest.noise)), 3),
                 "noise_counts_max": round(float(rest.noise.max()), 3),
                 "drift_pct_per_min_max": round(float(np.abs(rest.drift_per_min).max()) * 100, 4),
                 "baseline_shift_pct_max": None if rest.shift is None
                 else round(float(np.abs(rest.shift).max()) * 100, 3),
                 "frames": len(rest_raw)},
        "reasons": reasons, "reference_check": ref["check_id"],
        "reference_calibration": ref["calibration_id"],
        "baseline": [round(float(v), 2) for v in rest.baseline],
        "noise": [round(float(v), 3) for v in rest.noise],
        "device": engine.device_info(), "check_id": None,
    }
    if store:
        with Logbook() as book:
            result["check_id"] = book.add_check(sensor, result)
    progress(1.0, f"verdict {verdict}")
    bench.emit(CheckDone(verdict, result["check_id"]))
    return result
