"""The simulator's people beside the real recordings (issue 37's table), and what the
difficulties do to a random forest leave-one-participant-out.

Part 1, the table: populations of 10 virtual people as ``collect --virtual-participant
--seed S --set seed=S`` draws them (default ``real`` difficulty, shear9, 2 blocks, flat surface),
decoded with the project's ``decode`` on the physical grid; the statistics of
``tactile_studio.learn.data.touch_stats`` (median [IQR] over trials, CV of the participants'
medians) for population seed 0 alone and pooled over ``--populations`` seeds (the mean,
with the lowest and highest CV: ten people are a small sample), then each pooled figure
divided by the real one (issue 37 asks 0.75-1.25).

Part 2, rf (full preset) LOPO per difficulty: 10 people x 9 gestures x 4 repetitions.
Run: .venv/bin/python -m benchmarks population [--populations 8] [--no-rf]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from learn_fixtures import make_dataset_folder, make_virtual_population  # noqa: E402

from tactile_studio.learn.data.dataset import read_sessions  # noqa: E402
from tactile_studio.learn.data.touch_stats import (  # noqa: E402
    format_table,
    pooled,
    population_stats,
    ratios_to_real,
)
from tactile_studio.learn.experiments.experiment import (  # noqa: E402
    ExperimentConfig,
    run_experiment,
)

COHORTS = (("easy", "FLAT"), ("real", "FLAT"), ("real", "PILLOW"), ("hard", "FLAT"))


def simulator_table(populations: int) -> None:
    stats = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(populations):
            folder = Path(tmp) / f"pop{seed}"
            make_virtual_population(folder, seed)
            ds = read_sessions([folder]).select(None)
            stats.append(population_stats(ds.trials, ds.participants, ds.channel_names))
    print(f"Simulated people (difficulty real, shear9, 2 blocks, flat) beside the real "
          f"recordings; {populations} populations of 10 in {time.perf_counter() - t0:.1f} s\n")
    print(format_table({"simulator, seed 0": stats[0],
                        f"simulator, mean of {populations}": pooled(stats)}))
    print("\nsimulator / real (mean of the populations; goal 0.75-1.25):")
    for name, r in ratios_to_real(pooled(stats)).items():
        cells = "  ".join(f"{k} x{v:.2f}{'' if 0.75 <= v <= 1.25 else ' (!)'}"
                          for k, v in r.items())
        print(f"  {name:16s} {cells}")


def forest_by_difficulty() -> None:
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
    print("\n" + format_table(columns))
    print("\nrf (full) LOPO, 10 participants x 9 gestures x 4 trials, per-trial accuracy:")
    for name, n, acc, made, took in accs:
        print(f"  {name:12s} {n} trials  accuracy {acc:.3f}  "
              f"(simulate+decode {made:.1f} s, rf LOPO {took:.1f} s)")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--populations", type=int, default=8)
    p.add_argument("--no-rf", action="store_true", help="the table only")
    args = p.parse_args(argv)
    simulator_table(args.populations)
    if not args.no_rf:
        forest_by_difficulty()


if __name__ == "__main__":
    main()
