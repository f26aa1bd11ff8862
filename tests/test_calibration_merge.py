"""A partial calibration merges with the sensor's active one (the taxels it measured
replace theirs, the rest are kept, the record says which came from where) unless the user
chooses to replace it: ``calibrate --replace``, or the wizard's result page. Every
calibration says how many taxels it covers (``sensor ID``, ``--json``, Sensors window)."""

from __future__ import annotations

import json

import pytest

from tactile_studio.cli import main
from tactile_studio.errors import EXIT_INCOMPLETE
from tactile_studio.storage.books.logbook import Logbook

SIM = ["--device", "simulated", "--set", "speed=0", "--set", "seed=6", "--sensor", "sim-6",
       "--auto"]
PLATE = ["--loads-g", "1000,2000,5000,10000,20000", "--plate"]
FOUR = ["--loads-g", "20,50,100,200,500", "--taxels", "B2,B5,E2,E5"]


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def calibrate(capsys, tmp_path, name, *extra):
    assert main(["calibrate", *SIM, *extra, "--out", str(tmp_path / name)]) == 0
    return capsys.readouterr().out


def sensor_json(capsys):
    assert main(["sensor", "sim-6", "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_a_partial_calibration_merges_with_the_plate_one_unless_replaced(capsys, tmp_path):
    calibrate(capsys, tmp_path, "plate.json", *PLATE)
    out = calibrate(capsys, tmp_path, "four.json", *FOUR)
    assert ("covers 36 of 36 taxels: 4 measured now, 32 kept from calibration #1 "
            "(--replace drops them)") in out
    cals = sensor_json(capsys)["calibrations"]
    assert [(c["id"], c["taxels"], len(c["measured"]), c["active"]) for c in cals] == [
        (1, 36, 36, False), (2, 36, 4, True)]
    assert sorted(cals[1]["measured"]) == ["B2", "B5", "E2", "E5"]
    assert len(cals[1]["kept"]["1"]) == 32 and "B2" not in cals[1]["kept"]["1"]
    with Logbook() as book:
        plate, merged = book.calibration(1), book.calibration(2)
    kept = {f["taxel"]: f for f in merged["fits"]}
    # the kept taxels read with the plate calibration's curves; the four with the new ones
    for f in plate["fits"]:
        if f["taxel"] in ("B2", "B5", "E2", "E5"):
            assert kept[f["taxel"]].get("from_calibration") is None
            assert kept[f["taxel"]]["params"] != f["params"]
        else:
            assert kept[f["taxel"]]["params"] == f["params"]
            assert kept[f["taxel"]]["from_calibration"] == 1
    assert set(merged["gains"]) == {f["taxel"] for f in plate["fits"]}
    assert len(json.loads((tmp_path / "four.json").read_text())["fits"]) == 36
    assert main(["sensor", "sim-6"]) == 0
    text = capsys.readouterr().out
    assert "calibration: #2, covers 36 of 36 taxels" in text
    assert "per-taxel 36 of 36 taxels (4 measured, 32 from #1)" in text

    out = calibrate(capsys, tmp_path, "replace.json", *FOUR, "--replace")
    assert ("covers 4 of 36 taxels (replaced calibration #2: 32 other taxels now read "
            "with the nominal curve)") in out
    cals = sensor_json(capsys)["calibrations"]
    assert (cals[-1]["taxels"], cals[-1]["active"], cals[-1]["kept"]) == (4, True, {})


def test_the_wizard_merges_by_default_and_can_replace_on_its_result_page(qtbot, tmp_path):
    from PySide6.QtWidgets import QWizard

    from tactile_studio.ui.calibration_wizard import CalibrationWizard
    from tactile_studio.ui.sensors_window import SensorsWindow

    assert main(["calibrate", *SIM, *PLATE, "--out", str(tmp_path / "plate.json")]) == 0
    w = CalibrationWizard("simulated", {"speed": 0, "seed": 6})
    qtbot.addWidget(w)
    w.show()
    w.setup.per_taxel.setChecked(True)  # plate is the default
    w.setup.taxels.setText("B2,E5")
    w.setup.out.setText(str(tmp_path / "cal.json"))
    w.next()
    page = w.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    qtbot.waitUntil(lambda: page.phase.text() == "Done", timeout=5000)
    w.next()
    res = w.result_page
    assert res.coverage.text().splitlines()[-1].startswith(
        "covers 36 of 36 taxels: 2 measured now, 34 kept from calibration #1")
    assert res.replace.isVisible() and res.table.rowCount() == 2
    w.grab().save(str(tmp_path / "merged.png"))
    with Logbook() as book:
        assert book.calibrations("sim-6")[-1]["taxels"] == 36
    res.replace.click()
    assert res.coverage.text().splitlines()[-1].startswith(
        "covers 2 of 36 taxels (replaced calibration #1")
    assert not res.replace.isVisible()
    with Logbook() as book:
        cal = book.calibrations("sim-6")[-1]
        assert (cal["id"], cal["taxels"], cal["active"]) == (2, 2, True)
    assert len(json.loads((tmp_path / "cal.json").read_text())["fits"]) == 2
    w.button(QWizard.WizardButton.FinishButton).click()

    sensors = SensorsWindow()
    qtbot.addWidget(sensors)
    sensors.show()
    assert "active calibration 2 (2 of 36 taxels)" in sensors.facts.text()
    assert sensors.calibrations.item(0, 3).text() == "36 of 36"
    assert sensors.calibrations.item(1, 3).toolTip() == "2 of 36 taxels (2 measured)"
    sensors.grab().save(str(tmp_path / "sensors.png"))


def test_a_characterisation_calibration_merges_too(capsys, tmp_path):
    calibrate(capsys, tmp_path, "plate.json", *PLATE)
    assert main(["characterise", "--set", "speed=0", "--set", "gesture=idle", "--set",
                 "seed=6", "--taxels", "B2", "--sequence", "normal", "--sensor", "sim-6",
                 "--save-calibration", "--out", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert ("calibration #2 of sim-6 saved to the logbook (active), covers 36 of 36 taxels "
            "(1 measured, 35 from #1)") in err
    with Logbook() as book:
        merged = book.calibration(2)
    assert merged["kind"] == "characterisation" and len(merged["fits"]) == 36
    assert [f["taxel"] for f in merged["fits"] if f.get("from_calibration") is None] == ["B2"]


def test_a_taxel_that_cannot_be_calibrated_stores_the_others_and_exits_3(capsys, tmp_path):
    """Asked for B2 and E5 with B2 dead: E5 was stored and the command exited 0, as if
    both had been calibrated (walking issue 33's 'documented non-zero exit')."""
    dead = ["--set", "fault=dead_taxel", "--set", "fault_taxel=B2"]
    code = main(["calibrate", *SIM, *dead, "--loads-g", "20,50,100,200,500", "--taxels",
                 "B2,E5", "--out", str(tmp_path / "two.json")])
    out, err = capsys.readouterr()
    assert code == EXIT_INCOMPLETE
    assert "not calibrated: B2:" in out
    errors = [ln for ln in err.splitlines() if ln.startswith("tactile-studio: error:")]
    assert len(errors) == 1 and "1 taxel(s) not calibrated (B2: " in errors[0]
    cals = sensor_json(capsys)["calibrations"]
    assert [(c["id"], c["measured"], c["active"]) for c in cals] == [(1, ["E5"], True)]
