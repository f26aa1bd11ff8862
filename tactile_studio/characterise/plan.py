"""What a characterisation run does: the paper's sequences, every number editable."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from tactile_studio.errors import SettingsError

SEQUENCES = ("normal", "shear", "repeat")
DIRECTIONS = ("+x", "-x", "+y", "-y")


@dataclass
class Plan:
    """Defaults are the shear paper's (normal 0 -> 0.8 mm; shear 0 -> 2 mm in 0.2 mm
    steps every 3 s at 2 mm/s under a 2.5 kPa preload; 22,000 repeatability cycles)."""

    sequences: tuple[str, ...] = SEQUENCES
    speed_mm_s: float = 2.0          # every move while touching the skin
    acceleration_mm_s2: float = 50.0
    travel_speed_mm_s: float = 10.0  # moves clear of the skin
    dwell_s: float = 3.0             # hold after every step
    window_s: float = 0.5            # the end of each hold that is averaged
    settle_s: float = 5.0            # lifted before each sequence, then tare
    approach_mm: float = 0.3         # start of the contact search above the surface
    search_step_mm: float = 0.01     # contact / preload search step
    contact_kpa: float = 0.3         # load-cell stress that counts as contact
    normal_depth_mm: float = 0.8
    normal_steps: int = 16
    relax_hold_s: float = 10.0       # hold at full depth for the relaxation fit
    shear_max_mm: float = 2.0
    shear_step_mm: float = 0.2
    preload_kpa: float = 2.5
    directions: tuple[str, ...] = DIRECTIONS
    return_dwell_s: float = 3.0      # hold after returning to the start of a drag
    cycles: int = 22000
    cycle_depth_mm: float = 0.8
    cycle_hold_s: float = 0.5

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def with_overrides(cls, overrides: dict[str, Any]) -> Plan:
        """A plan with ``--param k=v`` style overrides parsed to each field's type."""
        plan = cls()
        known = {f.name: f for f in fields(cls)}
        for key, value in overrides.items():
            if key not in known:
                raise SettingsError(f"unknown characterisation parameter {key!r} "
                                    f"(known: {', '.join(known)})")
            current = getattr(plan, key)
            try:
                if isinstance(current, tuple):
                    parsed: Any = tuple(v.strip() for v in str(value).split(",") if v.strip())
                else:
                    parsed = type(current)(value)
            except (ValueError, OverflowError):
                raise SettingsError(f"characterisation parameter {key}: {value!r} is not "
                                    f"a {type(current).__name__}") from None
            if isinstance(parsed, float) and not math.isfinite(parsed):
                raise SettingsError(f"characterisation parameter {key}: {value} is not a "
                                    "finite number")
            setattr(plan, key, parsed)
        plan.check()
        return plan

    def check(self) -> None:
        bad = [s for s in self.sequences if s not in SEQUENCES]
        if bad:
            raise SettingsError(f"unknown sequence {bad[0]!r} (known: {', '.join(SEQUENCES)}, all)")
        bad = [d for d in self.directions if d not in DIRECTIONS]
        if bad:
            raise SettingsError(f"unknown shear direction {bad[0]!r} "
                                f"(known: {', '.join(DIRECTIONS)})")
        for name in ("speed_mm_s", "dwell_s", "normal_depth_mm", "shear_max_mm",
                     "shear_step_mm", "search_step_mm", "window_s"):
            if getattr(self, name) <= 0:
                raise SettingsError(f"characterisation parameter {name} must be positive")
        for hold in ("dwell_s", "settle_s"):  # the holds whose end window_s averages
            if self.window_s > getattr(self, hold):
                raise SettingsError(
                    f"characterisation parameter window_s ({self.window_s:g} s) is longer "
                    f"than {hold} ({getattr(self, hold):g} s): it would average frames from "
                    "before the hold began")
        if self.normal_steps < 4:
            raise SettingsError("characterisation parameter normal_steps must be at least 4")
        if self.cycles < 1:
            raise SettingsError("characterisation parameter cycles must be at least 1")
