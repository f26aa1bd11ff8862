"""Screenshots of the research workspace's Sweep tab (offscreen): idle with the choices,
running with per-task progress, finished with the results table. The data are virtual
participants at the simulator's default ("real") difficulty, so the models differ.

    QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_sweep_screenshots.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or ROOT / "docs" / "screenshots")


def main() -> int:
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    sys.path.insert(0, str(ROOT / "tests"))  # the simulated-session writer the tests use
    from learn_fixtures import make_dataset_folder

    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.research.window import ResearchWindow

    app = ensure_app()

    def settle(seconds: float = 0.2) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            app.processEvents()
            time.sleep(0.02)

    def wait(cond, timeout: float) -> None:  # noqa: ANN001
        end = time.monotonic() + timeout
        while not cond():
            if time.monotonic() > end:
                raise SystemExit("timed out")
            settle(0.1)

    with tempfile.TemporaryDirectory() as tmp:
        os.environ["TACTILE_STUDIO_SETTINGS"] = str(Path(tmp) / "settings.ini")
        os.environ["TACTILE_STUDIO_CACHE_DIR"] = str(Path(tmp) / "cache")
        make_dataset_folder(Path(tmp) / "sessions", participants=5, blocks=2,
                            difficulty="real")
        w = ResearchWindow()
        w.resize(1400, 860)
        w.show()
        w.sessions.set_folders([str(Path(tmp) / "sessions")])
        w.tabs.setCurrentWidget(w.sweep)
        p = w.sweep
        p.set_models(["rf", "knn"])
        p.set_channels(["normal", "shear", "both"])
        p.evaluation.setCurrentText("lopo")
        p.jobs.setValue(2)
        p.out.setText(str(Path(tmp) / "sweeps" / "rf-vs-knn"))
        settle()
        w.grab().save(str(HERE / "research_sweep_idle.png"))
        p.start()
        wait(lambda: p.tasks.rowCount() >= 8, 600)
        settle()
        w.grab().save(str(HERE / "research_sweep_running.png"))
        wait(lambda: not p.job.running, 900)
        settle()
        w.grab().save(str(HERE / "research_sweep_done.png"))
        print(p.status.text())
        w.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
