"""Regenerate lsl-device-main-window.png: the live window viewing, through the `lsl` device,
the stream another engine publishes (offscreen, loopback-only LSL).

    QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_lsl_screenshot.py

(lsl-device-panel.png and lsl-collect-console.png come from tests/test_lsl_ui.py with
TACTILE_STUDIO_SHOTS=docs/screenshots.)
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

HERE = (Path(__file__).resolve().parents[2] / "docs" / "screenshots")


def main() -> int:
    os.environ.setdefault("LSLAPICFG", str(HERE.parent.parent / "tests" / "lsl_api.cfg"))
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    os.environ["TACTILE_STUDIO_SETTINGS"] = os.path.join(tempfile.mkdtemp(), "settings.ini")
    from tactile_studio.acquisition.open_stream import open_stream
    from tactile_studio.streams.lsl_outlet import LslStreamer
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.main_window import MainWindow, wait_for

    ensure_app()
    engine = open_stream("simulated", {"rate": 43, "gesture": "Twist"})
    streamer = LslStreamer(engine, name="Lab-sensor").start()
    engine.start()
    w = MainWindow(device="lsl", settings={"name": "Lab-sensor"}, persist=False)
    try:
        w.resize(1280, 800)
        w.show()
        if not w.panel.connect_device():
            raise SystemExit(w.panel.error_text())
        wait_for(3.0)
        w.refresh_status()
        w.tick()
        wait_for(0.1)
        w.grab().save(str(HERE / "lsl-device-main-window.png"))
    finally:
        w.shutdown()
        streamer.stop()
        engine.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
