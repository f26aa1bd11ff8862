"""metrics.json from fold records: per-sample (window) and per-trial metrics, per fold,
per round (pooled over its folds) and overall (medians over rounds)."""

from __future__ import annotations

from typing import Any

import numpy as np

from tactile_studio.learn.data.windowing import aggregate as aggregate_trials
from tactile_studio.learn.evaluation import metrics as M
from tactile_studio.learn.learners.fold_predictions import (
    FoldPredictions,
    FoldRecord,
    PredictionsKey,
)

TRIAL_KEYS = ("accuracy", "balanced_accuracy", "f1_macro", "kappa", "confusion_matrix",
              "confusion_counts", "per_class_accuracy")


def _sample_metrics(y: np.ndarray, probs: np.ndarray, owner: np.ndarray, labels: list[str],
                    windowed: bool = False, aggregate: str = "mean") -> dict[str, Any]:
    """Per-sample (window) metrics, plus ``trial_*`` metrics of the trials' aggregated
    predictions (identical when every trial is one sample)."""
    out = M.classification_metrics(y, probs.argmax(axis=1), labels)
    trials, pred = aggregate_trials(owner, probs, aggregate)
    _, first = np.unique(owner, return_index=True)  # same sorted order as ``trials``
    trial = M.classification_metrics(y[first], pred, labels) if len(trials) else \
        M.classification_metrics(np.zeros(0, np.int64), np.zeros(0, np.int64), labels)
    for key in TRIAL_KEYS:
        out[f"trial_{key}"] = trial[key]
    out["n_trials"] = int(len(trials))
    out["aggregate"] = aggregate
    return out


def fold_metrics(rec: FoldRecord, labels: list[str], windowed: bool,
                 key: PredictionsKey = "predictions", aggregate: str = "mean") -> dict[str, Any]:
    p = FoldPredictions.from_dict(rec[key])
    return _sample_metrics(p.y_true, p.probs, p.owner, labels, windowed, aggregate)


def _pooled(records: list[FoldRecord], labels: list[str], windowed: bool,
            key: PredictionsKey = "predictions", aggregate: str = "mean") -> dict[str, Any]:
    """Metrics over the test predictions of several folds together (trial ids made unique
    per fold so votes never mix folds)."""
    ys, ps, os_ = [], [], []
    for i, rec in enumerate(records):
        p = FoldPredictions.from_dict(rec[key])
        ys.append(p.y_true)
        ps.append(p.class_probs(len(labels)))
        os_.append(p.owner + i * 10_000_000)
    return _sample_metrics(np.concatenate(ys), np.concatenate(ps), np.concatenate(os_),
                           labels, windowed, aggregate)


def shot_counts(records: list[FoldRecord]) -> list[int]:
    """The K of a few-shot run's folds (``--shots``), sorted; [] for other runs."""
    return sorted({int(r["shots"]) for r in records if r.get("shots") is not None})


def summarise(records: list[FoldRecord], labels: list[str], windowed: bool,
              header: dict[str, Any], complete: bool) -> dict[str, Any]:
    """metrics.json: pooled test metrics (medians over rounds), rounds, per-fold metrics.

    ``accuracy`` and ``confusion_*`` are per sample (window); ``trial_accuracy`` and
    ``trial_confusion_*`` per trial, aggregated as ``header["aggregate"]`` (mean
    probability by default).

    A few-shot run (``--shots``) is summarised at its smallest K (0: the person never
    seen), every fold of every K listed in ``per_fold``, and ``shots`` holds the curve:
    per K the same figures, on the same test trials."""
    ks = shot_counts(records)
    if ks:
        by_k = {k: _summarise([r for r in records if r.get("shots") == k], labels, windowed,
                              header, complete) for k in ks}
        out = dict(by_k[ks[0]])
        out["per_fold"] = [m for k in ks for m in by_k[k]["per_fold"]]
        out["shots"] = [{"k": k, **{key: by_k[k].get(key) for key in SHOT_KEYS}}
                        for k in ks]
        return out
    return _summarise(records, labels, windowed, header, complete)


