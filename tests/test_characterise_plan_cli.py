"""What `characterise` runs when asked, and how long it says that takes (issue 47):
`--sequence normal,shear` (the wizard's own default) was refused; `all` (the default)
ran the paper's 22,000 repeat cycles unless `--cycles` was given."""

from __future__ import annotations

import json

import pytest

from tactile_studio.characterise import CharacterisationRequest, Plan, run_characterisation
from tactile_studio.cli import main
from tactile_studio.devices.registry import create_device
from tactile_studio.plugins.sim_force import SimulatedForce
from tactile_studio.plugins.sim_stage import SimulatedStage

QUICK = ["--param", "dwell_s=0.5", "--param", "relax_hold_s=2", "--param", "settle_s=1",
         "--param", "directions=+x"]


def run(tmp_path, *argv):
    return main(["characterise", "--set", "speed=0", "--taxels", "B2", *QUICK,
                 "--out", str(tmp_path / "run"), "--json", *argv])


def error_lines(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if not ln.startswith("characterise [")]


def test_a_list_of_sequences_runs_each_of_them(tmp_path, capsys):
    assert run(tmp_path, "--sequence", "normal,shear") == 0
    out, err = capsys.readouterr()
    figures = json.loads(out)["B2"]
    assert "normal_sensitivity_low" in figures and "shear_sensitivity_x" in figures
    assert "repeat_cycles" not in figures
    # it said what it would do and how long that takes on a real stage and here
    assert "characterise: 1 taxel(s) x normal, shear: about" in err and "of stage time" in err
    saved = json.loads((tmp_path / "run" / "characterisation.json").read_text())
    assert saved["plan"]["sequences"] == ["normal", "shear"]


def test_the_default_is_the_wizards_normal_and_shear(tmp_path, capsys):
    assert run(tmp_path) == 0
    assert json.loads((tmp_path / "run" / "characterisation.json").read_text()
                      )["plan"]["sequences"] == ["normal", "shear"]


@pytest.mark.parametrize("sequence", ["all", "repeat", "normal,repeat"])
def test_repeat_without_cycles_is_refused_with_what_the_papers_would_take(
        tmp_path, capsys, sequence):
    assert run(tmp_path, "--sequence", sequence) == 1
    (line,) = error_lines(capsys.readouterr().err)
    assert "repeat needs --cycles N" in line and "22,000 cycles take about" in line
    assert "h of stage time per taxel" in line
    assert not (tmp_path / "run").exists()  # refused before anything moved


def test_a_bad_sequence_is_named(tmp_path, capsys):
    assert run(tmp_path, "--sequence", "normal,sheer") == 1
    (line,) = error_lines(capsys.readouterr().err)
    assert "unknown sequence 'sheer'" in line and "all" in line


@pytest.mark.parametrize("sequences", [("normal",), ("shear",), ("repeat",)])
def test_the_stage_time_estimate_is_the_simulated_bench_within_10_percent(tmp_path,
                                                                          sequences):
    from tactile_studio.characterise.plan import plan_lab_s
    dev = create_device("simulated", {"speed": 0})
    plan = Plan(sequences=sequences, cycles=30)
    run_characterisation(dev, SimulatedStage(), SimulatedForce(),
                         CharacterisationRequest(plan, [7], tmp_path, report=False))
    lab_s = dev.simulator.frame / dev.simulator.rate
    assert plan_lab_s(plan, 1) == pytest.approx(lab_s, rel=0.10)
