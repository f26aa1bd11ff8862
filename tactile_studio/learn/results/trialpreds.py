"""A run's test predictions as one row per (round, trial), with the trial's identity.

Window-based models predict many windows per trial; a trial's prediction aggregates them
as the run's ``trial_accuracy`` does (its ``aggregate``: mean probability by default, or
majority vote), its probabilities are the windows' mean.
Confidence is the mean probability of the predicted gesture; the runner-up is the
gesture with the next-highest mean probability.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.data.windowing import aggregate
from tactile_studio.learn.experiments.runfolder import read_run
from tactile_studio.learn.experiments.trialinfo import load_trial_table
from tactile_studio.learn.learners.fold_predictions import FoldPredictions, FoldRecord
from tactile_studio.storage.format.trials import trial_number


@dataclass
class TrialPrediction:
    round: int
    fold: str
    uid: str
    participant: str
    session: str
    trial: int
    condition: str
    true: int
    pred: int
    confidence: float
    runner_up: int
    probs: np.ndarray
    path: str = ""
    start_sample: int = 0
    shots: int | None = None  # a few-shot run's K for this fold (``--shots``)

    @property
    def number(self) -> int:
        """The trial's number in its session as people see it (from 1, as the console and
        the player count; ``trial`` is the file's index)."""
        return trial_number(self.trial)

    @property
    def correct(self) -> bool:
        return self.true == self.pred


@dataclass
class RunPredictions:
    """Everything a viewer needs from a run folder: config, labels and trial rows."""

    path: Path
    config: dict[str, Any]
    resolved: dict[str, Any]
    labels: list[str]
    trials: list[TrialPrediction]

    @property
    def name(self) -> str:
        return self.path.name

    def accuracy(self) -> float:
        return float(np.mean([t.correct for t in self.trials])) if self.trials else 0.0

    @property
    def shot_counts(self) -> list[int]:
        """The K of a few-shot run (``--shots``), sorted; [] for other runs."""
        return sorted({t.shots for t in self.trials if t.shots is not None})

    def at_shots(self, k: int | None) -> RunPredictions:
        """The predictions of the folds trained with ``k`` shots (all when None): a
        few-shot run tests each trial once per K."""
        if k is None or not self.shot_counts:
            return self
        return RunPredictions(self.path, self.config, self.resolved, self.labels,
                              [t for t in self.trials if t.shots == k])


def _trial_rows(rec: FoldRecord, labels: list[str], table: list[dict[str, Any]],
                how: str = "mean") -> list[TrialPrediction]:
    p = FoldPredictions.from_dict(rec["predictions"])
    owner = p.owner
    if not len(owner):
        return []
    probs, y = p.class_probs(len(labels)), p.y_true
    trials, predicted = aggregate(owner, probs, how)
    _, inverse = np.unique(owner, return_inverse=True)
    mean = np.zeros((len(trials), len(labels)))
    np.add.at(mean, inverse, probs)
    mean /= np.bincount(inverse, minlength=len(trials))[:, None]
    _, first = np.unique(owner, return_index=True)
    rows = []
    for k, t in enumerate(trials):
        if t >= len(table):
            raise UserError(f"{rec.get('_dir', 'run')}: predictions name trial {t} but the "
                            f"run's trial table has {len(table)} (incompatible layout)")
        ident = table[t]
        order = np.argsort(-mean[k])
        pred = int(predicted[k])
        runner = int(order[1] if order[0] == pred else order[0]) if len(labels) > 1 else pred
        rows.append(TrialPrediction(
            round=int(rec["round"]), fold=str(rec["name"]), uid=str(ident.get("uid", t)),
            participant=str(ident.get("participant", "")), session=str(ident.get("session", "")),
            trial=int(ident.get("trial", -1)), condition=str(ident.get("condition", "")),
            true=int(y[first[k]]), pred=pred, confidence=float(mean[k, pred]),
            runner_up=runner, probs=mean[k], path=str(ident.get("path", "")),
            start_sample=int(ident.get("start_sample", 0)),
            shots=None if rec.get("shots") is None else int(rec["shots"])))
    return rows


def load_predictions(run: str | os.PathLike, data: list[str] | None = None) -> RunPredictions:
    """Per-trial test predictions of every finished fold of a run folder."""
    cfg, records = read_run(run)
    try:
        labels = list(cfg["resolved"]["dataset"]["labels"])
        for rec in records:
            FoldPredictions.from_dict(rec["predictions"])  # layout check
    except (KeyError, TypeError):
        raise UserError(f"{run}: not a run folder of this version (config.json or fold.json "
                        "lacks labels/predictions)") from None
    table = load_trial_table(run, data)
    how = (cfg.get("config") or {}).get("aggregate") or "mean"  # as the run's trial_accuracy
    rows: list[TrialPrediction] = []
    for rec in records:
        rows.extend(_trial_rows(rec, labels, table, how))
    return RunPredictions(Path(run), cfg.get("config", {}), cfg.get("resolved", {}), labels, rows)
