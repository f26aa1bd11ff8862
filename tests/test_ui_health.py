"""The wellness and calibration wizards and the Sensors window, driven by pytest-qt."""

from __future__ import annotations

import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QWizard

from tactile_studio.sensor.layout import SHEARSENSE_6X6 as LAY
from tactile_studio.sensor.wellness import parse_taxel
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.ui.wellness_wizard import WellnessWizard

FAULTS = [("none", "B2", None), ("dead_taxel", "E5", "E5"), ("stuck_channel", "C3", "C3"),
          ("worn", "B5", "B5"), ("delaminated", "E2", "E2")]


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def finish_run_page(qtbot, wizard):
    page = wizard.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    qtbot.waitUntil(lambda: page.isComplete() and page.phase.text() == "Done", timeout=5000)


@pytest.mark.parametrize("fault, taxel, named", FAULTS)
def test_wellness_wizard_to_the_end(qtbot, tmp_path, fault, taxel, named):
    settings = {"speed": 0, "seed": 21, "fault": fault,
                "fault_taxel": parse_taxel(LAY, taxel)}
    w = WellnessWizard("simulated", settings)
    qtbot.addWidget(w)
    w.show()
    assert w.setup.sensor.currentText() == "sim-21" and w.setup.auto.isChecked()
    w.setup.weight.setValue(200)
    w.next()
    assert w.currentPage() is w.run_page
    finish_run_page(qtbot, w)
    assert w.run_page.phase.text() == "Done"
    w.next()
    assert w.currentPage() is w.result_page
    res = w.result_page.result
    verdict = "pass" if fault == "none" else "fail"
    assert res["verdict"] == verdict
    assert w.result_page.verdict.text().startswith(f"sim-21: {verdict.upper()}")
    rows = {w.result_page.table.item(i, 0).text(): w.result_page.table.item(i, 4).text()
            for i in range(w.result_page.table.rowCount())}
    if named:
        assert rows[named] == "fail" and named in w.result_page.reasons.text()
    else:
        assert set(rows.values()) == {"pass"}
    saved = w.result_page.save_report(str(tmp_path / "r.html"))
    assert "data:image/png" in open(saved).read()
    w.button(QWizard.WizardButton.FinishButton).click()
    with Logbook() as book:
        assert [c["verdict"] for c in book.checks("sim-21")] == [verdict]


def test_wellness_wizard_reports_an_error_and_stores_nothing(qtbot):
    w = WellnessWizard("simulated", {"speed": 0, "seed": 3})
    qtbot.addWidget(w)
    w.show()
    w.setup.spots.setText("B2,Z9")
    w.next()
    finish = w.run_page
    qtbot.waitUntil(lambda: finish.run is not None and not finish.run.running, timeout=20000)
    finish.poll()
    assert "'Z9' is not a taxel" in finish.status.text()
    assert finish.retry_button.isVisibleTo(w) and not finish.isComplete()
    with Logbook() as book:
        assert book.checks("sim-3") == []


@pytest.mark.parametrize("fault, plate", [
    ("none", False), ("none", True), ("worn", False), ("dead_taxel", True),
    ("stuck_channel", False), ("delaminated", False)])
def test_calibration_wizard_to_the_end(qtbot, tmp_path, fault, plate):
    from tactile_studio.ui.calibration_wizard import CalibrationWizard
    settings = {"speed": 0, "seed": 31, "sensitivity_spread": 0.1, "fault": fault,
                "fault_taxel": parse_taxel(LAY, "B2")}
    w = CalibrationWizard("simulated", settings)
    qtbot.addWidget(w)
    w.show()
    (w.setup.plate if plate else w.setup.per_taxel).setChecked(True)
    w.setup.taxels.setText("B2,E5")
    w.setup.out.setText(str(tmp_path / "cal.json"))
    w.next()
    page = w.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    qtbot.waitUntil(lambda: page.phase.text() == "Done", timeout=5000)
    w.next()
    res = w.result_page
    cal = res.result
    n = 36 if plate else 2
    assert res.table.rowCount() == n and (tmp_path / "cal.json").exists()
    rows = {res.table.item(i, 0).text(): res.table.item(i, 1).text() for i in range(n)}
    if fault in ("dead_taxel", "stuck_channel"):  # B2 cannot be calibrated: said, not hidden
        assert rows["B2"] == "not calibrated" and cal["skipped"][0]["taxel"] == "B2"
        assert "B2: the response does not grow" in res.summary.text()
        assert len(cal["fits"]) == n - 1
    else:
        assert cal["skipped"] == [] and set(rows.values()) == {"two-range"}
    assert cal["rms_pct_max"] <= 1.0
    if fault == "worn":  # the worn taxel is calibrated too, with its low sensitivity
        sens = {f["taxel"]: f["sensitivity"] for f in cal["fits"]}
        assert sens["B2"] < 0.6 * sens["E5"]
    w.button(QWizard.WizardButton.FinishButton).click()
    with Logbook() as book:
        assert book.active_calibration("sim-31") == cal["calibration_id"]


