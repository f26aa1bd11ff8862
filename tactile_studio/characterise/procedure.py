"""Running a characterisation: taxel after taxel, cancellable, pausable, crash-safe.

``run_characterisation`` drives a sensor device, a stage and a force reference through
the plan's sequences on each taxel, records everything into ``DIR/session.h5`` and
rewrites ``DIR/characterisation.json`` after every taxel, so whatever happens (abort,
a stage error, a silent load cell) the data so far stays on disk. On abort or error the
stage retracts first, then the files are closed and the report is written for what was
measured.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.characterise.analyse import analyse_taxel
from tactile_studio.characterise.folder import check_out_dir, clear_run
from tactile_studio.characterise.lab import Lab
from tactile_studio.characterise.plan import Plan, plan_text
from tactile_studio.characterise.sequences import (
    normal_sequence,
    repeat_sequence,
    shear_sequence,
)
from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.errors import UserError
from tactile_studio.file_claims import claim_folder, replace_whole
from tactile_studio.instruments.contract import ForcePlugin, StagePlugin
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress, signals_deferred
from tactile_studio.sensor.calibration import sensitivity_spread
from tactile_studio.sensor.layout import get_layout
from tactile_studio.sensor.wellness import parse_taxel
from tactile_studio.storage.books.calibration_store import store_calibration
from tactile_studio.storage.books.logbook import Logbook, check_sensor_id

RESULT_FORMAT = "tactile-studio-characterisation"
CALIBRATION_FORMAT = "tactile-studio-calibration"


class RunControl(CancelToken):
    """Cancel (abort) plus pause/resume: a pause takes effect between taxels (the
    stage retracts and waits); resuming continues with the next taxel."""

    def __init__(self) -> None:
        super().__init__()
        self._running = threading.Event()
        self._running.set()

    def pause(self) -> None:
        self._running.clear()

    def resume(self) -> None:
        self._running.set()

    @property
    def paused(self) -> bool:
        return not self._running.is_set()

    def wait_while_paused(self) -> None:
        while not self._running.wait(0.05):
            self.check()
        self.check()


def _write_json(path: Path, data: dict[str, Any]) -> None:
    text = json.dumps(data, indent=1, default=float)
    replace_whole(path, lambda tmp: tmp.write_text(text))


def calibration_from(result: dict[str, Any]) -> dict[str, Any]:
    """The derived calibration in the sensor logbook's format (``sensor/calibration.py``):
    per taxel a two-range curve from the centre channel's relative change to kPa (the
    inverse of the fitted normal response), its sensitivity against the layout's nominal
    one, and equilibration gains; the measured slopes are kept under ``taxels``."""
    layout = get_layout(result["layout"])
    nominal = layout.calibration.normal_slope_low if layout.calibration else 1.0
    taxels, fits = {}, []
    for name, m in result["taxels"].items():
        keys = ("normal_sensitivity_low", "normal_sensitivity_high", "breakpoint_kpa")
        if not all(m.get(k) is not None for k in keys) or m["normal_sensitivity_low"] <= 0 \
                or m["normal_sensitivity_high"] <= 0:
            continue
        taxels[name] = {k: m.get(k) for k in (*keys, "shear_sensitivity_x",
                                               "shear_sensitivity_y")}
        low, high, bp = (m["normal_sensitivity_low"], m["normal_sensitivity_high"],
                         m["breakpoint_kpa"])
        fits.append({"taxel": name, "index": parse_taxel(layout, name), "model": "two-range",
                     "params": [1.0 / low, 1.0 / high, low * bp],
                     "sensitivity": round(low / nominal, 5),
                     "rms_pct": round(float(m.get("calibration_rms_pct") or 0.0), 4)})
    sens = {f["taxel"]: f["sensitivity"] for f in fits}
    median = float(np.median(list(sens.values()))) if sens else 1.0
    rms = [f["rms_pct"] for f in fits] or [0.0]
    return {"format": CALIBRATION_FORMAT, "version": 1, "layout": layout.name,
            "kind": "characterisation", "sensor": result.get("sensor"),
            "created": result.get("finished") or result.get("started"),
            "source": "characterisation.json", "units": result["units"], "fits": fits,
            "gains": {t: round(median / v, 5) for t, v in sens.items()},
            "rms_pct_median": float(np.median(rms)), "rms_pct_max": float(np.max(rms)),
            **sensitivity_spread(list(sens.values())), "taxels": taxels}


def check_sensor_request(sensor_id: str | None, plan: Plan, save: bool) -> str | None:
    """Before the stage moves: the sensor ID is one the logbook takes, and a calibration
    to save can come from the plan (only the normal sequence gives one: otherwise the run
    went through, hours for ``repeat``, and was refused at the end). Returns the ID."""
    if sensor_id is None:
        return None
    sensor = check_sensor_id(sensor_id)
    if save and "normal" not in plan.sequences:
        raise UserError(f"a calibration to save comes from the normal sequence, and this "
                        f"run has only {','.join(plan.sequences)}: add normal, or do not "
                        "save the calibration")
    return sensor


def save_calibration(sensor_id: str, calibration: dict[str, Any],
                     replace: bool = False) -> int:
    """Store a characterisation-derived calibration in the sensor logbook as the active
    one, merged with the active calibration (its other taxels kept) unless ``replace``;
    returns its id."""
    if not calibration["fits"]:
        raise UserError("the characterisation gave no normal fit to calibrate with "
                        "(run the normal sequence)")
    with Logbook(on_damage="replace") as book:  # a damaged one is moved aside, said once
        book.ensure_sensor(sensor_id, calibration["layout"])
        stored = store_calibration(book, sensor_id, "characterisation", calibration,
                                   get_layout(calibration["layout"]).n_taxels, replace,
                                   rms_pct=calibration["rms_pct_median"])
        return int(stored["calibration_id"])


@dataclass(frozen=True)
class CharacterisationRequest:
    """What the user asked a characterisation for: ``plan`` on ``taxels`` (indices)
    into ``out_dir``, the sensor's logbook id (``sensor_id``), whether to write the
    report (``report``) and whether an earlier run in the folder may go (``overwrite``)."""

    plan: Plan
    taxels: list[int]
    out_dir: Path
    sensor_id: str | None = None
    report: bool = True
    overwrite: bool = False


def run_characterisation(device: DevicePlugin, stage: StagePlugin, force: ForcePlugin,
                         request: CharacterisationRequest, *,
                         progress: ProgressFn = no_progress,
                         control: RunControl | None = None,
                         on_point: Any = None, on_taxel: Any = None,
                         on_start: Any = None) -> dict[str, Any]:
    """Characterise ``request.taxels`` and return the result dict (also in
    characterisation.json).

    The folder is claimed for the whole run (tactile_studio/file_claims.py): a second
    run into it is refused in one line before it clears or writes anything (with
    ``overwrite`` it would otherwise remove the running one's files).

    Raises Cancelled (after retracting and saving) when ``control`` is cancelled, and
    UserError subclasses for instrument problems, also after saving what was measured.
    ``on_point(taxel_name, point)`` sees every measured point (a live plot) and
    ``on_taxel(taxel_name, metrics)`` each taxel's metrics as it ends, and
    ``on_start(line)`` what the run will do and how long it takes, once the instruments
    are open and the stage has homed (all optional, called from the calling thread).
    ``request.report``: also write figures/ and report.html (for what was measured).
    ``request.overwrite``: a folder that holds an earlier run is refused (UserError)
    unless set; then that run's files are removed first, so two runs are never mixed.
    """
    with claim_folder(request.out_dir, "characterisation folder"):
        return _characterise(device, stage, force, request, progress,
                             control or RunControl(), on_point, on_taxel, on_start)


def _result_header(device: DevicePlugin, stage: StagePlugin, force: ForcePlugin, plan: Plan,
                   sensor_id: str | None, names: list[str]) -> dict[str, Any]:
    """characterisation.json before any taxel is measured: what, with what, in which units."""
    return {
        "format": RESULT_FORMAT, "version": 1, "sensor": sensor_id,
        "layout": device.layout.name,
        "device": device.info(), "stage": stage.info(), "force": force.info(),
        "plan": plan.to_dict(), "taxels_requested": names, "taxels": {},
        "session": "session.h5", "complete": False, "aborted": None,
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "units": {"normal_sensitivity": "relative change per kPa", "breakpoint": "kPa",
                  "shear_sensitivity": "differential relative change per kPa",
                  "relaxation": "s", "hysteresis": "fraction of loading area",
                  "shear_offset": "fraction of peak", "crosstalk": "fraction of target"}}


def _measure_taxel(lab: Lab, plan: Plan, taxel: int, centre: tuple[float, float],
                   sub: Callable[[float, str], None]) -> dict[str, Any]:
    """The plan's sequences (normal, shear, repeat) on one taxel, each saying when the
    skin settled; ``sub(done, message)`` reports progress within the taxel."""
    x0, y0 = centre
    data: dict[str, Any] = {}
    seqs = plan.sequences
    lab.settles = []
    for k, seq in enumerate(seqs):
        sub(k / len(seqs), seq)

        def settled(s: Any, k: int = k, seq: str = seq) -> None:
            sub(k / len(seqs), f"{seq}: skin settled after {s.waited_s:.1f} s" if
                s.steady else f"{seq}: skin still moving after {s.waited_s:.0f} s "
                "(settle_max_s); measuring anyway")
        lab.on_settled = settled
        if seq == "normal":
            data["normal"] = normal_sequence(lab, plan, taxel, x0, y0)
        elif seq == "shear":
            data["shear"] = shear_sequence(lab, plan, taxel, x0, y0)
        else:
            data["repeat"] = repeat_sequence(
                lab, plan, taxel, x0, y0, lambda f, m, k=k: sub((k + f) / len(seqs), m))
    return data


def _characterise(device: DevicePlugin, stage: StagePlugin, force: ForcePlugin,
                  request: CharacterisationRequest, progress: ProgressFn, control: RunControl,
                  on_point: Any, on_taxel: Any, on_start: Any) -> dict[str, Any]:
    plan, taxels, out_dir = request.plan, request.taxels, Path(request.out_dir)
    sensor_id, report, overwrite = request.sensor_id, request.report, request.overwrite
    check_out_dir(out_dir, overwrite)
    clear_run(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    layout = device.layout
    if not layout.has_shear:
        raise UserError(f"device {device.name}: characterisation needs a shear sensor layout, "
                        f"not {layout.name}")
    names = [layout.taxel_name(*layout.taxel_rc(t)) for t in taxels]
    result = _result_header(device, stage, force, plan, sensor_id, names)
    json_path = out_dir / "characterisation.json"
    (out_dir / "raw").mkdir(exist_ok=True)
    raw_by_taxel: dict[str, Any] = {}  # measured points and traces, also in raw/<taxel>.json
    stage.open()
    force.open()
    lab: Lab | None = None
    try:
        stage.couple(device)
        force.couple(device, stage)
        result["device"] = device.info()  # as coupled (the simulated bench idles its hand)
        area = float(stage.settings.get("indenter_mm", 14.0)) ** 2
        lab = Lab(device, stage, force, out_dir / "session.h5", area, control,
                  {"characterisation": {"plan": plan.to_dict(), "taxels": names,
                                        "stage": stage.info(), "force": force.info(),
                                        "indenter_area_mm2": area}})
        result["clock"] = lab.clock.name
        lab.on_point = on_point
        lab.clock.sleep(0.5, control)
        stage.home()
        lab.event("char_homed")
        if on_start is not None:
            on_start(plan_text(plan, len(taxels)))
        for i, (taxel, name) in enumerate(zip(taxels, names)):
            if control.paused:
                lab.retract()
                lab.event("char_paused", before=name)
                progress(i / len(taxels), f"paused before {name}")
                control.wait_while_paused()
                lab.event("char_resumed", at=name)
            x0, y0 = layout.taxel_centre_mm(*layout.taxel_rc(taxel))
            lab.event("char_taxel", taxel=name, x=x0, y=y0)

            def sub(done: float, msg: str, i: int = i, name: str = name) -> None:
                progress((i + min(done, 1.0)) / len(taxels), f"{name}: {msg}")
            data = _measure_taxel(lab, plan, taxel, (x0, y0), sub)
            result["taxels"][name] = {**analyse_taxel(data), **settle_summary(lab.settles)}
            raw_by_taxel[name] = data
            _write_json(out_dir / "raw" / f"{name}.json", data)
            if on_taxel is not None:
                on_taxel(name, result["taxels"][name])
            _write_json(json_path, result)
            progress((i + 1) / len(taxels), f"{name} done")
        result["complete"] = True
    except BaseException as exc:  # also a second Ctrl-C: the indenter is lifted first
        result["aborted"] = str(exc) or type(exc).__name__
        _retract(stage, lab, exc)
        raise
    finally:
        result["finished"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        if lab is not None:
            lab.close()
        stage.close()
        force.close()
        _write_json(json_path, result)
        _write_json(out_dir / "calibration.json", calibration_from(result))
        if report and result["taxels"]:
            from tactile_studio.characterise.report import write_report

            write_report(out_dir, result, layout, raw_by_taxel)
    return result


def settle_summary(settles: list[Any]) -> dict[str, Any]:
    """A taxel's settling waits in its figures: the longest, and whether every sequence
    began on a steady skin (a figure measured on a moving one is marked, not hidden)."""
    if not settles:
        return {}
    return {"settle_wait_s": max(s.waited_s for s in settles),
            "settled": all(s.steady for s in settles)}


def _retract(stage: StagePlugin, lab: Lab | None, exc: BaseException) -> None:
    """Abort path: lift the indenter first, and let no Ctrl-C cut the lifting short (an
    indenter left pressed into the sensor can damage it); record why; never mask the
    original error."""
    try:
        with signals_deferred():
            lab.retract() if lab is not None else stage.retract()
    except Exception as err:  # the stage may be what failed
        if lab is not None:
            lab.event("char_retract_failed", error=str(err))
    except KeyboardInterrupt:  # Ctrl-C again while lifting: the original error stands
        pass
    if lab is not None:
        lab.event("char_aborted", reason=str(exc) or type(exc).__name__)
