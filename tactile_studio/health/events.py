"""The events of a wellness check or a calibration (the bench's steps, the
:class:`~tactile_studio.health.health_check.HealthCheck` around them) for whoever follows it: the
wizard's run page, the ``wellness`` and ``calibrate`` commands' prompts. One frozen
dataclass per kind, declared here once, so a follower switches on the type and a misspelt
field is an error where the event is made. None of them is written to a file.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Phase:
    """A step of the procedure began: ``rest``, ``place``, ``settle``, ``record`` or
    ``lift``, on ``taxel`` (its label, for the load steps); ``prompt`` tells the person."""

    phase: str
    prompt: str
    taxel: str | None = None


@dataclass(frozen=True)
class Misplaced:
    """The weight is on taxel ``at``, not where it was asked; ``prompt`` says so."""

    at: str
    prompt: str


@dataclass(frozen=True)
class Warned:
    """Something the person should know that does not stop the procedure."""

    message: str


@dataclass(frozen=True)
class LogbookReplaced:
    """The logbook was damaged and set aside before anything was measured."""

    message: str


@dataclass(frozen=True)
class SpotMeasured:
    """A wellness spot was measured (judged at the end, with the others)."""

    taxel: str
    normal_kpa: float


@dataclass(frozen=True)
class Progress:
    """How far the procedure is (0..1), in words."""

    fraction: float
    message: str


@dataclass(frozen=True)
class CheckDone:
    """A wellness check finished with ``verdict``; ``check_id``: its logbook row (None
    when it was not stored)."""

    verdict: str
    check_id: int | None


@dataclass(frozen=True)
class CalibrationDone:
    """A calibration finished and was stored as ``calibration_id``."""

    calibration_id: int


@dataclass(frozen=True)
class Failed:
    """The run stopped (cancelled, a user error, a fault), told in one line."""

    message: str


HealthEvent = (Phase | Misplaced | Warned | LogbookReplaced | SpotMeasured | Progress
               | CheckDone | CalibrationDone | Failed)
#: every declared kind, for a test that checks nothing else is ever sent
KINDS: tuple[type, ...] = (Phase, Misplaced, Warned, LogbookReplaced, SpotMeasured, Progress,
                           CheckDone, CalibrationDone, Failed)
EventFn = Callable[[HealthEvent], None]
