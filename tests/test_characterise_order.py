"""A taxel's characterisation figures do not depend on the order of the taxels nor on what
the taxel before it went through: each sequence starts from a settled skin (the wait is
said and journaled), the baseline's drift over a staircase or a run of cycles is taken
out, and the simulated bench keeps the simulated sensor's own virtual hand off the skin.
Issue 47: E5's shear r² was 0.706 after B2 (50 cycles), 0.992 after B2 (500 cycles) and
0.816 measured first, on the simulator's default settings."""

from __future__ import annotations

import pytest

from tactile_studio.characterise import CharacterisationRequest, Plan, run_characterisation
from tactile_studio.devices.registry import create_device
from tactile_studio.plugins.sim_force import SimulatedForce
from tactile_studio.plugins.sim_stage import SimulatedStage
from tactile_studio.sensor.characterise import parse_taxels
from tactile_studio.storage.format.session_file import SessionFile

# a shortened paper plan (shorter dwells and holds), all three sequences
PLAN = dict(sequences=("normal", "shear", "repeat"), dwell_s=1.0,
            cycles=20)
SAME_REL = {"normal_sensitivity_low": 0.02, "normal_sensitivity_high": 0.02,
            "breakpoint_kpa": 0.03, "shear_sensitivity_x": 0.02, "shear_sensitivity_y": 0.02,
            "relaxation_s": 0.05}
SAME_ABS = {"r2_normal": 0.002, "r2_shear": 0.002, "shear_offset": 0.01, "hysteresis": 0.006,
            "crosstalk_max": 0.006, "repeat_drift": 0.008, "repeat_cv": 0.003}


def characterise(order: str, tmp_path, cycles: int = 20) -> dict:
    # the simulator as it comes (its demo gestures on), as the commands ran it
    dev = create_device("simulated", {"speed": 0})
    out = tmp_path / order.replace(",", "-") / str(cycles)
    result = run_characterisation(dev, SimulatedStage(), SimulatedForce(), CharacterisationRequest(
        Plan(**{**PLAN, "cycles": cycles}), parse_taxels(dev.layout, order), out, report=False))
    assert result["device"]["settings"]["gesture"] == "idle"  # the bench's hand is off
    with SessionFile(out / "session.h5") as s:
        waits = [e for e in s.events if e["kind"] == "char_settled"]
    # before each sequence and shear direction, after the staircase and after the cycles
    assert len(waits) == 2 * (1 + 4 + 1 + 2)
    return result["taxels"]


@pytest.mark.parametrize("first, second", [("B2", "E5")])
def test_two_taxels_give_the_same_figures_in_either_order(tmp_path, first, second):
    a = characterise(f"{first},{second}", tmp_path)
    b = characterise(f"{second},{first}", tmp_path)
    after_longer = characterise(f"{first},{second}", tmp_path, cycles=60)
    for taxel in (first, second):
        for other in (b, after_longer):
            for key, rel in SAME_REL.items():
                assert other[taxel][key] == pytest.approx(a[taxel][key], rel=rel), (taxel, key)
            for key, tol in SAME_ABS.items():
                if key.startswith("repeat") and other is after_longer:
                    continue  # 60 cycles drift more than 20: its own figure
                assert other[taxel][key] == pytest.approx(a[taxel][key], abs=tol), (taxel, key)
        for run in (a, b, after_longer):  # said: how long the skin took, and that it settled
            assert run[taxel]["settled"] is True
            assert PLAN.get("settle_s", 5.0) <= run[taxel]["settle_wait_s"] < 60
