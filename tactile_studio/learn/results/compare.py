"""Comparing two runs on the test trials they share: accuracies, per-participant paired
accuracies, the difference matrix, significance tests, and the result as a sentence.

Trials are matched by (round, trial uid), so two runs of the same data and evaluation
(e.g. the channel ablation normal / shear / both) compare trial by trial.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.evaluation.stats import mcnemar_exact, wilcoxon_signed_rank
from tactile_studio.learn.experiments.experiment import RESULT_KEYS, result_defaults
from tactile_studio.learn.learners.fused import display_name
from tactile_studio.learn.results.trialpreds import RunPredictions, load_predictions

_ADAPT_LABEL = {"person": "adapted", "person-condition": "adapted per condition",
                "none": "as trained"}
# settings that mean nothing unless another one says so: (setting, in effect when)
_IN_EFFECT = {
    "folds": lambda c: c.get("evaluation") == "group-kfold",
    "heldout_fraction": lambda c: c.get("evaluation") == "group-kfold",
    "split": lambda c: c.get("evaluation") == "all-inclusive",
    "shots_by": lambda c: bool(c.get("shots")),
    "augment_copies": lambda c: bool(c.get("augment")),
}
_NONE_WHEN_EMPTY = ("shots", "augment")  # an empty value means "none", not "default"


def _value_text(key: str, value: Any) -> str:
    """A setting's value in a phrase: lists joined ("0,1,2"), switches on/off, an unset
    setting "default" (the model's or evaluation's own), an empty list or text "none"."""
    if value is None or (isinstance(value, (list, tuple, str)) and not value):
        return "none" if key in _NONE_WHEN_EMPTY else "default"
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, (list, tuple)):
        return ",".join(_value_text(key, v) for v in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def config_difference(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """Every result-changing setting two run configs differ in, one phrase each
    ("channels: normal → both", "shots: none → 0,1,2"); a setting counts only where it
    acts (a k-fold's folds under lopo do not). Pass the configs as the runs ran
    (:func:`as_ran`): a setting left to its default reads as the value it took."""
    since = result_defaults()  # what a run written before a setting existed ran with
    out = []
    for key in RESULT_KEYS:
        va, vb = a.get(key, since.get(key)), b.get(key, since.get(key))
        if key in ("shots", "split"):  # lists and tuples alike
            va, vb = list(va or []), list(vb or [])
        if va == vb:
            continue
        if key in _IN_EFFECT and not (_IN_EFFECT[key](a) or _IN_EFFECT[key](b)):
            continue
        if key == "overrides" and isinstance(va, dict) and isinstance(vb, dict):
            for k in sorted(set(va) | set(vb)):
                if va.get(k) != vb.get(k):
                    out.append(f"{k}: {_value_text(k, va.get(k))} → "
                               f"{_value_text(k, vb.get(k))}")
        elif key == "data":
            out.append(f"data: {len(va or [])} → {len(vb or [])} source(s)"
                       if len(va or []) != len(vb or []) else "data: different sources")
        else:
            out.append(f"{key}: {_value_text(key, va)} → {_value_text(key, vb)}")
    return out


def as_ran(config: dict[str, Any], channels: str | None) -> dict[str, Any]:
    """``config`` with the channel set the run used (``channels``: from its dataset or
    metrics) where train left it to the model (None): "normal → default" named no
    difference two runs on normal and on both channels had."""
    if config.get("channels") is None and channels:
        return {**config, "channels": channels}
    return config


_LABELLED = ("model", "channels", "grid", "preset", "evaluation", "adapt", "shots")
_PHRASE = {"channels": "{} channels", "grid": "{} grid", "preset": "preset {}",
           "evaluation": "{} evaluation"}
_OWN_PHRASE = ("model", "adapt", "shots")  # named by their phrase even when alone


def _phrase(run: RunPredictions, key: str, value: Any) -> str:
    if key == "model":  # "cnn1d + rf 0.5" when fused with rf (learn/learners/fused.py)
        return display_name(run.config["model"], run.config.get("overrides"))
    if key == "adapt":
        return _ADAPT_LABEL[value or "none"]
    if key == "shots":
        return f"few-shot (K {_value_text(key, value)})" if value else "plain"
    return _PHRASE.get(key, "{}").format(value)


def _channels_used(run: RunPredictions) -> str | None:
    return (run.resolved.get("dataset") or {}).get("channels")


def _labelled(run: RunPredictions) -> dict[str, Any]:
    """The run's labelled settings as it ran: ``channels`` left to the model's default
    (None, as train without --channels writes it) is the set it used ("None channels"
    named a difference two runs on the same channels did not have)."""
    since = result_defaults()
    config = as_ran(run.config, _channels_used(run))
    out = {k: config.get(k, since.get(k)) for k in _LABELLED}
    out["shots"] = list(out["shots"] or [])
    return out


def run_label(run: RunPredictions, other: RunPredictions) -> str:
    """A short name for a run next to another, by what differs: the value of the one
    setting they differ in (``both``), else up to three phrases ("rf · preset tiny";
    model options too: "n_estimators 80"), else the folder name. A folder name says
    nothing about the runs ("rf-tiny beats normal" compared two folder names)."""
    mine_set, theirs_set = _labelled(run), _labelled(other)
    keys = [k for k in _LABELLED if mine_set[k] != theirs_set[k]]
    mine, theirs = run.config.get("overrides") or {}, other.config.get("overrides") or {}
    opts = [k for k in sorted(set(mine) | set(theirs)) if mine.get(k) != theirs.get(k)]
    if "model" in keys:  # a model's options differ with it: the model says it
        opts = []
    if len(keys) == 1 and not opts and (mine_set[keys[0]] is not None or keys[0] == "shots"):
        value = mine_set[keys[0]]
        return _phrase(run, keys[0], value) if keys[0] in _OWN_PHRASE else str(value)
    phrases = [_phrase(run, k, mine_set[k]) for k in keys]
    phrases += [f"{k} {mine.get(k, 'default')}" for k in opts]
    if 1 <= len(phrases) <= 3:
        return " · ".join(phrases)
    if run.name == other.name:
        return str(run.path)
    return run.name


def _fmt_p(p: float) -> str:
    return "p < 0.001" if p < 0.001 else f"p = {p:.3f}" if p < 0.1 else f"p = {p:.2f}"


def compare_predictions(a: RunPredictions, b: RunPredictions) -> dict[str, Any]:
    """Every number of the comparison (see module doc); JSON-ready."""
    if a.labels != b.labels:
        raise UserError(f"{a.path} and {b.path} classify different gestures "
                        f"({len(a.labels)} vs {len(b.labels)} labels); they cannot be compared")
    ia = {(t.round, t.uid): t for t in a.trials}
    ib = {(t.round, t.uid): t for t in b.trials}
    keys = sorted(set(ia) & set(ib))
    if not keys:
        raise UserError(f"{a.path} and {b.path} share no test trials (different data or "
                        "evaluation); they cannot be compared")
    _same_recordings(a, b, [(ia[k], ib[k]) for k in keys])
    ca = np.array([ia[k].correct for k in keys])
    cb = np.array([ib[k].correct for k in keys])
    parts = sorted({ia[k].participant for k in keys})
    pp = {}
    for p in parts:
        m = np.array([ia[k].participant == p for k in keys])
        pp[p] = {"accuracy_a": float(ca[m].mean()), "accuracy_b": float(cb[m].mean()),
                 "trials": int(m.sum())}
    acc_a, acc_b = float(ca.mean()), float(cb.mean())
    if len(parts) >= 2:
        _, w_p, w_n = wilcoxon_signed_rank(np.array([pp[p]["accuracy_b"] for p in parts]),
                                           np.array([pp[p]["accuracy_a"] for p in parts]))
    else:
        w_p, w_n = None, 0
    only_a, only_b = int((ca & ~cb).sum()), int((~ca & cb).sum())
    n = len(a.labels)
    rows_a, rows_b = np.zeros((n, n)), np.zeros((n, n))
    for k in keys:
        rows_a[ia[k].true, ia[k].pred] += 1
        rows_b[ib[k].true, ib[k].pred] += 1
    support = np.maximum(rows_a.sum(axis=1, keepdims=True), 1)
    diff = (rows_b - rows_a) / support
    name_a, name_b = run_label(a, b), run_label(b, a)
    result = {
        "run_a": str(a.path), "run_b": str(b.path), "name_a": name_a, "name_b": name_b,
        "labels": a.labels, "accuracy_a": acc_a, "accuracy_b": acc_b,
        "difference": acc_b - acc_a, "n_matched": len(keys), "n_participants": len(parts),
        "n_trials_a": len(ia), "n_trials_b": len(ib),  # a partial run has fewer
        "wilcoxon_p": w_p, "wilcoxon_n": w_n, "mcnemar_p": mcnemar_exact(only_a, only_b),
        "only_a_correct": only_a, "only_b_correct": only_b, "per_participant": pp,
        "difference_matrix": diff.round(6).tolist(),
        "config_difference": config_difference(as_ran(a.config, _channels_used(a)),
                                               as_ran(b.config, _channels_used(b))),
    }
    result["sentence"] = sentence(result)
    return result


def _same_recordings(a: RunPredictions, b: RunPredictions,
                     pairs: list[tuple[Any, Any]]) -> None:
    """Refuse pairs that are only namesakes: trials are matched by name (session file and
    trial number), and another study's P01.h5 names other performances. The same
    recordings in another folder agree in person, gesture and start in every trial."""
    for ta, tb in pairs:
        if (ta.participant, ta.true, ta.start_sample) != \
                (tb.participant, tb.true, tb.start_sample):
            raise UserError(
                f"{a.path} and {b.path} were not tested on the same recordings: trial "
                f"{ta.number} of {ta.session} is {a.labels[ta.true]} by {ta.participant} in "
                f"one and {b.labels[tb.true]} by {tb.participant} in the other; they cannot "
                "be compared trial by trial")


ALPHA = 0.05  # a difference is said as a win only when its tests put p under this


def _significance(r: dict[str, Any]) -> str:
    """How the difference stands: "significant" (every test run says p < ALPHA), "not
    significant" (none does), or which test does and which does not."""
    over_people = r["wilcoxon_p"] is not None and r["wilcoxon_p"] < ALPHA
    over_trials = r["mcnemar_p"] < ALPHA
    if r["wilcoxon_p"] is None:
        return "significant" if over_trials else "not significant"
    if over_people and over_trials:
        return "significant"
    if over_trials:
        return "significant over trials, not over participants"
    if over_people:
        return "significant over participants, not over trials"
    return "not significant"


def sentence(r: dict[str, Any]) -> str:
    """"both beats normal by 7.9 points, p = 0.020, Wilcoxon signed-rank over 10
    participants; McNemar on 270 matched test trials p = 0.004"; a difference its tests
    do not support is said as a difference, not a win ("both is 1.5 points above normal,
    not significant: p = 0.27, ...")."""
    d = 100 * r["difference"]
    a, b = r["name_a"], r["name_b"]
    better, worse = (b, a) if d > 0 else (a, b)
    how = _significance(r)
    if abs(d) < 0.05:
        head = f"{b} and {a} are equally accurate ({100 * r['accuracy_a']:.1f}%)"
    elif how == "significant":
        head = f"{better} beats {worse} by {abs(d):.1f} points"
    else:
        head = f"{better} is {abs(d):.1f} points above {worse}, {how}:"
    if r["wilcoxon_p"] is None:
        wil = f"no Wilcoxon test (only {r['n_participants']} participant)"
    else:
        wil = (f"{_fmt_p(r['wilcoxon_p'])}, Wilcoxon signed-rank over "
               f"{r['n_participants']} participants")
    return (f"{head}{'' if head.endswith(':') else ','} {wil}; McNemar on "
            f"{r['n_matched']} matched test trials {_fmt_p(r['mcnemar_p'])}")


def compare_runs(run_a: str | os.PathLike, run_b: str | os.PathLike) -> dict[str, Any]:
    """The comparison; for few-shot runs (``--shots``) at their smallest shared K, with
    ``shots`` listing the comparison at every K both have (a run without shots pairs
    with each K of the other)."""
    a, b = load_predictions(run_a), load_predictions(run_b)
    ka, kb = a.shot_counts, b.shot_counts
    if not ka and not kb:
        return compare_predictions(a, b)
    ks = sorted(set(ka) & set(kb)) if ka and kb else (ka or kb)
    if not ks:
        raise UserError(f"{run_a} (K {ka}) and {run_b} (K {kb}) share no shot count")
    per_k = [(k, compare_predictions(a.at_shots(k), b.at_shots(k))) for k in ks]
    result = dict(per_k[0][1])
    result["shots"] = [{"k": k, **{key: r[key] for key in SHOT_FIELDS}} for k, r in per_k]
    return result


SHOT_FIELDS = ("accuracy_a", "accuracy_b", "difference", "n_matched", "wilcoxon_p",
               "mcnemar_p", "sentence")
