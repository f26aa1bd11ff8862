"""``tactile-studio characterise``: the shear paper's characterisation with a stage and a
load cell, headless. Writes DIR/characterisation.json, calibration.json, session.h5,
figures/ and report.html; on an error or Ctrl-C the stage retracts first and everything
measured so far stays on disk."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from tactile_studio.characterise import (
    CharacterisationRequest,
    Plan,
    RunControl,
    run_characterisation,
)
from tactile_studio.characterise.folder import check_out_dir, describe_run
from tactile_studio.characterise.plan import (
    DEFAULT_SEQUENCES,
    SEQUENCES,
    parse_sequences,
    sequence_lab_s,
    stage_time_text,
)
from tactile_studio.characterise.procedure import check_sensor_request, save_calibration
from tactile_studio.cli.json_output import print_json
from tactile_studio.devices.registry import create_device, parse_set_options
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.health.history import covers_text
from tactile_studio.instruments import create_force, create_stage
from tactile_studio.jobs import TerminalProgress, ctrl_c_cancels
from tactile_studio.sensor.characterise import parse_taxels
from tactile_studio.storage.books.logbook import Logbook

PAPER_TAXELS = "B2,B5,E2,E5,A1,C4"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("characterise", help="characterise taxels with a stage and a load cell",
                       description=__doc__)
    p.add_argument("--device", default="simulated", help="sensor device plugin (default simulated)")
    p.add_argument("--stage", default="simulated", help="stage plugin (simulated, gcode, ...)")
    p.add_argument("--force", default="simulated",
                   help="force-reference plugin (simulated, serial, ...)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="device setting")
    p.add_argument("--stage-set", action="append", metavar="KEY=VALUE", help="stage setting")
    p.add_argument("--force-set", action="append", metavar="KEY=VALUE", help="force setting")
    p.add_argument("--param", action="append", metavar="KEY=VALUE",
                   help="characterisation parameter, e.g. dwell_s=1 (see docs/characterisation.md)")
    p.add_argument("--taxels", default=PAPER_TAXELS,
                   help="comma-separated taxel names or 'all' "
                        f"(default: the paper's {PAPER_TAXELS})")
    p.add_argument("--sequence", default=",".join(DEFAULT_SEQUENCES), metavar="SEQ[,SEQ]",
                   help=f"which sequence(s) to run: {', '.join(SEQUENCES)} or all, several "
                        f"with commas (default {','.join(DEFAULT_SEQUENCES)}, as the wizard)")
    p.add_argument("--cycles", type=int, default=None,
                   help="repeatability cycles; required with repeat (the paper's 22000 take "
                        "about 12 h of stage time per taxel)")
    p.add_argument("--sensor", default=None, help="sensor id for the report and calibration")
    p.add_argument("--save-calibration", action="store_true",
                   help="store the derived calibration in the sensor logbook as the sensor's "
                        "active one (needs --sensor)")
    p.add_argument("--json", action="store_true", help="print the per-taxel results as JSON")
    p.add_argument("--out", default=None, help="output folder (required without --wizard)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the run a folder already holds (its files are removed "
                        "first; without this such a folder is refused)")
    p.add_argument("--wizard", action="store_true",
                   help="open the characterisation wizard instead (--out pre-fills its folder)")
    p.set_defaults(func=run)


def run_wizard(out: str | None, sensor: str | None = None) -> int:
    """The wizard; without --out it names a run folder under the data folder."""
    from tactile_studio.cli.gui import require_display

    require_display("run `tactile-studio characterise ... --out DIR` on a headless machine")
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.characterise_wizard import CharacteriseWizard

    app = ensure_app()
    wizard = CharacteriseWizard(out, sensor_id=sensor or "")
    wizard.resize(1000, 760)
    wizard.show()
    return 0 if app.exec() == 0 else 1


def _finished(out: Path) -> str:
    """'1 of 6 taxel(s) finished, kept in DIR (report.html)': what an aborted run left."""
    try:
        done = json.loads((out / "characterisation.json").read_text(encoding="utf-8"))
        n, of = len(done["taxels"]), len(done["taxels_requested"])
    except (OSError, ValueError, KeyError, TypeError):
        return f"data so far kept in {out}"
    report = " (report.html)" if n and (out / "report.html").exists() else ""
    return f"{n} of {of} taxel(s) finished, kept in {out}{report}"


def run(args: argparse.Namespace) -> int:
    if args.wizard:
        return run_wizard(args.out, args.sensor)
    if not args.out:
        raise UserError("characterise: --out DIR is required (or use --wizard)")
    params = parse_set_options(args.param)
    if args.cycles is not None:
        params["cycles"] = str(args.cycles)
    params["sequences"] = ",".join(parse_sequences(args.sequence))
    plan = Plan.with_overrides(params)
    if "repeat" in plan.sequences and "cycles" not in params:
        paper = Plan.with_overrides({"sequences": "repeat"})
        raise UserError(f"--sequence {args.sequence}: repeat needs --cycles N: the paper's "
                        f"{paper.cycles:,} cycles take " + stage_time_text(
                            sequence_lab_s(paper, "repeat"), " per taxel"))
    device = create_device(args.device, parse_set_options(args.set))
    try:
        taxels = parse_taxels(device.layout, args.taxels)
    except ValueError as exc:
        raise UserError(f"--taxels: {exc}") from None
    stage = create_stage(args.stage, parse_set_options(args.stage_set))
    force = create_force(args.force, parse_set_options(args.force_set))
    out = Path(args.out)
    check_out_dir(out, args.overwrite)
    if args.save_calibration and not args.sensor:
        raise UserError("--save-calibration needs --sensor ID (the logbook files it there)")
    args.sensor = check_sensor_request(args.sensor, plan, args.save_calibration)
    control = RunControl()
    progress = TerminalProgress("characterise")
    try:
        with ctrl_c_cancels(control):
            request = CharacterisationRequest(plan, taxels, out, sensor_id=args.sensor,
                                              overwrite=args.overwrite)
            result = run_characterisation(device, stage, force, request, progress=progress,
                                          control=control,
                                          on_start=lambda line: print(
                                              f"characterise: {line}", file=sys.stderr))
    except Cancelled:
        raise Cancelled(f"characterisation cancelled: {_finished(out)}") from None
    except UserError as exc:
        kept = (f"data so far kept in {out}" if describe_run(out)
                else "no taxel was measured; the same --out can be used again")
        stopped = UserError(f"{exc} ({kept})")
        stopped.exit_code = exc.exit_code  # a full disk stays "incomplete" (3), not 1
        raise stopped from None
    if args.save_calibration:
        cal = json.loads((out / "calibration.json").read_text())
        cal_id = save_calibration(args.sensor, cal)
        with Logbook() as book:  # a partial one merged with the active calibration
            row = next(c for c in book.calibrations(args.sensor) if c["id"] == cal_id)
        print(f"calibration #{cal_id} of {args.sensor} saved to the logbook (active), "
              f"covers {covers_text(row)}", file=sys.stderr)
    if args.json:
        print_json(result["taxels"], indent=1)
    else:
        print(f"characterised {len(result['taxels'])} taxel(s); report: {out / 'report.html'}",
              file=sys.stderr)
    return 0
