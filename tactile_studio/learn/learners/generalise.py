"""Options that help a model hold on people it has never seen (off by default, but for
``adapt``: ``auto`` in train, sweep and the panels, so every model adapts to held-out
people).

* ``augment`` — geometry-aware augmented copies of the *training* windows (see
  :mod:`tactile_studio.learn.data.augment`), ``augment_copies`` per window, made per fold
  with the fold's seed; every model gets them (rf and knn through their features).
* ``participant_norm`` — each participant's normal and shear channels divided by that
  participant's own typical peak (median over their trials of the 90th-percentile
  peak), then put back on the scale of the real recordings' typical person (6.65 kPa
  normal, 0.72 kPa shear). Uses no labels, only the person's own recordings, so it is
  allowed for a held-out person (in use it needs a few of their touches first).
* ``balance`` — training samples of rarer classes repeated until every class counts as
  many as the most common one.
* ``adapt="person"`` — each test person is met on their own terms, from their own
  unlabelled samples: a network's batch-norm statistics are re-estimated on that
  person's windows before it predicts them (AdaBN, ``train.adapt_batchnorm``); rf and
  knn (and a fused model's forest) see every person's features standardised by that
  person's own mean and spread, in training and at test alike. Like
  ``participant_norm`` it uses no labels, but it needs the person's whole session
  (all gestures, roughly evenly, as a protocol session has); live, a network adapts
  to the participant's last touches instead (``live_inference.RunningCalibration``).
  ``adapt="auto"`` (what train, sweep and the panels choose unless told): ``person`` for
  a network on held-out people (lopo, group-kfold), ``person-condition`` for extra-trees
  (issue 45: +6.2 points on the development set's real people), ``none`` for rf and knn
  (on the real recordings adapting cost rf 1.7 points while cnn3d gained 3.3), for
  all-inclusive and
  for a forest trained on augmented windows, which have no person's statistics
  (``resolve_adapt``). ``adapt="person-condition"`` does the same per
  person *and* session condition (the surface, FLAT / PILLOW): a person's touches on a
  soft pillow are spread and damped against the same person's on a flat table, and one
  pooled set of statistics would carry that difference into every gesture.
* ``val_by="participant"`` — model selection (early stopping) on whole training
  participants held out from training, never on the test participant and never on
  trials of people the model also trains on.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tactile_studio.learn.data.augment import augment_trials, parse_kinds
from tactile_studio.learn.data.splits import Fold
from tactile_studio.learn.data.touch_stats import REAL, trial_stats

VAL_BY = ("trial", "participant")
ADAPT = ("none", "person", "person-condition")
# what train, sweep and the panels choose unless told: adapt to held-out people
ADAPT_AUTO = "auto"
ADAPT_CHOICES = (ADAPT_AUTO, *ADAPT)
# how titles, summaries and the GUI name an adaptation
ADAPT_PHRASE = {"none": "as trained", "person": "adapted to each person",
                "person-condition": "adapted to each person and condition"}


def participant_normalised(ds):
    """``ds`` with every participant's channels scaled to a typical person (see doc)."""
    names = list(ds.channel_names)
    stats = [trial_stats(t, names) for t in ds.trials]
    trials = list(ds.trials)
    shear = [i for i, n in enumerate(names) if n.startswith("shear")]
    normal = [i for i, n in enumerate(names) if not n.startswith("shear")]
    for p in np.unique(ds.participants):
        idx = np.flatnonzero(ds.participants == p)
        scale = np.ones(len(names), dtype=np.float32)
        peak = float(np.median([stats[i]["peak_normal_p90"] for i in idx]))
        scale[normal] = REAL["peak_normal_p90"][0] / max(peak, 1e-3)
        if shear:
            s = float(np.median([stats[i]["peak_shear_p90"] for i in idx]))
            scale[shear] = REAL["peak_shear_p90"][0] / max(s, 1e-3)
        for i in idx:
            trials[i] = trials[i] * scale[:, None, None, None]
    return replace(ds, trials=trials)


def person_standardised(x: np.ndarray, people: np.ndarray,
                        reference: np.ndarray | None = None) -> np.ndarray:
    """Features ``x`` (N, F) with each person's rows z-scored by that person's own mean
    and standard deviation (a feature constant for a person is only centred). With
    ``reference`` (one person's calibration samples, for live use) every row is z-scored
    by the reference's statistics instead."""
    out = np.array(x, dtype=np.float32, copy=True)
    if reference is not None:
        return _standardised(out, np.asarray(reference, dtype=np.float32))
    for p in np.unique(people):
        rows = people == p
        out[rows] = _standardised(out[rows], out[rows])
    return out


Moments = dict[str, tuple[int, np.ndarray, np.ndarray]]


def group_moments(x: np.ndarray, groups: np.ndarray) -> Moments:
    """Each group's sample count, feature sums and sums of squares (float64), taken from
    the features as computed, before they are standardised per person: enough to pool
    any set of groups afterwards (``pooled_reference``)."""
    out = {}
    for g in np.unique(groups):
        rows = np.asarray(x[groups == g], dtype=np.float64)
        out[str(g)] = (len(rows), rows.sum(axis=0), np.square(rows).sum(axis=0))
    return out


