"""``sensors``, ``sensor``, ``wellness`` and ``calibrate``: the sensor engineer's commands."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.json_output import print_json
from tactile_studio.devices.frame_stream import LiveStream
from tactile_studio.devices.registry import create_device, parse_set_options
from tactile_studio.errors import (
    EXIT_CHECK_FAIL,
    EXIT_CHECK_WARN,
    EXIT_OK,
    Cancelled,
    CheckFailed,
    IncompleteError,
    UserError,
)
from tactile_studio.health.bench import Bench, Placer, SimulatedPlacer
from tactile_studio.health.calibration import CalibrationSpec, coverage_line, run_calibration
from tactile_studio.health.events import EventFn, HealthEvent, Misplaced, Phase, Warned
from tactile_studio.health.history import covers_text
from tactile_studio.health.report import write_report
from tactile_studio.health.wellness import REFERENCE_RULE, WellnessSpec, run_wellness
from tactile_studio.jobs import CancelToken, TerminalProgress, ctrl_c_cancels
from tactile_studio.output_faults import (
    CALIBRATION_FILE,
    HTML_REPORT,
    require_writable_file,
    stored_already,
)
from tactile_studio.sensor.calibration import spread_line
from tactile_studio.sensor.wellness import DEFAULT_SPOTS
from tactile_studio.storage.books.logbook import Logbook, age_text


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sensors", help="list sensors in the logbook (hours, last check)")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=cmd_sensors)

    p = sub.add_parser("sensor", help="one sensor's history: checks, calibrations, notes")
    p.add_argument("id", help="sensor ID (see `sensors`)")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=cmd_sensor)

    p = sub.add_parser("wellness", help="check a sensor with a known weight on a few spots",
                       description=f"Ratios are judged {REFERENCE_RULE}.")
    _device_args(p)
    p.add_argument("--weight-g", type=finite_float, required=True, help="the known weight, grams")
    p.add_argument("--spots", default=",".join(DEFAULT_SPOTS),
                   help=f"taxels to load, or all (every taxel; default "
                        f"{','.join(DEFAULT_SPOTS)}: a pass speaks only for these)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--report", metavar="FILE.html", help="write an HTML report with figures")
    p.set_defaults(func=cmd_wellness)

    p = sub.add_parser("calibrate", help="equilibrate and calibrate a sensor with known loads")
    _device_args(p)
    p.add_argument("--loads-g", required=True, help="loads in grams, increasing: 20,50,100,200,500")
    p.add_argument("--taxels", default="all", help="all, or taxels to calibrate: B2,B5,...")
    p.add_argument("--plate", action="store_true",
                   help="a uniform plate over the whole array instead of a weight per taxel")
    p.add_argument("--replace", action="store_true",
                   help="replace the active calibration outright: taxels this one does not "
                        "measure fall back to the nominal curve (default: merge, keeping "
                        "the active calibration's curves for them)")
    p.add_argument("--json", action="store_true", help="print the calibration summary as JSON")
    p.add_argument("--out", required=True, metavar="CAL.json", help="calibration file to write")
    p.set_defaults(func=cmd_calibrate)


def _device_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--device", default="simulated", help="device plugin name (see `devices`)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="device setting")
    p.add_argument("--sensor", required=True, help="sensor ID (see `sensors`)")
    p.add_argument("--auto", action="store_true",
                   help="the (simulated) device places the weights itself")


def _split(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def _start(args: argparse.Namespace) -> tuple[LiveStream, Placer]:
    device = create_device(args.device, parse_set_options(args.set))
    placer = SimulatedPlacer(device) if args.auto else Placer()
    engine = open_stream(device)
    engine.start()
    if not engine.wait_frames(1, timeout=10.0):
        engine.stop()
        raise UserError(engine.error or f"device {args.device}: no frames within 10 s")
    return engine, placer


def _prompter(quiet: bool) -> EventFn:
    def on_event(event: HealthEvent) -> None:
        if quiet:
            return
        match event:
            case Phase(prompt=text) | Misplaced(prompt=text) | Warned(message=text):
                print(f"\n{text}", file=sys.stderr)
    return on_event


def _check_report_path(path: str | None, purpose: str = "the report",
                       replaces: tuple[bytes, str] = HTML_REPORT) -> None:
    """Before the device is touched: an output that cannot be written, or would replace
    a file of another kind, is refused now, not after the check or calibration was
    measured and stored."""
    if path:
        require_writable_file(path, purpose, replaces)


def _calibration_report(out: str) -> Path:
    """The residual report beside CAL.json; refused when it would be CAL.json itself."""
    report = Path(out).with_suffix(".html")
    if report == Path(out):
        raise UserError(f"--out {out}: the calibration's HTML report is written beside it "
                        f"as {report.name} and would replace it; name the calibration "
                        f"{Path(out).with_suffix('.json').name}")
    return report


def cmd_wellness(args: argparse.Namespace) -> int:
    _check_report_path(args.report)
    spec = WellnessSpec(args.sensor, args.weight_g, tuple(_split(args.spots)))
    engine, placer = _start(args)
    token = CancelToken()
    try:
        with ctrl_c_cancels(token), _nothing_stored(f"wellness check of {args.sensor}"):
            bench = Bench(engine, placer, cancel=token, on_event=_prompter(args.auto))
            result = run_wellness(bench, spec, progress=TerminalProgress("wellness"))
    except BaseException:
        print(file=sys.stderr)  # end the progress line before the error
        raise
    finally:
        engine.stop()
    if args.report:
        with stored_already(f"check #{result['check_id']} of {result['sensor']} is stored "
                            f"in the logbook ({result['verdict'].upper()})"):
            write_report(args.report,
                         f"Wellness check #{result['check_id']} of {result['sensor']}", result)
    if args.json:
        _dump({k: v for k, v in result.items() if k not in ("baseline", "noise")})
    else:
        print(f"sensor {result['sensor']}: {result['verdict'].upper()} "
              f"(check #{result['check_id']})")
        print(f"  {result['tested']['line']}")
        print(f"  ratios against {result['judged_against']}")
        for s in result["spots"]:
            ratio = "-" if s["ratio"] is None else f"{s['ratio'] * 100:.0f}%"
            print(f"  {s['taxel']:<4} {s['normal_kpa']:7.2f} kPa  shear {s['shear_kpa']:5.2f} "
                  f"kPa  {ratio:>5} of reference  {s['verdict']}")
        for reason in result["reasons"]:
            print(f"  - {reason}")
    return _wellness_status(result)


@contextmanager
def _nothing_stored(what: str, more: str = "") -> Iterator[None]:
    """Ctrl-C part way: only a complete check or calibration is stored, so the line says
    that nothing was (not the general 'finished work was kept')."""
    try:
        yield
    except Cancelled:
        raise Cancelled(f"{what} cancelled: nothing was stored{more}") from None


def _wellness_status(result: dict[str, Any]) -> int:
    """0 on PASS; a WARN or FAIL (stored, printed and reported already) ends with its own
    exit status (4 / 5) so a pre-session script can stop on it."""
    verdict = result["verdict"]
    if verdict == "pass":
        return EXIT_OK
    line = (f"sensor {result['sensor']}: wellness {verdict.upper()} (check "
            f"#{result['check_id']}, {result['tested']['line'].split(':')[0]})")
    if result["reasons"]:
        line += f": {result['reasons'][0]}"
    raise CheckFailed(line, EXIT_CHECK_WARN if verdict == "warn" else EXIT_CHECK_FAIL)


def _loads(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in _split(text))
    except ValueError:
        raise UserError(f"--loads-g {text!r}: expected grams separated by commas") from None


def cmd_calibrate(args: argparse.Namespace) -> int:
    taxels = None if args.taxels.strip().lower() == "all" else tuple(_split(args.taxels))
    spec = CalibrationSpec(args.sensor, _loads(args.loads_g), taxels, args.plate,
                           replace=args.replace)
    from tactile_studio.sensor.calibration import check_loads
    check_loads(list(spec.loads_g))  # before connecting: bad input fails at once
    report = _calibration_report(args.out)
    _check_report_path(args.out, "the calibration", CALIBRATION_FILE)
    _check_report_path(str(report), "the calibration's report")
    engine, placer = _start(args)
    token = CancelToken()
    try:
        with ctrl_c_cancels(token), _nothing_stored(
                f"calibration of {args.sensor}", "; its active calibration is unchanged"):
            cal = run_calibration(engine, spec, args.out, placer, cancel=token,
                                  progress=TerminalProgress("calibrate"),
                                  on_event=_prompter(args.auto))
    except BaseException:
        print(file=sys.stderr)
        raise
    finally:
        engine.stop()
    with stored_already(f"calibration #{cal['calibration_id']} of {cal['sensor']} is stored "
                        f"in the logbook (active) and in {args.out}"):
        write_report(report, f"Calibration #{cal['calibration_id']} of {cal['sensor']}", cal,
                     kind="calibration")
    summary = {"sensor": cal["sensor"], "calibration_id": cal["calibration_id"],
               "report": str(report),
               "kind": cal["kind"], "loads_g": cal["loads_g"], "out": args.out,
               "rms_pct_median": round(cal["rms_pct_median"], 4),
               "rms_pct_max": round(cal["rms_pct_max"], 4),
               "cv_pct_median": round(cal.get("cv_pct_median", float("nan")), 4),
               "cv_pct_max": round(cal.get("cv_pct_max", float("nan")), 4),
               "gains": cal["gains"],
               "sensitivity_spread": cal.get("sensitivity_spread"),
               "sensitivity_range": cal.get("sensitivity_range"),
               "skipped": cal["skipped"], "coverage": cal["coverage"],
               "replaced_calibration": cal["replaced_calibration"],
               "taxels": [{k: f.get(k) for k in ("taxel", "model", "rms_pct", "cv_pct",
                                                 "sensitivity")}
                          for f in cal["fits"] if f.get("from_calibration") is None]}
    if args.json:
        _dump(summary)
        _raise_if_skipped(cal)
        return 0
    print(f"calibration #{cal['calibration_id']} of {cal['sensor']} ({cal['kind']}) -> {args.out}")
    print(f"  {coverage_line(cal)}")
    if spread_line(cal):
        print(f"  {spread_line(cal)}")
    # the curve through the loads' means, and the error of a reading (cross-validated
    # over the frames): the first is 0 by construction for a 3-parameter curve, 3 loads
    print(f"  rms error of the curve: median {cal['rms_pct_median']:.2f}%, worst "
          f"{cal['rms_pct_max']:.2f}% of range")
    print(f"  rms error of a reading (cross-validated over the frames): median "
          f"{cal['cv_pct_median']:.2f}%, worst {cal['cv_pct_max']:.2f}% of range")
    for f in summary["taxels"]:
        print(f"  {f['taxel']:<4} {f['model']:<10} sensitivity {f['sensitivity']:.3f}  "
              f"rms {f['rms_pct']:.2f}%  cross-validated {f['cv_pct']:.2f}%")
    for skip in cal["skipped"]:
        print(f"  not calibrated: {skip['reason']}")
    _raise_if_skipped(cal)
    return 0


def _raise_if_skipped(cal: dict) -> None:
    """Some asked-for taxels could not be calibrated (dead, misplaced, saturated): what
    was measured is stored, and the exit status says the request was not met (3)."""
    if cal["skipped"]:
        n = len(cal["skipped"])
        raise IncompleteError(
            f"calibration #{cal['calibration_id']} of {cal['sensor']}: {n} taxel(s) not "
            f"calibrated ({cal['skipped'][0]['reason']}{'; ...' if n > 1 else ''}); "
            "the others were stored")


def _dump(obj: Any) -> None:
    print_json(obj)


def cmd_sensors(args: argparse.Namespace) -> int:
    with Logbook() as book:
        rows = [book.summary(s).to_dict() for s in book.sensor_ids()]
    if args.json:
        _dump(rows)
        return 0
    if not rows:
        print("no sensors in the logbook yet (a recording adds one: the simulator's own, or "
              "record --sensor ID for a receiver that reports none)")
        return 0
    print(f"{'sensor':<20} {'hours':>8}  {'last check':<22} {'calibration':>11}")
    for r in rows:
        check = (f"{r['last_verdict']} {age_text(r['last_check_at'])}"
                 if r["last_verdict"] else "never")
        cal = str(r["active_calibration"]) if r["active_calibration"] else "-"
        print(f"{r['id']:<20} {r['hours']:>8.3f}  {check:<22} {cal:>11}")
    return 0


def _active_text(hist: dict[str, Any]) -> str:
    """"#2, covers 36 of 36 taxels" (how much of the array reads with its own curve)."""
    active = next((c for c in hist["calibrations"] if c["active"]), None)
    if active is None:
        return "none active"
    if active["taxels"] is None:
        return f"#{active['id']}"
    return f"#{active['id']}, covers {active['taxels']} of {active['of']} taxels"


def cmd_sensor(args: argparse.Namespace) -> int:
    with Logbook() as book:
        hist = book.history(args.id)
    if args.json:
        _dump(hist)
        return 0
    lines = [f"sensor:      {hist['id']}  ({hist['layout'] or 'layout unknown'})",
             f"registered:  {hist['created']}",
             f"hours used:  {hist['hours']:.3f}",
             f"calibration: {_active_text(hist)}",
             f"checks:      {len(hist['checks'])}"]
    for c in hist["checks"]:
        lines.append(f"  #{c['id']} {c['at']} at {c['hours']:.2f} h  {c['verdict'].upper()}"
                     f"  {c['weight_g']:g} g")
        lines.extend(f"      {reason}" for reason in c["reasons"])
    lines.append(f"calibrations: {len(hist['calibrations'])}")
    for c in hist["calibrations"]:
        covers = covers_text(c)
        lines.append(f"  #{c['id']} {c['at']} {c['kind']}{' ' + covers if covers else ''} "
                     f"rms {c['rms_pct']:.2f}% of range" + ("  (active)" if c["active"] else ""))
    lines.append(f"notes:       {len(hist['notes'])}")
    lines.extend(f"  {n['at']} [{n['kind']}] {n['text']}" for n in hist["notes"])
    print("\n".join(lines))
    return 0
