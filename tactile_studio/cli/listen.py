"""``listen``: stream a device and let an experiment script start and stop recordings
through LabRecorder's remote-control commands (streams/remote_control.py)."""

from __future__ import annotations

import argparse
import sys
import time

from tactile_studio.acquisition.events import AcquisitionEvent, RecordingStarted, RecordingStopped
from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.recording_warnings import (
    add_silence_option,
    apply_silence_option,
    watch_health,
)
from tactile_studio.devices.registry import create_device, parse_set_options
from tactile_studio.errors import IncompleteError, UserError
from tactile_studio.jobs import CancelToken, ctrl_c_cancels
from tactile_studio.paths import make_out_dir
from tactile_studio.streams.remote_control import (
    DEFAULT_PORT,
    LOOPBACK,
    RemoteControl,
    this_machine_only,
)
from tactile_studio.terminal import printable

POLL_S = 0.05
ECHO_CHARS = 200


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "listen", help="record when an experiment script says so (LabRecorder's remote "
                       "control: start, stop, filename {...}, mark TEXT, status)",
        description="Stream a device and take LabRecorder's remote-control commands on a "
                    "TCP port (loopback only unless --host names another interface). "
                    "Ctrl-C ends; a recording in progress is closed first.")
    p.add_argument("--device", default="simulated", help="device plugin name (see `devices`)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="device setting")
    p.add_argument("--out", required=True, help="folder the recordings go into (a "
                                                "filename's relative {root:...} is under it)")
    p.add_argument("--port", type=int, default=DEFAULT_PORT,
                   help=f"TCP port (default {DEFAULT_PORT}, LabRecorder's; 0 = any free port)")
    p.add_argument("--host", default=LOOPBACK,
                   help="interface to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--lsl", action="store_true",
                   help="also publish the device on LSL (recordings then carry its clock)")
    p.add_argument("--seconds", type=finite_float, default=None,
                   help="stop listening after this long (default: until Ctrl-C)")
    add_silence_option(p)
    p.set_defaults(func=cmd_listen)


def cmd_listen(args: argparse.Namespace) -> int:
    out = make_out_dir(args.out)
    device = create_device(args.device, parse_set_options(args.set))
    acquisition = LiveAcquisition()
    apply_silence_option(acquisition, args)
    acquisition.use_device(device, args.device)
    if args.lsl:
        acquisition.set_lsl(True)
    control = RemoteControl(acquisition, out, args.port, args.host,
                            metadata={"notes": "recorded by listen"})
    incomplete: list[str] = []  # lines of recordings that ended short (acquisition/outcome.py)
    acquisition.add_listener(lambda e: _report(e, incomplete))
    watch_health(acquisition)
    token = CancelToken()
    try:
        port = control.listen()  # a port in use: one line, nothing started
        acquisition.start()
        print(f"remote control: listening on {args.host}:{port} for {args.device}; "
              "Ctrl-C ends", file=sys.stderr, flush=True)
        if not this_machine_only(args.host):
            print(f"remote control: warning: {args.host} is not this machine only; anyone "
                  "who reaches it may start and stop recordings (there is no password)",
                  file=sys.stderr, flush=True)
        end = None if args.seconds is None else time.monotonic() + args.seconds
        with ctrl_c_cancels(token):
            while not token.wait(POLL_S):
                acquisition.poll()
                for line, reply in control.process():  # a stranger's text: escaped, cut
                    print(f"> {_echo(line)}\n< {_echo(reply)}", flush=True)
                if end is not None and time.monotonic() >= end:
                    break
    finally:
        control.close()
        acquisition.close()
    if incomplete:  # a recording ended short (disk full, device lost, frames lost): exit 3
        raise IncompleteError(incomplete[-1] if len(incomplete) == 1 else
                              f"{len(incomplete)} recordings incomplete; the last: "
                              f"{incomplete[-1]}")
    if acquisition.engine is not None and acquisition.engine.error:
        raise UserError(f"{args.device}: {acquisition.engine.error}")
    return 0


def _echo(text: str) -> str:
    """A client's line or its reply as shown on the terminal: one line of printable
    characters, at most ``ECHO_CHARS`` of them."""
    cut = text if len(text) <= ECHO_CHARS else f"{text[:ECHO_CHARS]}... ({len(text)} characters)"
    return printable(cut, keep="")


def _report(event: AcquisitionEvent, incomplete: list[str]) -> None:
    if isinstance(event, RecordingStarted):
        print(f"recording {printable(event.path, keep='')}", flush=True)
    elif isinstance(event, RecordingStopped):
        print(f"wrote {printable(event.path, keep='')} ({event.reason})", flush=True)
        if event.message:
            incomplete.append(event.message)
            print(printable(event.message, keep=""), file=sys.stderr, flush=True)
