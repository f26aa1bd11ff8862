"""Evaluations (lopo, group k-fold, all-inclusive) as lists of folds of trial indices.

Splits are made over trials, never over samples, so the windows of one trial always land
in the same part. Protocols:

* ``all-inclusive`` — one fold: 70% train / 20% validation / 10% test of the trials,
  stratified by gesture (each gesture with at least 2 trials gets a test trial, with at
  least 3 a validation trial).
* ``lopo`` — leave one participant out: one fold per participant, whose trials are the
  test set; the validation set (for early stopping) is a stratified share of the other
  participants' trials.
* ``group-kfold`` — as the CNN-Transformer paper: about 10% of the participants (at least
  one) are held out; the rest are split into ``k`` participant-disjoint folds (``k`` at
  most their number); each fold tests on its participants, trains on the others, and
  also predicts the held-out participants.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.learn.choices import EVALUATIONS


@dataclass
class Fold:
    name: str
    train: np.ndarray
    val: np.ndarray
    test: np.ndarray
    test_participants: list[str] = field(default_factory=list)
    heldout: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    shots: int | None = None  # labelled performances per gesture of the test people trained on


def with_shots(folds: list[Fold], labels: np.ndarray, shots: tuple[int, ...],
               seed: int) -> list[Fold]:
    """Few-shot personalisation: each fold once per K in ``shots``, with K labelled
    performances (trials, never windows: a trial's windows stay on one side) of every
    gesture of each test person joining the training.

    The shot trials are drawn once per fold and person: the first K of the same random
    order, so K = 2 adds one trial to K = 1's. Every K of a fold tests on the same trials
    (those never drawn for the largest K), so the curve over K compares like with like.
    A gesture with n trials gives at most n - 1 shots (one trial stays to test). A K
    larger than any test person can give for any gesture is refused: its folds would be
    a smaller K's again, reported as K."""
    top = max(shots)
    _check_shots_can_be_given(folds, labels, top)
    out = []
    for i, fold in enumerate(folds):
        rng = np.random.default_rng([seed, 0x5407, i])
        pools: list[np.ndarray] = []
        for c in np.unique(labels[fold.test]):
            members = fold.test[labels[fold.test] == c].copy()
            rng.shuffle(members)
            pools.append(members[:min(top, len(members) - 1)])
        test = np.setdiff1d(fold.test, np.concatenate(pools) if pools else fold.test[:0])
        for k in shots:
            add = np.concatenate([p[:k] for p in pools]) if pools else fold.test[:0]
            out.append(Fold(f"{fold.name} k{k}", np.union1d(fold.train, add).astype(np.int64),
                            fold.val, test.astype(np.int64), list(fold.test_participants),
                            fold.heldout, k))
    return out


def _check_shots_can_be_given(folds: list[Fold], labels: np.ndarray, top: int) -> None:
    """Refuse a K that no test person can give for any gesture (one performance stays to
    test): every fold of it would train on fewer shots than the figure it is shown as."""
    most = 0  # the most performances of one gesture one fold's test people have
    for fold in folds:
        if len(fold.test):
            most = max(most, int(np.bincount(labels[fold.test]).max()))
    if top <= max(most - 1, 0):
        return
    if most < 2:
        raise UserError(f"--shots: K = {top} asks for labelled performances of the test "
                        f"people, but none has more than {most} performance of a gesture "
                        "(one must stay to test); few-shot needs 2 or more")
    raise UserError(f"--shots: K = {top} asks for {top} labelled performances per gesture of "
                    f"each test person, but they have at most {most} performances of a "
                    f"gesture and one stays to test; use K up to {most - 1}")


def parse_shot_counts(text: str) -> tuple[int, ...]:
    """"0,1,2" -> (0, 1, 2) (sorted); "" -> () (no few-shot personalisation)."""
    text = text.replace(" ", "")
    if not text:
        return ()
    try:
        ks = tuple(int(k) for k in text.split(",") if k != "")
    except ValueError:
        raise UserError(f"shots {text!r}: not a list of counts such as 0,1,2") from None
    if not ks or min(ks) < 0 or len(set(ks)) != len(ks):
        raise UserError(f"shots {text!r}: give distinct counts of 0 or more, such as 0,1,2")
    return tuple(sorted(ks))


def stratified_parts(idx: np.ndarray, labels: np.ndarray, fractions: tuple[float, ...],
                     rng: np.random.Generator) -> list[np.ndarray]:
    """Split trial indices ``idx`` by class into parts with the given fractions.

    Part 0 takes the remainder. Parts are filled from the last: the last part gets at
    least one trial of every class with 2 or more, the one before it with 3 or more,
    and so on, so small classes still reach the test set.
    """
    parts: list[list[int]] = [[] for _ in fractions]
    carry = np.zeros(len(fractions))  # rounding left over, so the totals stay on target
    classes = np.unique(labels[idx])
    for c in classes[rng.permutation(len(classes))]:
        members = idx[labels[idx] == c].copy()
        rng.shuffle(members)
        n, pos = len(members), 0
        sizes: list[int] = []
        for j, k in enumerate(range(len(fractions) - 1, 0, -1)):
            exact = n * fractions[k] + carry[k]
            want = int(np.floor(exact + 0.5))
            if n >= j + 2:
                want = max(want, 1)
            want = max(min(want, n - 1 - sum(sizes)), 0)
            carry[k] = exact - want
            sizes.append(want)
        sizes = [n - sum(sizes)] + sizes[::-1]
        for k, size in enumerate(sizes):
            parts[k].extend(members[pos:pos + size].tolist())
            pos += size
    return [np.array(sorted(p), dtype=np.int64) for p in parts]


def all_inclusive(labels: np.ndarray, seed: int,
                  fractions: tuple[float, float, float] = (0.7, 0.2, 0.1)) -> list[Fold]:
    rng = np.random.default_rng([seed, 0xA11])
    train, val, test = stratified_parts(np.arange(len(labels)), labels, fractions, rng)
    if len(test) == 0:  # every gesture has one trial: nothing to test on (was a traceback)
        raise UserError(f"the all-inclusive split has no test trial: {len(labels)} trial(s), "
                        "one of each gesture, and a gesture needs 2 trials to reach the "
                        "test set; record more trials")
    return [Fold("all", train, val, test)]


def _check_participants(participants: np.ndarray, need: int, evaluation: str) -> list[str]:
    names = sorted(set(participants.tolist()))
    if len(names) < need:
        raise UserError(f"{evaluation} needs at least {need} participants; the data has "
                        f"{len(names)} ({', '.join(names)})")
    return names


def lopo(labels: np.ndarray, participants: np.ndarray, seed: int,
         val_fraction: float = 0.15) -> list[Fold]:
    names = _check_participants(participants, 2, "leave-one-participant-out (lopo)")
    folds = []
    for i, p in enumerate(names):
        rng = np.random.default_rng([seed, 0x1090, i])
        test = np.flatnonzero(participants == p)
        rest = np.flatnonzero(participants != p)
        train, val = stratified_parts(rest, labels, (1 - val_fraction, val_fraction), rng)
        folds.append(Fold(p, train, val, test, [p]))
    return folds


def group_kfold(labels: np.ndarray, participants: np.ndarray, seed: int, k: int = 10,
                heldout_fraction: float = 0.1, val_fraction: float = 0.15) -> list[Fold]:
    names = _check_participants(participants, 3, "group-kfold")
    if k < 2:
        raise UserError(f"group-kfold needs at least 2 folds, got {k}")
    rng = np.random.default_rng([seed, 0x6F0])
    order = [names[i] for i in rng.permutation(len(names))]
    n_held = min(max(1, int(round(len(names) * heldout_fraction))), len(names) - 2)
    held, rest = sorted(order[:n_held]), order[n_held:]
    k = min(k, len(rest))
    groups = [sorted(rest[i::k]) for i in range(k)]
    heldout = np.flatnonzero(np.isin(participants, held))
    folds = []
    for i, group in enumerate(groups):
        test = np.flatnonzero(np.isin(participants, group))
        train_pool = np.flatnonzero(~np.isin(participants, group + held))
        frng = np.random.default_rng([seed, 0x6F1, i])
        train, val = stratified_parts(train_pool, labels, (1 - val_fraction, val_fraction), frng)
        folds.append(Fold(f"fold{i + 1}", train, val, test, group, heldout))
    return folds


def make_folds(evaluation: str, labels: np.ndarray, participants: np.ndarray, seed: int,
               k: int = 10, heldout_fraction: float = 0.1, val_fraction: float = 0.15,
               fractions: tuple[float, float, float] = (0.7, 0.2, 0.1)) -> list[Fold]:
    """The folds of ``evaluation`` (one of :data:`EVALUATIONS`)."""
    if evaluation == "all-inclusive":
        return all_inclusive(labels, seed, fractions)
    if evaluation == "lopo":
        return lopo(labels, participants, seed, val_fraction)
    if evaluation == "group-kfold":
        return group_kfold(labels, participants, seed, k, heldout_fraction, val_fraction)
    raise UserError(f"unknown evaluation {evaluation!r} (available: {', '.join(EVALUATIONS)})")
