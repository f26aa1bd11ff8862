"""Few-shot personalisation of a finished run's fold model with a new person's labelled
touches: live inference's form of ``train --shots K`` (splits.with_shots).

Offline, K labelled performances per gesture of the held-out person join the fold's
training. Live, the experimenter prompts the person for each gesture K times and each
prompt gives one labelled window of the model's window length (touch_prompts.py);
:func:`personalise` then

* rf / knn: refits the fold's model on its training windows (the run's data, read
  again through the dataset cache, exactly the fold's ``train`` trials) plus the
  person's windows: the offline mechanism, the same learner and options;
* a network: fine-tunes its output layers on the person's windows (the rest
  frozen, batch norm as trained; learn/learners/fine_tune.py, which says why), without
  the training data. Offline, ``train --shots K --shots-by fine-tune`` uses the same
  fine-tuning (``--shots-by join`` joins the shots to the training instead).
* a network fused with rf (``--set rf_weight=W``): both at once, the forest refit as
  rf is, the network's output layers fine-tuned, fused again with the same W.

With two or more rounds of prompts (K >= 2) the result carries a measured
:class:`HeldOutCheck`: each round's touches predicted by the model personalised with the
other rounds', beside the run's model as trained on the same touches. With K = 1 no
touch is left over to check on, and nothing is measured. ``progress`` and ``cancel``
are the usual long-job pair (the live panel's dialog runs this off the GUI thread).

The result is used by ``WindowModel.personalise`` until ``forget_personalisation``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.learners.fine_tune import fine_tune_head
from tactile_studio.learn.learners.fused import FusedFitted, person_columns
from tactile_studio.sensor.layout import Layout


@dataclass(frozen=True)
class LabelledTouches:
    """One person's labelled touches a model is personalised with: decoded windows
    (C, N, R, X) recorded on ``layout`` at ``rate`` Hz, each labelled with one of the
    run's gesture names; ``rounds``: the prompt round of each window (None: one round,
    nothing to hold out)."""

    layout: Layout
    windows: Sequence[np.ndarray]
    gestures: Sequence[str]
    rate: float
    rounds: Sequence[int] | None = None


@dataclass(frozen=True)
class _Prepared:
    """The touches as model inputs: the samples ``x``, each sample's window (``owner``),
    each window's class (``labels``) and, for a forest to refit, the fold's training
    samples and labels (else None)."""

    x: np.ndarray
    owner: np.ndarray
    labels: np.ndarray
    training: Any


@dataclass
class HeldOutCheck:
    """The person's own prompted touches, each predicted by a model that did not see it:
    one round of prompts left out at a time (``rounds`` >= 2, so K >= 2), the model
    personalised with the other rounds' touches; and the run's model as trained on the
    same touches. Accuracy per touch (one window each)."""

    before: float | None  # the run's model as trained (None: it has no view as trained)
    after: float          # personalised without the touch's own round
    touches: int          # touches tested
    rounds: int           # rounds left out in turn


@dataclass
class Personalised:
    fitted: Any                    # the refitted / fine-tuned model (predict_proba)
    norm: dict[str, Any]           # its input normalisation
    reference: np.ndarray | None   # the person's feature statistics (rf/knn --adapt runs)
    how: str                       # "refit" (rf/knn), "fine-tuned" (a network's head) or
                                   # "refit and fine-tuned" (a fused model: both parts)
    windows: int                   # labelled windows it rests on
    per_gesture: int               # the fewest labelled windows of a gesture (K)
    check: HeldOutCheck | None = None  # measured on their touches when K >= 2


def personalise(model: WindowModel, touches: LabelledTouches, seed: int = 0,
                dataset: Any = None, progress: ProgressFn = no_progress,
                cancel: CancelToken | None = None,
                calibration: Sequence[np.ndarray] | None = None) -> Personalised:
    """``model``'s fold model personalised with one person's ``touches``. ``dataset``:
    the run's TrialDataset when the caller has it (else read from the run's data paths).
    With two or more ``touches.rounds``, the result carries a
    :class:`HeldOutCheck` (one more fit per round; :func:`held_out_check` measures it
    apart). Always starts from the run's own fold model (a second personalisation
    replaces the first). ``calibration``: decoded windows of the person (unlabelled, e.g.
    their whole session) whose statistics standardise their features in a run trained
    with ``--adapt``, as ``train --shots`` standardises a held-out person by all their
    windows; without it, by the labelled windows' own statistics."""
    cancel = cancel or CancelToken()
    prepared = _inputs(model, touches, dataset, progress, cancel)
    x_p, owner, y_win, training = prepared.x, prepared.owner, prepared.labels, prepared.training
    x_cal = None if calibration is None else model._samples(
        touches.layout, list(calibration), touches.rate)[0]
    per_gesture = int(min(np.bincount(y_win, minlength=len(model.labels))[np.unique(y_win)]))
    folds = _folds(touches.rounds)
    fits = 1 + len(folds)

    def part(i: int) -> ProgressFn:  # fit i of ``fits``, its messages saying which
        what = "personalising" if i == 0 else f"held-out check {i} of {len(folds)}"
        return lambda f, msg="": progress((i + f) / fits, f"{what}: {msg}" if msg else what)

    fitted, norm, reference, how = _fit(model, x_p, y_win[owner], training, seed,
                                        part(0), cancel, x_cal)
    check = None
    if folds:
        check = _held_out_check(model, prepared, np.asarray(touches.rounds), folds, seed,
                                part, cancel)
    cancel.check()  # cancelled while the last step ran: nothing changes
    progress(1.0, "personalised")
    return Personalised(fitted, norm, reference, how, len(touches.windows), per_gesture,
                        check)


