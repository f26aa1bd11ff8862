"""``emulate-serial``: the sensor's receiver on a pseudo-terminal, for trying the serial path.

Typical use, in two terminals::

    tactile-studio emulate-serial --corrupt 0.05 --link /tmp/ts-port
    tactile-studio record --device serial --set port=/tmp/ts-port --seconds 10 --out s.h5

Stopping the emulator and starting it again with the same ``--link`` is an unplug and
replug: the recorder reconnects and carries on in the same file.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.json_output import print_json
from tactile_studio.devices.line_decoder import KINDS
from tactile_studio.devices.serial_emulator import Corruption, SerialEmulator
from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ctrl_c_cancels
from tactile_studio.storage.recording.frame_sources import load_source


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("emulate-serial",
                       help="stream frames in the receiver's serial format on a pseudo-terminal")
    p.add_argument("--source", default="simulated",
                   help="'simulated' (default) or a session .h5 / ShearSense .csv to loop")
    p.add_argument("--rate", type=finite_float, default=None,
                   help="lines per second (default: 44, or the file's own rate)")
    p.add_argument("--corrupt", type=finite_float, default=0.0, metavar="FRACTION",
                   help="fraction of lines sent malformed, spread over the kinds (default 0)")
    p.add_argument("--kinds", default=",".join(KINDS),
                   help=f"malformed kinds to inject (default: all of {','.join(KINDS)})")
    p.add_argument("--seed", type=int, default=0, help="random seed (simulator and corruption)")
    p.add_argument("--seconds", type=finite_float, default=None, help="stop after this long")
    p.add_argument("--link", default=None, metavar="PATH",
                   help="stable symlink to the pty, re-pointed when the emulator restarts")
    p.add_argument("--no-trailing-comma", action="store_true",
                   help="end lines with the last value instead of a comma")
    p.add_argument("--json", action="store_true", help="print the final counts as JSON")
    p.set_defaults(func=cmd_emulate_serial)


def _summary(report: dict) -> str:
    kinds = ", ".join(f"{k} {n}" for k, n in report["malformed_by_kind"].items())
    text = (f"sent {report['lines']} lines: {report['good']} good, "
            f"{report['malformed']} malformed" + (f" ({kinds})" if kinds else ""))
    if report["interrupted"]:
        text += f"; {report['interrupted']} cut short by the stop"
    return text


def cmd_emulate_serial(args: argparse.Namespace) -> int:
    if not hasattr(os, "openpty"):
        raise UserError("emulate-serial needs pseudo-terminals (Linux or macOS)")
    if args.seconds is not None and args.seconds <= 0:
        raise UserError(f"--seconds must be positive, got {args.seconds}")
    if args.rate is not None and args.rate <= 0:
        raise UserError(f"--rate must be positive, got {args.rate}")
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    source, rate = load_source(args.source, args.seed, args.rate)
    if args.link and os.path.exists(args.link) and not os.path.islink(args.link):
        raise UserError(f"--link {args.link}: exists and is not a symlink")
    emu = SerialEmulator(source, rate_hz=rate,
                         corruption=Corruption(args.corrupt, kinds, args.seed),
                         link=args.link, trailing_comma=not args.no_trailing_comma)
    path = emu.open()
    where = f"{path} (link {args.link})" if args.link else path
    print(f"serial emulator on {where}: {rate:g} lines/s, corrupt {args.corrupt:g}, "
          f"source {args.source}", flush=True)
    print(f"port: {emu.port}", flush=True)
    print("streams while a program has the port open; Ctrl-C to stop", file=sys.stderr,
          flush=True)
    token = CancelToken()
    start = time.monotonic()
    emu.start()
    try:
        with ctrl_c_cancels(token):
            while not token.wait(0.1):
                if args.seconds is not None and time.monotonic() - start >= args.seconds:
                    break
    finally:
        emu.close(drain=5.0)  # let the reader take what is queued, so the counts are exact
    report = emu.report()
    if args.json:
        print_json(report, indent=None)
    else:
        print(_summary(report))
    return 0
