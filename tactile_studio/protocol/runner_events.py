"""The events a :class:`~tactile_studio.protocol.trial_runner.TrialRunner` tells its
listeners (the collection console, ``qc``, the LSL marker stream): one frozen dataclass per
kind, declared here once, so a listener switches on the type and a misspelt field is an
error where the event is made.

The marker stream (docs/lsl.md) carries them as JSON; :meth:`to_record` is that plain form,
``{"kind": ..., **fields}`` in the fields' order, exactly as the runner sent dicts before
its events were typed (streams/markers.py turns it into a marker).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any, ClassVar

from tactile_studio.storage.format.trials import TrialRecord


@dataclass(frozen=True)
class _RunnerEvent:
    kind: ClassVar[str]

    def to_record(self) -> dict[str, Any]:
        """The plain form: ``kind`` then the fields (lists and dicts copied, a trial in
        the file's form)."""
        out: dict[str, Any] = {"kind": self.kind}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = (value.to_dict() if isinstance(value, TrialRecord) else
                           dict(value) if isinstance(value, dict) else
                           list(value) if isinstance(value, (list, tuple)) else value)
        return out


@dataclass(frozen=True)
class StateChanged(_RunnerEvent):
    """The runner entered ``state`` (a :class:`~tactile_studio.protocol.snapshot.State`)."""

    kind: ClassVar[str] = "state"
    state: str


@dataclass(frozen=True)
class Refused(_RunnerEvent):
    """An input was refused; ``text`` says why (the console's hint line)."""

    kind: ClassVar[str] = "hint"
    text: str


@dataclass(frozen=True)
class BlockStarted(_RunnerEvent):
    """Block ``block`` began (-1: the practice block)."""

    kind: ClassVar[str] = "block"
    block: int


@dataclass(frozen=True)
class TrialStarted(_RunnerEvent):
    """A trial of ``gesture`` (prompted by ``key``) began at stream frame ``start_frame``."""

    kind: ClassVar[str] = "trial_started"
    gesture: str
    key: str
    start_frame: int


@dataclass(frozen=True)
class CheckPersonalised(_RunnerEvent):
    """The trial check was fitted to this participant with ``trials`` trials."""

    kind: ClassVar[str] = "check_personalised"
    trials: int
    model: str


@dataclass(frozen=True)
class TrialEnded(_RunnerEvent):
    """A trial was written to the file: ``trial`` as written, its quality ``flags`` and
    their ``reason`` in words ("" when it is clean)."""

    kind: ClassVar[str] = "trial_ended"
    trial: TrialRecord
    flags: tuple[str, ...]
    reason: str


@dataclass(frozen=True)
class Beep(_RunnerEvent):
    """The end-of-trial beep sounded."""

    kind: ClassVar[str] = "beep"
    frequency_hz: float
    length_s: float


@dataclass(frozen=True)
class TrialUpdated(_RunnerEvent):
    """A written trial changed (redone, discarded): ``trial`` as it now is in the file."""

    kind: ClassVar[str] = "trial_updated"
    trial: TrialRecord


@dataclass(frozen=True)
class NoteAdded(_RunnerEvent):
    """The experimenter added a note."""

    kind: ClassVar[str] = "note"
    text: str


RunnerEvent = (StateChanged | Refused | BlockStarted | TrialStarted | CheckPersonalised
               | TrialEnded | Beep | TrialUpdated | NoteAdded)
#: every declared kind, for a test that checks nothing else is ever sent
KINDS: tuple[type[_RunnerEvent], ...] = (StateChanged, Refused, BlockStarted, TrialStarted,
                                         CheckPersonalised, TrialEnded, Beep, TrialUpdated,
                                         NoteAdded)
RunnerListener = Callable[[RunnerEvent], None]
