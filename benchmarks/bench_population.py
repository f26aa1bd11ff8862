"""The simulator's populations beside the real recordings (issue 15's table), and what
they do to a random forest leave-one-participant-out.

For each difficulty: 10 virtual participants x 9 gestures x 4 repetitions of 2 s (one
sensor, flat surface; ``real`` also on a pillow), decoded with the project's ``decode``
on the physical grid; the statistics of ``tactile_studio.learn.touch_stats`` (median
[IQR] over trials, CV of the participants' medians); then rf (full preset) LOPO,
per-trial accuracy. Run: .venv/bin/python -m benchmarks population
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from learn_fixtures import make_dataset_folder  # noqa: E402

from tactile_studio.learn.dataset import read_sessions  # noqa: E402
from tactile_studio.learn.experiment import ExperimentConfig, run_experiment  # noqa: E402
from tactile_studio.learn.touch_stats import format_table, population_stats  # noqa: E402

COHORTS = (("easy", "FLAT"), ("real", "FLAT"), ("real", "PILLOW"), ("hard", "FLAT"))


def main() -> None:
    columns, accs = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        for level, surface in COHORTS:
            name = f"{level} {surface.lower()}"
            folder = Path(tmp) / name.replace(" ", "-")
            t0 = time.perf_counter()
            make_dataset_folder(folder, participants=10, blocks=4, difficulty=level,
                                condition=surface)
            ds = read_sessions([folder]).select(None)
            made = time.perf_counter() - t0
            columns[name] = population_stats(ds.trials, ds.participants, ds.channel_names)
            t0 = time.perf_counter()
            cfg = ExperimentConfig(data=[str(folder)], model="rf", protocol="lopo")
            m = run_experiment(cfg, dataset=ds).metrics
            accs.append((name, len(ds), m["trial_accuracy"], made, time.perf_counter() - t0))
    print(format_table(columns))
    print("\nrf (full) LOPO, 10 participants x 9 gestures x 4 trials, per-trial accuracy:")
    for name, n, acc, made, took in accs:
        print(f"  {name:12s} {n} trials  accuracy {acc:.3f}  "
              f"(simulate+decode {made:.1f} s, rf LOPO {took:.1f} s)")


if __name__ == "__main__":
    main()
