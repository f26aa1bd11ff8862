"""Do the learned models beat the 2 s-window random forest on unseen people?

Data: 10 virtual participants x 9 gestures x 4 repetitions of 2 s at the simulator's
default difficulty (``real``, calibrated to the real recordings). Protocol: LOPO, every
(model, round, fold) a task of one sweep on local worker processes (``--jobs``, one torch
thread each). Per model: per-trial accuracy and macro F1 pooled over the folds (median
over ``--rounds``, each round its own seed), the training time summed over folds and
rounds (the cost on one core), the sweep's wall time, the parameters of the model (3
channels, 6x6, 9 gestures) and its inference time per 2 s trial (batch of 64, one thread,
including the mirror averaging of the full recipe). With rf among the models (first),
every learned model is also compared with it trial by trial on the same test trials of
every round (learn/results/compare.py: the accuracy difference, Wilcoxon signed-rank over the
participants, McNemar over the trials): one accuracy has a standard error of ~2.5 points,
the paired test says whether a difference is more than that.

Run: .venv/bin/python benchmarks/bench_generalise.py [--jobs N] [--rounds R]
       [--models rf cnn1d ...] [--preset full|tiny] [--epochs N] [--options]
       [--set KEY=VALUE ...] [--repeats N --blocks B] [--keep DIR] [--fuse W ...]
       [--participants N] [--adapt [person|person-condition]] [--surfaces FLAT PILLOW]
       [--difficulty easy|real|people|hard] [--augment SPEC [--augment-copies N]]
       [--extra-gestures NAME ...] [--first-person K]
(--rounds R: each model's median over R rounds, every round listed;
--options: the generalisation options of docs/learning/learners.md on top: augment all x2,
participant norm, balance, validation by participant; --set: model options for the
learned models, e.g. --set members=1 to measure one network instead of the preset's
ensemble; --repeats 6 --blocks 2: each trial 6 back-to-back performances, 12 s cut into
2 s windows whose mean probability is the trial's answer, like the real recordings;
--fuse 0.3 0.5: each learned model also fused with rf at those rf weights, as
--set rf_weight=W trains it, scored from the two runs' test predictions and paired against
rf; --keep DIR: keep the data and run folders there; --participants N: N virtual people
instead of 10, the first 10 the same as the default's; --adapt: every model trained and
tested with --adapt person (or the mode named), paired against rf adapted the same way;
--surfaces FLAT PILLOW: each participant records --blocks blocks on each surface, a session
per surface, as in the real recordings; --difficulty hard: the simulator's hardest
population, where the plain rf scores about what it scores on real people; --augment
scale,shift: the learned models train on augmented windows, rf on the windows as recorded;
--extra-gestures tap slap scratch squeeze press: 14 gestures as in the real recordings, the
5 extra performed as the virtual participant performs cost14's, each a kin of one of the
9 at its own intensity and speed, so harder to tell from it than a new movement would be;
--first-person 11: the simulator's people 11-20 (named P01-P10), a second population to
replicate a finding on people the first never saw.)
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

from learn_fixtures import make_dataset_folder  # noqa: E402

from tactile_studio.learn.experiments.executors import LocalExecutor  # noqa: E402
from tactile_studio.learn.experiments.experiment import ExperimentConfig  # noqa: E402
from tactile_studio.learn.experiments.sweep import run_sweep  # noqa: E402
from tactile_studio.learn.learners.baselines import BASELINES  # noqa: E402
from tactile_studio.learn.learners.contract import PRESETS  # noqa: E402
from tactile_studio.learn.learners.fused import fuse  # noqa: E402
from tactile_studio.learn.results.compare import compare_predictions, compare_runs  # noqa: E402
from tactile_studio.learn.results.trialpreds import (  # noqa: E402
    RunPredictions,
    load_predictions,
)
from tactile_studio.simulate import GESTURE_NAMES  # noqa: E402
from tactile_studio.simulate.population import DIFFICULTIES  # noqa: E402

MODELS = ["rf", "cnn1d", "cnn3d", "sefusion", "mts3d", "cnn_transformer"]
OPTIONS = {"augment": "all", "augment_copies": 2, "participant_norm": True, "balance": True,
           "val_by": "participant"}


def model_cost(name: str, preset: str, sets: dict[str, str],
               classes: int = 9) -> tuple[int, float]:
    """(parameters, ms per trial) of ``name`` for 3 channels on 6x6 and ``classes`` gestures."""
    import torch

    from tactile_studio.learn.models import MODELS as REGISTRY
    from tactile_studio.learn.models._common import count_parameters

    spec = REGISTRY[name]
    view = spec.view(preset)
    frames = int(sets.get("view_frames", view.frames))
    stride = int(sets.get("view_stride", view.stride or frames))
    model = spec.build(classes, 3, (6, 6), preset, **sets).eval()
    # a 2 s trial of 86 frames gives one sample, or several windows for a windowed view
    per_trial = 1 if view.kind != "windows" else 1 + max(0, (86 - frames) // stride)
    x = torch.randn(64 * per_trial, 3, frames, 6, 6)
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with torch.inference_mode():
            model(x[:8])
            t0 = time.perf_counter()
            model(x)
            ms = (time.perf_counter() - t0) * 1000 / 64
    finally:
        torch.set_num_threads(previous)
    return count_parameters(model), ms


def fused_trials(rf: RunPredictions, net: RunPredictions, w: float) -> RunPredictions:
    """``net``'s test trials with learn/learners/fused.py's probabilities, (1 - w) * net + w * rf:
    what ``--set rf_weight=w`` predicts, since the fused model trains the same network and
    forest with the same seeds (tests/test_fused.py). Per trial: mean window probabilities."""
    by_trial = {(t.round, t.uid): t for t in rf.trials}
    trials = []
    for t in net.trials:
        p = fuse(t.probs, by_trial[(t.round, t.uid)].probs, w)
        trials.append(replace(t, probs=p, pred=int(p.argmax())))
    overrides = {**(net.config.get("overrides") or {}), "rf_weight": w}
    return replace(net, trials=trials, config={**net.config, "overrides": overrides})


def print_fused(rf_run: str, net_run: str, w: float) -> None:
    rf, net = load_predictions(rf_run), load_predictions(net_run)
    fused = fused_trials(rf, net, w)
    rounds = sorted({t.round for t in fused.trials})
    accs = [float(np.mean([t.correct for t in fused.trials if t.round == r])) for r in rounds]
    name = f"+ rf w={w:g}"
    print(f"{name:>16s}{float(np.median(accs)):>11.3f}   rounds: "
          + ", ".join(f"{a:.3f}" for a in accs), flush=True)
    print(f"{'':>16s}vs rf: {compare_predictions(rf, fused)['sentence']}", flush=True)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--models", nargs="+", default=MODELS)
    ap.add_argument("--preset", default=PRESETS[0], choices=PRESETS)
    ap.add_argument("--epochs", type=int, default=None)
    ap.add_argument("--options", action="store_true")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE")
    ap.add_argument("--repeats", type=int, default=1,
                    help="each trial N back-to-back 2 s performances, cut into 2 s windows "
                         "(6 and --blocks 2: like the real recordings' ~12 s performances)")
    ap.add_argument("--blocks", type=int, default=4)
    ap.add_argument("--first-person", type=int, default=1, metavar="K",
                    help="the population starts at the simulator's K-th person (11: people "
                         "11-20, a second population independent of the default's)")
    ap.add_argument("--participants", type=int, default=10,
                    help="virtual participants (LOPO folds); more people: do the networks "
                         "gain on rf?")
    ap.add_argument("--fuse", nargs="*", type=float, default=[], metavar="W",
                    help="also score each learned model fused with rf at these rf weights "
                         "(as --set rf_weight=W trains it), paired against rf")
    ap.add_argument("--adapt", nargs="?", const="person", default=None,
                    choices=("person", "person-condition"),
                    help="--adapt person: each test person met with their own statistics "
                         "(networks: batch norm; rf/knn: standardised features); "
                         "person-condition: per person and surface")
    ap.add_argument("--surfaces", nargs="*", default=[], metavar="SURFACE",
                    help="a session per participant and surface (FLAT, PILLOW)")
    ap.add_argument("--augment", default="", metavar="SPEC",
                    help="augment the training windows of the learned models (e.g. scale,shift "
                         "or all; --augment-copies N), as train --augment does; rf and knn "
                         "train on the windows as recorded")
    ap.add_argument("--augment-copies", type=int, default=1)
    ap.add_argument("--extra-gestures", nargs="*", default=[], metavar="NAME",
                    help="protocol gestures besides the 9 (e.g. cost14's tap slap scratch "
                         "squeeze press), performed as a virtual participant performs them: "
                         "a kin model at its own intensity and speed")
    ap.add_argument("--difficulty", default="real", choices=DIFFICULTIES,
                    help="the simulator's population (hard: rf near real people's 51%%)")
    ap.add_argument("--keep", metavar="DIR", default=None,
                    help="write the data and every run folder here (kept, for "
                         "tactile-studio compare / trials) instead of a temporary folder")
    args = ap.parse_args(argv if argv is not None else [])
    options = dict(OPTIONS) if args.options else {}
    if args.adapt:
        options["adapt"] = args.adapt
    if args.augment:
        options.update(augment=args.augment, augment_copies=args.augment_copies)
    sets = dict(item.split("=", 1) for item in args.set)
    with tempfile.TemporaryDirectory() as scratch:
        tmp = args.keep or scratch
        data = Path(tmp) / "data"
        gestures = (*GESTURE_NAMES, *args.extra_gestures)
        make_dataset_folder(data, participants=args.participants, blocks=args.blocks,
                            gestures=gestures,
                            difficulty=args.difficulty, repeats=args.repeats,
                            conditions=tuple(s.upper() for s in args.surfaces),
                            first_style=100 + args.first_person)
        what = f"{args.blocks} trials" if args.repeats == 1 else \
            f"{args.blocks} performances of {2 * args.repeats} s (2 s windows, 50% overlap)"
        if args.surfaces:
            what += f" on each of {', '.join(s.upper() for s in args.surfaces)}"
        print(f"LOPO, {args.participants} participants x {len(gestures)} gestures "
              f"(chance {100 / len(gestures):.1f}%) x {what}, difficulty "
              f"{args.difficulty}, preset {args.preset}, {args.rounds} round(s), "
              f"{args.jobs} workers"
              + (", options: augment all x2 + participant norm + balance + val by "
                 "participant" if args.options else "")
              + (f", --adapt {args.adapt}" if args.adapt else "")
              + (f", --augment {args.augment} x{args.augment_copies} (learned models)"
                 if args.augment else "")
              + (f", --set {' '.join(args.set)}" if sets else ""))
        print(f"{'model':>16s}{'trial acc':>11s}{'trial f1':>9s}{'train s':>9s}{'wall s':>8s}"
              f"{'params':>9s}{'ms/trial':>10s}")
        runs: dict[str, str | None] = {}
        for model in args.models:
            baseline = model in BASELINES
            own = dict(options)
            if baseline and (args.augment or args.adapt):
                # the forest the learned models are measured against trains on the windows
                # as recorded (and --adapt's per-person features refuse augmented windows)
                own.pop("augment", None)
                own.pop("augment_copies", None)
            base = ExperimentConfig(data=[str(data)], model=model, evaluation="lopo",
                                    preset=args.preset, rounds=args.rounds,
                                    epochs=None if baseline else args.epochs,
                                    overrides={} if baseline else sets,
                                    cache_dir=str(Path(tmp) / "cache"), **own)
            t0 = time.perf_counter()
            with LocalExecutor(args.jobs) as ex:
                res = run_sweep(base, [model], [None], ex, out=Path(tmp) / "sweeps" / model)
            wall = time.perf_counter() - t0
            params, ms = ("-", float("nan")) if baseline else \
                model_cost(model, args.preset, sets, len(gestures))
            for row in res.rows:
                print(f"{row['model']:>16s}{row['trial_accuracy']:>11.3f}"
                      f"{row['trial_f1_macro']:>9.3f}{row['train_seconds']:>9.1f}{wall:>8.1f}"
                      f"{params:>9}{ms:>10.2f}", flush=True)
            if args.rounds > 1:  # the median above; every round's trial accuracy here
                rounds = next(iter(res.metrics.values())).get("rounds", [])
                print(f"{'':>16s}rounds: " + ", ".join(
                    f"{r.get('trial_accuracy', float('nan')):.3f}" for r in rounds), flush=True)
            runs[model] = res.rows[0].get("run")
            if model != "rf" and runs.get("rf") and runs[model]:
                # paired, on the same test trials of every round: how we know
                print(f"{'':>16s}vs rf: {compare_runs(runs['rf'], runs[model])['sentence']}",
                      flush=True)
                for w in args.fuse:
                    print_fused(runs["rf"], runs[model], w)


if __name__ == "__main__":
    main(sys.argv[1:])
