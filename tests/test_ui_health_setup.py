"""The health wizards' set-up pages (issue 47, items 18-19): the calibration wizard is
plate-first, with a time estimate for each choice; the wellness and calibration wizards
offer the simulator's full speed (and use it by default) instead of taking the live
view's real-time speed; the characterisation wizard's plan says what it will take."""

from __future__ import annotations

import pytest
from PySide6.QtWidgets import QWizard

from tactile_studio.storage.books.logbook import Logbook

LIVE_VIEW = {"speed": 1.0, "seed": 4, "gesture": "auto"}  # what the main window passes


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def minutes(text: str) -> float:
    """'about 45 min' / 'about 2 min 3 s' / 'about 4 s' -> minutes (the first figure)."""
    import re
    m = re.search(r"about (\d+) (h|min|s)", text)
    value, unit = float(m.group(1)), m.group(2)
    return value * {"h": 60.0, "min": 1.0, "s": 1 / 60}[unit]


def test_the_calibration_wizard_is_plate_first_with_an_estimate_for_each_choice(qtbot):
    from tactile_studio.ui.calibration_wizard import CalibrationWizard

    w = CalibrationWizard("simulated", LIVE_VIEW)
    qtbot.addWidget(w)
    w.show()
    s = w.setup
    assert s.plate.isChecked() and not s.taxels.isEnabled()
    assert s.loads.text() == "1000,2000,5000,10000,20000"
    # each choice says what it takes, here and at a bench
    plate, taxel = s.plate_estimate.text(), s.taxel_estimate.text()
    assert plate.startswith("5 placements") and "at a bench: about " in plate
    assert taxel.startswith("36 taxels x 5 loads = 180 placements")
    at_bench = [minutes(t.split("at a bench: ")[1]) for t in (plate, taxel)]
    assert at_bench[1] > 15 * at_bench[0] and at_bench[1] > 20  # per taxel: most of an hour
    assert s.estimate.text() == plate.split(": ", 1)[1]
    # the other choice: its own loads, taxels, and the estimate follows the taxels typed
    s.per_taxel.setChecked(True)
    assert s.taxels.isEnabled() and s.loads.text() == "20,50,100,200,500"
    s.taxels.setText("B2,E5")
    assert s.taxel_estimate.text().startswith("2 taxels x 5 loads = 10 placements")
    assert s.estimate.text() == s.taxel_estimate.text().split(": ", 1)[1]
    assert s.spec().plate is False and s.spec().taxels == ("B2", "E5")


@pytest.mark.parametrize("kind", ["wellness", "calibration"])
def test_a_wizard_opened_from_the_live_view_runs_the_simulator_at_full_speed(qtbot, kind):
    from tactile_studio.ui.calibration_wizard import CalibrationWizard
    from tactile_studio.ui.wellness_wizard import WellnessWizard

    w = (WellnessWizard if kind == "wellness" else CalibrationWizard)("simulated", LIVE_VIEW)
    qtbot.addWidget(w)
    w.show()
    assert w.setup.speed.currentText().startswith("Full speed")
    assert w.setup.run_settings()["speed"] == 0.0
    assert "on the simulator at full speed (at a bench: about" in w.setup.estimate.text()
    w.setup.speed.setCurrentIndex(1)  # real time is still there, and says how long
    assert w.setup.run_settings()["speed"] == 1.0
    assert "on the simulator in real time" in w.setup.estimate.text()
    w.setup.speed.setCurrentIndex(0)
    w.next()
    page = w.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    qtbot.waitUntil(lambda: page.isComplete(), timeout=5000)
    assert page.run.device.settings["speed"] == 0.0  # its own device, at full speed
    w.next()
    result = w.result_page.result
    assert result["device"]["settings"]["speed"] == 0.0
    w.button(QWizard.WizardButton.FinishButton).click()
    with Logbook() as book:
        stored = book.checks("sim-4") if kind == "wellness" else book.calibrations("sim-4")
        assert len(stored) == 1


def test_a_real_devices_wizard_offers_no_simulator_speed(qtbot):
    from tactile_studio.ui.wellness_wizard import WellnessWizard

    w = WellnessWizard("serial", {"port": "/dev/null"})
    qtbot.addWidget(w)
    assert w.setup.speed.isHidden() and w.setup.run_settings() == {"port": "/dev/null"}
    assert w.setup.estimate.text().startswith("5 spots after a 3 s rest: about")
    assert "simulator" not in w.setup.estimate.text()


def test_the_characterisation_plan_says_what_it_takes(qtbot, tmp_path):
    from tactile_studio.ui.characterise_wizard import CharacteriseWizard

    w = CharacteriseWizard(str(tmp_path / "run"))
    qtbot.addWidget(w)
    w.show()
    w.next()
    plan = w.plan_page
    assert plan.estimate.text().startswith("Takes: 6 taxel(s) x normal, shear: about")
    assert "of stage time (the simulated bench at speed 0: about" in plan.estimate.text()
    plan.set_param("sequences", "normal,shear,repeat")
    assert "repeat (22,000 cycles): about" in plan.estimate.text()
    assert " h of stage time" in plan.estimate.text()
    plan.taxels.setText("all")
    assert plan.estimate.text().startswith("Takes: 36 taxel(s)")
