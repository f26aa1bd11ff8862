"""What a characterisation run does: the paper's sequences, every number editable."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from tactile_studio.errors import SettingsError
from tactile_studio.jobs import about

SEQUENCES = ("normal", "shear", "repeat")
# What a run measures unless told otherwise (the CLI and the wizard alike): the paper's
# 22,000-cycle repeatability test takes about 11 h of stage time per taxel (14 h in the
# paper), so it is asked for by name, with its number of cycles, never by default.
DEFAULT_SEQUENCES = ("normal", "shear")
DIRECTIONS = ("+x", "-x", "+y", "-y")


def parse_sequences(text: str) -> tuple[str, ...]:
    """``"normal,shear"`` (any order, any subset) or ``"all"`` (the three) -> names."""
    names = tuple(v.strip().lower() for v in str(text).split(",") if v.strip())
    if names == ("all",):
        return SEQUENCES
    bad = [n for n in names if n not in SEQUENCES]
    if bad or not names:
        raise SettingsError(f"unknown sequence {bad[0] if bad else text!r} "
                            f"(known: {', '.join(SEQUENCES)}, all; several with commas)")
    return tuple(dict.fromkeys(names))  # each once, in the order given


@dataclass
class Plan:
    """Defaults are the shear paper's (normal 0 -> 0.8 mm; shear 0 -> 2 mm in 0.2 mm
    steps every 3 s at 2 mm/s under a 2.5 kPa preload; 22,000 repeatability cycles)."""

    sequences: tuple[str, ...] = DEFAULT_SEQUENCES
    speed_mm_s: float = 2.0          # every move while touching the skin
    acceleration_mm_s2: float = 50.0
    travel_speed_mm_s: float = 10.0  # moves clear of the skin
    dwell_s: float = 3.0             # hold after every step
    window_s: float = 0.5            # the end of each hold that is averaged
    settle_s: float = 5.0            # lifted before each sequence, at least; then tare
    steady_per_s: float = 2e-4       # ... and until the skin has stopped moving: the
    #                                  taxel and its neighbours change by less than this
    #                                  (relative change per second, ~0.02 kPa/s)
    settle_max_s: float = 60.0       # the longest wait for that (then measured anyway)
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
                if key == "sequences":
                    parsed: Any = parse_sequences(str(value))
                elif isinstance(current, tuple):
                    parsed = tuple(v.strip() for v in str(value).split(",") if v.strip())
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
        parse_sequences(",".join(self.sequences))
        bad = [d for d in self.directions if d not in DIRECTIONS]
        if bad:
            raise SettingsError(f"unknown shear direction {bad[0]!r} "
                                f"(known: {', '.join(DIRECTIONS)})")
        for name in ("speed_mm_s", "dwell_s", "normal_depth_mm", "shear_max_mm",
                     "shear_step_mm", "search_step_mm", "window_s", "steady_per_s"):
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


def _move_s(distance_mm: float, speed: float, acceleration: float) -> float:
    """A stage move's duration as the stages plan it: distance over speed plus the ramp."""
    return distance_mm / speed + speed / acceleration if distance_mm > 0 else 0.0


# After a full-depth hold (the relaxation step, a run of cycles) the skin relaxes for
# about three of the paper's 3 s relaxation times before it is steady: the wait for a
# settled skin is that much longer than ``settle_s`` once per such hold
RESIDUE_WAIT_S = 10.0


def sequence_lab_s(plan: Plan, sequence: str, skin_kpa_per_mm: float = 80.0) -> float:
    """Stage time one taxel's ``sequence`` takes, from the plan alone (the holds, dwells
    and moves the procedure makes, the waits for a settled skin as the paper's skin
    needs them); ``skin_kpa_per_mm`` (the simulated skin's stiffness) only sets how deep
    the preload search goes."""
    v, a, p = plan.speed_mm_s, plan.acceleration_mm_s2, plan

    def search(kpa: float) -> float:  # step down from the approach height until the load
        steps = (p.approach_mm + kpa / skin_kpa_per_mm) / p.search_step_mm
        return steps * (_move_s(p.search_step_mm, v, a) + 0.1)
    tare = p.settle_s
    if sequence == "normal":
        steps = 2 * p.normal_steps + 1
        return (tare + search(p.contact_kpa)
                + steps * (_move_s(p.normal_depth_mm / p.normal_steps, v, a) + p.dwell_s)
                + _move_s(p.approach_mm, v, a) + p.settle_s
                + _move_s(p.approach_mm + p.normal_depth_mm, v, a) + p.relax_hold_s
                + _move_s(p.approach_mm + p.normal_depth_mm, v, a) + RESIDUE_WAIT_S)
    if sequence == "shear":
        n = int(round(p.shear_max_mm / p.shear_step_mm))
        drag = (n * (_move_s(p.shear_step_mm, v, a) + p.dwell_s) + p.dwell_s
                + _move_s(p.shear_max_mm, v, a) + p.return_dwell_s
                + _move_s(p.approach_mm, v, a) + p.settle_s)
        return (len(p.directions) * (tare + drag) + search(p.preload_kpa)
                + (len(p.directions) - 1) * _move_s(p.approach_mm, v, a))
    if sequence == "repeat":
        press = 2 * (_move_s(p.cycle_depth_mm, v, a) + p.cycle_hold_s)
        return (tare + search(p.contact_kpa) + p.cycles * press + _move_s(p.approach_mm, v, a)
                + p.settle_s + RESIDUE_WAIT_S)
    raise SettingsError(f"unknown sequence {sequence!r}")


# How much faster than real time the simulated bench runs at speed 0 (a lower bound:
# ``python -m benchmarks characterise`` measured 107-251x on the 2-core machine, the
# repeat sequence's many short moves being the slowest)
SIMULATED_SPEEDUP = 100.0


def plan_lab_s(plan: Plan, n_taxels: int) -> float:
    """Stage time of a whole run: every sequence on every taxel, plus the travel between
    taxels (at ``travel_speed_mm_s`` over about one taxel pitch, 16 mm)."""
    travel = _move_s(16.0, plan.travel_speed_mm_s, plan.acceleration_mm_s2)
    return n_taxels * (travel + sum(sequence_lab_s(plan, s) for s in plan.sequences))


def stage_time_text(lab_s: float, per: str = "") -> str:
    """"about 11 min of stage time (the simulated bench at speed 0: about 7 s)"."""
    return (f"{about(lab_s)} of stage time{per} (the simulated bench at speed 0: "
            f"{about(lab_s / SIMULATED_SPEEDUP)})")


def plan_text(plan: Plan, n_taxels: int) -> str:
    """What a run will do and how long it takes, in one line (the CLI prints it, the
    wizard shows it): "2 taxel(s) x normal, shear: about 11 min of stage time (...)"."""
    seqs = ", ".join(f"repeat ({plan.cycles:,} cycles)" if s == "repeat" else s
                     for s in plan.sequences)
    return f"{n_taxels} taxel(s) x {seqs}: {stage_time_text(plan_lab_s(plan, n_taxels))}"
