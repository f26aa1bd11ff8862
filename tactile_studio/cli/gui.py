"""``tactile-studio gui`` (the default command) and ``tactile-studio snapshot``.

Qt is imported inside the command functions only, so ``tactile_studio.cli`` stays
Qt-free and commands that never show a window start fast.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.recording_warnings import add_silence_option
from tactile_studio.devices.registry import DEFAULT_DEVICE, parse_set_options, plugin_class
from tactile_studio.errors import UserError


def _checked_settings(device: str, pairs: list[str] | None) -> dict[str, Any]:
    """``--set`` pairs for ``device``, validated now so errors are one line, not a window."""
    values = parse_set_options(pairs)
    plugin_class(device).validate_settings(dict(values))
    return values


def _last_device() -> str:
    from tactile_studio.ui.settings import app_settings

    return str(app_settings().value("device/name", "") or DEFAULT_DEVICE)


def cmd_gui(args: argparse.Namespace) -> int:
    require_display()
    device = args.device or DEFAULT_DEVICE
    if device == "last":
        device = _last_device()
    settings = _checked_settings(device, args.set)
    if args.lsl or args.markers:
        from tactile_studio.streams import load_pylsl

        load_pylsl()  # no liblsl: one line now, not a dialog later
    from tactile_studio.ui.app import run_gui

    return run_gui(device, settings, connect=not args.no_connect, lsl=args.lsl,
                   markers=args.markers, silence_warning_s=args.silence_warning)


def cmd_snapshot(args: argparse.Namespace) -> int:
    if args.seconds < 0:
        raise UserError("--seconds must be zero or more")
    settings = _checked_settings(args.device, args.set)
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY") \
            and sys.platform.startswith("linux"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from tactile_studio.ui.app import snapshot

    out = snapshot(args.device, settings, args.seconds, args.out, virtual=args.virtual,
                   hover=args.hover)
    print(out)
    return 0


def require_display(
        instead: str = "use `tactile-studio snapshot` (or QT_QPA_PLATFORM=offscreen) on a "
                       "headless machine") -> None:
    """A one-line error, not a Qt abort, when a window cannot be shown; ``instead`` is
    what to do on a headless machine (every command that opens a window calls this)."""
    if sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
            or os.environ.get("QT_QPA_PLATFORM")):
        raise UserError(f"no display: run on a desktop, or {instead}")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "gui", help="open the live view (default command)",
        description="Open Tactile Studio's live view, connected to a device "
                    f"({DEFAULT_DEVICE} by default, so it works with no hardware).")
    p.add_argument("--device", default=None,
                   help=f"device plugin (default {DEFAULT_DEVICE}; 'last' = the last used)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="device setting, repeatable (see `tactile-studio devices`)")
    p.add_argument("--no-connect", action="store_true", help="open without connecting")
    p.add_argument("--lsl", action="store_true", help="switch on \"Stream to LSL\": frames "
                   "and markers on the Lab Streaming Layer (see docs/lsl.md)")
    p.add_argument("--markers", action="append", metavar="NAME", default=None,
                   help="record this LSL marker stream's markers (by name; repeatable) with "
                        "every recording, each as an event at its frame")
    add_silence_option(p)
    p.set_defaults(func=cmd_gui)

    s = subparsers.add_parser(
        "snapshot", help="render the live view offscreen to a PNG",
        description="Connect, show S seconds of live data, and save the main window as a PNG "
                    "(works without a display).")
    s.add_argument("--device", default=DEFAULT_DEVICE,
                   help=f"device plugin (default {DEFAULT_DEVICE})")
    s.add_argument("--set", action="append", metavar="KEY=VALUE", help="device setting, repeatable")
    s.add_argument("--seconds", type=finite_float, default=3.0,
                   help="seconds of live data first (3)")
    s.add_argument("--out", required=True, help="PNG file to write")
    s.add_argument("--virtual", action="store_true", help="show the virtual 11x11 grid")
    s.add_argument("--hover", metavar="TAXEL", help="show this taxel's readout, e.g. C3")
    s.set_defaults(func=cmd_snapshot)
