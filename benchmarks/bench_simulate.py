"""Frames per second of the simulated sensor's generator (no threads, no pacing).

The goal is >= 5,000 frames/s on one core: the engine's ingest rate with recording on.
Run: python -m benchmarks.bench_simulate (or python benchmarks/bench_simulate.py).
"""

from __future__ import annotations

import time

from tactile_studio.simulate import GESTURE_NAMES, SensorSimulator


def _fps(sim: SensorSimulator, frames: int, batch: int) -> float:
    sim.step(batch)  # warm caches
    t0 = time.perf_counter()
    done = 0
    while done < frames:
        done += len(sim.step(batch))
    return done / (time.perf_counter() - t0)


def main() -> None:
    print("simulated sensor generator, frames/s (one core)")
    for batch in (1, 16, 256, 4096):
        fps = _fps(SensorSimulator(gesture="auto", seed=1), 20000 if batch > 1 else 5000, batch)
        print(f"  auto demo, batch {batch:5d}: {fps:10.0f}")
    for name in ("idle", *GESTURE_NAMES):
        fps = _fps(SensorSimulator(gesture=name, seed=1), 20000, 256)
        print(f"  {name:17s} batch 256: {fps:10.0f}")


if __name__ == "__main__":
    main()
