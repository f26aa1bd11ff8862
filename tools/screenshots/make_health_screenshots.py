"""Regenerate the screenshots of the wellness and calibration wizards and the Sensors window.

Everything runs on the simulated sensor in a temporary logbook; the run pages are
grabbed in each phase while the simulated device places the weights in real time.

    QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_health_screenshots.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

HERE = (Path(__file__).resolve().parents[2] / "docs" / "screenshots")


def _wait(app, cond, timeout: float = 120.0) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise TimeoutError("screenshot state not reached")
        app.processEvents()
        time.sleep(0.01)


def _grab_phases(app, wizard, prefix: str, phases: tuple[str, ...]) -> None:
    page = wizard.run_page
    for phase in phases:
        _wait(app, lambda: page.phase.text().lower().startswith(phase))
        wizard.grab().save(str(HERE / f"{prefix}-run-{phase}.png"))


def live_speed(wizard) -> None:  # noqa: ANN001
    """Run at the speed the wizard was opened with (the last choice), not full speed."""
    wizard.setup.speed.setCurrentIndex(wizard.setup.speed.count() - 1)


def main() -> int:
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    os.environ["TACTILE_STUDIO_DATA_DIR"] = tempfile.mkdtemp(prefix="ts-health-shots-")
    from tactile_studio.cli import main as cli
    from tactile_studio.storage.books.logbook import Logbook
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.calibration_wizard import CalibrationWizard
    from tactile_studio.ui.sensors_window import SensorsWindow
    from tactile_studio.ui.wellness_wizard import WellnessWizard

    app = ensure_app()
    # a history: healthy checks, hours of use, then a taxel wearing out (E5 = taxel 28)
    base = ["wellness", "--set", "speed=0", "--set", "seed=21", "--sensor", "sim-21",
            "--weight-g", "200", "--auto", "--json"]
    for hours, extra in ((0, []), (6, []), (12, ["--set", "fault=worn", "--set", "fault_taxel=28"]),
                         (20, ["--set", "fault=worn", "--set", "fault_taxel=28"])):
        with Logbook() as book:
            book.ensure_sensor("sim-21")
            book.add_usage("sim-21", hours * 3600.0 - book.hours("sim-21") * 3600.0)
        cli([*base, *extra])
    cli(["calibrate", "--set", "speed=0", "--set", "seed=21", "--set", "sensitivity_spread=0.1",
         "--sensor", "sim-21", "--loads-g", "1000,2000,5000,10000,20000", "--plate", "--auto",
         "--out", os.path.join(os.environ["TACTILE_STUDIO_DATA_DIR"], "cal.json")])
    with Logbook() as book:
        book.add_note("sim-21", "E5 re-glued after the 20 h check", "repair")
        book.add_usage("sim-21", 2 * 3600.0)
    cli(base)  # after the repair, against the new calibration: a new line in the trend
    s = SensorsWindow()  # the history as the CLI made it (the wizards below add to it)
    s.show()
    app.processEvents()
    s.grab().save(str(HERE / "sensors-window.png"))
    s.close()

    w = WellnessWizard("simulated", {"speed": 4, "seed": 21, "fault": "worn",
                                     "fault_taxel": 28})
    w.show()
    w.setup.spots.setText("B2,B5,E2,E5,C3")
    app.processEvents()
    w.grab().save(str(HERE / "wellness-setup.png"))
    live_speed(w)  # slow enough to grab each phase
    w.next()
    _grab_phases(app, w, "wellness", ("rest", "place", "settling", "recording", "lift"))
    _wait(app, lambda: w.run_page.phase.text() == "Done")
    w.next()
    app.processEvents()
    w.grab().save(str(HERE / "wellness-result.png"))
    w.done(0)

    # the weight put on the wrong taxel: the page says where it is
    from tactile_studio.health.bench import SimulatedPlacer

    class WrongPlacer(SimulatedPlacer):
        def place(self, mass_g, taxel, contact_mm):
            return super().place(mass_g, "C4" if taxel == "B2" else taxel, contact_mm)

    m = WellnessWizard("simulated", {"speed": 2, "seed": 21})
    make = m._make_run

    def misplacing():
        run = make()
        run.placer = WrongPlacer(run.device)
        return run
    m.run_page.make_run = misplacing
    live_speed(m)
    m.show()
    m.next()
    _wait(app, lambda: m.run_page.picture.detected == "C4")
    m.grab().save(str(HERE / "wellness-run-misplaced.png"))
    m.done(0)

    c = CalibrationWizard("simulated", {"speed": 8, "seed": 21, "sensitivity_spread": 0.1})
    c.show()
    app.processEvents()
    c.grab().save(str(HERE / "calibration-setup.png"))  # as it opens: plate first
    c.setup.per_taxel.setChecked(True)
    c.setup.taxels.setText("B2,B5,E2,E5")
    live_speed(c)
    c.next()
    _grab_phases(app, c, "calibration", ("place", "settling"))
    _wait(app, lambda: c.run_page.phase.text() == "Done", timeout=600)
    c.next()
    app.processEvents()
    c.grab().save(str(HERE / "calibration-result.png"))
    c.done(0)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
