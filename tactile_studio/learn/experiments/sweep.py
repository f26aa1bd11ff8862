"""Sweeps: models x channel sets x rounds x folds as independent tasks on an executor.

Every task trains and tests one fold of one (model, channel set) in a round, in a fresh
process with one torch thread and its own seed (round ``r``: ``seed + r``, the same
splits and initialisation ``run_experiment`` uses), so the metrics are the same whatever
executor runs it and in whatever order. Finished tasks are saved to
``OUT/tasks/*.json`` as they arrive: a cancelled sweep keeps them (and writes the table
of what finished), and running the same sweep again with the same ``OUT`` only runs the
rest.

``OUT/results.csv`` / ``results.json``: one row per (model, channel set) with the pooled
metrics of its finished folds (medians over rounds), per-window ``accuracy`` and
per-trial ``trial_accuracy``, the folds done and the training time summed over folds.

``OUT/runs/<model>-<channels>/`` is an ordinary run folder per row (config.json, every
finished fold's record and model file, metrics.json and its figures), so the research
workspace lists, opens, compares and exports a sweep's runs like any ``train`` run. A
task sends its fold model's files back as bytes (no shared file system needed on a cluster).
"""

from __future__ import annotations

import csv
import os
import re
import tempfile
import time
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from tactile_studio.errors import Cancelled, IncompleteError, UserError
from tactile_studio.file_claims import claim_folder
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.data.dataset import build_dataset
from tactile_studio.learn.experiments.executors import WorkerLost
from tactile_studio.learn.experiments.experiment import (
    ExperimentConfig,
    _torch_threads,
    _train_fold,
    adapt_people,
    folds_for,
    prepare_inputs,
    run_header,
    run_title,
    summarise,
)
from tactile_studio.learn.experiments.fold_plan import FoldPlan
from tactile_studio.learn.experiments.job_events import Plan, Task
from tactile_studio.learn.experiments.runfolder import (
    FOLD,
    WEIGHTS,
    RunFolder,
    differences,
    read_json,
    write_json,
)
from tactile_studio.learn.learners.families import DataInfo, make_learner
from tactile_studio.learn.learners.fold_predictions import FoldPredictions, FoldRecord
from tactile_studio.learn.learners.fused import display_name

SweepListener = Callable[[Plan | Task], None]

TABLE_KEYS = ("accuracy", "trial_accuracy", "f1_macro", "trial_f1_macro", "balanced_accuracy",
              "kappa")


@dataclass
class SweepResult:
    rows: list[dict[str, Any]]
    metrics: dict[str, dict[str, Any]] = field(default_factory=dict)  # "model/channels" ->
    complete: bool = True
    out: Path | None = None


def task_gpus(model: str, device: str = "auto") -> float:
    """GPUs a task asks the scheduler for: a torch model on ``--device cuda`` asks for one,
    a model declaring ``gpus`` (ModelSpec.gpus) for that many; the baselines and CPU runs
    for none."""
    from tactile_studio.learn.learners.baselines import BASELINES
    from tactile_studio.learn.models import get_model_spec

    if model in BASELINES:
        return 0.0
    return max(float(get_model_spec(model).gpus), 1.0 if device.startswith("cuda") else 0.0)


def run_fold_task(config: dict[str, Any], round_: int, fold: int) -> FoldRecord:
    """One fold of one round of ``config`` (an ExperimentConfig dict): its fold record
    (split, history, test predictions), without the fitted model. Runs in a worker."""
    from tactile_studio.learn.learners.baselines import BASELINES

    cfg = ExperimentConfig.from_dict(config)
    _warm_imports()
    if cfg.model not in BASELINES:
        _warm_torch()
    with _torch_threads(1):
        learner = make_learner(cfg.model, cfg.preset, cfg.overrides, cfg.epochs, cfg.device)
        ds = build_dataset(cfg.data, cfg.grid, cfg.channels, cfg.cache_dir, cfg.use_cache)
        info = DataInfo.of(ds)
        folds = folds_for(cfg, ds, round_)
        ds, x, owner, _, _, extra, moments = prepare_inputs(learner, ds, cfg)
        plan = FoldPlan(learner, ds, x, owner, folds[fold], round_, fold, cfg.seed + round_,
                        adapt_people(cfg, ds, owner), extra, cfg.balance, moments)
        rec, fitted = _train_fold(plan, info, CancelToken(), lambda e: None)
    name = getattr(fitted, "file_name", WEIGHTS)
    with tempfile.TemporaryDirectory() as tmp:  # every file the model saves (fused: two)
        fitted.save(Path(tmp) / name)
        rec["_model"] = {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir())}
    return rec


