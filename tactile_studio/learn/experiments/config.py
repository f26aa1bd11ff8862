"""A training run's settings (``ExperimentConfig``): what ``train`` is asked, what a run
folder's ``config.json`` records and every reader of a run takes back.

Its own module so that the run folder's integrity check (``run_shapes``) can hold a
stranger's ``config.json`` to the types declared here without importing the training.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, TypeVar

from tactile_studio.errors import UserError
from tactile_studio.learn.choices import GRIDS, SHOTS_BY
from tactile_studio.learn.data.augment import parse_kinds
from tactile_studio.learn.data.splits import EVALUATIONS
from tactile_studio.learn.data.windowing import AGGREGATES
from tactile_studio.learn.learners.baselines import BASELINES
from tactile_studio.learn.learners.fused import (
    ADAPT_OPTION,
    display_name,
    forest_adapts,
    rf_weight,
)
from tactile_studio.learn.learners.generalise import (
    ADAPT_AUTO,
    ADAPT_CHOICES,
    VAL_BY,
    resolve_adapt,
)

# Config fields that change results (a resumed run must match on these).
RESULT_KEYS = ("data", "model", "channels", "grid", "evaluation", "rounds", "preset", "epochs",
               "overrides", "seed", "folds", "heldout_fraction", "val_fraction", "split",
               "window_s", "window_overlap", "aggregate", "augment", "augment_copies",
               "participant_norm", "balance", "val_by", "adapt", "shots", "shots_by")
# settings renamed since run folders were first written: a run's config.json (and its
# metrics.json header) is read under today's names, so older runs keep loading
RENAMED = {"protocol": "evaluation"}
V = TypeVar("V")


def upgraded(d: dict[str, V]) -> dict[str, V]:
    """``d`` with each renamed setting under its current name (a current name wins)."""
    out = {RENAMED.get(k, k): v for k, v in d.items() if k not in RENAMED}
    for old, new in RENAMED.items():
        if old in d and new not in out:
            out[new] = d[old]
    return out


# what ``auto`` means for a network (rf, knn and fused models always join): measured on
# the simulator, docs/learning/figures.md "Few-shot personalisation, measured"
NETWORK_SHOTS_BY = "fine-tune"


@dataclass
class ExperimentConfig:
    data: list[str]
    model: str
    channels: str | None = None          # normal | shear | both; None = all the data has
    grid: str = "physical"               # physical | virtual
    evaluation: str = "lopo"             # all-inclusive | lopo | group-kfold
    rounds: int = 1
    preset: str = "full"                 # full | tiny
    epochs: int | None = None            # overrides the model's max_epochs
    overrides: dict[str, Any] = field(default_factory=dict)  # training + model options
    seed: int = 0
    folds: int = 10                      # k of group-kfold
    heldout_fraction: float = 0.1        # group-kfold held-out participants
    val_fraction: float = 0.15           # validation share of training participants' trials
    split: tuple[float, float, float] = (0.7, 0.2, 0.1)  # all-inclusive train/val/test
    window_s: float | None = None        # long trials -> windows this long (None: protocol's)
    window_overlap: float = 0.5          # share of a window overlapping the next
    aggregate: str = "mean"              # trial prediction from windows: mean | vote
    augment: str = ""                    # flip,rotate,shift,warp,scale | all ("" none)
    augment_copies: int = 1              # augmented copies of every training window
    participant_norm: bool = False       # scale each participant to a typical person
    balance: bool = False                # repeat rarer classes' training samples
    val_by: str = "trial"                # validation: trials | whole training participants
    # none | person | person-condition: each test person's own statistics; auto: person
    # for a network under lopo / group-kfold (train's default), resolved before a run
    adapt: str = "none"
    # few-shot personalisation: each held-out fold once per K, with K labelled
    # performances per gesture of the test person in the training (() = off)
    shots: tuple[int, ...] = ()
    # join: the shots join the training (one training per K); fine-tune: the fold is
    # trained once without them and a copy's output layers fine-tuned per K (networks);
    # auto: NETWORK_SHOTS_BY for a network, join for rf / knn / fused (resolved())
    shots_by: str = "auto"
    device: str = "auto"
    threads: int | None = None           # CPU threads (None: experiment.TRAIN_THREADS, one)
    cache_dir: str | None = None
    use_cache: bool = True
    # leave out trials the collection flagged (signal or model checks; issue 46)
    exclude_flagged: bool = False

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["data"] = [str(Path(p).resolve()) for p in self.data]
        d["split"] = list(self.split)
        d["shots"] = list(self.shots)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ExperimentConfig:
        known = {k: v for k, v in upgraded(d).items() if k in cls.__dataclass_fields__}
        if "split" in known:
            known["split"] = tuple(known["split"])
        if "shots" in known:
            known["shots"] = tuple(int(k) for k in known["shots"] or ())
        return cls(**known)

    @property
    def forest(self) -> bool:
        """rf / knn, or a network fused with rf: features, not batch norm, adapt."""
        return self.model in BASELINES or rf_weight(self.overrides) > 0

    @property
    def can_adapt(self) -> bool:
        """False for a forest trained on augmented windows: they carry no person's
        statistics to standardise its features by. A network fused with rf can, when
        its forest stays as trained (``rf_adapt=0``): only the network adapts then."""
        if not (self.forest and self.augment):
            return True
        return self.model not in BASELINES and not forest_adapts(self.overrides)

    def resolved(self) -> ExperimentConfig:
        """This config with ``adapt="auto"`` (generalise.resolve_adapt) and
        ``shots_by="auto"`` made concrete for its model and evaluation; what a run folder
        records and every fold reads."""
        overrides = self.overrides
        if (self.adapt == ADAPT_AUTO and self.evaluation != "all-inclusive"
                and self.model not in BASELINES and self.forest
                and ADAPT_OPTION not in overrides):
            # auto adapts the network, and keeps the fused forest as rf alone is kept
            # (recorded, so the run reads the same when it is resumed or deployed)
            overrides = {**overrides, ADAPT_OPTION: 0}
        adapt = resolve_adapt(self.adapt, self.evaluation,
                              replace(self, overrides=overrides).can_adapt,
                              network=self.model not in BASELINES, model=self.model)
        shots_by = self.shots_by
        if shots_by == "auto":  # join without shots: what a run before the setting did
            shots_by = NETWORK_SHOTS_BY if self.shots and not self.forest else "join"
        if (adapt, shots_by, overrides) == (self.adapt, self.shots_by, self.overrides):
            return self
        return replace(self, adapt=adapt, shots_by=shots_by, overrides=overrides)

    def validate(self) -> None:
        if self.evaluation not in EVALUATIONS:
            raise UserError(f"unknown evaluation {self.evaluation!r} "
                            f"(available: {', '.join(EVALUATIONS)})")
        if self.grid not in GRIDS:
            raise UserError(f"unknown grid {self.grid!r} (available: {', '.join(GRIDS)})")
        if self.rounds < 1:
            raise UserError(f"--rounds must be at least 1, got {self.rounds}")
        if self.threads is not None and self.threads < 1:
            raise UserError(f"--threads must be at least 1, got {self.threads}")
        if self.epochs is not None and self.epochs < 1:
            raise UserError(f"--epochs must be at least 1, got {self.epochs}")
        if not 0 < self.val_fraction < 1 or not 0 < self.heldout_fraction < 1:
            raise UserError("validation and held-out fractions must be between 0 and 1")
        if self.aggregate not in AGGREGATES:
            raise UserError(f"unknown aggregate {self.aggregate!r} "
                            f"(available: {', '.join(AGGREGATES)})")
        if self.window_s is not None and self.window_s <= 0:
            raise UserError(f"--window must be positive, got {self.window_s}")
        if not 0 <= self.window_overlap < 1:
            raise UserError(f"window overlap must be in [0, 1), got {self.window_overlap}")
        parse_kinds(self.augment)
        if self.augment_copies < 0:
            raise UserError(f"augment_copies must be 0 or more, got {self.augment_copies}")
        if self.val_by not in VAL_BY:
            raise UserError(f"unknown validation split {self.val_by!r} "
                            f"(available: {', '.join(VAL_BY)})")
        if self.adapt not in ADAPT_CHOICES:
            raise UserError(f"unknown adaptation {self.adapt!r} "
                            f"(available: {', '.join(ADAPT_CHOICES)})")
        resolved = self.resolved()
        adapt = resolved.adapt
        if adapt != "none" and self.evaluation == "all-inclusive":
            raise UserError(f"--adapt {adapt} meets each test person with their own "
                            "session; "
                            "use it with an evaluation that holds whole people out (lopo, "
                            "group-kfold), not all-inclusive")
        if adapt != "none" and not resolved.can_adapt:
            raise UserError(f"--adapt {adapt} standardises {self.model}'s features per "
                            "person; "
                            "it does not combine with --augment (augmented windows have no "
                            "person's statistics of their own)"
                            + ("; --set rf_adapt=0 adapts its network alone"
                               if self.model not in BASELINES else ""))
        if len(self.split) != 3 or min(self.split) <= 0:
            raise UserError("the all-inclusive split needs three positive fractions")
        if self.shots:
            if self.evaluation == "all-inclusive":
                raise UserError("--shots gives a held-out person's labelled performances to "
                                "the training; use it with lopo or group-kfold, not "
                                "all-inclusive")
            if min(self.shots) < 0 or len(set(self.shots)) != len(self.shots):
                raise UserError(f"--shots takes distinct counts of 0 or more, got "
                                f"{','.join(map(str, self.shots))}")
        if self.shots_by not in SHOTS_BY:
            raise UserError(f"unknown --shots-by {self.shots_by!r} "
                            f"(available: {', '.join(SHOTS_BY)})")
        if self.shots_by == "fine-tune" and self.forest:
            name = display_name(self.model, self.overrides)
            raise UserError(f"{name} has no fine-tuning: its shots join the training "
                            "(--shots-by join)")
