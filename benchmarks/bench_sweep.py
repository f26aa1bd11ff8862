"""A sweep of 12 tasks (rf and cnn1d x normal and shear x 3 LOPO folds, tiny presets, 3
virtual participants of 2 shear9 blocks) on local worker processes and on a local Ray
instance: wall time each, and what of it is starting the workers. The README's "sweep of
12 tasks" row comes from here.

Run: python -m benchmarks sweep [--no-ray]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from tactile_studio.cli import main as cli
from tactile_studio.learn.experiments.executors import LocalExecutor, RayExecutor
from tactile_studio.learn.experiments.experiment import ExperimentConfig
from tactile_studio.learn.experiments.sweep import run_sweep

MODELS, CHANNELS = ["rf", "cnn1d"], ["normal", "shear"]


def data(folder: Path) -> Path:
    for p in (1, 2, 3):
        cli(["collect", "--protocol", "shear9", "--participant", f"P0{p}", "--device",
             "simulated", "--virtual-participant", "--speed", "0", "--blocks", "2",
             "--seed", str(p), "--out", str(folder)])
    return folder


def timed(executor, base: ExperimentConfig, out: Path) -> tuple[float, float, int]:  # noqa: ANN001
    """(wall s of the whole sweep, s until the executor was up, tasks)."""
    t0 = time.perf_counter()
    with executor as ex:
        started = time.perf_counter() - t0
        result = run_sweep(base, MODELS, CHANNELS, ex, out)
    return time.perf_counter() - t0, started, sum(r["folds"] for r in result.rows)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--no-ray", action="store_true")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        base = ExperimentConfig(data=[str(data(root / "data"))], model="rf", evaluation="lopo",
                                preset="tiny", epochs=3, cache_dir=str(root / "cache"),
                                overrides={}, adapt="auto")
        wall, up, n = timed(LocalExecutor(2), base, root / "local")
        print(f"sweep of {n} tasks on local workers (--jobs 2): {wall:.1f} s wall")
        if not args.no_ray:
            wall, up, n = timed(RayExecutor(jobs=2), base, root / "ray")
            print(f"sweep of {n} tasks on a local Ray instance: {wall:.1f} s wall, "
                  f"{up:.1f} s of it starting Ray")


if __name__ == "__main__":
    import sys
    main(sys.argv[1:])