def _warm_imports() -> None:
    """Import the baselines' libraries before a fold is timed, so a worker's first task
    does not report several seconds of imports as training time (measured: rf's first
    fold 5.7 s instead of ~0.8 s)."""
    import onnxruntime  # noqa: F401
    import skl2onnx  # noqa: F401
    import sklearn.ensemble  # noqa: F401
    import sklearn.neighbors  # noqa: F401


_torch_warm = False


def _warm_torch() -> None:
    """torch's first forward, backward and optimiser step in a process cost ~1 s that no
    later one does (measured: 0.97 s, then 1 ms); made here, once per worker, so a
    worker's first fold does not report it as training time (a sweep's train_s column
    read 4.9 s for a task whose twin took 0.6 s)."""
    global _torch_warm
    if _torch_warm:
        return
    import torch

    with _torch_threads(1):
        layer = torch.nn.Conv1d(2, 2, 3)
        layer(torch.zeros(2, 2, 8)).sum().backward()
        torch.optim.AdamW(layer.parameters(), fused=True).step()
    _torch_warm = True


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def run_sweep(base: ExperimentConfig, models: list[str], channel_sets: list[str | None],
              executor, out: str | os.PathLike | None = None, progress: ProgressFn = no_progress,
              cancel: CancelToken | None = None,
              listener: SweepListener | None = None) -> SweepResult:
    """Run ``models`` x ``channel_sets`` x ``base.rounds`` x folds on ``executor`` (an
    entered :mod:`~tactile_studio.learn.experiments.executors` executor); see the module doc.

    ``listener`` receives a :class:`~tactile_studio.learn.experiments.job_events.Plan` once the
    tasks
    are known and a :class:`~tactile_studio.learn.experiments.job_events.Task` as each one finishes
    (the GUI's per-task progress)."""
    if not models or not channel_sets:
        raise UserError("a sweep needs at least one model and one channel set")
    base.validate()
    # one writer per sweep folder (file_claims): a second sweep into OUT is refused
    # before any data is read
    held = claim_folder(out, "sweep folder") if out is not None else nullcontext()
    with held:
        return _sweep(base, models, channel_sets, executor, out, progress,
                      cancel or CancelToken(), listener or (lambda event: None))