def test_calibration_with_no_responding_taxel_stores_nothing(qtbot, tmp_path):
    from tactile_studio.ui.calibration_wizard import CalibrationWizard
    w = CalibrationWizard("simulated", {"speed": 0, "seed": 32, "fault": "dead_taxel",
                                        "fault_taxel": parse_taxel(LAY, "C3")})
    qtbot.addWidget(w)
    w.show()
    w.setup.per_taxel.setChecked(True)
    w.setup.taxels.setText("C3")
    w.setup.out.setText(str(tmp_path / "cal.json"))
    w.next()
    page = w.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    page.poll()
    assert "no taxel could be calibrated (C3: the response" in page.status.text()
    assert not page.isComplete() and not (tmp_path / "cal.json").exists()
    with Logbook() as book:
        assert book.calibrations("sim-32") == []


def test_sensors_window_shows_the_trend(qtbot):
    from tactile_studio.ui.sensors_window import SensorsWindow
    with Logbook() as book:
        book.ensure_sensor("S7")
        for i, ratio in enumerate((1.0, 0.9, 0.7, 0.45)):
            book.add_usage("S7", 3600.0 * 6)
            verdict = "pass" if ratio > 0.8 else ("warn" if ratio > 0.5 else "fail")
            book.add_check("S7", {"verdict": verdict, "weight_g": 200, "reasons": [],
                                  "spots": [{"taxel": "E5", "normal_kpa": 10 * ratio,
                                             "shear_kpa": 0.0, "ratio": ratio,
                                             "verdict": verdict}]})
        book.add_calibration("S7", "plate", 0.3, {"fits": []})
    w = SensorsWindow()
    qtbot.addWidget(w)
    w.show()
    assert w.sensors.currentItem().text() == "S7"
    curves = [c for c in w.trend.getPlotItem().listDataItems() if c.name() == "E5"]
    assert len(curves) == 1
    x, y = curves[0].getData()
    assert list(x) == [6.0, 12.0, 18.0, 24.0] and list(y) == [1.0, 0.9, 0.7, 0.45]
    assert len(w.timeline.getPlotItem().listDataItems()) == 4
    assert "24.00 h of use" in w.facts.text() and "FAIL" in w.facts.text()
    assert w.calibrations.item(0, 0).text() == "1 (active)"
    w.note_kind.setCurrentText("re-covered")
    qtbot.keyClicks(w.note_text, "new skin")
    qtbot.mouseClick(w.add_note_button, Qt.MouseButton.LeftButton)
    assert w.notes.item(0).text().endswith("[re-covered] new skin")
    with Logbook() as book:
        assert book.notes("S7")[0]["text"] == "new skin"


def test_main_window_sensor_id_goes_into_recordings_and_menus_open(qtbot, tmp_path,
                                                                   monkeypatch):
    from tactile_studio.storage.format.session_file import SessionFile
    from tactile_studio.ui.main_window import MainWindow
    from tactile_studio.ui.settings import SETTINGS_ENV
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    w = MainWindow(device="simulated", settings={"rate": "200", "gesture": "idle"},
                   persist=False)
    qtbot.addWidget(w)
    w.show()
    assert w.panel.connect_device()
    qtbot.waitUntil(lambda: w.acquisition.engine.state == "running", timeout=10000)
    w.panel.sensor_box.setCurrentText("array-007")
    assert w.panel.start_recording(str(tmp_path / "s.h5"))
    qtbot.waitUntil(lambda: w.acquisition.recorder.rows_written > 50, timeout=10000)
    w.panel.stop_recording()
    with SessionFile(tmp_path / "s.h5") as s:
        assert s.metadata["sensor_id"] == "array-007"
    with Logbook() as book:
        assert book.hours("array-007") > 0
    wizard = w.open_health("wellness")
    assert not w.acquisition.engine.running  # the wizard gets the device to itself
    assert wizard.setup.device == "simulated" and wizard.setup.settings["rate"] == "200"
    wizard.done(0)
    sensors = w.open_sensors()
    assert "array-007" in [sensors.sensors.item(i).text() for i in range(sensors.sensors.count())]
    sensors.close()
    w.shutdown()
