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

``adapt`` meets the person with their own statistics: a run trained with ``--adapt``
(train's default model, extra-trees adapted per person and surface) read every test
person's features standardised by that person's own; as trained, the check can only use
the training people's pooled statistics, which cost the check 4-5 points of ROC AUC on
the development set's people (docs/trial-check.md). So after each block the collection
hands the check all the person's trials so far on this surface (whole blocks: every
gesture about as often) and the check calibrates on them (``WindowModel.calibrate``, the
one standardisation); ``qc`` hands it a whole session per person and surface.
"""

from __future__ import annotations

import os
import re
from collections import Counter
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

Trial = tuple[np.ndarray, np.ndarray, str]  # a trial's raw counts, baseline, gesture


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


def balanced(gestures: Sequence[str], n_labels: int) -> bool:
    """True when trials of these gestures are a sample to take a person's statistics
    from: no gesture more than a third of them (half of 4 gestures, all of 2), the share
    live inference's RunningCalibration holds its touches to; statistics of one gesture
    repeated would standardise that gesture away."""
    if len(gestures) < 2:
        return False
    alike = max(1 / 3, 2 / max(1, n_labels))
    return max(Counter(gestures).values()) <= alike * len(gestures) + 1e-9


class ModelTrialCheck:
    """A run's model judging whether each trial looks like its prompted gesture
    (``adapt``: meet each person with their own statistics when the run was trained
    with ``--adapt``; False: always as trained)."""

    def __init__(self, path: str | os.PathLike, top_k: int = DEFAULT_TOP_K,
                 threshold: float = DEFAULT_THRESHOLD, participant: str | None = None,
                 adapt: bool = True) -> None:
        if int(top_k) < 0:
            raise UserError(f"--qc-top-k {top_k}: give 0 (off) or more")
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
        # a run trained with --adapt meets each person with their own statistics
        self._adapt_asked = bool(adapt)
        self.adapts = bool(adapt) and self.model.adapts_as_they_touch \
            and self.model.can_calibrate
        self.adapted_on = 0  # trials of the person whose statistics it reads them with
        self._own: np.ndarray | None = None  # the samples it adapted to
        # each trial's samples by id of its raw counts (kept, so the id is not reused): a
        # collection hands the same trials again after every block
        self._memo: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def fresh(self) -> ModelTrialCheck:
        """The same check as loaded, before it met anyone: the console personalises this
        copy while the check in use goes on scoring (protocol/background_check.py)."""
        return ModelTrialCheck(self.path, self.top_k, self.threshold, self.participant,
                               self._adapt_asked)

    @property
    def out_of_fold(self) -> bool:
        """True when the fold in use never saw ``participant`` (a LOPO run's own person)."""
        return bool(self.participant) and self.participant in (
            self.model.record.get("test_participants") or [])

    def describe(self) -> dict[str, Any]:
        d = self.model.describe()
        own = f"+{self.personalised_on} own trials" if self.personalised_on else ""
        if self.adapted_on:
            own += f" (adapted to {self.adapted_on} own trials)"
        return {"model": f"{self.model.run.name}/{d['fold']}{own}", "run": d["run"],
                "family": d["model"], "fold": d["fold"],
                "version": str(self.model.record.get("version", "")),
                "top_k": self.top_k, "threshold": self.threshold,
                "out_of_fold": self.out_of_fold, "personalised_on": self.personalised_on,
                "adapts": self.adapts, "adapted_on": self.adapted_on,
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
        if self._own is not None:  # adapted before: their statistics, not the shots'
            self.model.calibrate_samples(self._own, f"{self.adapted_on} own trials")
        return len(own)

    def adapt(self, layout: Layout, trials: Sequence[Trial],
              rate_hz: float | Sequence[float]) -> int:
        """Read the person's trials with their own statistics, taken from ``trials``
        (``(raw, baseline, gesture)``; labels only to see that the sample is balanced,
        ``rate_hz`` theirs or one per trial), as ``--adapt`` met each test person in
        training. Returns the number of trials it now rests on; 0 (and the check as it
        was) for a run trained without ``--adapt``, or trials too few or too alike."""
        if not self.adapts:
            return 0
        rates = np.broadcast_to(np.asarray(rate_hz, dtype=np.float64), (len(trials),))
        own = [(r, b, g, float(h)) for (r, b, g), h in zip(trials, rates) if len(r) >= 2]
        if not balanced([g for *_, g, _ in own], len(self.model.labels)):
            return 0
        self._own = np.concatenate([self._samples_of(layout, r, b, h) for r, b, _, h in own])
        self.model.calibrate_samples(self._own, f"{len(own)} own trials")
        self.adapted_on = len(own)
        return len(own)

    def _samples_of(self, layout: Layout, raw: np.ndarray, baseline: np.ndarray,
                    rate: float) -> np.ndarray:
        """One trial's samples, computed once per trial (``_memo``)."""
        got = self._memo.get(id(raw))
        if got is None or got[0] is not raw:
            window = self.model.decode(layout, np.asarray(raw), np.asarray(baseline))
            got = (raw, self.model.samples(layout, [window], rate))
            self._memo[id(raw)] = got
        return got[1]

    def as_trained(self) -> None:
        """Forget the person: the run's fold model with the training people's
        statistics (``qc`` moving to the next person on a shared model)."""
        if self.personalised_on:
            self.model.forget_personalisation()
        else:
            self.model.uncalibrate()
        self._own, self.adapted_on, self.personalised_on = None, 0, 0
        self._memo.clear()


class RunChecks:
    """One :class:`ModelTrialCheck` per participant over one run (``qc``): each person is
    checked by the fold that never saw them when the run has one (out of fold), else by
    the run's model (the first fold, or the exported one). A run trained with
    ``--adapt`` meets each person with their statistics over all the trials given to
    :meth:`meet` (``adapt`` False: as trained)."""

    def __init__(self, path: str | os.PathLike, top_k: int = DEFAULT_TOP_K,
                 threshold: float = DEFAULT_THRESHOLD, adapt: bool = True) -> None:
        self.path, self.top_k, self.threshold = Path(path), top_k, threshold
        self.adapt = adapt
        self._by: dict[str, ModelTrialCheck] = {}
        self.default = self.for_participant(None)
        self.known = self.default.known

    def for_participant(self, participant: str | None) -> ModelTrialCheck:
        key = participant or ""
        if key not in self._by:
            check = ModelTrialCheck(self.path, self.top_k, self.threshold, participant,
                                    self.adapt)
            # a fold that saw them is no better than the run's own model: share it
            self._by[key] = check if (check.out_of_fold or not self._by) else self._by[""]
        return self._by[key]

    def group(self, participant: str, condition: str) -> tuple[str, str]:
        """The sessions whose trials one person's statistics are taken over: theirs, on
        the same surface (``condition``) for a run adapted per person and surface."""
        per_surface = self.default.model.config.adapt == "person-condition"
        return participant, condition if per_surface else ""

    def meet(self, participant: str, layout: Layout, trials: Sequence[Trial],
             rates: Sequence[float]) -> ModelTrialCheck:
        """The check for ``participant``, adapted to their ``trials`` (all of one
        :meth:`group`, unlabelled but for the balance guard; as trained when it does not
        adapt or they are too few or too alike)."""
        check = self.for_participant(participant)
        check.as_trained()  # a check shared between people forgets the last one
        check.adapt(layout, trials, rates)
        return check
