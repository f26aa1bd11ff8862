"""``tactile-studio collect``: a whole collection session headless, with a virtual
participant on the simulated sensor; without ``--virtual-participant`` it opens the
experimenter console pre-filled from the options (or resuming ``--resume FILE``).

Arguments are checked here, before any window, so mistakes are one line; Qt is imported
only on the console path, so ``tactile_studio.cli`` stays Qt-free.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.gui import require_display
from tactile_studio.cli.lsl_markers import add_markers_option, start_markers
from tactile_studio.cli.qc import add_qc_options, announce_check, qc_checker, qc_personalise
from tactile_studio.cli.recording_warnings import (
    add_silence_option,
    apply_silence_option,
    watch_health,
)
from tactile_studio.cli.stream import add_lsl_option, start_lsl
from tactile_studio.devices.frame_stream import ERROR, LiveStream
from tactile_studio.devices.registry import create_device, parse_set_options, plugin_class
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.health.gate import admit, wellness_status
from tactile_studio.jobs import CancelToken, TerminalProgress, ctrl_c_cancels
from tactile_studio.paths import make_out_dir
from tactile_studio.protocol.collect import (
    Collection,
    CollectionSettings,
    check_participant,
    open_collection,
    read_resume_info,
    resume_collection,
    resume_device,
)
from tactile_studio.protocol.console_options import ConsoleOptions
from tactile_studio.protocol.trial_runner import State, StreamClock
from tactile_studio.protocol.virtual import VirtualParticipant
from tactile_studio.storage.format.protocol_file import CollectionProtocol, load_protocol

DEFAULT_SPEED = 20.0
TICK_S = 0.002


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "collect", help="run a gesture-collection session (console, or headless)",
        description="Open the experimenter console pre-filled with these options (or "
                    "resuming --resume FILE), or with --virtual-participant run the whole "
                    "session headless on the simulated sensor.")
    p.add_argument("--protocol", help="protocol name (shear9, cost14, haart7) or .toml path")
    p.add_argument("--participant", help="participant id, e.g. P01")
    p.add_argument("--device", default=None,
                   help="device plugin (headless default: simulated; the console preselects "
                        "the last one used, else simulated)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="device setting")
    p.add_argument("--virtual-participant", action="store_true",
                   help="a simulated participant presses the keys and performs the gestures")
    p.add_argument("--speed", type=finite_float, default=None,
                   help=f"simulator speed, x real time (headless default {DEFAULT_SPEED:g}, "
                        "console 1)")
    p.add_argument("--blocks", type=int, default=None, help="run only the first N blocks")
    p.add_argument("--seed", type=int, default=None,
                   help="order seed: the blocks' random orders (and a virtual participant's "
                        "style); the simulated sensor keeps its own seed (--set seed=N)")
    p.add_argument("--condition", default="", help="condition label, e.g. FLAT")
    p.add_argument("--pilot", action="store_true",
                   help="a rehearsal: the file is marked pilot (named PILOT_...) and "
                        "datasets, train and info's study leave it out unless it is named; "
                        "the console opens with Pilot ticked (on the simulated sensor a "
                        "virtual participant performs)")
    p.add_argument("--out", default=None,
                   help="output folder (default: the current folder; the console: its form's "
                        "folder, sessions under the app's data folder or the last one used)")
    p.add_argument("--resume", metavar="FILE", help="continue a killed or closed session")
    p.add_argument("--allow-other-sensor", metavar="NOTE",
                   help="resume although the device or sensor differs from the file's (the "
                        "note, why, is stored in the session)")
    add_qc_options(p, "--qc-model", "check each trial as it ends with this model of "
                   "earlier participants: a run folder or RUN/export/<fold>.onnx")
    p.add_argument("--qc-personalise", action=argparse.BooleanOptionalAction, default=None,
                   help="after the first block, fit the check to the participant with their "
                        "own trials of it (the few-shot route; on by default with "
                        "--qc-model, the console's setup remembers it per study)"),
    add_lsl_option(p)
    add_markers_option(p)
    add_silence_option(p)
    p.add_argument("--wellness-override", metavar="NOTE",
                   help="start although the protocol's required wellness check failed, is "
                        "stale or missing (the note is stored in the session)")
    p.set_defaults(func=run)


def _device_settings(args: argparse.Namespace, name: str,
                     base: dict[str, Any] | None = None) -> dict[str, Any]:
    """The device's settings: ``base`` (a resumed file's), the speed, then ``--set``.
    The order seed (``--seed``) is not the simulated sensor's seed, which is its
    identity (sim-N): another order must not mean another sensor."""
    settings: dict[str, Any] = dict(base or {})
    if name == "simulated":
        settings.pop("speed", None)
        settings["gesture"] = "idle"
        settings["speed"] = DEFAULT_SPEED if args.speed is None else args.speed
    elif args.speed is not None:
        raise UserError("--speed applies to the simulated device only")
    settings.update(parse_set_options(args.set))
    return settings


def _check_resume(args: argparse.Namespace) -> dict[str, Any]:
    """The resume info of ``--resume FILE``, refusing options that contradict the file."""
    info = read_resume_info(args.resume)
    protocol, participant, seed = info["protocol"], info["participant"], info["seed"]
    if args.protocol and args.protocol not in (protocol.name, str(protocol.source)):
        raise UserError(f"{args.resume}: was recorded with protocol {protocol.name}, "
                        f"not {args.protocol}")
    if args.participant and args.participant != participant:
        raise UserError(f"{args.resume}: belongs to participant {participant}, "
                        f"not {args.participant}")
    if args.pilot and not info.get("pilot"):
        raise UserError(f"{args.resume}: is not a pilot session; --pilot cannot make a "
                        "participant's session a rehearsal")
    if args.seed is not None and args.seed != seed:
        raise UserError(f"{args.resume}: was recorded with order seed {seed}, not {args.seed}")
    return info


def _new_session(args: argparse.Namespace) -> tuple[CollectionProtocol, str, int]:
    """Protocol (with --blocks applied), participant and seed of a new session."""
    if not args.protocol or not args.participant:
        raise UserError("collect needs --protocol and --participant (or --resume FILE)")
    protocol = load_protocol(args.protocol)
    if args.blocks is not None:
        if args.blocks < 1:
            raise UserError(f"--blocks must be at least 1, got {args.blocks}")
        if args.blocks > protocol.blocks:  # refused, never silently the protocol's count
            raise UserError(f"--blocks {args.blocks}: protocol {protocol.name} has "
                            f"{protocol.blocks} blocks")
        protocol = protocol.with_overrides(blocks=args.blocks)
    return protocol, check_participant(args.participant), 0 if args.seed is None else args.seed


def console_options(args: argparse.Namespace) -> ConsoleOptions:
    """What ``run_console`` pre-fills the console with, every option checked (Qt-free).

    Resuming keeps the file's device settings that differ from the plugin's defaults,
    except the simulator's speed and scripted gesture (a virtual participant's, not an
    interactive session's).
    """
    if args.resume:
        info = _check_resume(args)
        file_device, file_settings = resume_device(info)  # the console's form does the same
        name = args.device or info["device"].get("plugin") or None
        settings: dict[str, Any] = dict(file_settings) if name == file_device else {}
        options: dict[str, Any] = {"resume": str(Path(args.resume).resolve())}
    else:
        protocol, participant, _ = _new_session(args)
        name, settings = args.device, {}
        out = None if args.out is None else Path(args.out).expanduser().resolve()
        options = {"protocol": args.protocol, "participant": participant,
                   "out_dir": None if out is None else str(out),
                   "blocks": protocol.blocks if args.blocks is not None else None,
                   "seed": args.seed, "condition": args.condition, "pilot": args.pilot}
    if args.speed is not None:
        if name != "simulated":
            raise UserError("--speed applies to the simulated device only")
        settings["speed"] = args.speed
    settings.update(parse_set_options(args.set))
    if settings and name is None:
        raise UserError("--set needs --device")
    if name is not None:
        plugin_class(name).validate_settings(dict(settings))
    options.update(device=name, device_settings=settings)
    personalise = qc_personalise(args)
    if getattr(args, "qc_model", None):  # the setup's trial check, pre-filled (checked
        # here: a model that cannot check is one line before any window opens)
        qc_checker(args.qc_model, args.qc_top_k, args.qc_threshold)
        options["qc"] = {"model": str(Path(args.qc_model).expanduser().resolve()),
                         "top_k": args.qc_top_k, "threshold": args.qc_threshold,
                         "personalise": personalise}
    if getattr(args, "markers", None):
        options["markers"] = tuple(args.markers)  # the console's recording takes them in
    if getattr(args, "silence_warning", None) is not None:
        options["silence_warning_s"] = args.silence_warning
    if getattr(args, "lsl", False):
        from tactile_studio.streams import load_pylsl

        load_pylsl()  # no liblsl: one line now, not a message in the window later
        options["lsl"] = True
    return ConsoleOptions(**options)


def run_console_command(args: argparse.Namespace) -> int:
    """Open the experimenter console pre-filled (a real participant presses the keys)."""
    require_display("add --virtual-participant for a headless session")
    options = console_options(args)
    from tactile_studio.ui.collect.app import run_console

    return run_console(options)


def run(args: argparse.Namespace) -> int:
    if not args.virtual_participant:
        return run_console_command(args)
    if args.resume:
        info = _check_resume(args)
        protocol, participant, seed = info["protocol"], info["participant"], info["seed"]
        old_dev = info["device"]
        name = args.device or old_dev.get("plugin") or "simulated"
        base = old_dev.get("settings") if old_dev.get("plugin") == name else None
    else:
        protocol, participant, seed = _new_session(args)
        name, base = args.device or "simulated", None
    check = qc_checker(args.qc_model, args.qc_top_k, args.qc_threshold, participant)
    personalise = qc_personalise(args)
    device = create_device(name, _device_settings(args, name, base))
    if not hasattr(device, "perform"):
        raise UserError(f"--virtual-participant needs the simulated device, not {name}")
    acquisition = LiveAcquisition()
    apply_silence_option(acquisition, args)
    watch_health(acquisition)  # a device gone silent is said as it happens, as record says it
    engine = acquisition.use_device(device, name)
    clock = StreamClock(engine)
    if args.resume:
        collection = resume_collection(args.resume, acquisition, clock=clock,
                                       allow_other_sensor=args.allow_other_sensor,
                                       trial_check=check)
        print(f"resuming {collection.path} (backup of the original: {collection.backup.name}); "
              f"{info['trials_done']}/{info['trials_total']} trials were done", file=sys.stderr)
    else:
        out = make_out_dir(args.out or ".")
        status = wellness_status(device.sensor_id(), protocol.wellness_required,
                                 protocol.wellness_max_age_h)
        print(status.text(), file=sys.stderr)
        collection = open_collection(CollectionSettings(
            protocol, participant, out, seed=seed, condition=args.condition,
            wellness=admit(status, args.wellness_override), pilot=args.pilot,
            trial_check=check, personalise_check=personalise), acquisition, clock=clock)
        print(f"writing {collection.path}", file=sys.stderr)
    if check is not None:
        announce_check(check, protocol, collection.runner)
    vp = VirtualParticipant(collection.runner, device, participant, seed)
    vp.prepare()
    try:
        if args.lsl:  # stopped before the file closes: the end of streaming is recorded
            acquisition.add_outlet(start_lsl(engine,
                                             wait_s=args.lsl_wait)).attach_runner(collection.runner)
        if args.markers:
            acquisition.add_outlet(start_markers(engine, args.markers))
        acquisition.start()
        _drive(collection, vp, engine, acquisition)
    finally:
        acquisition.close_outlets()
        collection.close()
        acquisition.close()
    print(collection.path)
    # acquisition/outcome.py: the same judgement as record and the GUI
    if acquisition.outcome is not None:
        if not acquisition.outcome.complete:
            print(acquisition.outcome.summary_line, file=sys.stderr)
        acquisition.outcome.raise_if_incomplete()  # device failed, write failed, frames lost: 3
    return 0


def _drive(session: Collection, vp: VirtualParticipant, engine: LiveStream,
           acq: LiveAcquisition) -> None:
    runner = session.runner
    progress = TerminalProgress(f"collect {session.participant}")
    token = CancelToken()
    shown = 0.0
    with ctrl_c_cancels(token):
        while runner.state not in State.DONE:
            if token.cancelled:
                runner.abort()
                done = runner.snapshot().trials_done
                print(f"\nstopped: {done} completed trials kept in {session.path}; continue with "
                      f"tactile-studio collect --virtual-participant --resume {session.path}",
                      file=sys.stderr)
                raise Cancelled("collection stopped")
            cut_off = session.end_if_cut_off()
            if cut_off is not None:
                if session.recorder.write_error or engine.state == ERROR:
                    return  # the outcome says which, and what was kept (exit 3)
                raise UserError(f"{cut_off}; completed trials are kept in {session.path}")
            acq.check_health()  # silence said, not stopped: a device may come back
            before = (runner.state, len(runner.trials))
            runner.tick()
            acted = vp.step()
            if time.monotonic() - shown >= 0.1:
                shown = time.monotonic()
                snap = runner.snapshot()
                where = ("practice" if snap.practice
                         else f"block {snap.block_number}/{snap.blocks_total}")
                progress(snap.progress, f"{where} {snap.trials_done}/{snap.trials_total} trials "
                                        f"{snap.state}")
            if not acted and (runner.state, len(runner.trials)) == before:
                time.sleep(TICK_S)  # idle; while things happen, go on at once
    progress(1.0, f"{runner.state}: {len(runner.trials)} trials")
