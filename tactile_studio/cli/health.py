"""``sensors``, ``sensor``, ``wellness`` and ``calibrate``: the sensor engineer's commands."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from tactile_studio.storage.logbook import Logbook, age_text


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sensors", help="list sensors in the logbook (hours, last check)")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=cmd_sensors)

    p = sub.add_parser("sensor", help="one sensor's history: checks, calibrations, notes")
    p.add_argument("id", help="sensor ID (see `sensors`)")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=cmd_sensor)


def _dump(obj: Any) -> None:
    json.dump(obj, sys.stdout, indent=2, default=str)
    print()


def cmd_sensors(args: argparse.Namespace) -> int:
    with Logbook() as book:
        rows = [book.summary(s).to_dict() for s in book.sensor_ids()]
    if args.json:
        _dump(rows)
        return 0
    if not rows:
        print("no sensors in the logbook yet (a recording or a wellness check adds one)")
        return 0
    print(f"{'sensor':<20} {'hours':>8}  {'last check':<22} {'calibration':>11}")
    for r in rows:
        check = (f"{r['last_verdict']} {age_text(r['last_check_at'])}"
                 if r["last_verdict"] else "never")
        cal = str(r["active_calibration"]) if r["active_calibration"] else "-"
        print(f"{r['id']:<20} {r['hours']:>8.3f}  {check:<22} {cal:>11}")
    return 0


def cmd_sensor(args: argparse.Namespace) -> int:
    with Logbook() as book:
        hist = book.history(args.id)
    if args.json:
        _dump(hist)
        return 0
    lines = [f"sensor:      {hist['id']}  ({hist['layout'] or 'layout unknown'})",
             f"registered:  {hist['created']}",
             f"hours used:  {hist['hours']:.3f}",
             f"calibration: {hist['active_calibration'] or 'none active'}",
             f"checks:      {len(hist['checks'])}"]
    for c in hist["checks"]:
        lines.append(f"  #{c['id']} {c['at']} at {c['hours']:.2f} h  {c['verdict'].upper()}"
                     f"  {c['weight_g']:g} g")
        lines.extend(f"      {reason}" for reason in c["reasons"])
    lines.append(f"calibrations: {len(hist['calibrations'])}")
    for c in hist["calibrations"]:
        lines.append(f"  #{c['id']} {c['at']} {c['kind']} rms {c['rms_pct']:.2f}% of range"
                     + ("  (active)" if c["active"] else ""))
    lines.append(f"notes:       {len(hist['notes'])}")
    lines.extend(f"  {n['at']} [{n['kind']}] {n['text']}" for n in hist["notes"])
    print("\n".join(lines))
    return 0