def pooled_reference(moments: Moments, groups) -> np.ndarray:
    """Two feature rows whose mean and spread are those of ``groups``' samples pooled:
    ``person_standardised(x, ..., reference=this)`` reads features as a model trained on
    those people would if it had not standardised per person. rf/knn (and fused forests)
    trained with ``--adapt`` keep it as their view "as trained" (live's guard,
    live_inference.py)."""
    n = sum(moments[str(g)][0] for g in groups)
    mean = sum(moments[str(g)][1] for g in groups) / max(n, 1)
    var = sum(moments[str(g)][2] for g in groups) / max(n, 1) - np.square(mean)
    std = np.sqrt(np.maximum(var, 0.0))
    return np.stack([mean - std, mean + std]).astype(np.float32)


def _standardised(x: np.ndarray, reference: np.ndarray) -> np.ndarray:
    mean, std = reference.mean(axis=0), reference.std(axis=0)
    return (x - mean) / np.where(std > 1e-9, std, 1.0)


# auto for a forest model that adapts (issue 45): extra-trees on the touch features gained
# 6.2 points per performance on the development set's five real people adapted per
# person and surface (4 of 5 people; 3 seeds 0.605 against 0.543), and its few-shot
# gains doubled; per person alone cost the one person recorded on two surfaces.
FOREST_AUTO_ADAPT = {"et": "person-condition"}


def resolve_adapt(adapt: str, evaluation: str, can_adapt: bool = True,
                  network: bool = True, model: str = "") -> str:
    """``adapt`` made concrete: ``auto`` is ``person`` for a network (``network``: any
    model with a learned network, fused with rf or not) when the test people were never
    seen (lopo, group-kfold), else ``none``; ``none`` for rf and knn, and when the model
    cannot adapt (``can_adapt`` False: a forest on augmented windows). A fused model's
    forest then stays as trained (``ExperimentConfig.resolved`` records ``rf_adapt=0``).

    Decided on people (issue 37, the real recordings, LOPO, per performance): adapting
    gained cnn3d 3.3 points (batch-norm re-estimation) and cost rf 1.7 (standardising a
    forest's features by each person's own statistics); on the first simulator it gained
    rf up to 9 points, which did not hold on people, so the forest's default follows the
    people. Live, an adapted model predicts as trained until it has the person's touches,
    and a guard keeps it safe in free play. Extra-trees (``model`` "et") is the forest
    that adapts: ``person-condition`` (``FOREST_AUTO_ADAPT``, measured on the development
    set's real people, issue 45)."""
    if adapt != ADAPT_AUTO:
        return adapt
    if not can_adapt or evaluation == "all-inclusive":
        return "none"
    if network:
        return "person"
    return FOREST_AUTO_ADAPT.get(model, "none")


def adapt_groups(adapt: str, ds) -> np.ndarray | None:
    """Each trial's adaptation group (``ADAPT``): its participant, or its participant and
    session condition; None without adaptation."""
    if adapt == "none":
        return None
    if adapt == "person-condition":
        # "\x1f" (unit separator) cannot occur in a participant id typed by anyone
        return np.char.add(np.char.add(ds.participants.astype(str), "\x1f"),
                           ds.trial_conditions().astype(str))
    return ds.participants


def balanced_index(y: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices of ``y`` with rarer classes repeated (random picks) up to the largest."""
    counts = np.bincount(y)
    top = counts.max()
    out = [np.arange(len(y))]
    for c, n in enumerate(counts):
        if 0 < n < top:
            out.append(rng.choice(np.flatnonzero(y == c), top - n, replace=True))
    return np.concatenate(out)


def participant_val(fold: Fold, participants: np.ndarray, val_fraction: float,
                    seed: int) -> Fold:
    """The fold with its validation set made of whole training participants."""
    pool = np.concatenate([fold.train, fold.val])
    people = np.unique(participants[pool])
    if len(people) < 2:
        return fold
    rng = np.random.default_rng([seed, 0x7A1])
    n_val = min(len(people) - 1, max(1, int(round(val_fraction * len(people)))))
    chosen = set(rng.choice(people, n_val, replace=False).tolist())
    is_val = np.array([participants[i] in chosen for i in pool])
    return replace(fold, train=np.sort(pool[~is_val]), val=np.sort(pool[is_val]))


def augmenter(learner, pieces, piece_owner: np.ndarray, spec: str, copies: int):
    """A function (training trial indices, seed) -> (extra samples, their trial index),
    or None when ``spec`` asks for no augmentation."""
    kinds = parse_kinds(spec)
    if not kinds or copies < 1:
        return None

    def extra(train_trials: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
        sel = np.flatnonzero(np.isin(piece_owner, train_trials))
        rng = np.random.default_rng([seed, 0xA06])
        new, src = augment_trials([pieces.trials[i] for i in sel], list(pieces.channel_names),
                                  kinds, copies, rng)
        aug = replace(pieces, trials=new, labels=pieces.labels[sel][src],
                      participants=pieces.participants[sel][src],
                      uids=[pieces.uids[i] for i in sel[src]], rates=pieces.rates[sel][src])
        x, sample_piece = learner.samples(aug)
        return x, piece_owner[sel][src][sample_piece]

    return extra
