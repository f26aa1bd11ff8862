"""Memory while recording for a long time: flat once the ring buffer is full.

A 1 kHz simulated recording through the same path as ``record`` (LiveAcquisition,
recorder thread, a poll loop ten times a second) for ``--minutes`` (default 20). The
process's resident memory is sampled every 10 s; once the engine's ring is full (its
capacity / rate, ~66 s at 1 kHz) nothing should grow any more, so the figure is the
least-squares slope of RSS after that, in KB/s. Goal: <= 1 KB/s (issue 33 measured
+40 KB/s: h5py's default chunk cache, see storage/format/session_writer.py).

    python -m benchmarks.bench_soak --minutes 4
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

GOAL_KB_S = 1.0


def rss_kb() -> int:
    """Resident set size of this process (Linux /proc; else the peak from getrusage)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") // 1024
    except OSError:
        import resource

        return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def soak(minutes: float, rate: float = 1000.0, sample_s: float = 10.0,
         folder: Path | None = None) -> dict:
    """Record ``minutes`` at ``rate`` Hz; RSS samples and the slope after the ring fills."""
    from tactile_studio.acquisition.live_acquisition import LiveAcquisition

    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        acq = LiveAcquisition()
        engine = acq.open("simulated", {"rate": rate})
        acq.start_recording(Path(tmp) / "soak.h5", metadata={"source": "bench_soak"})
        acq.start()
        fill_s = engine.ring.capacity / rate
        t0 = time.monotonic()
        samples: list[tuple[float, int]] = []
        next_sample = 0.0
        try:
            while (now := time.monotonic() - t0) < minutes * 60:
                acq.poll()
                if not acq.recording:
                    raise RuntimeError("recording stopped early: "
                                       f"{acq.outcome and acq.outcome.line}")
                if now >= next_sample:
                    samples.append((now, rss_kb()))
                    print(f"  {now:7.0f} s  {samples[-1][1] / 1024:8.1f} MB  "
                          f"{engine.frames:,} frames", flush=True)
                    next_sample += sample_s
                time.sleep(0.1)
        finally:
            acq.close()
        outcome = acq.outcome
    after = [(t, r) for t, r in samples if t >= fill_s + sample_s]
    slope = float(np.polyfit([t for t, _ in after], [r for _, r in after], 1)[0]) \
        if len(after) >= 3 else float("nan")
    return {"samples": samples, "fill_s": fill_s, "slope_kb_s": slope,
            "frames": outcome.frames if outcome else 0,
            "complete": bool(outcome and outcome.complete)}


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="bench_soak", description=__doc__.splitlines()[0])
    p.add_argument("--minutes", type=float, default=20.0, help="how long to record")
    p.add_argument("--rate", type=float, default=1000.0, help="simulated frame rate (Hz)")
    args = p.parse_args(argv or [])
    with tempfile.TemporaryDirectory() as appdirs:  # the user's sensor logbook is not touched
        for name in ("DATA", "CACHE"):
            os.environ.setdefault(f"TACTILE_STUDIO_{name}_DIR", os.path.join(appdirs, name))
        print(f"soak: {args.rate:g} Hz simulated recording for {args.minutes:g} min, "
              "RSS every 10 s", flush=True)
        r = soak(args.minutes, args.rate)
    first = r["samples"][0][1] / 1024 if r["samples"] else 0.0
    last = r["samples"][-1][1] / 1024 if r["samples"] else 0.0
    verdict = "ok" if r["slope_kb_s"] <= GOAL_KB_S else "OVER GOAL"
    print(f"soak: {r['frames']:,} frames recorded "
          f"({'complete' if r['complete'] else 'INCOMPLETE'});"
          f" RSS {first:.1f} -> {last:.1f} MB; ring full after {r['fill_s']:.0f} s; slope "
          f"after it {r['slope_kb_s']:.2f} KB/s (goal <= {GOAL_KB_S:g}: {verdict})")


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
