"""One stated rule for what a wellness check's ratios are against, said the same by the
CLI and the wizard (issue 47, item 21: the GUI said "ratios against check #2", the CLI
"reference: calibration #1" for the same sensor): each spot against the sensor's active
calibration, else its first passing check with this weight, else the nominal curve."""

from __future__ import annotations

import json

import pytest

from tactile_studio.cli import main

SIM = ["--device", "simulated", "--set", "speed=0", "--set", "difficulty=easy"]


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def cli_check(capsys, *extra) -> tuple[dict, str]:
    assert main(["wellness", *SIM, "--sensor", "sim-0", "--weight-g", "200", "--auto",
                 "--json", *extra]) == 0
    out = json.loads(capsys.readouterr().out)
    return out, out["judged_against"]


def wizard_check(qtbot) -> str:
    from PySide6.QtWidgets import QLabel

    from tactile_studio.ui.wellness_wizard import WellnessWizard

    w = WellnessWizard("simulated", {"speed": 0, "difficulty": "easy"})
    qtbot.addWidget(w)
    w.show()
    from tactile_studio.health.wellness import REFERENCE_RULE
    assert any(REFERENCE_RULE in label.text() for label in w.setup.findChildren(QLabel))
    w.next()
    page = w.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    qtbot.waitUntil(page.isComplete, timeout=5000)
    w.next()
    return w.result_page.reasons.text().splitlines()[0]


def test_a_calibration_made_after_a_passing_check_is_the_reference_in_both(capsys, qtbot,
                                                                           tmp_path):
    first, words = cli_check(capsys)  # no calibration, no earlier check: nominal
    assert words.startswith("the nominal curve") and first["verdict"] == "pass"
    second, words = cli_check(capsys)  # the first passing check is the reference now
    assert words.startswith(f"check #{first['check_id']}, its first passing check")
    assert {s["reference"] for s in second["spots"]} == {f"check #{first['check_id']}"}
    assert main(["calibrate", *SIM, "--sensor", "sim-0", "--loads-g",
                 "1000,2000,5000,10000,20000", "--plate", "--auto", "--out",
                 str(tmp_path / "cal.json")]) == 0
    capsys.readouterr()
    # the calibration takes over, for the CLI and the wizard alike, in the same words
    third, cli_words = cli_check(capsys)
    assert cli_words == "calibration #1, the sensor's active calibration"
    assert {s["reference"] for s in third["spots"]} == {"calibration #1"}
    assert third["active_calibration"] == 1
    gui_line = wizard_check(qtbot)
    assert gui_line.endswith(f"ratios against {cli_words}")


def test_the_cli_says_the_rule(capsys):
    from tactile_studio.health.wellness import REFERENCE_RULE
    with pytest.raises(SystemExit):
        main(["wellness", "--help"])
    assert " ".join(REFERENCE_RULE.split()[:6]) in " ".join(capsys.readouterr().out.split())
