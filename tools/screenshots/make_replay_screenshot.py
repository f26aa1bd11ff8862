"""Regenerate main-window-replay-malformed.png: the live window replaying an old-format
ShearSense CSV (quoted decimal counts) with 6 short rows and 2 merged numbers; the
status bar and device panel show them by kind, as `import` counts them.

    QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_replay_screenshot.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

HERE = (Path(__file__).resolve().parents[2] / "docs" / "screenshots")


def _bad_csv(folder: Path) -> Path:
    """Simulated touches written as the old software did: every count a quoted decimal."""
    import re

    import numpy as np

    from tactile_studio.simulate.simulator import SensorSimulator, SimConfig
    from tactile_studio.storage.exchange.shearsense import write_shearsense_csv

    sim = SensorSimulator(SimConfig(rate=44.0, seed=3, gesture="idle", style_seed=5))
    for k, g in enumerate(("Poke", "Circular Stroke", "Heavy Pat", "Back & Forth Rub")):
        sim.perform(g, 2.5, at_frame=40 + 130 * k)
    raw = sim.step(600)
    times = 1.69e9 + np.arange(600) / 44.0
    path = write_shearsense_csv(folder / "P03_old_FLAT.csv", raw, times,
                                np.zeros(600, dtype=np.int64), raw[:30].mean(axis=0))
    lines = [re.sub(r'"(\d+)"', r'"\1.0"', ln) for ln in path.read_text().splitlines()]
    for i in range(6):
        lines.insert(10 + 7 * i, '"1690000000.5","1491.0","1502.0"')
    for i in range(2):
        lines.insert(70 + i, ",".join(['"1690000001.0"'] + ['"25000.0"'] * 179
                                      + ['"2500025000.0"', '"0.0"', '"0.0"']))
    path.write_text("\n".join(lines) + "\n")
    return path


def main(out: str = str(HERE / "main-window-replay-malformed.png")) -> int:
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.main_window import MainWindow, wait_for

    ensure_app()
    with tempfile.TemporaryDirectory() as tmp:
        csv = _bad_csv(Path(tmp))
        w = MainWindow(device="replay", settings={"path": str(csv), "speed": 1.0},
                       connect=True, persist=False)
        try:
            w.resize(1280, 800)
            w.show()
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                wait_for(0.1)
                if w.acquisition.status().malformed and w.acquisition.status().frames > 215:
                    break
            w.refresh_status()
            w.grab().save(out)
            print(out, w.acquisition.status().malformed_by_kind)
        finally:
            w.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:2]))
