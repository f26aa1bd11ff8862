"""How long a wellness check or a calibration takes, said before it starts.

The figures are per placement of a weight (place, settle, record, lift, recover) and come
from ``python -m benchmarks health``, which measures them on the simulated device: at
real time (what a person at the bench waits for the skin, the simulated hands' 2 s of
handling included) and at full speed (``speed=0``, the simulator as fast as this
machine makes it; a lower bound on a busy 2-core machine).
"""

from __future__ import annotations

from typing import Any

from tactile_studio.health.bench import SimulatedPlacer, Timing
from tactile_studio.jobs import about

# seconds per placement at real time, measured (bench_health): the calibrations wait for
# the skin to stop creeping after each load (heavier plate loads longest), the wellness
# check only for the load to come off
REAL_TIME_S = {"plate": 18.5, "taxel": 13.5, "spot": 8.6}
# wall seconds per placement with the simulated device at speed 0 (bench_health: 0.6 / 0.15
# / 0.2 on a quiet 2-core machine, 1.1 / 0.26 / 0.21 at load 14; the busier figure)
FULL_SPEED_S = {"plate": 1.0, "taxel": 0.25, "spot": 0.25}


def placements(kind: str, loads: int, taxels: int) -> int:
    """Weights placed: a plate takes each load once, a per-taxel calibration each load on
    each taxel, a wellness check one weight per spot (``loads`` 1)."""
    return loads if kind == "plate" else loads * taxels


def estimate_s(kind: str, n_placements: int, full_speed: bool = False,
               busy_hand: bool = False) -> float:
    """Seconds a procedure of ``n_placements`` of ``kind`` (plate | taxel | spot) takes:
    the rest phase plus the placements. ``busy_hand``: the simulated device was performing
    gestures, whose residue it lets fade first (device time: free at full speed)."""
    if full_speed:
        return 0.5 + n_placements * FULL_SPEED_S[kind]
    fade = SimulatedPlacer.RESIDUE_FADE_S if busy_hand else 0.0
    return fade + Timing().rest_s + n_placements * REAL_TIME_S[kind]


def estimate_text(kind: str, n_placements: int, simulated: bool, full_speed: bool,
                  busy_hand: bool = False) -> str:
    """"about 2 min" at a bench; on the simulator "about 4 s on the simulator at full
    speed (at a bench: about 2 min)" or "about 2 min 23 s on the simulator in real time"."""
    bench = about(estimate_s(kind, n_placements))
    if not simulated:
        return bench
    if full_speed:
        return (f"{about(estimate_s(kind, n_placements, full_speed=True))} on the simulator "
                f"at full speed (at a bench: {bench})")
    return f"{about(estimate_s(kind, n_placements, busy_hand=busy_hand))} on the simulator " \
           "in real time"


def simulated_speed(settings: dict[str, Any]) -> float:
    """The simulator's ``speed`` setting (1 = real time, 0 = as fast as it goes)."""
    try:
        return float(settings.get("speed", 1.0))
    except (TypeError, ValueError):
        return 1.0
