"""Screenshots of the characterisation wizard on the simulated bench (offscreen).

    QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_characterise_screenshots.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

HERE = (Path(__file__).resolve().parents[2] / "docs" / "screenshots")


def main() -> int:
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.characterise_wizard import CharacteriseWizard

    app = ensure_app()

    def settle(seconds: float = 0.2) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            app.processEvents()
            time.sleep(0.01)

    with tempfile.TemporaryDirectory() as tmp:
        w = CharacteriseWizard(str(Path(tmp) / "run"))
        w.resize(1000, 760)
        w.show()
        w.setup.sensor.setText("SIM-0")
        settle()
        w.grab().save(str(HERE / "characterise-instruments.png"))
        w.next()
        w.plan_page.taxels.setText("B2,B5,E2,E5")
        for k, v in {"sequences": "normal,shear", "dwell_s": "1"}.items():
            w.plan_page.set_param(k, v)
        settle()
        w.grab().save(str(HERE / "characterise-plan.png"))
        w.next()
        while not w.run_page.status.text().startswith("B5: shear"):
            settle(0.05)
        settle(1.0)
        w.grab().save(str(HERE / "characterise-run.png"))
        while not w.run_page.finished_run:
            settle(0.1)
        w.next()
        settle()
        w.grab().save(str(HERE / "characterise-report.png"))
        for name in ("maps.png", "B2.png"):
            (HERE / f"characterise-{name}").write_bytes(
                (Path(tmp) / "run" / "figures" / name).read_bytes())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
