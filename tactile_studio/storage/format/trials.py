"""A trial as code reads and writes it: :class:`TrialRecord` and :class:`TrialStatus`.

On disk (the session journal, ``trials_json``) and in the runner's snapshot a trial stays
the flat dict of docs/file-format (index, block, gesture, key, start_sample, end_sample,
start_time, end_time, status, reason, flags, ``collected_again`` when true, plus any
columns an importer adds); code
converts at the edge with :meth:`TrialRecord.from_dict` / :meth:`TrialRecord.to_dict`
instead of indexing dicts by string. :func:`trials_done` is the one definition of
progress (the runner's snapshot, resume and the console all use it).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Any


class TrialStatus(StrEnum):
    """What became of a trial (strings, as stored in the file)."""

    OK = "ok"                # counts (flags may still say it is doubtful)
    REDONE = "redone"        # replaced by a later trial of the same gesture and block
    DISCARDED = "discarded"  # kept in the file but not used (practice, or by hand);
    # with ``collected_again`` its gesture is collected once more, so it does not count


def trial_number(index: int) -> int:
    """The number people see for the trial stored with ``index``: the file counts from 0,
    every screen and message from 1 (the console's "Trial 22" is index 21)."""
    return int(index) + 1


_FIELDS = ("index", "block", "gesture", "key", "start_sample", "end_sample", "start_time",
           "end_time", "status", "reason", "flags")
_OPTIONAL = ("check", "decision", "performed")


@dataclass(frozen=True)
class TrialRecord:
    """One trial: file rows ``start_sample..end_sample`` (end exclusive) of ``gesture``."""

    index: int
    block: int                      # 0-based; -1 for practice
    gesture: str
    key: str | None = None
    start_sample: int = 0
    end_sample: int = 0
    start_time: float = 0.0         # device time of the first frame, s
    end_time: float = 0.0
    status: TrialStatus = TrialStatus.OK
    reason: str | None = None
    flags: tuple[str, ...] = ()     # quality flags (tactile_studio.protocol.quality)
    # a discarded trial whose gesture is collected again (a later trial replaces it):
    # discarded on record, but not counted as done (resume collects it if it is not yet)
    collected_again: bool = False
    # issue 46 (storage/format/trial_checks.py), stored only when set: the model's verdict
    # (``check``), the experimenter's ``decision`` on a flagged trial (redo / keep), and
    # what a virtual participant actually ``performed`` (its mistakes)
    check: Mapping[str, Any] | None = None
    decision: str | None = None
    performed: str | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)  # importers' extra columns

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> TrialRecord:
        """From the file's form; missing optional fields take their defaults."""
        known = {k: d[k] for k in _FIELDS if k in d}
        known["index"] = int(known.get("index", 0))
        known["block"] = int(known.get("block", 0))
        known["gesture"] = str(known.get("gesture") or "")
        known["status"] = TrialStatus(known.get("status") or TrialStatus.OK)
        known["flags"] = tuple(known.get("flags") or ())
        again = bool(d.get("collected_again", False))
        optional = {k: d[k] for k in _OPTIONAL if d.get(k) is not None}
        return cls(**known, collected_again=again, **optional,
                   extra={k: v for k, v in d.items()
                          if k not in (*_FIELDS, *_OPTIONAL, "collected_again")})

    def to_dict(self) -> dict[str, Any]:
        """The file's form (plain strings and lists; the key order of the journal)."""
        out: dict[str, Any] = {k: getattr(self, k) for k in _FIELDS}
        out["status"] = self.status.value
        out["flags"] = list(self.flags)
        if self.collected_again:  # only then: the file's trials keep their columns
            out["collected_again"] = True
        for k in _OPTIONAL:
            if getattr(self, k) is not None:
                out[k] = dict(self.check or {}) if k == "check" else getattr(self, k)
        out.update(self.extra)
        return out

    def with_changes(self, **changes: Any) -> TrialRecord:
        if "status" in changes:
            changes["status"] = TrialStatus(changes["status"])
        if "flags" in changes:
            changes["flags"] = tuple(changes["flags"])
        return replace(self, **changes)

    @property
    def practice(self) -> bool:
        return self.block < 0

    @property
    def ok(self) -> bool:
        return self.status == TrialStatus.OK

    @property
    def usable(self) -> bool:
        """Goes into a dataset (and a run's trial table): ``ok`` and naming a gesture.
        Flags do not take a trial out; ``train --exclude-flagged`` does that."""
        return self.ok and bool(self.gesture)

    def uid(self, session: str) -> str:
        """The trial's id among a set of sessions (a dataset's ``uids``, a run's
        ``trials.json``): ``session`` is the file's path relative to the set's root."""
        return f"{session}#{self.index}"

    @property
    def flagged(self) -> bool:
        """An ``ok`` trial with quality flags: the experimenter may want it redone."""
        return self.ok and bool(self.flags)

    @property
    def counts(self) -> bool:
        """Counts toward progress: a real block's trial not replaced by a later one (a
        redo, or a discard whose gesture is collected again)."""
        return (not self.practice and self.status != TrialStatus.REDONE
                and not self.collected_again)


def records(trials: Iterable[Mapping[str, Any] | TrialRecord]) -> list[TrialRecord]:
    """Trials in either form as records."""
    return [t if isinstance(t, TrialRecord) else TrialRecord.from_dict(t) for t in trials]


def label_order(metadata: Iterable[Mapping[str, Any]], seen: Iterable[str],
                keep_unseen: bool = True) -> list[str]:
    """Gesture names in label order: the protocol's (each metadata's ``gestures``, names or
    ``{"name": ...}``), then any other gesture in ``seen``, sorted. ``keep_unseen=False``
    leaves out protocol gestures no trial names (a dataset's classes)."""
    order: list[str] = []
    for meta in metadata:
        for g in meta.get("gestures") or []:
            name = g.get("name", "") if isinstance(g, Mapping) else g
            if name and str(name) not in order:
                order.append(str(name))
    gestures = set(seen)
    names = order if keep_unseen else [g for g in order if g in gestures]
    return names + sorted(gestures - set(names))


def trials_done(trials: Iterable[Mapping[str, Any] | TrialRecord]) -> int:
    """Gestures done: distinct (block, gesture) with a counting trial. A discarded
    trial still counts (its gesture is not collected again) unless it is
    ``collected_again``; a redone one does not."""
    return len({(t.block, t.gesture) for t in records(trials) if t.counts})


@dataclass(frozen=True)
class CollectionProgress:
    """How far a collection got against its stored block orders (``info``)."""

    trials_done: int
    trials_total: int
    blocks_done: int    # blocks with every gesture done
    blocks_total: int

    @property
    def finished(self) -> bool:
        return self.trials_done >= self.trials_total

    def to_dict(self) -> dict[str, Any]:
        return {"trials_done": self.trials_done, "trials_total": self.trials_total,
                "blocks_done": self.blocks_done, "blocks_total": self.blocks_total,
                "finished": self.finished}


def collection_progress(block_order: list[list[str]],
                        trials: Iterable[Mapping[str, Any] | TrialRecord]) -> CollectionProgress:
    """Progress of a collection whose blocks are ``block_order`` (the metadata's), by
    :func:`trials_done`'s rule."""
    done = {(t.block, t.gesture) for t in records(trials) if t.counts}
    blocks = sum(1 for b, order in enumerate(block_order)
                 if all((b, g) in done for g in order))
    total = sum(len(order) for order in block_order)
    return CollectionProgress(len(done), total, blocks, len(block_order))
