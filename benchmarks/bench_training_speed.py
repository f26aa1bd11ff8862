"""How long does a network's full-preset LOPO round take on the benchmark-shaped set?

Data: the set ``bench_generalise.py --extra-gestures tap slap scratch squeeze press
--surfaces FLAT PILLOW --repeats 6 --blocks 1`` trains on (10 virtual people, 14
gestures, one 12 s performance per gesture and surface, cut into 2 s windows). Per
model, ONE fold of a LOPO round (the first held-out person) trains with one torch thread
and the full preset, timed by the process's CPU time (``time.process_time``): on a
shared, loaded machine wall time says more about the neighbours than about the model.
Printed per model: the fold's CPU and wall seconds, the epochs it ran, the training
cost per window per epoch (ms, forward + backward + the validation pass of every
epoch, CPU), inference per window (ms, batch of 64, one thread, eval mode with the
mirror averaging of the full recipe), the fold's accuracy per performance, and the
estimated wall time of a whole round (folds x fold CPU / workers, default 2 workers of
one thread each on the 2-core machine: what a quiet machine takes, plus start-up).
The goal (issue 37): <= 5 min per round for every network.

The last column is the wall time of a round: MEASURED (a whole LOPO round run as a sweep
on ``--workers`` local worker processes of one thread, timed from start to the last
fold) when the machine is quiet enough (1-minute load average under ``--quiet-load``,
default 0.5, or always with ``--measure``; never with ``--no-measure``), else the
ESTIMATE above; the "round" column says which.

Run: .venv/bin/python benchmarks/bench_training_speed.py [--models cnn1d cnn3d ...]
       [--data DIR] [--workers 2] [--keep DIR] [--measure | --no-measure]
(--data: a folder of the set's sessions, made there when it holds none; default a
temporary folder; --keep DIR: make the data there and keep it.)
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from learn_fixtures import make_dataset_folder  # noqa: E402

import tactile_studio.learn.experiments.experiment as experiment  # noqa: E402
from tactile_studio.learn.data.dataset import read_sessions  # noqa: E402
from tactile_studio.learn.learners.contract import DataInfo  # noqa: E402
from tactile_studio.learn.models import MODELS  # noqa: E402
from tactile_studio.simulate import GESTURE_NAMES  # noqa: E402

NETWORKS = ["cnn1d", "cnn3d", "sefusion", "cnn_transformer", "mts3d"]
EXTRA = ("tap", "slap", "scratch", "squeeze", "press")


def make_data(folder: Path) -> Path:
    """The benchmark-shaped set in ``folder`` (kept when it is already there)."""
    if not any(folder.glob("*.h5")):
        folder.mkdir(parents=True, exist_ok=True)
        make_dataset_folder(folder, participants=10, blocks=1, gestures=(*GESTURE_NAMES, *EXTRA),
                            difficulty="real", repeats=6, conditions=("FLAT", "PILLOW"),
                            first_style=101)
    return folder


def one_fold(model: str, data: Path, ds) -> dict[str, float]:
    """Train and test the first LOPO fold of round 1; CPU and wall seconds and more."""
    cfg = experiment.ExperimentConfig(data=[str(data)], model=model, evaluation="lopo",
                                      threads=1, adapt="auto")
    whole = experiment.folds_for
    folds = whole(cfg, ds, 0)
    experiment.folds_for = lambda c, d, r: whole(c, d, r)[:1]  # one fold of the round
    try:
        c0, t0 = time.process_time(), time.perf_counter()
        res = experiment.run_experiment(cfg, dataset=ds)
        cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    finally:
        experiment.folds_for = whole
    fold = res.folds[0]
    epochs = len(fold["history"])
    owners = fold["predictions"]["owner"]  # one entry per test window
    windows = round(len(fold["train"]) * len(owners) / max(1, len(set(owners))))
    return {"folds": len(folds), "cpu": cpu, "wall": wall, "epochs": epochs,
            "train_ms": 1000 * cpu / max(1, windows * epochs), "windows": windows,
            "acc": float(res.metrics["trial_accuracy"])}


def inference_ms(model: str, ds, batch: int = 64, repeat: int = 5) -> float:
    """CPU ms per window of the full preset's eval forward (one thread, weights as built)."""
    import torch

    from tactile_studio.learn.learners.train import predict_proba

    info = DataInfo.of(ds)
    net = MODELS[model].build(info.n_classes, info.in_channels, info.grid, "full")
    shape = net.input_shape
    x = np.random.default_rng(0).normal(size=(batch, *shape)).astype(np.float32)
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        predict_proba(net, x)  # warm up
        c0 = time.process_time()
        for _ in range(repeat):
            predict_proba(net, x)
        return 1000 * (time.process_time() - c0) / (repeat * batch)
    finally:
        torch.set_num_threads(previous)


