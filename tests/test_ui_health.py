"""The wellness and calibration wizards and the Sensors window, driven by pytest-qt."""

from __future__ import annotations

import pytest
from PySide6.QtWidgets import QWizard

from tactile_studio.sensor.layout import SHEARSENSE_6X6 as LAY
from tactile_studio.sensor.wellness import parse_taxel
from tactile_studio.storage.logbook import Logbook
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
