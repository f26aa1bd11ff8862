"""The simulator's people beside the real recordings (issue 37's table), and what the
difficulties do to a random forest leave-one-participant-out.

Part 1, the table: populations of 10 virtual people as ``collect --virtual-participant
--seed S --set seed=S`` draws them (the default difficulty, ``people`` since issue 45;
``--difficulty real`` for issue 37's table; shear9, 2 blocks, flat surface),
decoded with the project's ``decode`` on the physical grid; the statistics of
``tactile_studio.learn.data.touch_stats`` (median [IQR] over trials, CV of the participants'
medians) for population seed 0 alone and pooled over ``--populations`` seeds (the mean,
with the lowest and highest CV: ten people are a small sample), then each pooled figure
divided by the real one (issue 37 asks 0.75-1.25).

Part 2, rf (full preset) LOPO per difficulty: 10 people x 9 gestures x 4 repetitions.

Part 3 (issue 45 item 5), the variance split: each touch statistic's variance split into
person / gesture / person x gesture / within (learn/data/variance_parts.py) for the
real development set (five people, 2 s windows of their 12 s performances, as the
product cuts them; benchmarks/real_data.py, skipped with one line where it is absent)
beside ``--variance-populations`` simulated populations of 10 x shear9 x 4 blocks
(``--variance-difficulties``, real and people by default; flat), as shares and as
standard deviations of each part.
Run: .venv/bin/python -m benchmarks.bench_population [--populations 8] [--no-rf]
     [--difficulty D] [--variance-only] [--variance-populations 3]
(``python -m benchmarks population`` runs it with these defaults: it passes no options)
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from learn_fixtures import make_dataset_folder, make_virtual_population  # noqa: E402

from tactile_studio.learn.data import variance_parts as vp  # noqa: E402
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
from tactile_studio.simulate.population import DEFAULT_DIFFICULTY, DIFFICULTIES  # noqa: E402

COHORTS = (("easy", "FLAT"), ("real", "FLAT"), ("real", "PILLOW"), ("people", "FLAT"),
           ("hard", "FLAT"))


def simulator_table(populations: int, difficulty: str) -> None:
    stats = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(populations):
            folder = Path(tmp) / f"pop{seed}"
            make_virtual_population(folder, seed, difficulty=difficulty)
            ds = read_sessions([folder]).select(None)
            stats.append(population_stats(ds.trials, ds.participants, ds.channel_names))
    print(f"Simulated people (difficulty {difficulty}, shear9, 2 blocks, flat) beside the real "
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
            cfg = ExperimentConfig(data=[str(folder)], model="rf", evaluation="lopo")
            m = run_experiment(cfg, dataset=ds).metrics
            took = time.perf_counter() - t0
            # per-person standardisation: on real people it cost rf (issue 37: -1.7 points);
            # a population whose differences are real ones should not reward it
            adapted = run_experiment(replace(cfg, adapt="person"), dataset=ds).metrics
            accs.append((name, len(ds), m["trial_accuracy"], adapted["trial_accuracy"], made,
                         took))
    print("\n" + format_table(columns))
    print("\nrf (full) LOPO, 10 participants x 9 gestures x 4 trials, per-trial accuracy "
          "(as trained; --adapt person):")
    for name, n, acc, adapted, made, took in accs:
        print(f"  {name:12s} {n} trials  accuracy {acc:.3f}; adapted {adapted:.3f} "
              f"({100 * (adapted - acc):+.1f})  (simulate+decode {made:.1f} s, rf LOPO "
              f"{took:.1f} s)")


def _rows(ds, windows: bool) -> tuple[list[dict[str, float]], list, list]:
    from tactile_studio.learn.data.windowing import WindowSpec, cut

    if windows:
        ds, _ = cut(ds, WindowSpec(2.0, 0.5))
    names = list(ds.channel_names)
    rows = [vp.stats_of(x, names, float(r)) for x, r in zip(ds.trials, ds.rates)]
    return rows, list(ds.participants), list(ds.labels)


def real_parts() -> dict[str, dict[str, float]] | None:
    """The development set's parts (2 s windows), or None (one line said) without it."""
    from benchmarks.real_data import dev_sessions, dev_set, skip_reason

    if dev_set() is None:
        print(f"real development set: skipped: {skip_reason()}")
        return None
    return vp.parts_table(*_rows(read_sessions([dev_sessions()]).select(None), True))


def simulated_parts(populations: int, **kw: object) -> dict[str, dict[str, float]]:
    """The mean parts of ``populations`` simulated populations (10 x shear9 x 4 blocks)."""
    tables = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(populations):
            folder = Path(tmp) / f"pop{seed}"
            make_virtual_population(folder, seed, blocks=4, **kw)
            tables.append(vp.parts_table(*_rows(read_sessions([folder]).select(None), False)))
    return vp.mean_parts(tables)


def _fmt_shares(parts: dict[str, float] | None) -> str:
    if parts is None:
        return "-"
    return " / ".join(f"{100 * v:3.0f}" for v in vp.shares(parts).values())


def _fmt_sds(parts: dict[str, float] | None) -> str:
    if parts is None:
        return "-"
    return " / ".join(f"{np.sqrt(parts[p]):.2f}" for p in vp.PARTS)


def variance_split(populations: int, difficulties: list[str]) -> None:
    t0 = time.perf_counter()
    columns = {"real people": real_parts()}
    for level in difficulties:
        columns[f"sim {level}"] = simulated_parts(populations, difficulty=level)
    print(f"\nVariance split of the touch statistics (issue 45): person / gesture / "
          f"person x gesture / within; real = the development set's 2 s windows, sim = "
          f"mean of {populations} simulated populations (10 people, shear9, 4 blocks, "
          f"flat); {time.perf_counter() - t0:.0f} s")
    print("shares, %:")
    print(f"  {'statistic':22s}" + "".join(f"{name:>24s}" for name in columns))
    for k in vp.STATS:
        unit = " (log)" if k in vp.LOG_OFFSET else ""
        print(f"  {k + unit:22s}" + "".join(
            f"{_fmt_shares(c and c[k]):>24s}" for c in columns.values()))
    print("standard deviation of each part (log units where marked; s; Hz):")
    for k in vp.STATS:
        print(f"  {k:22s}" + "".join(f"{_fmt_sds(c and c[k]):>28s}" for c in columns.values()))


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--populations", type=int, default=8)
    p.add_argument("--no-rf", action="store_true", help="the table only")
    p.add_argument("--difficulty", default=DEFAULT_DIFFICULTY, choices=DIFFICULTIES,
                   help="the table's virtual people (default: the simulator's)")
    p.add_argument("--variance-only", action="store_true", help="part 3 only")
    p.add_argument("--variance-populations", type=int, default=3)
    p.add_argument("--variance-difficulties", default="real,people",
                   help="simulated difficulties beside the real people (comma-separated)")
    args = p.parse_args(argv)
    if not args.variance_only:
        simulator_table(args.populations, args.difficulty)
        if not args.no_rf:
            forest_by_difficulty()
    variance_split(args.variance_populations, args.variance_difficulties.split(","))


if __name__ == "__main__":
    main(sys.argv[1:])
