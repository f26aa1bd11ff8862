"""``emulate-printer`` and ``emulate-loadcell``: the characterisation instruments on
pseudo-terminals, for trying the gcode stage and serial load cell without hardware::

    tactile-studio emulate-printer --link /tmp/ts-printer
    tactile-studio emulate-loadcell --link /tmp/ts-loadcell --force 0 0 1.5
    tactile-studio characterise --stage gcode --stage-set port=/tmp/ts-printer \
        --force serial --force-set port=/tmp/ts-loadcell ...
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from tactile_studio.cli.argtypes import finite_float, non_negative_float, positive_float
from tactile_studio.errors import UserError
from tactile_studio.instruments.loadcell_emulator import MODES, LoadCellEmulator
from tactile_studio.instruments.printer_emulator import PrinterEmulator
from tactile_studio.jobs import CancelToken, ctrl_c_cancels


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("emulate-printer", help="a Marlin-style 3D printer on a pseudo-terminal")
    p.add_argument("--link", default=None, metavar="PATH", help="stable symlink to the pty")
    p.add_argument("--fail-home", action="store_true", help="homing fails (endstop never triggers)")
    p.add_argument("--seconds", type=finite_float, default=None, help="stop after this long")
    p.set_defaults(func=cmd_printer)
    q = sub.add_parser("emulate-loadcell", help="a serial load cell on a pseudo-terminal")
    q.add_argument("--link", default=None, metavar="PATH", help="stable symlink to the pty")
    q.add_argument("--rate", type=positive_float, default=100.0,
                   help="lines per second (default 100)")
    q.add_argument("--axes", choices=("z", "xyz"), default="xyz", help="values per line")
    q.add_argument("--force", type=finite_float, nargs=3, default=(0.0, 0.0, 0.0),
                   metavar=("FX", "FY", "FZ"),
                   help="constant force to report (raw units)")
    q.add_argument("--noise", type=non_negative_float, default=0.001,
                   help="Gaussian noise (raw units)")
    q.add_argument("--mode", choices=MODES, default="ok", help="ok, garbage or silent")
    q.add_argument("--seconds", type=finite_float, default=None, help="stop after this long")
    q.set_defaults(func=cmd_loadcell)


def _serve(emu, label: str, seconds: float | None) -> int:  # noqa: ANN001
    if not hasattr(os, "openpty"):
        raise UserError(f"{label} needs pseudo-terminals (Linux or macOS)")
    if seconds is not None and seconds <= 0:
        raise UserError(f"--seconds must be positive, got {seconds}")
    emu.open()
    print(f"{label} on {emu.port}", file=sys.stderr, flush=True)
    token = CancelToken()
    end = time.monotonic() + seconds if seconds else None
    with ctrl_c_cancels(token):
        while not token.cancelled and (end is None or time.monotonic() < end):
            token.wait(0.1)
    emu.stop()
    return 0


def cmd_printer(args: argparse.Namespace) -> int:
    return _serve(PrinterEmulator(link=args.link, fail_home=args.fail_home), "printer",
                  args.seconds)


def cmd_loadcell(args: argparse.Namespace) -> int:
    force = tuple(args.force)
    emu = LoadCellEmulator(lambda t: force, rate_hz=args.rate, axes=args.axes, link=args.link,
                           noise=args.noise)
    emu.set_mode(args.mode)
    return _serve(emu, "load cell", args.seconds)
