"""Regenerate the README screenshots of the live main window (offscreen, no hardware).

A simulated participant performs a gesture and the window is grabbed mid-gesture, once
the map shows shear arrows (the caption names them: a gesture too gentle to drag the
skin over 0.3 kPa showed none), so the pictures show pressure and shear arrows. The
third picture shows stress below baseline with the diverging colour map: the sensor was
tared while a palm rested on it, so where the palm was, counts now read above the
baseline.

    QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_screenshots.py
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = (Path(__file__).resolve().parents[2] / "docs" / "screenshots")


def main(gesture: str = "Wide Pinch", at_s: float = 0.7) -> int:
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from tactile_studio.ui.app import ensure_app
    from tactile_studio.ui.main_window import MainWindow, wait_for

    ensure_app()
    w = MainWindow(device="simulated", settings={"gesture": "idle"}, connect=True,
                   persist=False)
    try:
        w.resize(1280, 800)
        w.show()
        engine = w.acquisition.engine
        while engine.baseline is None and engine.running:
            wait_for(0.1)
        w.hover_taxel("C3")
        for virtual, name in ((False, "main-window.png"), (True, "main-window-virtual.png")):
            w.set_virtual(virtual)
            w.hover_taxel("C3")
            show_arrows(w, gesture, at_s)
            w.refresh_status()
            out = HERE / name
            w.grab().save(str(out))
            print(out)
            wait_for(2.0)  # let the gesture finish before the next one
        below_baseline(w, gesture, at_s)
    finally:
        w.shutdown()
    return 0


def show_arrows(w, gesture: str, at_s: float, tries: int = 6) -> None:  # noqa: ANN001
    """Perform ``gesture`` until the map shows a drag (3 arrows or more); a virtual
    participant's touches vary, and a gentle one drags the skin under 0.3 kPa."""
    from tactile_studio.ui.main_window import wait_for

    for _ in range(tries):
        w.acquisition.engine.device.perform(gesture, duration_s=2.0)
        wait_for(at_s)
        for _ in range(50):
            if w.heatmap.arrows.count() >= 3:
                return
            wait_for(0.025)
        wait_for(1.5)  # let this one end before the next
    raise RuntimeError(f"{gesture}: no shear arrows in {tries} tries")


def below_baseline(w, gesture: str, at_s: float) -> None:  # noqa: ANN001 - MainWindow
    """Tare under a resting palm, lift it, and grab mid-gesture with the diverging map."""
    from tactile_studio.ui.main_window import wait_for

    engine = w.acquisition.engine
    w.set_virtual(False)
    w.heatmap.set_color_scheme("diverging")
    engine.device.perform("Constant Touch", duration_s=4.0)
    wait_for(1.5)
    taring = len(engine.events_since(0))
    engine.tare(20)
    while not any(e["kind"] == "tare" for e in engine.events_since(taring)):
        wait_for(0.05)
    wait_for(3.0)  # the palm lifts: where it rested now reads below baseline
    engine.device.perform(gesture, duration_s=2.0)
    wait_for(at_s)
    w.paint_timer.stop()  # hold the frame: the readout names the lowest taxel shown
    low = w.heatmap.image_data()
    w.heatmap.hover_cell(*divmod(int(low.argmin()), low.shape[1]))
    w.refresh_status()
    out = HERE / "main-window-below-baseline.png"
    w.grab().save(str(out))
    w.paint_timer.start()
    print(out)
    w.heatmap.set_color_scheme("sequential")


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:2]))
