"""Decode throughput of the real-device paths, one core, no I/O.

Serial: lines/s of 180 values through LineDecoder, fed in reads of several sizes (a
read of one line is what a 44 Hz receiver gives; large reads are a backlog), clean and
with 5% malformed lines. Goal: >= 20,000 lines/s, so a 1 kHz sensor costs < 5% of a core.
BLE: frames/s through the Reassembler at several ATT MTUs.

Run: python -m benchmarks.bench_serial (or python benchmarks/bench_serial.py).
"""

from __future__ import annotations

import time

import numpy as np

from tactile_studio.devices.ble_payload import Reassembler, encode_packets
from tactile_studio.devices.line_decoder import KINDS, LineDecoder, encode_frame
from tactile_studio.devices.serial_emulator import corrupt_line

LINES = 20000


def _stream(corrupt: float, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    raw = rng.normal(30000, 6000, (LINES + 1, 180)).clip(0, 65535).astype(np.int64)
    out = []
    for i in range(LINES):
        if rng.random() < corrupt:
            out.append(corrupt_line(KINDS[i % len(KINDS)], raw[i:i + 2], rng))
        else:
            out.append(encode_frame(raw[i]))
    return b"".join(out)


def _lines_per_s(data: bytes, read_size: int) -> float:
    dec = LineDecoder()
    t0 = time.perf_counter()
    for pos in range(0, len(data), read_size):
        dec.feed(data[pos:pos + read_size])
    elapsed = time.perf_counter() - t0
    return (dec.good + sum(dec.malformed.values())) / elapsed


def _ble_frames_per_s(mtu: int, frames: int = 5000) -> float:
    raw = np.random.default_rng(1).integers(0, 65536, (frames, 180))
    packets = [p for i, row in enumerate(raw) for p in encode_packets(i, row, mtu)]
    r = Reassembler()
    t0 = time.perf_counter()
    for p in packets:
        r.feed(p)
    elapsed = time.perf_counter() - t0
    assert r.frames == frames
    return frames / elapsed


def main() -> None:
    line_bytes = len(encode_frame(np.full(180, 30000)))
    print(f"serial line decode, lines/s of 180 values (one core; goal >= 20,000; "
          f"a line is ~{line_bytes} bytes)")
    for corrupt in (0.0, 0.05):
        data = _stream(corrupt)
        for label, size in (("one line per read", line_bytes), ("4 KiB reads", 4096),
                            ("64 KiB reads", 65536)):
            print(f"  {corrupt:4.0%} malformed, {label:18s}: {_lines_per_s(data, size):10.0f}")
    print("BLE reassembly, frames/s (one core)")
    for mtu in (23, 247, 517):
        print(f"  MTU {mtu:3d} ({len(encode_packets(0, np.zeros(180), mtu)):2d} notifications"
              f"/frame): {_ble_frames_per_s(mtu):10.0f}")


if __name__ == "__main__":
    main()