def held_out_check(model: WindowModel, touches: LabelledTouches, seed: int = 0,
                   dataset: Any = None, progress: ProgressFn = no_progress,
                   cancel: CancelToken | None = None) -> HeldOutCheck | None:
    """The :class:`HeldOutCheck` of personalising with these windows (None with fewer
    than two rounds: nothing to test on), measured apart from :func:`personalise` so a
    caller can use the personalised model while it runs."""
    cancel = cancel or CancelToken()
    folds = _folds(touches.rounds)
    if not folds:
        return None
    prepared = _inputs(model, touches, dataset, progress, cancel)

    def part(i: int) -> ProgressFn:
        what = f"held-out check {i} of {len(folds)}"
        return lambda f, msg="": progress((i - 1 + f) / len(folds),
                                          f"{what}: {msg}" if msg else what)

    check = _held_out_check(model, prepared, np.asarray(touches.rounds), folds, seed, part,
                            cancel)
    cancel.check()
    progress(1.0, "measured")
    return check


def _folds(rounds: Sequence[int] | None) -> list[int]:
    """The rounds to leave out in turn: none unless there are two or more."""
    return sorted(set(rounds)) if rounds is not None and len(set(rounds)) >= 2 else []


def _inputs(model: WindowModel, touches: LabelledTouches, dataset: Any, progress: ProgressFn,
            cancel: CancelToken) -> _Prepared:
    """``touches`` as the model's inputs; one-line refusals."""
    windows, gestures = touches.windows, touches.gestures
    if len(windows) != len(gestures) or not len(windows):
        raise UserError("personalisation needs labelled windows: none were recorded")
    unknown = sorted(set(gestures) - set(model.labels))
    if unknown:
        raise UserError(f"{model.run}: the run has no gesture {', '.join(unknown)}")
    y_win = np.array([model.labels.index(g) for g in gestures], dtype=np.int64)
    x_p, owner = model._samples(touches.layout, list(windows), touches.rate)
    training = None
    if model.learner.kind != "torch":  # the forest is refit with the fold's training
        progress(0.0, "reading the run's training windows…")
        training = fold_training_samples(model, dataset)
        cancel.check()
    return _Prepared(x_p, owner, y_win, training)


def _fit(model: WindowModel, x_p: np.ndarray, y_p: np.ndarray,
         training: tuple[np.ndarray, np.ndarray] | None, seed: int, progress: ProgressFn,
         cancel: CancelToken, x_cal: np.ndarray | None = None
         ) -> tuple[Any, dict[str, Any], np.ndarray | None, str]:
    """(fitted, norm, reference, how): the run's fold model retrained with the person's
    samples ``x_p`` labelled ``y_p``: rf/knn refit on the fold's training samples plus
    theirs; a network's output layers fine-tuned on theirs; a fused model both, fused
    again with the run's weight."""
    learner, info = model.learner, model.info
    reference = None
    if model.reads_person_features:  # the person's features standardised by their own
        reference = person_columns(learner, x_p if x_cal is None else x_cal)
        x_p = learner.adapt_inputs(x_p, np.zeros(len(x_p)), reference)
    if learner.kind == "baseline":
        assert training is not None
        x_all = np.concatenate([training[0], x_p])
        y_all = np.concatenate([training[1], y_p])
        stats = learner.norm_stats(x_all)
        progress(0.1, f"refitting {model.config.model} on its training windows and theirs…")
        fitted, _, _ = learner.fit(info, (learner.apply_norm(x_all, stats), y_all),
                                   (x_all[:0], y_all[:0]), seed, cancel, None, norm=stats)
        return fitted, stats, reference, "refit"
    base, norm = model.run_trained, model.run_norm
    xn = learner.apply_norm(x_p, norm)
    if learner.kind == "torch":
        return (fine_tune_head(base, xn, y_p, len(model.labels), seed, progress=progress,
                               cancel=cancel), norm, None, "fine-tuned")
    if learner.kind != "fused":
        raise UserError(f"{model.run}: {model.config.model} cannot be personalised")
    assert training is not None
    views, features = learner.split(xn, info)
    progress(0.05, "refitting its forest on its training windows and theirs…")
    forest, _, _ = learner.forest.fit(
        info, (np.concatenate([learner.split(training[0], info)[1], features]),
               np.concatenate([training[1], y_p])), (features[:0], y_p[:0]), seed, cancel,
        None)
    network = fine_tune_head(base.network, views, y_p, len(model.labels), seed,
                             progress=lambda f, msg="": progress(0.2 + 0.8 * f, msg),
                             cancel=cancel)
    fused = FusedFitted(network, forest, base.weight, learner, info)
    return fused, norm, reference, "refit and fine-tuned"


