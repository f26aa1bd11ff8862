"""``tactile-studio collect``: a whole collection session headless, with a virtual
participant on the simulated sensor (interactive collection is the GUI's)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from tactile_studio.devices.engine import ERROR, AcquisitionEngine
from tactile_studio.devices.registry import create_device, parse_set_options
from tactile_studio.errors import Cancelled, UserError
from tactile_studio.jobs import CancelToken, TerminalProgress, ctrl_c_cancels
from tactile_studio.protocol.collect import (
    CollectionSession,
    check_participant,
    open_session,
    read_resume_info,
    resume_session,
)
from tactile_studio.protocol.protocol_file import load_protocol
from tactile_studio.protocol.runner import State, StreamClock
from tactile_studio.protocol.virtual import VirtualParticipant

DEFAULT_SPEED = 20.0
TICK_S = 0.002


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "collect", help="run a gesture-collection session headless (virtual participant)",
        description="Run a collection protocol headless. Interactive sessions with a real "
                    "participant run in the GUI (tactile-studio gui, Collect).")
    p.add_argument("--protocol", help="protocol name (shear9, cost14, haart7) or .toml path")
    p.add_argument("--participant", help="participant id, e.g. P01")
    p.add_argument("--device", default=None, help="device plugin (default: simulated)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="device setting")
    p.add_argument("--virtual-participant", action="store_true",
                   help="a simulated participant presses the keys and performs the gestures")
    p.add_argument("--speed", type=float, default=None,
                   help=f"simulator speed, x real time (default {DEFAULT_SPEED:g})")
    p.add_argument("--blocks", type=int, default=None, help="run only the first N blocks")
    p.add_argument("--seed", type=int, default=None, help="randomisation and simulation seed")
    p.add_argument("--condition", default="", help="condition label, e.g. FLAT")
    p.add_argument("--out", default=".", help="output folder (default: current folder)")
    p.add_argument("--resume", metavar="FILE", help="continue a killed or closed session")
    p.set_defaults(func=run)


def _device_settings(args: argparse.Namespace, name: str, seed: int,
                     base: dict[str, Any] | None = None) -> dict[str, Any]:
    settings: dict[str, Any] = dict(base or {})
    if name == "simulated":
        settings.pop("speed", None)
        settings.setdefault("seed", seed)
        settings["gesture"] = "idle"
        settings["speed"] = DEFAULT_SPEED if args.speed is None else args.speed
    elif args.speed is not None:
        raise UserError("--speed applies to the simulated device only")
    settings.update(parse_set_options(args.set))
    return settings


def run(args: argparse.Namespace) -> int:
    if not args.virtual_participant:
        raise UserError("interactive collection needs the GUI: run `tactile-studio gui` and "
                        "open Collect (or add --virtual-participant for a headless session)")
    if args.resume:
        info = read_resume_info(args.resume)
        protocol, participant, seed = info["protocol"], info["participant"], info["seed"]
        if args.protocol and args.protocol not in (protocol.name, str(protocol.source)):
            raise UserError(f"{args.resume}: was recorded with protocol {protocol.name}, "
                            f"not {args.protocol}")
        if args.participant and args.participant != participant:
            raise UserError(f"{args.resume}: belongs to participant {participant}, "
                            f"not {args.participant}")
        if args.seed is not None and args.seed != seed:
            raise UserError(f"{args.resume}: was recorded with seed {seed}, not {args.seed}")
        old_dev = info["device"]
        name = args.device or old_dev.get("plugin") or "simulated"
        base = old_dev.get("settings") if old_dev.get("plugin") == name else None
    else:
        if not args.protocol or not args.participant:
            raise UserError("collect needs --protocol and --participant (or --resume FILE)")
        protocol = load_protocol(args.protocol)
        if args.blocks is not None:
            if args.blocks < 1:
                raise UserError(f"--blocks must be at least 1, got {args.blocks}")
            protocol = protocol.with_overrides(blocks=min(args.blocks, protocol.blocks))
        participant = check_participant(args.participant)
        seed = 0 if args.seed is None else args.seed
        name, base = args.device or "simulated", None
    device = create_device(name, _device_settings(args, name, seed, base))
    if not hasattr(device, "perform"):
        raise UserError(f"--virtual-participant needs the simulated device, not {name}")
    # at speed 0 the simulator can run far ahead of the participant: a deeper ring keeps
    # every trial's frames available for its quality check
    fast = name == "simulated" and float(device.settings.get("speed", 1.0)) == 0.0
    engine = AcquisitionEngine(device, capacity=1 << 18 if fast else 1 << 16)
    clock = StreamClock(engine)
    if args.resume:
        session = resume_session(args.resume, engine, clock=clock)
        print(f"resuming {session.path} (backup of the original: {session.backup.name}); "
              f"{info['trials_done']}/{info['trials_total']} trials were done", file=sys.stderr)
    else:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        session = open_session(protocol, participant, engine, out, seed=seed, clock=clock,
                               condition=args.condition)
        print(f"writing {session.path}", file=sys.stderr)
    vp = VirtualParticipant(session.runner, device, participant, seed)
    vp.prepare()
    engine.start()
    try:
        _drive(session, vp, engine)
    finally:
        session.close()
        engine.stop()
    print(session.path)
    return 0


def _drive(session: CollectionSession, vp: VirtualParticipant, engine: AcquisitionEngine) -> None:
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
            if engine.state == ERROR or not engine.running and runner.state != State.SETUP:
                runner.abort()
                raise UserError(f"device {engine.device.name}: {engine.error or 'stopped'}; "
                                f"completed trials are kept in {session.path}")
            before = (runner.state, len(runner.trials))
            runner.tick()
            acted = vp.step()
            if time.monotonic() - shown >= 0.1:
                shown = time.monotonic()
                snap = runner.snapshot()
                where = "practice" if snap.practice else f"block {snap.block_number}/{snap.blocks_total}"
                progress(snap.progress, f"{where} {snap.trials_done}/{snap.trials_total} trials "
                                        f"{snap.state}")
            if not acted and (runner.state, len(runner.trials)) == before:
                time.sleep(TICK_S)  # idle; while things happen, go on at once
    progress(1.0, f"{runner.state}: {len(runner.trials)} trials")
