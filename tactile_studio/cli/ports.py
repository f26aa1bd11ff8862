"""``ports`` and ``ble-scan``: finding the real sensor before recording from it."""

from __future__ import annotations

import argparse

from tactile_studio.cli import tables
from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.json_output import print_json
from tactile_studio.devices.discovery import list_serial_ports, scan_ble
from tactile_studio.errors import UserError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("ports", help="list serial ports (for --device serial --set port=...)")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=cmd_ports)

    p = sub.add_parser("ble-scan", help="scan for BLE sensors (for --device ble --set address=...)")
    p.add_argument("--seconds", type=finite_float, default=5.0, help="how long to scan (default 5)")
    p.add_argument("--name", default="", help="only names starting with this (case-insensitive)")
    p.add_argument("--service", default="", help="only devices advertising this service UUID")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=cmd_ble_scan)


def cmd_ports(args: argparse.Namespace) -> int:
    ports = list_serial_ports()
    if args.json:
        print_json([{"device": d, "description": desc, "vid_pid": vp}
                    for d, desc, vp in ports], indent=None)
    elif not ports:
        print("no serial ports found")
    elif ports:
        tables.table(("port", "vid:pid", "description"),
                     [(dev, vid_pid, desc) for dev, desc, vid_pid in ports])
    return 0


def cmd_ble_scan(args: argparse.Namespace) -> int:
    if args.seconds <= 0:
        raise UserError(f"--seconds must be positive, got {args.seconds}")
    found = scan_ble(args.seconds, args.name, args.service)
    if args.json:
        print_json([{"address": a, "name": n, "rssi": r} for a, n, r in found], indent=None)
    elif not found:
        print("no BLE devices found")
    for address, name, rssi in [] if args.json else found:
        print(f"{address:<20} {rssi:>5} dBm  {name}")
    return 0