def _sweep(base: ExperimentConfig, models: list[str], channel_sets: list[str | None],
           executor, out: str | os.PathLike | None, progress: ProgressFn,
           cancel: CancelToken, listener: SweepListener) -> SweepResult:
    progress(0.0, "reading data")
    full = build_dataset(base.data, base.grid, None, base.cache_dir, base.use_cache,
                         cancel=cancel)
    base = replace(base, data=[str(Path(p).resolve()) for p in base.data])
    groups: dict[str, dict[str, Any]] = {}
    tasks: dict[str, tuple[dict[str, Any], float]] = {}
    for model in models:
        for channels in channel_sets:
            cfg = replace(base, model=model,
                          channels=full.resolve_channels(channels)).resolved()
            learner = make_learner(model, cfg.preset, cfg.overrides, cfg.epochs, cfg.device)
            learner.check(DataInfo.of(full.select(cfg.channels)))
            key = f"{model}/{cfg.channels}"
            groups[key] = {"config": cfg, "windowed": learner.windowed, "ids": [],
                           "learner": learner}
            for r in range(cfg.rounds):
                folds = folds_for(cfg, full, r)
                for k, fold in enumerate(folds):
                    tid = f"{model}-{cfg.channels}-r{r}-{_safe(fold.name)}"
                    groups[key]["ids"].append(tid)
                    tasks[tid] = ({"config": cfg.to_dict(), "round_": r, "fold": k},
                                  task_gpus(model, cfg.device))
    folder = Path(out) if out is not None else None
    records: dict[str, FoldRecord] = {}
    if folder is not None:
        _start_folder(folder, base)
        _start_runs(folder, groups, full)
        for tid in list(tasks):
            path = folder / "tasks" / f"{tid}.json"
            if path.is_file():
                records[tid] = read_json(path)
                del tasks[tid]
    total = len(tasks) + len(records)
    owners = {tid: g for g in groups.values() for tid in g["ids"]}
    progress(len(records) / total, f"{len(tasks)} tasks to run ({len(records)} done before)")
    listener(Plan(total=total, done=len(records)))
    t0 = time.perf_counter()
    complete, lost = True, None
    try:
        for tid, rec in executor.run(run_fold_task, tasks, cancel):
            model_file = rec.pop("_model", None)
            records[tid] = rec
            if folder is not None:
                write_json(folder / "tasks" / f"{tid}.json", rec)
                _save_fold(owners[tid]["run"], rec, model_file)
            progress(len(records) / total, f"{tid} done ({time.perf_counter() - t0:.0f} s)")
            cfg = owners[tid]["config"]
            listener(Task(id=tid, model=cfg.model, channels=cfg.channels, done=len(records),
                          total=total, seconds=rec["seconds"], accuracy=_accuracy(rec),
                          row=_group_row(owners[tid], records, full.label_names)[0]))
    except Cancelled:
        complete = False
    except WorkerLost as exc:  # the finished tasks are kept and tabled, as on Ctrl-C
        lost = exc
    result = _table(groups, records, full.label_names, complete and lost is None, folder)
    if lost is not None:
        raise IncompleteError(
            "a worker process ended abruptly (killed, or out of memory) with task(s) "
            f"running: {', '.join(lost.running) or 'none'}; {len(records)} of {total} tasks "
            "finished" + (f", kept in {folder}" if folder else "")
            + "; the same command trains the rest")
    if not complete:
        raise Cancelled(f"sweep cancelled: {len(records)} of {total} tasks finished"
                        + (f", kept in {folder}" if folder else ""))
    return result


def _start_folder(folder: Path, base: ExperimentConfig) -> None:
    """Create OUT, or check that the sweep already in it used the same settings."""
    from tactile_studio.learn.experiments.experiment import RESULT_KEYS, result_defaults

    settings = {k: v for k, v in base.to_dict().items()
                if k in RESULT_KEYS and k not in ("model", "channels")}
    path = folder / "sweep.json"
    if path.is_file():
        old = {**read_json_roundtrip(result_defaults()), **read_json(path)}
        diff = differences(old, {k: read_json_roundtrip(v) for k, v in settings.items()})
        if diff:
            raise UserError(f"{folder} holds a sweep with other settings (differs in "
                            f"{diff}); choose another --out")
    elif folder.is_dir() and any(folder.iterdir()):
        raise UserError(f"{folder}: folder is not empty and holds no sweep; choose another --out")
    (folder / "tasks").mkdir(parents=True, exist_ok=True)
    write_json(path, settings)


def _start_runs(folder: Path, groups: dict[str, dict[str, Any]], full) -> None:  # noqa: ANN001
    """One run folder per (model, channel set) under ``OUT/runs`` (see the module doc)."""
    from tactile_studio.learn.experiments.experiment import RESULT_KEYS, _versions, result_defaults
    from tactile_studio.learn.experiments.trialinfo import write_trial_table

    for g in groups.values():
        cfg: ExperimentConfig = g["config"]
        ds = full.select(cfg.channels)
        resolved = {"model": g["learner"].describe(), "data_info": DataInfo.of(ds).to_dict(),
                    "dataset": ds.summary(), "versions": _versions(),
                    "created": time.strftime("%Y-%m-%dT%H:%M:%S"), "sweep": str(folder)}
        g["run"] = RunFolder(folder / "runs" / _safe(f"{cfg.model}-{cfg.channels}"))
        g["run"].start(cfg.to_dict(), resolved, RESULT_KEYS, result_defaults())
        write_trial_table(g["run"].path, ds.uids, ds.participants.tolist(), cfg.data)


