"""Display benchmark: how fast the live view paints and how stale what it paints is.

Runs the real main window offscreen on the simulated sensor at 43 Hz (the real sensor's
rate) and at 1 kHz, and reports display fps (frames actually painted per second) and
device-to-paint latency (time.time() at paint minus the frame's host arrival time),
median, p95 and p99, and the GUI thread's CPU time per painted frame (median, p95, mean) — each
with an
empty strip chart and with 8 taxels charted. Then times decoding one frame on the
physical 6x6 and virtual 11x11 grids, one frame at a time (what the live view does) and
in batches (what analysis does).

    QT_QPA_PLATFORM=offscreen .venv/bin/python benchmarks/bench_display.py [--seconds 5]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

STRIP_8 = [(1, 1), (1, 4), (2, 2), (2, 3), (3, 2), (3, 3), (4, 1), (4, 4)]


def replay_file(rate_hz: float, seconds: float, folder: str) -> str:
    """A session of simulated Twist frames at ``rate_hz`` to replay (recorded 4x faster)."""
    path = os.path.join(folder, f"twist-{rate_hz:g}hz.h5")
    subprocess.run([sys.executable, "-m", "tactile_studio", "record", "--device", "simulated",
                    "--set", f"rate={rate_hz:g}", "--set", "speed=4", "--set", "gesture=Twist",
                    "--seconds", f"{(seconds + 4) / 4:g}", "--out", path, "--force"],
                   check=True, capture_output=True, timeout=600)
    return path


def bench_window(rate_hz: float, seconds: float, display_hz: float = 60.0,
                 strip_taxels: list[tuple[int, int]] | None = None,
                 replay: str | None = None) -> dict:
    """Open the main window on the simulated sensor (or replaying the session ``replay``)
    and measure painting for ``seconds``."""
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.main_window import MainWindow, wait_for

    ensure_app()
    if replay is None:
        device, settings = "simulated", {"rate": str(rate_hz), "gesture": "Twist"}
    else:
        device, settings = "replay", {"path": replay, "speed": "1", "loop": "true"}
    w = MainWindow(device=device, settings=settings,
                   connect=True, persist=False, display_hz=display_hz)
    w.latency = type(w.latency)(keep=100_000)
    try:
        w.set_strip_taxels(strip_taxels or [])
        w.show()
        wait_for(2.5)  # baseline (100 frames) and warm-up
        marks: list[float] = []  # GUI thread CPU time at every newly painted frame
        last = [w._painted_index]

        def on_painted() -> None:  # connected after the window's own slot
            if w._painted_index != last[0]:
                last[0] = w._painted_index
                marks.append(time.thread_time())

        w.heatmap.painted.connect(on_painted)
        w.latency.clear()
        ticks0, frames0 = w._tick_count, w.controller.engine.frames
        t0, cpu0, proc0 = time.monotonic(), time.thread_time(), time.process_time()
        wait_for(seconds)
        elapsed = time.monotonic() - t0
        gui_cpu_s = time.thread_time() - cpu0
        other_cpu_s = time.process_time() - proc0 - gui_cpu_s
        w.heatmap.painted.disconnect(on_painted)
        lat = w.latency.values * 1e3
        cpu_ms = np.diff(marks) * 1e3  # between consecutive painted frames
        engine = w.controller.engine

        def pct(x: np.ndarray, q: float) -> float:
            return float(np.percentile(x, q)) if x.size else float("nan")

        return {
            "input_hz": (engine.frames - frames0) / elapsed,
            "polls_hz": (w._tick_count - ticks0) / elapsed,
            "display_fps": lat.size / elapsed,
            "gui_cpu_pct": gui_cpu_s / elapsed * 100,
            "other_cpu_pct": other_cpu_s / elapsed * 100,
            "latency_med_ms": pct(lat, 50),
            "latency_p95_ms": pct(lat, 95),
            "latency_p99_ms": pct(lat, 99),
            "cpu_ms_med": pct(cpu_ms, 50),
            "cpu_ms_p95": pct(cpu_ms, 95),
            "cpu_ms_mean": gui_cpu_s / lat.size * 1e3 if lat.size else float("nan"),
        }
    finally:
        w.shutdown()
        w.close()


def bench_decode(repeat: int = 2000, batch: int = 1000) -> dict:
    """Microseconds to decode one frame, singly and in a batch, physical and virtual."""
    from tactile_studio.devices import create_device
    from tactile_studio.sensor import compute_baseline, decode
    from tactile_studio.sensor.decode import FrameDecoder

    dev = create_device("simulated", {"speed": "0", "gesture": "Twist"})
    dev.open()
    raw = np.concatenate([dev.read(256).raw for _ in range(8)])
    dev.close()
    base = compute_baseline(raw[:100])
    lay = dev.layout
    out = {}
    for virtual in (False, True):
        name = "virtual" if virtual else "physical"
        one = raw[-1:]
        decode(lay, one, base, virtual=virtual)
        t0 = time.perf_counter()
        for _ in range(repeat):
            decode(lay, one, base, virtual=virtual)
        out[f"{name}_single_us"] = (time.perf_counter() - t0) / repeat * 1e6
        fd = FrameDecoder(lay, base, virtual=virtual)  # what the live view uses
        t0 = time.perf_counter()
        for _ in range(repeat):
            fd.decode(one[0])
        out[f"{name}_frame_decoder_us"] = (time.perf_counter() - t0) / repeat * 1e6
        many = raw[:batch]
        t0 = time.perf_counter()
        for _ in range(20):
            decode(lay, many, base, virtual=virtual)
        out[f"{name}_batch_us"] = (time.perf_counter() - t0) / (20 * len(many)) * 1e6
    return out


def _load() -> float:
    """The 1-minute load average (NaN where the OS has none)."""
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="measuring time per rate")
    parser.add_argument("--rates", type=float, nargs="+", default=[43.0, 1000.0],
                        help="device rates to measure (Hz)")
    parser.add_argument("--source", choices=("simulated", "replay", "both"), default="both",
                        help="simulated: the contact-mechanics simulator in the app's process "
                        "(competing with the GUI thread for the interpreter); replay: the same "
                        "frames replayed from a session file (like a serial device), so the "
                        "figures are the display's own cost; column 'rest' shows what the "
                        "source and the engine cost")
    args = parser.parse_args(argv)
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    print(f"Live view display benchmark (platform {os.environ.get('QT_QPA_PLATFORM', 'native')},"
          f" display rate 60 Hz, new frames looked for every 4 ms, {args.seconds:g} s per"
          " rate)")
    load = _load()
    print(f"(1-minute load average {load:.1f} on {os.cpu_count()} CPUs at the start: a busy "
          "machine lowers fps and raises latency and wall times)")
    rows = []
    sources = ("simulated", "replay") if args.source == "both" else (args.source,)
    with tempfile.TemporaryDirectory() as folder:
        for source in sources:
            for rate in args.rates:
                path = replay_file(rate, args.seconds, folder) if source == "replay" else None
                for taxels in ([], STRIP_8):
                    r = bench_window(rate, args.seconds, strip_taxels=taxels, replay=path)
                    r.update(rate=rate, taxels=len(taxels), load=_load(), source=source)
                    rows.append(r)
    print("GUI ms/frame: the GUI thread's CPU time (thread_time: polls, decode, set-up and "
          "paint,\nless sensitive to other processes than wall time) between consecutive "
          "painted frames,\nmedian, p95 and mean (total over painted frames); core: share "
          "of one core;\nrest: CPU of the app's other threads (device, engine) as a share of "
          "one core;\npolls: looks for a new frame per second.")
    print(f"{'source':>9} {'input':>7} {'strip':>6} {'polls':>5} {'fps':>5} | "
          f"{'GUI ms/frame med':>16} {'p95':>5} "
          f"{'mean':>5} {'core':>6} {'rest':>6} | {'latency med':>11} {'p95':>5} {'p99':>5} | "
          f"{'load':>4}")
    for r in rows:
        print(f"{r['source']:>9} {r['rate']:5.0f}Hz {r['taxels']:3d} tx {r['polls_hz']:4.0f}/s "
              f"{r['display_fps']:5.1f} | "
              f"{r['cpu_ms_med']:13.2f} ms {r['cpu_ms_p95']:5.2f} {r['cpu_ms_mean']:5.2f} "
              f"{r['gui_cpu_pct']:5.1f}% {r['other_cpu_pct']:5.1f}% | "
              f"{r['latency_med_ms']:8.1f} ms "
              f"{r['latency_p95_ms']:5.1f} {r['latency_p99_ms']:5.1f} | {r['load']:4.1f}")
    print("Goals (issue 12): GUI thread <= 3 ms per painted frame (<= 15 % of a core at 43 Hz), "
          ">= 58 fps at 1 kHz, p99 latency <= 20 ms; measured input rates "
          + ", ".join(f"{r['input_hz']:.0f} Hz" for r in rows))
    d = bench_decode()
    print("Decode cost per frame (6x6 ShearSense, 180 channels):")
    for name, label in (("physical", "physical 6x6: "), ("virtual", "virtual 11x11:")):
        print(f"  {label}  {d[f'{name}_frame_decoder_us']:6.1f} us one at a time "
              f"(FrameDecoder, live view), {d[f'{name}_single_us']:6.1f} us with decode(), "
              f"{d[f'{name}_batch_us']:5.2f} us in batches of 1000")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
