"""Regenerate main-window-serial.png: the live window on the serial plugin (offscreen).

The serial emulator streams the simulated sensor's demo gestures into a pty with 5% of
the lines malformed; the window connects to it through the emulator's link path, as a
user typing the port would, and is grabbed mid-gesture once every kind of bad line has
been counted at least once... or after a while, whichever comes first.

    QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_serial_screenshot.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = (Path(__file__).resolve().parents[2] / "docs" / "screenshots")


def main(out: str = str(HERE / "main-window-serial.png")) -> int:
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from tactile_studio.devices.serial_emulator import Corruption, SerialEmulator
    from tactile_studio.storage.recording.frame_sources import simulated_source
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.main_window import MainWindow, wait_for

    ensure_app()
    with tempfile.TemporaryDirectory() as tmp:
        link = Path(tempfile.gettempdir()) / "ts-port"  # short, as a user would type it
        if os.path.lexists(link):
            link = Path(tmp) / "ts-port"
        emu = SerialEmulator(simulated_source(seed=1), rate_hz=44, link=link,
                             corruption=Corruption(0.05, ("short", "non_numeric", "long"), 5))
        emu.open()
        emu.start()
        w = MainWindow(device="serial", settings={"port": emu.port}, connect=True,
                       persist=False)
        try:
            w.resize(1280, 800)
            w.show()
            while w.live.layout is None:
                wait_for(0.05)
            w.hover_taxel("C3")
            deadline = time.monotonic() + 40
            while time.monotonic() < deadline:
                wait_for(0.1)
                img = w.heatmap.image_data()
                kinds = w.acquisition.status().malformed_by_kind
                if (img is not None and len(kinds) >= 3 and sum(kinds.values()) >= 5
                        and float(np.max(img)) > 4.0):
                    break
            w.refresh_status()
            w.grab().save(out)
            print(out)
        finally:
            w.shutdown()
            emu.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:2]))
