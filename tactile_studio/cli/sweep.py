"""``tactile-studio sweep``: models x channel sets x rounds x folds on local worker
processes or a Ray cluster, with a results table."""

from __future__ import annotations

import argparse
from pathlib import Path

from tactile_studio.cli.argtypes import finite_float
from tactile_studio.cli.learn import (
    PRESET_HELP,
    PRESETS,
    _add_data_options,
    _Bar,
    add_generalisation_options,
    generalisation_kwargs,
)
from tactile_studio.devices.registry import parse_set_options
from tactile_studio.jobs import CancelToken, ctrl_c_cancels
from tactile_studio.learn.choices import AGGREGATES, CHANNEL_SETS, EVALUATIONS, EXECUTORS


def cmd_sweep(args: argparse.Namespace) -> int:
    from tactile_studio.learn.experiments.executors import make_executor
    from tactile_studio.learn.experiments.experiment import ExperimentConfig
    from tactile_studio.learn.experiments.sweep import format_rows, run_sweep

    base = ExperimentConfig(
        data=list(args.data), model=args.models[0], grid=args.grid, evaluation=args.evaluation,
        rounds=args.rounds, preset=args.preset, epochs=args.epochs,
        overrides=parse_set_options(args.sets), seed=args.seed, folds=args.folds,
        device=args.device, cache_dir=args.cache_dir, use_cache=not args.no_cache,
        window_s=args.window_s, aggregate=args.aggregate, **generalisation_kwargs(args))
    channels = [None if c == "all" else c for c in args.channels]
    token = CancelToken()
    bar = _Bar(f"sweep ({args.executor})")
    try:
        with ctrl_c_cancels(token), make_executor(args.executor, args.jobs, args.address) as ex:
            result = run_sweep(base, args.models, channels, ex, args.out, bar, token)
    finally:
        bar.close()
    print(f"sweep · {args.evaluation} · {args.preset} · {args.rounds} round(s) · "
          f"executor {args.executor}")
    print(format_rows(result.rows))
    if args.out:
        print(f"results: {Path(args.out) / 'results.csv'}")
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "sweep", help="train models x channel sets x rounds x folds as parallel tasks",
        description="Every (model, channel set, round, fold) is an independent task, run "
                    "on local worker processes (--jobs) or a Ray cluster (--executor ray). "
                    "Finished tasks are kept in OUT; Ctrl-C stops and writes the table of "
                    "what finished; the same command resumes.")
    _add_data_options(p)
    p.add_argument("--models", nargs="+", required=True, metavar="NAME")
    p.add_argument("--channels", nargs="+", default=["all"],
                   choices=(*CHANNEL_SETS, "all"),
                   help="channel sets (default all: every channel the data has)")
    p.add_argument("--eval", dest="evaluation", choices=EVALUATIONS, default=EVALUATIONS[0])
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--preset", choices=PRESETS, default=PRESETS[0], help=PRESET_HELP)
    p.add_argument("--epochs", type=int, default=None)
    p.add_argument("--set", dest="sets", nargs="+", action="extend", metavar="KEY=VALUE",
                   help="options applied to every model")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--folds", type=int, default=10, help="k for group-kfold")
    p.add_argument("--device", default="cpu", help="cpu or cuda (cuda tasks ask Ray for a GPU)")
    p.add_argument("--window", dest="window_s", type=finite_float, default=None, metavar="SECONDS")
    p.add_argument("--aggregate", choices=AGGREGATES, default=AGGREGATES[0])
    add_generalisation_options(p)
    p.add_argument("--out", default=None, metavar="DIR", help="results and finished tasks")
    p.add_argument("--executor", choices=EXECUTORS, default=EXECUTORS[0])
    p.add_argument("--jobs", type=int, default=None,
                   help="worker processes / local Ray CPUs (default: the number of cores)")
    p.add_argument("--address", default=None, metavar="HOST:PORT",
                   help="a running Ray cluster (default: start a local one)")
    p.set_defaults(func=cmd_sweep)
