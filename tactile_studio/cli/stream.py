"""``tactile-studio stream``: publish a device as LSL streams (frames + markers) until
Ctrl-C, and the ``--lsl`` helpers the ``record``, ``collect`` and ``gui`` commands share."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.cli.argtypes import finite_float
from tactile_studio.devices.frame_stream import ERROR, FINISHED, LiveStream
from tactile_studio.devices.registry import parse_set_options
from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ctrl_c_cancels
from tactile_studio.terminal import printable, raw_stream

LSL_HELP = ("also publish the frames (raw counts) and a marker stream on the Lab Streaming "
            "Layer (see docs/lsl.md)")


def add_lsl_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--lsl", action="store_true", help=LSL_HELP)
    add_lsl_wait_option(parser)


def add_lsl_wait_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--lsl-wait", type=finite_float, default=0.0, metavar="SECONDS",
                        help="before the device starts, wait up to this long for an LSL "
                             "recipient (e.g. LabRecorder) to open the streams (default 0)")


def start_lsl(engine: LiveStream, decoded: bool = False, name: str | None = None,
              wait_s: float = 0.0) -> Any:
    """A started LslStreamer on ``engine`` (LslUnavailable, one line, without liblsl);
    waits up to ``wait_s`` for a recipient so nothing from the start is missed."""
    from tactile_studio.streams.lsl_outlet import LslStreamer

    if wait_s < 0:
        raise UserError(f"--lsl-wait must be zero or more, got {wait_s}")
    streamer = LslStreamer(engine, decoded=decoded, name=name).start()
    print(f"LSL: publishing '{streamer.name}' ({streamer.content}, source_id "
          f"{streamer.source_id}) and '{streamer.marker_name}'", file=sys.stderr)
    if wait_s > 0:
        print(f"LSL: waiting up to {wait_s:g} s for a recipient...", file=sys.stderr)
        found = streamer.wait_for_recipient(wait_s)
        print("LSL: a recipient is connected" if found else
              "LSL: no recipient yet; starting anyway", file=sys.stderr)
    return streamer


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "stream", help="publish a device on the Lab Streaming Layer (frames + markers)",
        description="Publish a device's frames and a JSON marker stream (tare, gaps, "
                    "reconnects...) on the Lab Streaming Layer until Ctrl-C, for LabRecorder "
                    "or any LSL inlet. See docs/lsl.md.")
    p.add_argument("--device", default="simulated", help="device plugin (see `devices`)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="device setting")
    p.add_argument("--decoded", action="store_true",
                   help="stream normal / shear-x / shear-y per taxel instead of raw counts")
    p.add_argument("--name", default=None, help="frame stream name (default "
                   "TactileStudio-DEVICE; the marker stream adds -markers)")
    p.add_argument("--seconds", type=finite_float, default=None,
                   help="stop after this long (default: until Ctrl-C)")
    add_lsl_wait_option(p)
    p.set_defaults(func=cmd_stream)


def cmd_stream(args: argparse.Namespace) -> int:
    if args.seconds is not None and args.seconds <= 0:
        raise UserError(f"--seconds must be positive, got {args.seconds}")
    if args.name is not None and not args.name.strip():
        raise UserError("--name must not be empty")
    engine = open_stream(args.device, parse_set_options(args.set))
    streamer = start_lsl(engine, decoded=args.decoded, name=args.name, wait_s=args.lsl_wait)
    engine.start()
    token = CancelToken()
    start = time.monotonic()
    try:
        with ctrl_c_cancels(token):
            while not token.wait(0.25):
                status = printable(f"{streamer.status_line()}, "
                                   f"{engine.measured_rate_hz():.1f} Hz, {engine.state}   ")
                raw_stream(sys.stderr).write(f"\r{status}")  # the line redrawn in place
                sys.stderr.flush()
                if engine.state in (ERROR, FINISHED):
                    break
                if args.seconds is not None and time.monotonic() - start >= args.seconds:
                    break
    finally:
        engine.stop()
        streamer.stop()
    print(f"\nstreamed {streamer.frames_sent} frames and {streamer.markers_sent} markers "
          f"(lost {streamer.lost})", file=sys.stderr)
    if engine.state == ERROR:
        raise UserError(f"device {args.device}: {engine.error}")
    return 0
