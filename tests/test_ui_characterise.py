"""The characterisation wizard driven by pytest-qt on the simulated instruments to a report."""

from __future__ import annotations

import json

import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QWizard

from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.ui.characterise_wizard import CharacteriseWizard

QUICK = {"sequences": "normal,shear", "dwell_s": "0.5", "normal_steps": "4",
         "relax_hold_s": "2", "settle_s": "0.5", "window_s": "0.2", "directions": "+x,+y"}


@pytest.fixture
def wizard(qtbot, tmp_path):
    w = CharacteriseWizard(str(tmp_path / "run"))
    qtbot.addWidget(w)
    w.resize(900, 700)
    w.show()
    yield w
    if w.running:
        w.control.cancel()
        qtbot.waitUntil(lambda: not w.running, timeout=30000)


def fill_plan(w, taxels: str) -> None:
    w.plan_page.taxels.setText(taxels)
    for k, v in QUICK.items():
        w.plan_page.set_param(k, v)


def test_wizard_runs_to_a_report(qtbot, wizard, tmp_path):
    w = wizard
    w.setup.sensor.setText("S-42")
    w.next()
    fill_plan(w, "B2,C3")
    w.next()
    assert w.currentPage() is w.run_page
    qtbot.waitUntil(lambda: w.run_page.finished_run, timeout=90000)
    assert w.run_page.normal.getData()[0] is not None and len(w.run_page.normal.getData()[0]) > 10
    assert w.error == ""
    w.next()
    assert w.currentPage() is w.report
    assert w.report.table.rowCount() == 2
    assert w.report.table.item(0, 0).text() == "B2"
    assert "Run complete" in w.report.summary.text()
    saved = json.loads((tmp_path / "run" / "characterisation.json").read_text())
    assert saved["sensor"] == "S-42" and set(saved["taxels"]) == {"B2", "C3"}
    assert not w.report.maps.pixmap().isNull()
    w.report.grab().save(str(tmp_path / "report.png"))


def test_bad_taxel_stays_on_the_plan_page(qtbot, wizard):
    w = wizard
    w.next()
    w.plan_page.taxels.setText("B2,H9")
    w.next()
    assert w.currentPage() is w.plan_page
    assert "'H9' is not a taxel of shearsense-6x6" in w.plan_page.error.text()


def test_abort_lifts_and_reports_what_was_done(qtbot, wizard):
    w = wizard
    w.next()
    fill_plan(w, "B2,B3,B4")
    w.next()
    qtbot.waitUntil(lambda: w.run_page.status.text().startswith("B3"), timeout=60000)
    qtbot.mouseClick(w.run_page.abort, Qt.LeftButton)
    qtbot.waitUntil(lambda: w.run_page.finished_run, timeout=30000)
    assert "Stopped" in w.run_page.status.text()
    w.next()
    assert w.report.table.rowCount() == 1  # B2 finished before the abort
    assert "stopped" in w.report.summary.text()
    assert w.button(QWizard.FinishButton).isVisible()
    with SessionFile(w.out_dir / "session.h5") as session:
        stage = [e for e in session.events if e["kind"] == "stage"]
    assert stage[-1]["retract"] is True and stage[-1]["z"] == pytest.approx(5.0)


def test_the_main_window_opens_it_from_the_sensors_menu(qtbot, tmp_path, monkeypatch):
    from tactile_studio.ui.main_window import MainWindow
    from tactile_studio.ui.settings import SETTINGS_ENV
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    w = MainWindow(device="simulated", settings={"rate": "200", "gesture": "idle"},
                   persist=False)
    qtbot.addWidget(w)
    w.show()
    assert w.panel.connect_device()
    qtbot.waitUntil(lambda: w.acquisition.engine.state == "running", timeout=10000)
    menu = next(a.menu() for a in w.menuBar().actions() if a.text() == "&Sensors")
    action = next(a for a in menu.actions() if a.text().startswith("Characterise taxels"))
    action.trigger()
    wizard = w._wizard  # noqa: SLF001 - the window keeps the wizard it opened
    assert isinstance(wizard, CharacteriseWizard) and wizard.isVisible()
    assert not w.acquisition.engine.running  # the wizard gets the sensor to itself
    wizard.close()
    w.shutdown()


def answer_next_box(qtbot, button, seen: list[str]) -> None:
    """Click ``button`` on the message box the wizard is about to open (modal)."""
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication, QMessageBox

    def answer() -> None:
        box = QApplication.activeModalWidget()
        if not isinstance(box, QMessageBox):
            QTimer.singleShot(20, answer)
            return
        seen.append(box.text())
        box.button(button).click()
    QTimer.singleShot(0, answer)


def test_a_folder_holding_a_run_is_replaced_only_when_the_user_says_yes(qtbot, wizard, tmp_path):
    from PySide6.QtWidgets import QMessageBox

    from tactile_studio.characterise import CharacterisationRequest, Plan, run_characterisation
    from tactile_studio.devices.registry import create_device
    from tactile_studio.plugins.sim_force import SimulatedForce
    from tactile_studio.plugins.sim_stage import SimulatedStage
    from tactile_studio.sensor.characterise import parse_taxels

    out = tmp_path / "run"
    dev = create_device("simulated", {"speed": 0, "gesture": "idle"})
    run_characterisation(dev, SimulatedStage(), SimulatedForce(), CharacterisationRequest(
        Plan(sequences=("normal",), dwell_s=0.5, normal_steps=4, settle_s=0.5, window_s=0.2),
        parse_taxels(dev.layout, "B2,B3"), out, report=False))
    w, seen = wizard, []
    answer_next_box(qtbot, QMessageBox.StandardButton.No, seen)
    w.next()
    assert w.currentPage() is w.setup  # No: stays, says why, nothing touched
    assert "a finished characterisation of 2 taxel(s)" in seen[0] and str(out) in seen[0]
    assert "choose another folder" in w.setup.error.text()
    assert sorted(p.name for p in (out / "raw").iterdir()) == ["B2.json", "B3.json"]

    answer_next_box(qtbot, QMessageBox.StandardButton.Yes, seen)
    w.next()
    assert w.currentPage() is w.plan_page and w.overwrite
    fill_plan(w, "C3")
    w.plan_page.set_param("sequences", "normal")
    w.next()
    qtbot.waitUntil(lambda: w.run_page.finished_run, timeout=90000)
    assert w.error == ""
    assert sorted(p.name for p in (out / "raw").iterdir()) == ["C3.json"]
    with SessionFile(out / "session.h5") as session:
        assert [e["taxel"] for e in session.events if e["kind"] == "char_taxel"] == ["C3"]


def test_a_folder_that_cannot_be_made_ends_the_run_in_one_line(qtbot, tmp_path):
    blocker = tmp_path / "blocker"
    blocker.write_text("a regular file: no folder can be made under it")
    w = CharacteriseWizard(str(blocker / "run"))
    qtbot.addWidget(w)
    w.show()
    w.next()
    fill_plan(w, "B2")
    w.next()
    qtbot.waitUntil(lambda: w.run_page.finished_run, timeout=30000)
    assert w.error == f"{blocker}/run: cannot write (Not a directory)"
    assert w.run_page.status.text() == f"Stopped: {w.error}"