def predict_personalised(model: WindowModel, fitted: Any, norm: dict[str, Any],
                         reference: np.ndarray | None, x: np.ndarray, owner: np.ndarray,
                         n: int) -> np.ndarray:
    """Probabilities (n, classes) of samples ``x`` of ``n`` windows (``owner``) by
    ``fitted``, as ``WindowModel.predict_windows`` reads them once it uses that model
    (without changing the model live inference is predicting with)."""
    learner = model.learner
    if reference is not None and model.reads_person_features:
        x = learner.adapt_inputs(x, np.zeros(len(x)), reference)
    probs = np.zeros((n, len(model.labels)))
    np.add.at(probs, owner, fitted.predict_proba(learner.apply_norm(x, norm)))
    return probs / np.maximum(np.bincount(owner, minlength=n)[:, None], 1)


def _held_out_check(model: WindowModel, prepared: _Prepared, rounds: np.ndarray,
                    folds: list[int], seed: int, part: Any, cancel: CancelToken
                    ) -> HeldOutCheck:
    """Each round's touches predicted by the model personalised with the other rounds'
    touches (a round none of whose touches is left to learn from is not tested), and by
    the run's model as trained."""
    x_p, owner, y_win, training = prepared.x, prepared.owner, prepared.labels, prepared.training
    hits_after, tested = [], []
    for i, r in enumerate(folds, start=1):
        test_win = np.flatnonzero(rounds == r)
        learn = ~np.isin(owner, test_win)
        if not learn.any():
            continue
        step = part(i)
        step(0.0, f"round {r + 1}'s touches left out")
        fitted, norm, reference, _ = _fit(model, x_p[learn], y_win[owner[learn]], training,
                                          seed, step, cancel)
        sel = np.isin(owner, test_win)
        local = np.searchsorted(test_win, owner[sel])
        probs = predict_personalised(model, fitted, norm, reference, x_p[sel], local,
                                     len(test_win))
        hits_after.append(probs.argmax(1) == y_win[test_win])
        tested.append(test_win)
    cancel.check()
    win = np.concatenate(tested)
    before = None
    if model.has_view_as_trained:
        sel = np.isin(owner, win)
        probs = predict_personalised(model, model.run_trained, model.run_norm,
                                     model.pooled if model.reads_person_features else None,
                                     x_p[sel], np.searchsorted(np.sort(win), owner[sel]),
                                     len(win))
        before = float(np.mean(probs.argmax(1) == y_win[np.sort(win)]))
    return HeldOutCheck(before, float(np.mean(np.concatenate(hits_after))), len(win),
                        len(tested))


def fold_training_samples(model: WindowModel, dataset: Any = None
                          ) -> tuple[np.ndarray, np.ndarray]:
    """The samples (and labels) the fold model was trained on: the run's data, made into
    model inputs as the run made them, of the fold's ``train`` trials (a forest's, rf's
    or a fused model's: and its ``val`` trials, BaselineLearner.fit)."""
    from tactile_studio.learn.data.dataset import build_dataset
    from tactile_studio.learn.experiments.experiment import prepare_inputs

    cfg = model.config
    if dataset is None:
        try:
            dataset = build_dataset(cfg.data, cfg.grid, cfg.channels, cfg.cache_dir,
                                    cfg.use_cache, exclude_flagged=cfg.exclude_flagged)
        except UserError as exc:
            raise UserError(f"{model.run}: its training data cannot be read to refit "
                            f"with the person's touches ({exc})") from None
    elif cfg.channels not in (None, dataset.channels):
        dataset = dataset.select(cfg.channels)
    ds, x, owner, *_ = prepare_inputs(model.learner, dataset, cfg)
    wanted = set(model.record.get("train") or [])
    if model.learner.kind != "torch":  # a forest fits on the validation share too
        wanted |= set(model.record.get("val") or [])
    idx = np.array([i for i, u in enumerate(ds.uids) if u in wanted], dtype=np.int64)
    if len(idx) < len(wanted):
        raise UserError(f"{model.run}: its data changed since training ({len(wanted) - len(idx)}"
                        f" of the fold's {len(wanted)} training trials are gone from "
                        f"{', '.join(map(str, cfg.data))})")
    mask = np.isin(owner, idx)
    return x[mask], ds.labels[owner[mask]]
