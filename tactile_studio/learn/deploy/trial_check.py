"""The model check of issue 46 over a run folder: :class:`ModelTrialCheck`.

It implements the runner's ``TrialChecker`` (tactile_studio/protocol/trial_check.py)
through :class:`~tactile_studio.learn.deploy.window_model.WindowModel` only, so it works
with whatever model family the run holds. A trial is one window: its raw counts are
decoded and scored as the run scored a trial (a long trial cut into the run's windows,
their probabilities averaged). Which fold: the one that never saw the participant (a
leave-one-participant-out run checking one of its own people, out of fold), else the
fold named by an exported model (``RUN/export/<fold>.onnx``), else the run's first fold.
``personalise`` swaps in the few-shot route (learn/deploy/personalise.py) with the
person's own labelled trials, after their first block (research decision 5).
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.experiments.runfolder import read_run
from tactile_studio.learn.learners.fold_predictions import FoldRecord
from tactile_studio.sensor.layout import Layout
from tactile_studio.storage.format.trial_checks import (
    DEFAULT_THRESHOLD,
    DEFAULT_TOP_K,
    TrialVerdict,
    verdict,
)


def run_and_fold(path: str | os.PathLike) -> tuple[Path, str | None]:
    """(run folder, fold or None) of a run folder or of a model exported from one."""
    p = Path(path)
    if p.is_dir():
        return p, None
    if p.suffix == ".onnx" and p.parent.name == "export" and (p.parent.parent / "config.json"
                                                               ).is_file():
        fold = p.name[:-len(".onnx")]
        for suffix in (".int8", ".rf"):
            fold = fold.removesuffix(suffix)
        return p.parent.parent, fold
    if not p.exists():
        raise UserError(f"{p}: no such run folder or exported model")
    raise UserError(f"{p}: not a run folder nor a model exported from one "
                    "(RUN/export/<fold>.onnx)")


def _export_name(record: FoldRecord) -> str:
    """The stem export-model gives a fold's file: ``r<round>-<fold name>``."""
    safe = re.sub(r"[^A-Za-z0-9_.-]", "_", str(record.get("name")))
    return f"r{record.get('round', 0)}-{safe}"


def _fold_of(run: Path, fold: str | None, participant: str | None) -> tuple[str | None, int]:
    """(participant, round) that make WindowModel load the wanted fold: the one that never
    saw ``participant`` (it picks that itself), else the fold named ``fold`` (through one
    of its test participants), else the first."""
    if fold is None:
        return participant, 0
    _, records = read_run(run)
    rec = next((r for r in records if fold in (r.get("name"), _export_name(r))), None)
    if rec is None:
        raise UserError(f"{run}: the run has no fold {fold}")
    if participant and participant in (rec.get("test_participants") or []):
        return participant, int(rec.get("round", 0))
    tested = rec.get("test_participants") or []
    return (tested[0] if tested else None), int(rec.get("round", 0))


class ModelTrialCheck:
    """A run's model judging whether each trial looks like its prompted gesture."""

    def __init__(self, path: str | os.PathLike, top_k: int = DEFAULT_TOP_K,
                 threshold: float = DEFAULT_THRESHOLD, participant: str | None = None) -> None:
        if int(top_k) < 1:
            raise UserError(f"--qc-top-k {top_k}: give 1 or more")
        if not 0.0 <= float(threshold) <= 1.0:
            raise UserError(f"--qc-threshold {threshold}: give a probability from 0 to 1")
        self.path = Path(path)
        self.top_k, self.threshold = int(top_k), float(threshold)
        self.participant = participant
        run, fold = run_and_fold(path)
        self.model = WindowModel(run, *_fold_of(run, fold, participant))
        if self.model.needs_calibration:
            raise UserError(f"{run}: trained with --adapt {self.model.config.adapt} and no "
                            "view as trained; it cannot check a new person's trials")
        self.known: frozenset[str] = frozenset(self.model.labels)
        self.personalised_on = 0  # labelled trials of the person it was personalised with

    @property
    def out_of_fold(self) -> bool:
        """True when the fold in use never saw ``participant`` (a LOPO run's own person)."""
        return bool(self.participant) and self.participant in (
            self.model.record.get("test_participants") or [])

    def describe(self) -> dict[str, Any]:
        d = self.model.describe()
        own = f"+{self.personalised_on} own trials" if self.personalised_on else ""
        return {"model": f"{self.model.run.name}/{d['fold']}{own}", "run": d["run"],
                "family": d["model"], "fold": d["fold"],
                "version": str(self.model.record.get("version", "")),
                "top_k": self.top_k, "threshold": self.threshold,
                "out_of_fold": self.out_of_fold, "personalised_on": self.personalised_on,
                "labels": list(self.model.labels)}

    def probabilities(self, layout: Layout, raw: np.ndarray, baseline: np.ndarray,
                      rate_hz: float) -> np.ndarray:
        """The model's probabilities over its labels for one trial's raw counts."""
        frames = self.model.decode(layout, np.asarray(raw), np.asarray(baseline))
        return self.model.predict_windows(layout, [frames], float(rate_hz))[0]

    def check(self, layout: Layout, raw: np.ndarray, baseline: np.ndarray, rate_hz: float,
              prompted: str) -> TrialVerdict | None:
        if prompted not in self.known or len(raw) < 2:
            return None
        probs = self.probabilities(layout, raw, baseline, rate_hz)
        return verdict(self.model.labels, probs, prompted, self.top_k, self.threshold)

    def personalise(self, layout: Layout, trials: Sequence[tuple[np.ndarray, np.ndarray, str]],
                    rate_hz: float, seed: int = 0) -> int:
        """Fit the check to one person with their labelled trials ``(raw, baseline,
        gesture)`` (their first block): the few-shot route. Gestures the model does not
        know are left out. Returns the number of trials used."""
        from tactile_studio.learn.deploy.personalise import LabelledTouches, personalise

        own = [(r, b, g) for r, b, g in trials if g in self.known and len(r) >= 2]
        if not own:
            raise UserError("no trial of a gesture the check knows to personalise it with")
        windows = [self.model.decode(layout, np.asarray(r), np.asarray(b)) for r, b, _ in own]
        touches = LabelledTouches(layout, windows, [g for _, _, g in own], float(rate_hz))
        result = personalise(self.model, touches, seed)
        self.model.personalise(result)
        self.personalised_on = len(own)
        return len(own)


class RunChecks:
    """One :class:`ModelTrialCheck` per participant over one run (``qc``): each person is
    checked by the fold that never saw them when the run has one (out of fold), else by
    the run's model (the first fold, or the exported one)."""

    def __init__(self, path: str | os.PathLike, top_k: int = DEFAULT_TOP_K,
                 threshold: float = DEFAULT_THRESHOLD) -> None:
        self.path, self.top_k, self.threshold = Path(path), top_k, threshold
        self._by: dict[str, ModelTrialCheck] = {}
        self.default = self.for_participant(None)
        self.known = self.default.known

    def for_participant(self, participant: str | None) -> ModelTrialCheck:
        key = participant or ""
        if key not in self._by:
            check = ModelTrialCheck(self.path, self.top_k, self.threshold, participant)
            # a fold that saw them is no better than the run's own model: share it
            self._by[key] = check if (check.out_of_fold or not self._by) else self._by[""]
        return self._by[key]