SHOT_KEYS = ("accuracy", "trial_accuracy", "balanced_accuracy", "trial_balanced_accuracy",
             "f1_macro", "trial_f1_macro", "n", "n_trials")


def _summarise(records: list[FoldRecord], labels: list[str], windowed: bool,
               header: dict[str, Any], complete: bool) -> dict[str, Any]:
    agg = header.get("aggregate", "mean")
    per_fold, rounds = [], []
    for rec in records:
        m = fold_metrics(rec, labels, windowed, aggregate=agg)
        m.update({"round": rec["round"], "fold": rec["fold"], "name": rec["name"],
                  "test_participants": rec["test_participants"],
                  "best_epoch": rec.get("best_epoch"), "n_test_trials": len(rec["test"])})
        if rec.get("shots") is not None:
            m["shots"] = int(rec["shots"])
        if rec.get("heldout_predictions"):
            held = fold_metrics(rec, labels, windowed, "heldout_predictions", agg)
            m["heldout_accuracy"] = held["accuracy"]
            m["heldout_trial_accuracy"] = held["trial_accuracy"]
        per_fold.append(m)
    round_ids = sorted({r["round"] for r in records})
    for r in round_ids:
        recs = [x for x in records if x["round"] == r]
        m = _pooled(recs, labels, windowed, aggregate=agg)
        m.update({"round": r, "seed": recs[0]["seed"], "folds": len(recs)})
        if any(x.get("heldout_predictions") for x in recs):
            m["heldout"] = _pooled(recs, labels, windowed, "heldout_predictions", agg)
        rounds.append(m)
    overall = _pooled(records, labels, windowed, aggregate=agg)
    medians = M.median_of(rounds)
    overall.update(medians)  # with one round the median is that round's value
    out = {**header, **overall, "complete": complete, "medians": medians,
           "rounds": [{k: v for k, v in m.items() if not k.endswith(("confusion_matrix",
                                                                      "confusion_counts"))}
                      for m in rounds],
           "per_fold": per_fold}
    if any(r.get("heldout_predictions") for r in records):
        out["heldout"] = _pooled(records, labels, windowed, "heldout_predictions", agg)
    return out


def trials_were_cut(m: dict[str, Any]) -> bool:
    """Whether ``m`` (metrics.json, or one fold's) scored several windows per trial, so
    that accuracy per window and per trial differ."""
    return m.get("n", 0) > m.get("n_trials", 0) > 0


def headline(m: dict[str, Any]) -> str:
    """The run's accuracy in one phrase; both figures when long trials were cut into
    windows, since a figure per performance is the one people quote."""
    if trials_were_cut(m) and m.get("trial_accuracy") is not None:
        text = (f"accuracy {m['trial_accuracy']:.3f} per trial "
                f"({m['accuracy']:.3f} per window)")
    else:
        text = f"accuracy {m['accuracy']:.3f}"
    if m.get("shots"):  # not the test set of a plain run: said (short: progress lines
        # are cut at 80 characters), so no one sets the two figures side by side unwarned
        n, total = m.get("n_trials", m.get("n", "?")), m.get("data_trials")
        text += f" at K={m['shots'][0]['k']}, " + (
            f"{n} of {total} trials tested" if total else f"{n} trials tested")
    return text


def shots_test_set(m: dict[str, Any]) -> str:
    """What a few-shot run tested, against a plain run's test set: "45 test trials at
    every K; without --shots all 135 are tested" (a person's performances taken as shots
    at some K are tested at none)."""
    n = m.get("n_trials", m.get("n", "?"))
    total = m.get("data_trials")
    return f"{n} test trials at every K" + (
        f"; without --shots all {total} are tested" if total and total != n else "")


def shots_curve(shots: list[dict[str, Any]] | None) -> str:
    """A few-shot run's curve in one phrase ("K=0 0.61, K=1 0.70, K=2 0.74"): accuracy
    per performance (trial) at each K, the figure people quote; "" for other runs."""
    parts = []
    for s in shots or []:
        v = s.get("trial_accuracy")
        v = s.get("accuracy") if v is None else v
        if v is not None:
            parts.append(f"K={s['k']} {v:.2f}")
    return ", ".join(parts)
