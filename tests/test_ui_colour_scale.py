"""The live colour scale serves a typical touch and a heavy press (issue 47, item 24): it
was fixed at 0-10 kPa, so a typical touch looked dark and a 30 kPa press saturated. Now
auto range by default (said on the colour bar and in the max box), never below 0-5 kPa."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_studio.sensor import SHEARSENSE_6X6
from tactile_studio.sensor.taxels import parse_taxel
from tactile_studio.ui.heatmap import HeatmapView
from tactile_studio.ui.settings import SETTINGS_ENV


@pytest.fixture(autouse=True)
def isolated_settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


@pytest.fixture
def heat(qtbot):
    h = HeatmapView()
    h.set_layout(SHEARSENSE_6X6)
    qtbot.addWidget(h)
    h.resize(700, 600)
    h.show()
    return h


def frame(**kpa: float) -> np.ndarray:
    """A 6x6 normal-stress frame with a little noise and the named taxels loaded."""
    normal = np.random.default_rng(0).normal(0.0, 0.08, (6, 6)).astype(np.float32)
    for name, value in kpa.items():
        r, c = SHEARSENSE_6X6.taxel_rc(parse_taxel(SHEARSENSE_6X6, name))
        normal[r, c] = value
    return normal


def brightness(heat: HeatmapView, name: str) -> int:
    r, c = SHEARSENSE_6X6.taxel_rc(parse_taxel(SHEARSENSE_6X6, name))
    colour = int(heat.image.colors()[r, c])
    return sum(colour >> s & 0xFF for s in (16, 8, 0))


def test_auto_range_is_the_default_and_says_so(heat):
    assert heat.fixed_max is None and heat.auto_range.isChecked()
    assert not heat.max_spin.isEnabled()
    assert heat.colorbar.axis.labelText == "Normal stress (kPa), auto range"


def test_a_typical_touch_fills_the_scale_and_a_heavy_press_does_not_saturate(heat):
    heat.set_frame(frame())  # idle: the floor keeps the noise dark
    assert heat.levels() == (0.0, 5.0) and heat.max_spin.value() == 5.0
    idle = brightness(heat, "C3")
    heat.set_frame(frame(C3=4.0, C4=2.0))  # a typical touch (real people's peaks 3-13 kPa)
    assert heat.levels() == (0.0, 5.0)
    assert brightness(heat, "C3") > brightness(heat, "C4") > idle
    assert brightness(heat, "C3") > 380  # viridis at 80% (412); on 0-10 it was 40% (304)
    heat.set_frame(frame(C3=30.0, C4=20.0))  # a heavy press: a 0-30 scale, both readable
    assert heat.levels() == (0.0, 30.0) and heat.max_spin.value() == 30.0
    assert brightness(heat, "C3") > brightness(heat, "C4")
    for _ in range(200):  # released: back to the floor, not below it
        heat.set_frame(frame())
    assert heat.levels() == (0.0, 5.0)


def test_a_fixed_range_is_still_there_and_said(heat):
    heat.auto_range.setChecked(False)
    assert heat.max_spin.isEnabled() and heat.fixed_max == heat.max_spin.value()
    heat.max_spin.setValue(40.0)
    heat.set_frame(frame(C3=30.0))
    assert heat.levels() == (0.0, 40.0)
    assert heat.colorbar.axis.labelText == "Normal stress (kPa)"


def test_the_main_window_opens_on_auto_range(qtbot):
    from tactile_studio.ui.main_window import MainWindow
    w = MainWindow(device="simulated", settings={"gesture": "idle"}, persist=False)
    qtbot.addWidget(w)
    assert w.heatmap.fixed_max is None and w.heatmap.auto_range.isChecked()
