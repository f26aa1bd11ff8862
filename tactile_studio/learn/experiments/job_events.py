"""The events a training or sweep job sends to whoever watches it (the GUI panels, tests):
one small dataclass per kind, so a field is spelled once, here, and a typo is an error at
the sender instead of a silent ``KeyError`` (or a missing row) in a window.

The dataclasses themselves cross the multiprocessing queue (they are plain, module-level
and picklable); :func:`to_wire` / :func:`from_wire` turn one into a plain dict with a
``"type"`` and back, for anything that has to store or send JSON.

A job's last event is one of :data:`FINAL` (:class:`Done`, :class:`Cancelled`,
:class:`Failed`); a worker that dies without one is reported as a :class:`Failed`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any, ClassVar


@dataclass(frozen=True)
class Progress:
    """How far the job is (0..1) and what it is doing, in words."""

    type: ClassVar[str] = "progress"
    fraction: float
    message: str = ""


@dataclass(frozen=True)
class Epoch:
    """One training epoch of one fold finished (training only). ``val_acc`` is NaN when
    the fold has no validation split; ``extra`` holds what a learner adds beyond these."""

    type: ClassVar[str] = "epoch"
    round: int
    fold: int
    n_folds: int
    fold_name: str
    epoch: int
    train_loss: float | None = None
    train_acc: float | None = None
    val_loss: float | None = None
    val_acc: float | None = None
    seconds: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, round_: int, fold: int, n_folds: int, fold_name: str,
           record: dict[str, Any]) -> Epoch:
        """From a learner's epoch record (numbers made plain floats to cross processes)."""
        known = {f.name for f in fields(cls)} - {"round", "fold", "n_folds", "fold_name",
                                                 "extra"}
        plain = {k: (float(v) if isinstance(v, (int, float)) and not isinstance(v, bool)
                     else v) for k, v in record.items()}
        return cls(round=int(round_), fold=int(fold), n_folds=int(n_folds),
                   fold_name=str(fold_name), epoch=int(record.get("epoch", 0)),
                   **{k: plain[k] for k in known - {"epoch"} if k in plain},
                   extra={k: v for k, v in plain.items() if k not in known})

    @property
    def accuracy(self) -> float:
        """The curve's point: validation accuracy, else training accuracy (else 0)."""
        acc = self.val_acc
        if acc is None or (isinstance(acc, float) and math.isnan(acc)):
            acc = self.train_acc
        return float(acc or 0.0)


@dataclass(frozen=True)
class Fold:
    """One fold finished (training only); ``cut``: its trials were cut into windows,
    ``resumed``: it was kept from an earlier run of the same folder."""

    type: ClassVar[str] = "fold"
    round: int
    fold: int
    n_folds: int
    fold_name: str
    accuracy: float
    trial_accuracy: float
    cut: bool = False
    resumed: bool = False


@dataclass(frozen=True)
class Plan:
    """A sweep's tasks are known: ``total`` of them, ``done`` kept from before."""

    type: ClassVar[str] = "plan"
    total: int
    done: int


@dataclass(frozen=True)
class Task:
    """One sweep task (a fold of a model on a channel set) finished; ``row`` is its
    (model, channel set)'s results row over the folds finished so far."""

    type: ClassVar[str] = "task"
    id: str
    model: str
    channels: str
    done: int
    total: int
    accuracy: float | None
    seconds: float
    row: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Done:
    """The job finished into ``out``. Training fills ``accuracy``, ``headline`` (both
    figures when trials were cut), ``shots`` (a few-shot curve in words, else "") and
    ``curve`` (``{"k", "accuracy", "trial_accuracy"}`` per K); a sweep fills ``rows``."""

    type: ClassVar[str] = "done"
    out: str
    accuracy: float | None = None
    headline: str = ""
    shots: str = ""
    curve: list[dict[str, Any]] = field(default_factory=list)
    rows: list[dict[str, Any]] = field(default_factory=list)


@dataclass(frozen=True)
class Cancelled:
    """The user stopped the job; finished work is kept (a sweep: ``rows`` of it)."""

    type: ClassVar[str] = "cancelled"
    message: str = ""
    rows: list[dict[str, Any]] = field(default_factory=list)


@dataclass(frozen=True)
class Failed:
    """The job stopped on a fault, told in one line."""

    type: ClassVar[str] = "error"
    message: str


JobEvent = Progress | Epoch | Fold | Plan | Task | Done | Cancelled | Failed
FINAL = (Done, Cancelled, Failed)
_KINDS: dict[str, type] = {c.type: c for c in (Progress, Epoch, Fold, Plan, Task, Done,
                                               Cancelled, Failed)}


def to_wire(event: JobEvent) -> dict[str, Any]:
    """A plain dict: the event's fields and its ``"type"``."""
    return {"type": event.type, **asdict(event)}


def from_wire(data: dict[str, Any] | JobEvent) -> JobEvent:
    """The event a :func:`to_wire` dict stands for (an event is returned as it is).
    Unknown keys are refused: a sender and a reader that disagree should fail loudly."""
    if isinstance(data, FINAL + (Progress, Epoch, Fold, Plan, Task)):
        return data
    kind = dict(data)
    cls = _KINDS.get(str(kind.pop("type", "")))
    if cls is None:
        raise ValueError(f"not a job event: {data!r}")
    event: JobEvent = cls(**kind)
    return event


def is_final(event: JobEvent) -> bool:
    """True for a job's last event (done, cancelled or failed)."""
    return isinstance(event, FINAL)
