"""``devices``, ``record`` and ``info``: the session commands that need no GUI."""

from __future__ import annotations

import argparse
import os
import shlex
import time
from collections import Counter
from pathlib import Path
from typing import Any

from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.cli import tables
from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.json_output import print_json
from tactile_studio.cli.lsl_markers import add_markers_option, start_markers
from tactile_studio.cli.recording_warnings import (
    add_silence_option,
    apply_silence_option,
    watch_health,
)
from tactile_studio.cli.stream import add_lsl_option, start_lsl
from tactile_studio.devices.engine_events import Marker
from tactile_studio.devices.registry import available_plugins, create_device, parse_set_options
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.jobs import CancelToken, TerminalProgress, ctrl_c_cancels
from tactile_studio.paths import make_out_dir
from tactile_studio.storage.books.logbook import check_sensor_id
from tactile_studio.storage.format.aux_signals import AuxSignal
from tactile_studio.storage.format.session_file import SessionFile, measured_rate_hz
from tactile_studio.storage.format.trials import TrialRecord

FIRST_FRAME_TIMEOUT_S = 10.0  # `record` gives up when a device sends nothing this long


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("devices", help="list device plugins and their settings")
    p.set_defaults(func=cmd_devices)

    p = sub.add_parser("record", help="record a device to a session file")
    p.add_argument("--device", default="simulated", help="device plugin name (see `devices`)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="device setting")
    p.add_argument("--seconds", type=finite_float, required=True,
                   help="how long to record, in the device's own time: a simulation at "
                        "speed 0 or a replayed file gives this many seconds of frames "
                        "however fast it runs")
    p.add_argument("--out", required=True, help="session file to write (.h5)")
    p.add_argument("--notes", default="", help="free-form notes stored in the metadata")
    p.add_argument("--sensor", default=None, metavar="ID",
                   help="the sensor's ID, for a device that does not report its own "
                        "(serial, BLE): the logbook registers it, books this recording's "
                        "hours and decodes with its calibration")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    add_lsl_option(p)
    add_markers_option(p)
    add_silence_option(p)
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("info", help="summarise a session file, or a folder of them")
    p.add_argument("file", nargs="+", help="session file (.h5); several files or a folder: "
                                           "one row per file (e.g. after an import)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=cmd_info)


def cmd_devices(args: argparse.Namespace) -> int:
    rows = []
    for name, cls in available_plugins().items():
        if isinstance(cls, Exception):
            rows.append((name, f"failed to load ({cls})"))
            continue
        rows.append((name, cls.description))
        rows += [("", f"  {setting.describe()}") for setting in cls.settings_schema]
    tables.table(("plugin", "description / settings"), rows)
    return 0


def _sensor_for(device: Any, given: str) -> str:
    """``--sensor``: a usable ID, and not another than the one the device reports."""
    sensor = check_sensor_id(given)
    own = device.sensor_id()
    if own and own != sensor:
        raise UserError(f"--sensor {sensor}: the device reports sensor {own}; leave "
                        "--sensor out, or connect that sensor")
    return sensor


def cmd_record(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.exists() and not args.force:
        raise UserError(f"{out}: already exists (use --force to overwrite)")
    if args.seconds <= 0:
        raise UserError(f"--seconds must be positive, got {args.seconds}")
    device = create_device(args.device, parse_set_options(args.set))
    make_out_dir(out.parent)  # the rule of every output folder
    acquisition = LiveAcquisition()
    apply_silence_option(acquisition, args)
    watch_health(acquisition)  # a device gone silent while recording: a warning line
    metadata = {"notes": args.notes, "source": "record"}
    if args.sensor is not None:
        metadata["sensor_id"] = _sensor_for(device, args.sensor)
    engine = acquisition.use_device(device, args.device)
    # The recorder exists before the engine starts so the connect and tare events are
    # kept. The file is claimed there: another writer of it (a second `record`, a
    # listener, the GUI) is refused in one line before anything is recorded.
    acquisition.start_recording(out, metadata=metadata, overwrite=args.force)
    try:
        if args.lsl:
            acquisition.add_outlet(start_lsl(engine, wait_s=args.lsl_wait))
        if args.markers:
            acquisition.add_outlet(start_markers(engine, args.markers))
    except UserError:
        acquisition.stop_recording(discard=True)  # removed while still ours
        acquisition.close()
        raise
    acquisition.start()
    if not engine.wait_frames(1, timeout=FIRST_FRAME_TIMEOUT_S):
        acquisition.stop_recording(discard=True)
        acquisition.close()
        raise UserError(engine.error or f"{device_label(device)}: no frames within "
                        f"{FIRST_FRAME_TIMEOUT_S:g} s "
                        "(is it switched on and sending?)")
    progress = TerminalProgress(f"recording {out.name}", total=args.seconds, unit="s")
    token = CancelToken()
    start = time.monotonic()
    # a device that makes frames on demand runs at any speed: its seconds are its frames
    # (wall seconds recorded minutes of a simulation at speed 0, or a few frames of it)
    # (at least one frame: a tiny --seconds rounded to 0 fell back to the wall clock)
    want = max(1, round(args.seconds * device.nominal_rate_hz)) \
        if device.waits_for_reader else None
    acquisition.stop_recording_after(seconds=None if want is not None else args.seconds,
                                     frames=want, disconnect=True)
    with ctrl_c_cancels(token):
        while not token.wait(0.1):
            acquisition.poll()  # stops the recording at --seconds, or when the device ends
            elapsed = time.monotonic() - start
            done = engine.frames / want if want is not None else elapsed / args.seconds
            progress(min(1.0, done),
                     f"{engine.frames} frames, {engine.measured_rate_hz():.1f} Hz, {engine.state}")
            if not acquisition.recording:
                break
    progress.close()
    acquisition.close()  # engine, then the LSL outlet (its end goes into the file), then the file
    # acquisition/outcome.py: the same judgement as collect and the GUI
    outcome = acquisition.outcome
    if outcome is None:
        raise UserError(f"{out}: the recording did not start")
    print(f"\n{outcome.summary_line}")
    outcome.raise_if_incomplete()  # device lost, write failed, frames lost: exit 3
    if token.cancelled:  # Ctrl-C or SIGTERM before --seconds: exit 130, as collect and train
        raise Cancelled
    return 0


def device_label(device: Any) -> str:
    """"device serial on /dev/ttyUSB0": the plugin and where it is connected (port, BLE
    address or replayed file), for messages about a device that went quiet."""
    info = device.info()
    settings = info.get("settings", {})
    where = info.get("port") or info.get("address") or settings.get("path") or ""
    return (f"device {info.get('plugin', '?')} on {where}" if where
            else f"device {info.get('plugin', '?')}")


def _info_files(paths: list[str], as_json: bool) -> int:
    """One row per session file under ``paths`` (folders searched recursively): what an
    experimenter checks after importing a study (malformed rows, unmapped keys, trials).
    A file that cannot be read gets its one-line reason in the row; the exit code is 1."""
    from tactile_studio.storage.format.session_set import (
        is_pilot,
        is_resume_backup,
        scan_session_files,
    )
    from tactile_studio.storage.format.study_summary import study_counts

    files, backups = scan_session_files(paths)
    # a backup named explicitly is still a backup: its trials are its session's again
    backups = sorted({*backups, *(f for f in files if is_resume_backup(f))})
    every = sorted(set(files) | set(backups))
    counted: dict[str, int] = {}  # session_id -> index in ``study``: each session once
    root = Path(os.path.commonpath([f.parent for f in every]))
    summaries, rows, bad, study, pilots = [], [], 0, [], 0
    for f in every:
        name = f.relative_to(root).as_posix()
        try:
            with SessionFile(f) as s:
                summary = s.summary()
                ok_trials = [t for t in s.trials if t.ok]
        except UserError as exc:
            bad += 1
            rows.append((name, "", "", "", "", "", "", "", f"unreadable: {exc}"))
            summaries.append({"path": str(f), "error": str(exc)})
            continue
        summaries.append(summary)
        meta, trials = summary["metadata"], summary["trials"]
        ok = len(ok_trials)
        pilot = is_pilot(meta)  # a rehearsal: no one's data, left out of the study
        pilots += pilot
        if f not in backups and not pilot:  # a resume backup repeats its session's trials
            entry = (meta.get("participant") or "", meta.get("condition") or "",
                     Counter(t.gesture for t in ok_trials))
            sid = str(summary.get("session_id"))
            if sid not in counted:  # a copy of a session counts once (the fuller one)
                counted[sid] = len(study)
                study.append(entry)
            elif sum(entry[2].values()) > sum(study[counted[sid]][2].values()):
                study[counted[sid]] = entry
        notes = [] if summary["closed_cleanly"] else [
            "cut short (writes failed), recovered" if summary.get("cut_short")
            else "not closed cleanly (recovered)"]
        if summary["closed_cleanly"] and summary.get("cut_short"):
            notes.append("imported cut short")
        if f in backups:
            notes.append("resume backup")
        if pilot:
            notes.append("pilot (rehearsal; not counted)")
        lost = sum(summary["frames_lost"].values())
        if lost:
            notes.append(f"{lost} frames lost")
        rows.append((name, meta.get("participant") or "", meta.get("condition") or "",
                     summary["frames"], f"{summary['rate_hz']:.2f}", f"{ok}/{len(trials)}",
                     summary["malformed"], ", ".join(summary["unmapped_keys"]),
                     "; ".join(notes)))
    if as_json:
        print_json(summaries)
    else:
        tables.table(("file", "participant", "condition", "frames", "Hz", "ok trials",
                      "malformed", "unmapped keys", "note"), rows,
                     right=("frames", "Hz", "ok trials", "malformed"))
        print(f"{len(every)} session file(s) under {root}"
              + (f"; {bad} unreadable" if bad else "")
              + (f"; {pilots} pilot (rehearsals, not counted)" if pilots else ""))
        for line in study_counts(study).lines():
            print(line)
    return 1 if bad else 0


def _closed_text(summary: dict[str, Any]) -> str:
    source = summary["metadata"].get("source_incomplete")
    if summary["closed_cleanly"] and source:
        return f"cleanly; imported short of its source file: {source}"
    if summary["closed_cleanly"]:
        return "cleanly"
    if summary.get("cut_short"):
        return "NOT cleanly (recovered; cut short: its writes failed, e.g. disk full)"
    return "NOT cleanly (recovered)"


def _trial_table(trials: list[TrialRecord], gestures: list[str]) -> str:
    """Trials per gesture in the protocol's order."""
    from tactile_studio.protocol.report import trial_table
    return trial_table(trials, gestures)


def cmd_info(args: argparse.Namespace) -> int:
    if len(args.file) > 1 or Path(args.file[0]).is_dir():
        return _info_files(args.file, args.json)
    with SessionFile(args.file[0]) as s:
        summary = s.summary()
        table = _trial_table(s.trials, summary["gestures"]) if s.trials else ""
        aux = [_aux_line(a) for a in s.aux_signals()]
    if args.json:
        print_json(summary)
        return 0
    meta = summary["metadata"]
    device = meta.get("device", {})
    lines = [
        f"file:       {summary['path']}",
        f"session:    {summary['session_id']}",
        f"layout:     {summary['layout']}",
        f"device:     {device.get('plugin', '?')} {device.get('settings') or ''}".rstrip(),
        *([f"source:     {meta['source']}"] if meta.get("source") else []),
        f"created:    {meta.get('created', '?')}   app {meta.get('app_version', '?')}",
        f"frames:     {summary['frames']} over {summary['duration_s']:.2f} s "
        f"({summary['rate_hz']:.2f} Hz)",
        f"malformed:  {summary['malformed']} {summary['malformed_by_kind'] or ''}",
        f"gaps:       {summary['gaps']}{_gaps_why(summary)}   reconnects {summary['reconnects']}",
        *_lost_line(summary["frames_lost"]),
        f"events:     {len(summary['events'])}"
        + (f" ({', '.join(sorted({e['kind'] for e in summary['events']}))})"
           if summary["events"] else ""),
        f"closed:     {_closed_text(summary)}",
    ]
    from tactile_studio.storage.format.session_set import BACKUP_RE, is_pilot, is_resume_backup

    if is_resume_backup(Path(args.file[0])):  # as the table of several files marks it
        lines.insert(1, f"backup:     a resume backup: the session continues in "
                        f"{BACKUP_RE.sub('', Path(args.file[0]).stem)}.h5 "
                        "(folders and datasets skip this file)")
    elif summary["collection"] is not None:
        lines.append(_collection_line(summary["collection"], summary["path"]))
    if is_pilot(meta):
        lines.insert(1, "pilot:      yes: a rehearsal, not a participant's data; datasets, "
                        "train and info's study leave it out unless the file is named")
    if meta.get("participant"):
        lines.append(f"participant: {meta['participant']}")
    lines.extend(_recording_labels(meta))
    if meta.get("notes"):
        lines.append(f"notes:      {meta['notes']}")
    if summary["unmapped_keys"]:
        lines.append(f"unmapped keys: {', '.join(summary['unmapped_keys'])} "
                     "(no gesture name; trials keep the key)")
    lines.extend(f"aux:        {line}" for line in aux)
    lines.extend(_marker_lines(summary["events"], summary["rate_hz"]))
    if summary["trials"]:
        lines.append(f"trials:     {len(summary['trials'])}")
        lines.append(table)
    tables.fields(lines)
    return 0


MARKERS_SHOWN = 20


def _recording_labels(meta: dict[str, Any]) -> list[str]:
    """What a remote-controlled recording was named for (LabRecorder's filename fields:
    session, task, run, acquisition), as the experiment script sent them."""
    named = [(label, meta.get(key)) for label, key in (
        ("session", "session_label"), ("task", "task"), ("run", "run"),
        ("acquisition", "acquisition")) if meta.get(key)]
    if not named:
        return []
    return ["recording:  " + ", ".join(f"{label} {value}" for label, value in named)]


def _marker_lines(events: list[dict[str, Any]], rate: float) -> list[str]:
    """Each marker (another program's over LSL, or a script's ``mark TEXT``) with its
    row, its time into the recording and its text: what the experiment said happened."""
    marks = [e for e in events if e.get("kind") == Marker.kind]
    if not marks:
        return []
    lines = [f"markers:    {len(marks)}"]
    for e in marks[:MARKERS_SHOWN]:
        row = e.get("frame")
        at = f" ({row / rate:.2f} s)" if isinstance(row, int) and rate > 0 else ""
        source = e.get("stream") or e.get("source") or "?"
        lines.append(f"  row {row}{at}  {str(e.get('text', ''))!r}  from {source}")
    if len(marks) > MARKERS_SHOWN:
        lines.append(f"  … {len(marks) - MARKERS_SHOWN} more (info --json lists them all)")
    return lines


def _gaps_why(summary: dict[str, Any]) -> str:
    """Which of the gaps are resumes (a resume continues the file in a new recording
    segment: the device stopped between the runs), so one is not taken for a fault."""
    resumes = summary["segments"] - 1
    if not resumes:
        return ""
    others = summary["gaps"] - resumes
    what = f"{resumes} resume{'s' if resumes != 1 else ''}: the recording continued later"
    return f" ({what}; {others} in the stream)" if others else f" ({what})"


def _collection_line(progress: dict[str, Any], path: str) -> str:
    """A collection's progress: finished, or how far it got and how to go on."""
    blocks = f"{progress['blocks_done']} of {progress['blocks_total']} blocks"
    trials = f"{progress['trials_done']} of {progress['trials_total']} trials"
    if progress["finished"]:
        return f"collection: finished ({blocks}, {trials})"
    return (f"collection: unfinished, {blocks} done ({trials}); resume with "
            f"tactile-studio collect --resume {shlex.quote(path)}")


def _lost_line(lost: dict[str, int]) -> list[str]:
    """``lost: N frames (...)`` when frames never reached the file, else nothing."""
    total = lost["overrun"] + lost["missing"]
    if not total:
        return []
    return [f"lost:       {total} frames (the recorder fell behind: {lost['overrun']}; "
            f"the device skipped sequence numbers: {lost['missing']})"]


def _aux_line(a: AuxSignal) -> str:
    """An auxiliary signal (``/aux``: an imported EDA, ECG...) in one line: name, type,
    channels and unit, samples, the rate measured from its timestamps and the nominal one."""
    labels = ", ".join(a.labels[:4]) + (f", … {len(a.labels)}" if len(a.labels) > 4 else "")
    unit = f" [{a.unit}]" if a.unit else ""
    measured = measured_rate_hz(a.time)
    rate = f"{measured:.2f} Hz" if measured > 0 else "rate not measurable"
    nominal = f"nominal {a.rate_hz:g} Hz" if a.rate_hz > 0 else "irregular"
    kind = f" ({a.type})" if a.type else ""
    return (f"{a.name}{kind}: {a.n_channels} channel{'s' if a.n_channels != 1 else ''} "
            f"{labels}{unit}, {len(a.time)} samples at {rate} ({nominal})")
