"""May a collection session start? The protocol's ``[wellness]`` requirement, checked.

A protocol can require a passing (or warning) wellness check of the sensor, no older
than ``max_age_h``, before each participant. A failed, stale or missing check needs an
override with a note; either way the session metadata records the sensor, the check, its
verdict and age, and the override note.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from tactile_studio.errors import UserError
from tactile_studio.storage.books.logbook import Logbook, age_hours, age_text
from tactile_studio.storage.books.logbook_file import LogbookDamaged, say_once


class WellnessRequired(UserError):
    """The protocol requires a recent passing check and there is none (no override)."""


@dataclass(frozen=True)
class WellnessStatus:
    sensor: str | None
    required: bool
    max_age_h: float
    check_id: int | None = None
    verdict: str | None = None
    at: str | None = None
    age_h: float | None = None

    @property
    def problem(self) -> str | None:
        """Why the session should not start (None when it may)."""
        if not self.sensor:
            return "the device reports no sensor ID, so its wellness is unknown"
        if self.check_id is None:
            return f"sensor {self.sensor} has no wellness check"
        if self.verdict == "fail":
            return f"sensor {self.sensor}'s last wellness check failed ({age_text(self.at)})"
        if self.age_h is not None and self.age_h > self.max_age_h:
            return (f"sensor {self.sensor}'s last wellness check is {self.age_h:.1f} h old "
                    f"(the protocol allows {self.max_age_h:g} h)")
        return None

    @property
    def ok(self) -> bool:
        return not self.required or self.problem is None

    def text(self) -> str:
        """One line for the console: sensor, last verdict and its age."""
        if not self.sensor:
            return "Sensor: unknown (no wellness record)"
        if self.check_id is None:
            return f"Sensor {self.sensor}: never checked"
        return (f"Sensor {self.sensor}: last check {self.verdict.upper()} {age_text(self.at)}"
                f" (#{self.check_id})")

    def metadata(self, override_note: str | None = None) -> dict[str, Any]:
        """What the session file records about the sensor's health at the start."""
        return {"sensor_id": self.sensor, "check_id": self.check_id, "verdict": self.verdict,
                "checked_at": self.at, "age_h": None if self.age_h is None
                else round(self.age_h, 3), "required": self.required,
                "max_age_h": self.max_age_h, "problem": self.problem,
                "override": override_note}


def wellness_status(sensor: str | None, required: bool = False,
                    max_age_h: float = 24.0) -> WellnessStatus:
    """The sensor's last check from the logbook."""
    if not sensor:
        return WellnessStatus(None, required, max_age_h)
    try:
        with Logbook() as book:
            last = book.last_check(sensor)
    except LogbookDamaged as exc:  # no check can be trusted: said once, treated as none
        say_once(str(exc))
        last = None
    if last is None:
        return WellnessStatus(sensor, required, max_age_h)
    return WellnessStatus(sensor, required, max_age_h, last["id"], last["verdict"],
                          last["at"], age_hours(last["at"]))


def admit(status: WellnessStatus, override_note: str | None = None) -> dict[str, Any]:
    """Session metadata if the session may start; WellnessRequired if it needs an
    override note and has none."""
    note = (override_note or "").strip() or None
    if not status.ok and note is None:
        raise WellnessRequired(f"{status.problem}: run `tactile-studio wellness` first, or "
                               "start with an override note")
    return status.metadata(note)
