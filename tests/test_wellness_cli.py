"""``wellness`` through the CLI: exit 0 on PASS, 4 on WARN, 5 on FAIL (after the result
is printed, stored and reported), how many taxels were tested, ``--spots all``, and the
README's first-use flow (calibrate a new sensor, then check it) passing."""

from __future__ import annotations

import json

import pytest

from tactile_studio.cli import main
from tactile_studio.errors import EXIT_CHECK_FAIL, EXIT_CHECK_WARN
from tactile_studio.storage.books.logbook import Logbook

SIM = ["--device", "simulated", "--set", "speed=0"]


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))
    return tmp_path / "data"


def wellness(capsys, *extra, sensor="sim-0"):
    code = main(["wellness", *SIM, "--sensor", sensor, "--weight-g", "200", "--auto", *extra])
    out, err = capsys.readouterr()
    return code, out, [ln for ln in err.splitlines() if "error" in ln]


def test_a_pass_exits_0_and_says_which_taxels_were_tested(capsys, tmp_path):
    code, out, err = wellness(capsys, "--set", "difficulty=easy", "--set", "fault=dead_taxel",
                              "--set", "fault_taxel=0")  # A1 dead, but not a spot
    assert code == 0 and not err
    assert "sensor sim-0: PASS" in out
    assert "5 of 36 taxels tested: B2, B5, E2, E5, C3" in out
    # every taxel: the dead A1 is found
    report = tmp_path / "check.html"
    code, out, err = wellness(capsys, "--set", "difficulty=easy", "--set", "fault=dead_taxel",
                              "--set", "fault_taxel=0", "--spots", "all", "--report",
                              str(report))
    assert code == EXIT_CHECK_FAIL
    assert "36 of 36 taxels tested (all)" in out and "A1: no response" in out
    assert len(err) == 1 and "wellness FAIL" in err[0] and "36 of 36 taxels tested" in err[0]
    assert "36 of 36 taxels tested (all)" in report.read_text()  # reported before the exit
    with Logbook() as book:
        assert [c["verdict"] for c in book.checks("sim-0")][-1] == "fail"  # stored too


def test_a_fail_exits_5_and_a_warn_4_after_printing_the_result(capsys):
    code, out, err = wellness(capsys, "--set", "seed=1", "--set", "fault=dead_taxel",
                              "--set", "fault_taxel=14", "--json", sensor="sim-1")
    assert code == EXIT_CHECK_FAIL
    result = json.loads(out)
    assert result["verdict"] == "fail" and result["tested"]["taxels"] == [
        "B2", "B5", "E2", "E5", "C3"] and result["tested"]["of"] == 36
    assert len(err) == 1 and "C3: no response" in err[0]
    # the default simulator varies like real sensors: uncalibrated, B5 reads 130% of the
    # nominal curve, and the result says what it was judged against
    code, out, err = wellness(capsys)
    assert code == EXIT_CHECK_WARN and "sensor sim-0: WARN" in out
    assert "ratios against the nominal curve" in out and "calibrate it first" in out
    assert len(err) == 1 and "wellness WARN" in err[0]


def test_the_readme_flow_calibrates_first_and_then_passes(capsys, tmp_path):
    assert main(["calibrate", *SIM, "--sensor", "sim-0", "--loads-g",
                 "1000,2000,5000,10000,20000", "--plate", "--auto", "--out",
                 str(tmp_path / "cal.json")]) == 0
    capsys.readouterr()
    code, out, err = wellness(capsys)
    assert code == 0 and not err, out
    assert "sensor sim-0: PASS" in out and "ratios against calibration #1" in out
    # a dead taxel still fails against the calibration
    code, out, err = wellness(capsys, "--set", "fault=dead_taxel", "--set", "fault_taxel=14")
    assert code == EXIT_CHECK_FAIL and "C3: no response" in out


def test_the_wizard_tests_every_taxel_with_spots_all_and_says_so(qtbot, tmp_path):
    from tactile_studio.ui.wellness_wizard import WellnessWizard

    w = WellnessWizard("simulated", {"speed": 0, "difficulty": "easy", "seed": 2})
    qtbot.addWidget(w)
    w.show()
    w.setup.weight.setValue(200)
    w.setup.spots.setText("all")
    w.next()
    page = w.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    qtbot.waitUntil(lambda: page.phase.text() == "Done", timeout=5000)
    w.next()
    res = w.result_page
    assert res.result["verdict"] == "pass" and res.table.rowCount() == 36
    assert res.reasons.text().startswith("36 of 36 taxels tested (all); ratios against "
                                         "the nominal curve")
    w.grab().save(str(tmp_path / "wellness-all.png"))
