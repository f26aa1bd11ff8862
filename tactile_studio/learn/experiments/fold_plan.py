"""What one fold of an experiment is trained or fine-tuned on: one object for the three
fold steps (train, fine-tune, record) instead of a dozen positional arguments that the
training loop, the sweep's workers and the fine-tuning path had to keep in step."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tactile_studio.learn.data.dataset import TrialDataset
from tactile_studio.learn.data.splits import Fold
from tactile_studio.learn.learners.contract import Learner
from tactile_studio.learn.learners.generalise import Moments

# augmented copies of a fold's training windows: (training trials, seed) -> (x, owners)
Augmenter = Callable[[np.ndarray, int], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class FoldPlan:
    """One fold (``fold``, the ``k``-th of round ``round_``, trained from ``seed``) and
    the run's prepared inputs: the learner, the dataset, its samples ``x`` and each
    sample's trial (``owner``). ``people``: each sample's adaptation group under
    ``--adapt person`` (None otherwise); ``extra``, ``balance`` and ``moments`` (the
    groups' moments a forest is adapted with) only change training."""

    learner: Learner
    ds: TrialDataset
    x: np.ndarray
    owner: np.ndarray
    fold: Fold
    round_: int
    k: int
    seed: int
    people: np.ndarray | None = None
    extra: Augmenter | None = None
    balance: bool = False
    moments: Moments | None = None