def _save_fold(run: RunFolder, rec: FoldRecord, model: dict[str, Any] | None) -> None:
    if model is None:
        return
    d = run.fold_dir(rec["round"], rec["name"])
    d.mkdir(parents=True, exist_ok=True)
    for name, data in model.items():
        (d / name).write_bytes(data)
    write_json(d / FOLD, rec)


def _accuracy(rec: FoldRecord) -> float | None:
    """A finished fold's per-window test accuracy (for the progress display)."""
    if not rec.get("predictions"):
        return None
    p = FoldPredictions.from_dict(rec["predictions"])
    return float((p.y_pred == p.y_true).mean()) if len(p) else None


def read_json_roundtrip(value: Any) -> Any:
    import json

    from tactile_studio.learn.experiments.runfolder import clean_json

    return json.loads(json.dumps(clean_json(value)))


def _group_row(g: dict[str, Any], records: dict[str, FoldRecord], labels: list[str]
               ) -> tuple[dict[str, Any], dict[str, Any] | None, list[FoldRecord]]:
    """(table row, metrics or None, finished fold records) of one (model, channel set)."""
    cfg: ExperimentConfig = g["config"]
    recs = sorted((records[t] for t in g["ids"] if t in records),
                  key=lambda r: (r["round"], r["fold"]))
    name = display_name(cfg.model, cfg.overrides)
    row: dict[str, Any] = {"model": cfg.model,  # each test person met on their own terms?
                           "name": name if cfg.adapt == "none" else f"{name} (adapted)",
                           "adapt": cfg.adapt, "channels": cfg.channels,
                           "folds_done": len(recs), "folds": len(g["ids"])}
    if not recs:
        return row, None, recs
    header = run_header(cfg, cfg.channels, g["windowed"])
    m = summarise(recs, labels, g["windowed"], header, len(recs) == len(g["ids"]))
    row.update({k: m.get(k) for k in TABLE_KEYS})
    row["train_seconds"] = round(sum(r["seconds"] for r in recs), 2)
    return row, m, recs


def _table(groups: dict[str, dict[str, Any]], records: dict[str, FoldRecord],
           labels: list[str], complete: bool, folder: Path | None) -> SweepResult:
    rows, metrics = [], {}
    for key, g in groups.items():
        cfg: ExperimentConfig = g["config"]
        row, m, recs = _group_row(g, records, labels)
        if m is not None:
            metrics[key] = m
            if g.get("run") is not None:
                title = run_title(cfg, cfg.channels)
                g["run"].write_results(m, recs, title + ("" if m["complete"] else
                                                         " (partial)"))
                row["run"] = str(g["run"].path)
        rows.append(row)
    result = SweepResult(rows, metrics, complete, folder)
    if folder is not None:
        write_json(folder / "results.json", {"complete": complete, "rows": rows,
                                             "metrics": metrics})
        cols = ["model", "name", "adapt", "channels", "folds_done", "folds", *TABLE_KEYS,
                "train_seconds"]
        with open(folder / "results.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, cols, extrasaction="ignore")
            w.writeheader()
            w.writerows(rows)
    return result


def format_rows(rows: list[dict[str, Any]]) -> str:
    """The results table as aligned text."""
    cols = ["model", "channels", "folds", *TABLE_KEYS, "train_s"]
    lines = ["".join(f"{c:>19s}" for c in cols)]
    for r in rows:
        vals = [r.get("name", r["model"]), r["channels"], f"{r['folds_done']}/{r['folds']}"]
        vals += ["-" if r.get(k) is None else f"{r[k]:.3f}" for k in TABLE_KEYS]
        vals.append("-" if r.get("train_seconds") is None else f"{r['train_seconds']:.1f}")
        lines.append("".join(f"{v:>19s}" for v in vals))
    return "\n".join(lines)
