"""Re-scoring a finished run from its saved weights (``tactile-studio evaluate``).

Every fold's saved model is loaded (torch weights from safetensors, rf / knn as ONNX run
by onnxruntime; no pickle) and predicts again:

* ``folds`` mode — the data holds the run's test trials (found by their uids): each fold
  model re-predicts its own test trials, which reproduces the run's metrics (a check that
  the saved weights and normalisation are complete);
* ``external`` mode — none of the run's test trials are in the data (e.g. new
  participants): every fold model predicts every trial, and the metrics pool them.

The result is written to ``RUN/rescore.json`` (metrics.json is left as trained).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.data.dataset import TrialDataset, build_dataset
from tactile_studio.learn.evaluation.summary import headline
from tactile_studio.learn.experiments.experiment import (
    ExperimentConfig,
    _predictions,
    adapt_people,
    prepare_inputs,
    run_header,
    summarise,
)
from tactile_studio.learn.experiments.runfolder import model_file, read_run, write_json
from tactile_studio.learn.experiments.trialinfo import load_trial_table
from tactile_studio.learn.learners.baselines import legacy_options
from tactile_studio.learn.learners.families import DataInfo, make_learner
from tactile_studio.learn.learners.fold_predictions import FoldRecord
from tactile_studio.learn.learners.generalise import ADAPT
from tactile_studio.output_faults import require_writable_folder


class RunData(NamedTuple):
    """A run folder read back with its data: its config, its resolved description
    (config.json's ``resolved``), its fold records, the dataset with the run's label
    indices, the learner and the data facts. A tuple, so callers unpack what they use."""

    config: ExperimentConfig
    resolved: dict[str, Any]
    records: list[FoldRecord]
    ds: TrialDataset
    learner: Any  # a family's learner: a fused one has more than the Learner contract
    info: DataInfo


def load_run_data(run: str | os.PathLike, data: list[str] | None = None,
                  cache_dir: str | None = None, device: str = "auto",
                  progress: ProgressFn = no_progress, cancel: CancelToken | None = None
                  ) -> RunData:
    """The run folder ``run`` and its data (``data`` instead of the run's own paths)."""
    cfg_json, records = read_run(run)
    config = ExperimentConfig.from_dict(cfg_json["config"])
    resolved = cfg_json["resolved"]
    info = DataInfo.from_dict(resolved["data_info"])
    labels = list(resolved["dataset"]["labels"])
    ds = build_dataset(data or config.data, config.grid, config.channels,
                       cache_dir or config.cache_dir, config.use_cache, progress, cancel,
                       config.exclude_flagged)
    if ds.grid_shape != tuple(info.grid) or ds.n_channels != info.in_channels:
        raise UserError(f"the data ({ds.layout}, {ds.grid_shape[0]}x{ds.grid_shape[1]}, "
                        f"{ds.n_channels} channels) does not fit the run's models "
                        f"({info.grid[0]}x{info.grid[1]}, {info.in_channels} channels)")
    unknown = sorted(set(ds.label_names) - set(labels))
    if unknown:
        raise UserError(f"gesture '{unknown[0]}' in the data is not one of the run's labels "
                        f"({', '.join(labels)})")
    remap = np.array([labels.index(g) for g in ds.label_names], dtype=np.int64)
    ds = replace(ds, labels=remap[ds.labels], label_names=labels)
    learner = make_learner(config.model, config.preset,
                           legacy_options(config.model, resolved.get("model"), config.overrides),
                           config.epochs, device)
    return RunData(config, resolved, records, ds, learner, info)


def _other_recordings(run: str | os.PathLike, ds: Any, index: dict[str, int],
                      found: set[str]) -> bool:
    """Whether the data's trials named as the run's test trials are other recordings
    with the same file names: a trial whose person or gesture differs from the run's
    trial table (runs without a table, or rows without a gesture, are taken as named)."""
    try:
        table = {str(r.get("uid")): r for r in load_trial_table(run)}
    except (UserError, OSError):
        return False
    for uid in found:
        row = table.get(uid)
        if not row or "gesture" not in row:
            continue
        i = index[uid]
        if (str(row.get("participant")), str(row["gesture"])) != \
                (str(ds.participants[i]), ds.label_names[int(ds.labels[i])]):
            return True
    return False


def rescore_run(run: str | os.PathLike, data: list[str] | None = None,
                cache_dir: str | None = None, progress: ProgressFn = no_progress,
                cancel: CancelToken | None = None, adapt: str | None = None
                ) -> dict[str, Any]:
    """Metrics recomputed from the saved weights (see module doc); also saved to
    ``RUN/rescore.json``. ``adapt`` (generalise.ADAPT) overrides the run's adaptation
    to each test person: any network can adapt its batch norm after the fact, while
    rf/knn (and fused forests) were trained on features standardised or not, so theirs
    cannot change. A run folder that cannot be written is refused before any scoring."""
    if Path(run).is_dir():  # else load_run_data says what is wrong with it
        require_writable_folder(run, "where evaluate saves rescore.json")
    config, resolved, records, ds, learner, info = load_run_data(
        run, data, cache_dir, progress=lambda f, m: progress(0.3 * f, m), cancel=cancel)
    if adapt is not None and adapt != config.adapt:
        if adapt not in ADAPT:
            raise UserError(f"unknown adaptation {adapt!r} (available: {', '.join(ADAPT)})")
        if learner.kind != "torch":
            raise UserError(f"{run}: {config.model} was trained with --adapt {config.adapt}; "
                            "its features cannot be re-standardised afterwards (a network's "
                            f"batch norm can: train again with --adapt {adapt})")
        config = replace(config, adapt=adapt)
    index = {u: i for i, u in enumerate(ds.uids)}
    wanted = {u for rec in records for u in rec["test"]}
    found = wanted & set(index)
    if found and _other_recordings(run, ds, index, found):
        found = set()  # another study's P01.h5: new people to every fold model
    mode = "folds" if found else "external"
    if found and found != wanted:
        missing = sorted(wanted - found)
        raise UserError(f"{len(missing)} of the run's test trials are not in the data "
                        f"(first: {missing[0]})")
    if mode == "folds" and config.adapt != "none" and config.evaluation == "all-inclusive":
        raise UserError(f"{run}: --adapt {config.adapt} meets each test person with their own "
                        "session, but this all-inclusive run trained on the same people; "
                        "adapt when evaluating new people's data (--data) or a lopo run")
    ds, x, owner, *_ = prepare_inputs(learner, ds, config)
    people = adapt_people(config, ds, owner)  # new people adapt to themselves too
    # in external mode every fold model meets every trial of the data: its fold is named
    # as trained (the people it held out), but what it was tested on is the data's people
    fresh: list[FoldRecord] = []
    for k, rec in enumerate(records):
        if cancel is not None:
            cancel.check()
        progress(0.3 + 0.7 * k / len(records), f"fold {rec['name']}")
        fitted = learner.load(model_file(rec["_dir"]), info)
        idx = (np.array([index[u] for u in rec["test"]], dtype=np.int64) if mode == "folds"
               else np.arange(len(ds)))
        pred = _predictions(fitted, learner, x, owner, idx, ds.labels, rec["norm"], people)
        new = rec.copy()
        new.pop("heldout_predictions", None)
        new["predictions"] = pred
        if mode == "external":
            new["test"] = list(ds.uids)
            new["test_participants"] = sorted({str(p) for p in ds.participants})
        fresh.append(new)
    header = {**run_header(config, ds.channels, learner.windowed),
              "mode": mode, "data": [str(p) for p in (data or config.data)]}
    metrics = summarise(fresh, ds.label_names, learner.windowed, header, True)
    metrics["dataset_skipped"] = list(ds.skipped)  # resume backups, duplicate sessions
    write_json(Path(run) / "rescore.json", metrics)
    progress(1.0, headline(metrics))
    return metrics
