"""``tactile-studio train | evaluate | ablate | export-model``: the learning pipeline's CLI."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from tactile_studio.cli import tables
from tactile_studio.cli.argtypes import finite_float
from tactile_studio.devices.registry import parse_set_options
from tactile_studio.jobs import CancelToken, TerminalProgress, ctrl_c_cancels
from tactile_studio.learn.choices import (
    AGGREGATES,
    BASELINES,
    CHANNEL_SETS,
    EVALUATIONS,
    EXPORT_FORMATS,
    GRIDS,
    SHOTS_BY,
)
from tactile_studio.learn.learners.baselines import DEFAULT_MODEL
from tactile_studio.learn.learners.contract import PRESETS
from tactile_studio.learn.learners.generalise import (
    ADAPT,
    ADAPT_AUTO,
    ADAPT_CHOICES,
    ADAPT_PHRASE,
    VAL_BY,
)

PRESET_HELP = ("full (default): each model's recipe for unseen people; tiny: the "
               "CPU-test size, under rf on hard virtual people (docs/learning/figures.md)")


def _Bar(label: str) -> TerminalProgress:  # noqa: N802 - used like the class it was
    """Progress on stderr; ``close()`` ends it when the job stops early (error, Ctrl-C),
    so the one-line message that follows starts on a line of its own."""
    return TerminalProgress(label, stream=sys.stderr)


def _fold_rows(bar: TerminalProgress):  # noqa: ANN202
    """A run_experiment listener showing the current round's folds and the current
    fold's epochs as rows nested under the run's bar (in a terminal)."""
    from tactile_studio.learn.experiments.job_events import Epoch, Fold

    def listener(event: Any) -> None:
        where = f"round {event.round + 1}"
        if isinstance(event, Epoch):
            bar.subtask("fold", f"fold {event.fold + 1}/{event.n_folds} {event.fold_name}",
                        event.epoch, None, f"epoch {event.epoch}")
        elif isinstance(event, Fold):
            bar.end_subtask("fold")
            bar.subtask("round", where, event.fold + 1, event.n_folds,
                        f"fold {event.fold_name} accuracy {_fmt(event.accuracy)}")
    return listener


def _add_data_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", nargs="+", required=True, metavar="PATH",
                   help="folder(s) searched recursively for *.h5 sessions, or session files")
    p.add_argument("--grid", choices=GRIDS, default=GRIDS[0],
                   help="physical taxels or the virtual (2R-1)x(2C-1) grid")
    p.add_argument("--cache-dir", default=None,
                   help="dataset cache (default: $TACTILE_STUDIO_CACHE_DIR, else the "
                        "platform's user cache folder)")
    p.add_argument("--no-cache", action="store_true", help="decode the sessions again")


def _add_train_options(p: argparse.ArgumentParser) -> None:
    _add_data_options(p)
    p.add_argument("--model", default=DEFAULT_MODEL, metavar="NAME",
                   help=f"{DEFAULT_MODEL} (default: extra-trees on touch and shear features, "
                        "adapted per person and surface), "
                        + ", ".join(n for n in BASELINES if n != DEFAULT_MODEL)
                        + ", a network of docs/models.md (cnn1d, cnn3d...) or a model a "
                          "package registers")
    p.add_argument("--eval", dest="evaluation", choices=EVALUATIONS, default=EVALUATIONS[0],
                   help=f"how people are held out for testing (default {EVALUATIONS[0]})")
    p.add_argument("--shots", type=_shot_counts, default=(), metavar="K[,K...]",
                   help="few-shot personalisation under lopo/group-kfold: each held-out "
                        "person once per K, with K labelled performances per gesture of "
                        "theirs in the training and the rest tested (e.g. 0,1,2: the curve "
                        "over K in metrics.json; windows of a performance never split)")
    p.add_argument("--shots-by", dest="shots_by", choices=SHOTS_BY,
                   default="auto",
                   help="how the shots reach the model: join (they join the training, one "
                        "training per K) or fine-tune (networks only: the fold is trained "
                        "once without them and its output layers fine-tuned on each K's "
                        "shots, as live calibration does); default auto: fine-tune for a "
                        "network (as good on the simulator, half the time), join for rf, "
                        "knn and a network fused with rf")
    p.add_argument("--rounds", type=int, default=1, help="repeat with new seeds; medians reported")
    p.add_argument("--epochs", type=int, default=None, help="maximum epochs (default: the model's)")
    p.add_argument("--preset", choices=PRESETS, default=PRESETS[0], help=PRESET_HELP)
    p.add_argument("--set", dest="sets", nargs="+", action="extend", metavar="KEY=VALUE",
                   help="training options (lr, batch_size, patience, optimizer, weight_decay, "
                        "momentum) and model options")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--folds", type=int, default=10, help="k for group-kfold")
    p.add_argument("--device", default="auto", help="auto, cpu or cuda")
    p.add_argument("--threads", type=int, default=None,
                   help="CPU threads of the training (torch, OpenMP; default 1: more "
                        "threads spin-wait on a busy machine, docs/learning/training-time.md)")
    p.add_argument("--window", dest="window_s", type=finite_float, default=None, metavar="SECONDS",
                   help="trials longer than 1.5 windows are cut into windows this long "
                        "(default: the protocol's trial length, else 2 s)")
    p.add_argument("--overlap", dest="window_overlap", type=finite_float, default=0.5,
                   help="share of a window overlapping the next (default 0.5)")
    p.add_argument("--aggregate", choices=AGGREGATES, default=AGGREGATES[0],
                   help="trial prediction from its windows: mean probability or majority vote")
    add_generalisation_options(p)


def _shot_counts(text: str) -> tuple[int, ...]:
    """``--shots``: the train panel's parser (learn.data.splits.parse_shot_counts), as a usage
    error; on the command line the option names at least one count."""
    from tactile_studio.errors import UserError
    from tactile_studio.learn.data.splits import parse_shot_counts

    try:
        ks = parse_shot_counts(text)
    except UserError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if not ks:
        raise argparse.ArgumentTypeError("give counts such as 0,1,2")
    return ks


def add_generalisation_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--augment", default="", metavar="KINDS",
                   help="augment training windows: flip,rotate,shift,warp,scale or all")
    p.add_argument("--augment-copies", type=int, default=1, metavar="N",
                   help="augmented copies of every training window (default 1)")
    p.add_argument("--participant-norm", action="store_true",
                   help="scale each participant's normal and shear to a typical person")
    p.add_argument("--balance", action="store_true", help="repeat rarer classes when training")
    p.add_argument("--val-by", choices=VAL_BY, default=VAL_BY[0],
                   help="early stopping on training trials or on whole training participants")
    p.add_argument("--adapt", choices=ADAPT_CHOICES, default=ADAPT_AUTO,
                   help="person: meet each test person on their own terms, from their own "
                        "unlabelled windows (networks re-estimate batch-norm statistics, "
                        "rf/knn standardise each person's features); person-condition: "
                        "the same per person and session condition (surface); none: as "
                        "trained; auto (default): person for a network under lopo or "
                        "group-kfold, none for rf and knn (adapting cost rf 1.7 points on "
                        "real people) and under all-inclusive")


def generalisation_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    return {"augment": args.augment, "augment_copies": args.augment_copies,
            "participant_norm": args.participant_norm, "balance": args.balance,
            "val_by": args.val_by, "adapt": args.adapt}


def _config(args: argparse.Namespace, channels: str | None):
    from tactile_studio.learn.experiments.experiment import ExperimentConfig

    return ExperimentConfig(
        data=list(args.data), model=args.model, channels=channels, grid=args.grid,
        evaluation=args.evaluation, rounds=args.rounds, preset=args.preset, epochs=args.epochs,
        overrides=parse_set_options(args.sets), seed=args.seed, folds=args.folds,
        device=args.device, threads=args.threads, cache_dir=args.cache_dir,
        use_cache=not args.no_cache, window_s=args.window_s, window_overlap=args.window_overlap,
        aggregate=args.aggregate, shots=tuple(getattr(args, "shots", ()) or ()),
        shots_by=getattr(args, "shots_by", "auto"),
        exclude_flagged=bool(getattr(args, "exclude_flagged", False)),
        **generalisation_kwargs(args))


def _fmt(v: Any) -> str:
    return "-" if v is None else f"{v:.3f}"


def _print_summary(m: dict[str, Any], out: Path | None = None) -> None:
    from tactile_studio.learn.evaluation.summary import trials_were_cut
    from tactile_studio.learn.learners.fused import OPTION, display_name

    name = display_name(m["model"], {OPTION: m["rf_weight"]} if "rf_weight" in m else {})
    print(f"{name} · {m['evaluation']} · channels {m['channels']} · "
          f"{len(m['per_fold'])} fold(s)"
          + (f" · {ADAPT_PHRASE[m['adapt']]}" if m.get("adapt", "none") != "none" else ""))
    rows = [(key, _fmt(m[key])) for key in (
        "accuracy", "trial_accuracy", "precision_macro", "recall_macro", "f1_macro",
        "balanced_accuracy", "kappa") if key in m]
    if m.get("heldout"):
        rows.append(("heldout_accuracy", _fmt(m["heldout"]["accuracy"])))
    rounds = len(m.get("rounds", []))
    value = f"median of {rounds} rounds" if rounds > 1 else "value"
    tables.table(("metric", value), rows, right=(value,))
    # a fold's figure per trial beside its figure per window when trials were cut
    cut = trials_were_cut(m)
    keys = ("trial_accuracy", "accuracy") if cut else ("accuracy",)
    heads = ("trial accuracy", "per window") if cut else ("accuracy",)
    # rounds numbered from 1, as the progress line's "round 1/1" (they are 0 in the files)
    tables.table(("round", "fold", "test participants", *heads),
                 [(int(f["round"]) + 1, f["name"], ",".join(f["test_participants"]),
                   *(_fmt(f.get(k)) for k in keys)) for f in m["per_fold"]],
                 right=("round", *heads))
    if m.get("shots"):
        print_shots(m, cut)
    if m.get("windows") is not None:
        print(f"  ({m.get('n_trials', '?')} test trials, {m['windows']} windows of "
              f"{m.get('window_s', 0):g} s over the data's trials; "
              f"trial = {m.get('aggregate', 'mean')} of its windows)")
    if out is not None:
        print(f"run folder: {out}")


def print_shots(m: dict[str, Any], cut: bool) -> None:
    """The few-shot curve of metrics ``m``: accuracy for K labelled performances per
    gesture of the test person in the training, or fine-tuning it (the same test trials
    at every K, fewer than a plain run's: said)."""
    from tactile_studio.learn.evaluation.summary import shots_test_set

    shots, by = m["shots"], m.get("shots_by", "join")
    base = shots[0]
    key = "trial_accuracy" if cut else "accuracy"
    gain = f"points vs K={base['k']}"
    heads = ("trial accuracy", "per window") if cut else ("accuracy",)
    rows = []
    for s in shots:
        figures = (_fmt(s.get("trial_accuracy")), _fmt(s.get("accuracy"))) if cut else \
            (_fmt(s.get("accuracy")),)
        diff = "" if s is base or s.get(key) is None or base.get(key) is None else \
            f"{100 * (s[key] - base[key]):+.1f}"
        rows.append((s["k"], *figures, diff))
    how = "the K = 0 model's output layers fine-tuned on them" if by == "fine-tune" else \
        "in the training"
    print("few-shot personalisation: K labelled performances per gesture of the test "
          f"person {how}, {shots_test_set(m)}")
    tables.table(("K", *heads, gain), rows, right=("K", *heads, gain))


def _print_skipped(skipped: list[dict[str, Any]]) -> None:
    """Say which session files the dataset left out (resume backups, duplicates)."""
    from tactile_studio.storage.format.session_set import describe_skipped

    if skipped:
        print(f"data: {describe_skipped(skipped)}")


def cmd_train(args: argparse.Namespace) -> int:
    from tactile_studio.learn.experiments.experiment import run_experiment

    token = CancelToken()
    bar = _Bar("train")
    try:
        with ctrl_c_cancels(token):
            result = run_experiment(_config(args, args.channels), args.out, bar, token,
                                    listener=_fold_rows(bar))
    finally:
        bar.close()
    _print_skipped(result.dataset.get("skipped", []))
    _print_summary(result.metrics, result.out)
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from tactile_studio.learn.results.rescore import rescore_run

    token = CancelToken()
    bar = _Bar("evaluate")
    try:
        with ctrl_c_cancels(token):
            m = rescore_run(args.run, args.data, args.cache_dir, bar, token, args.adapt)
    finally:
        bar.close()
    _print_skipped(m.get("dataset_skipped", []))
    print(f"re-scored from saved weights ({m['mode']} mode)")
    _print_summary(m)
    return 0


def cmd_ablate(args: argparse.Namespace) -> int:
    from tactile_studio.learn.experiments.experiment import run_experiment

    token = CancelToken()
    rows = []
    with ctrl_c_cancels(token):
        for channels in args.channel_sets:
            out = Path(args.out) / channels if args.out else None
            bar = _Bar(f"{channels:6s}")
            try:
                res = run_experiment(_config(args, channels), out, bar, token)
            finally:
                bar.close()
            rows.append((channels, res.metrics))
    if rows:
        _print_skipped(res.dataset.get("skipped", []))
    keys = ["accuracy", "f1_macro", "balanced_accuracy", "kappa"]
    if any("trial_accuracy" in m for _, m in rows):
        keys.insert(1, "trial_accuracy")
    print(f"ablation: {args.model} · {args.evaluation} · {args.preset}")
    print(f"{'channels':10s}" + "".join(f"{k:>19s}" for k in keys))
    for channels, m in rows:
        print(f"{channels:10s}" + "".join(f"{_fmt(m.get(k)):>19s}" for k in keys))
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from tactile_studio.learn.deploy.export_run import export_run

    token = CancelToken()
    bar = _Bar("export")
    try:
        with ctrl_c_cancels(token):
            report = export_run(args.run, args.format, args.data, args.cache_dir, bar, token,
                                threads=args.threads or 0, aggregate=args.aggregate)
    finally:
        bar.close()
    print(f"{args.format} export of {report['model']} ({len(report['folds'])} fold model(s))"
          + (f", {report['quant_format']} quantisation" if "quant_format" in report else ""))
    for f in report["folds"]:
        extra = f"  max |logit diff| {f['max_abs_diff']:.2e}" if "max_abs_diff" in f else ""
        size = (f"  size {f['size_bytes'] / 1024:.1f} KiB "
                f"(float {f['float_size_bytes'] / 1024:.1f} KiB)"
                if "size_bytes" in f else "")
        print(f"  {f['name']:>10s}: accuracy {f['accuracy_torch']:.3f} "
              f"-> {f['accuracy_export']:.3f}"
              f"{extra}{size}" + (f"  -> {f['path']}" if f.get("path") else ""))
    print(f"test accuracy {report['accuracy_torch']:.4f} -> {report['accuracy_export']:.4f} "
          f"(change {report['accuracy_change']:+.4f}, {report['changed_predictions']} of "
          f"{report['n']} predictions changed)")
    print(f"trial accuracy ({report['aggregate']} over windows) "
          f"{report['trial_accuracy_torch']:.4f} -> {report['trial_accuracy_export']:.4f} "
          f"({report['n_trials']} trials)")
    if report.get("adapt_note"):
        print(f"note: {report['adapt_note']}")
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("train", help="train and evaluate a gesture model on session files")
    _add_train_options(p)
    p.add_argument("--channels", choices=CHANNEL_SETS, default=None,
                   help="channel set (default: every channel the data has)")
    p.add_argument("--out", required=True, metavar="RUN",
                   help="run folder (re-run with the same folder to resume)")
    p.add_argument("--exclude-flagged", action="store_true",
                   help="leave out trials stored with flags (signal checks, the model "
                        "check); off by default; the run's config.json says which")
    p.set_defaults(func=cmd_train)

    p = subparsers.add_parser("evaluate", help="re-score a run from its saved weights")
    p.add_argument("run", metavar="RUN")
    p.add_argument("--data", nargs="+", default=None, metavar="PATH",
                   help="data to score on (default: the run's own data)")
    p.add_argument("--cache-dir", default=None)
    p.add_argument("--adapt", choices=ADAPT, default=None,
                   help="adapt a network to each test person's own windows (per condition "
                        "too: person-condition), or not "
                        "(default: as the run was trained; rf/knn cannot change)")
    p.set_defaults(func=cmd_evaluate)

    p = subparsers.add_parser("ablate", help="compare channel sets normal / shear / both")
    _add_train_options(p)
    p.add_argument("--channels", dest="channel_sets", nargs="+",
                   choices=CHANNEL_SETS, default=list(CHANNEL_SETS))
    p.add_argument("--out", default=None, metavar="DIR",
                   help="keep one run folder per channel set under DIR")
    p.set_defaults(func=cmd_ablate)

    p = subparsers.add_parser("export-model", help="export a run's models to ONNX or int8 ONNX")
    p.add_argument("run", metavar="RUN")
    # checked by export_run, so a wrong value is the usual one-line error
    p.add_argument("--format", required=True, metavar="|".join(EXPORT_FORMATS),
                   help="onnx: RUN/export/<fold>.onnx; int8: RUN/export/<fold>.int8.onnx")
    p.add_argument("--data", nargs="+", default=None, metavar="PATH")
    p.add_argument("--cache-dir", default=None)
    p.add_argument("--threads", type=int, default=None,
                   help="torch and onnxruntime CPU threads (1 is fastest on a busy machine)")
    p.add_argument("--aggregate", default=None, metavar="mean|vote",
                   help="trial prediction from its windows (default: the run's)")
    p.set_defaults(func=cmd_export)