def measured_round_min(model: str, data: Path, workers: int) -> float:
    """Wall minutes of one whole LOPO round of ``model`` as a sweep on ``workers`` local
    processes of one torch thread each (what `tactile-studio sweep --jobs N` does)."""
    from tactile_studio.learn.experiments.executors import make_executor
    from tactile_studio.learn.experiments.sweep import run_sweep

    cfg = experiment.ExperimentConfig(data=[str(data)], model=model, evaluation="lopo",
                                      threads=1, adapt="auto")
    t0 = time.perf_counter()
    with make_executor("local", jobs=workers) as ex:
        result = run_sweep(cfg, [model], [None], ex)
    if not result.complete:
        raise RuntimeError(f"{model}: the round did not complete")
    return (time.perf_counter() - t0) / 60


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--models", nargs="+", default=NETWORKS)
    ap.add_argument("--data", type=Path, default=None)
    ap.add_argument("--keep", type=Path, default=None)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quiet-load", type=float, default=0.5,
                    help="measure a whole round when the 1-min load average is below this")
    how = ap.add_mutually_exclusive_group()
    how.add_argument("--measure", action="store_true", help="always measure a whole round")
    how.add_argument("--no-measure", action="store_true", help="never (the CPU estimate)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        data = make_data(args.data or args.keep or Path(tmp) / "data")
        ds = read_sessions([str(data)]).select(None)
        print(f"data: {data} ({len(ds.uids)} performances, {ds.n_classes} gestures)")
        print(f"{'model':16s} {'fold cpu s':>10s} {'wall s':>7s} {'epochs':>6s} "
              f"{'train ms/win':>12s} {'infer ms/win':>12s} {'acc':>5s} "
              f"{'round est. min':>14s} {'round min':>18s}")
        for model in args.models:
            r = one_fold(model, data, ds)
            infer = inference_ms(model, ds)
            estimate = r["folds"] * r["cpu"] / max(1, args.workers) / 60
            load = os.getloadavg()[0]
            if args.measure or (not args.no_measure and load < args.quiet_load):
                # two decimals: near the goal a rounded 5.0 could be 5.04
                wall = f"{measured_round_min(model, data, args.workers):.2f} MEASURED"
            else:
                wall = f"{estimate:.2f} ESTIMATE"
            print(f"{model:16s} {r['cpu']:10.1f} {r['wall']:7.1f} {r['epochs']:6d} "
                  f"{r['train_ms']:12.3f} {infer:12.3f} {r['acc']:5.2f} {estimate:14.2f} "
                  f"{wall:>18s}  (load {load:.1f})", flush=True)
        print(f"(round est.: {r['folds']} folds x fold CPU / {args.workers} workers of one "
              "thread, on a quiet machine; round min: a whole round measured as a sweep "
              f"on {args.workers} workers when the load was under {args.quiet_load}, else "
              "the estimate; goal <= 5 min)")


if __name__ == "__main__":
    main()
