"""The live heatmap and strip chart as real widgets: stress below baseline, the colour
range (issue 47: fixed at 0-10 kPa, a typical touch looked dark and a 30 kPa press
saturated; now auto by default, said on the bar, never below 0-5 kPa), the arrow field,
no per-frame scene items, hover, and the display's paint pacing.

Offscreen Qt (tests/conftest.py). Frames are decoded by the core from raw counts, so a
taxel whose counts rise above its baseline is what the sensor would really send.
"""

from __future__ import annotations

import numpy as np
import pytest
from ui_helpers import point_at_cell

from tactile_studio.live import History
from tactile_studio.live.meters import PaintPacer
from tactile_studio.sensor import SHEARSENSE_6X6
from tactile_studio.sensor.decode import FrameDecoder
from tactile_studio.sensor.layout import CENTRE, X_NEG, X_POS, Y_NEG, Y_POS
from tactile_studio.sensor.taxels import parse_taxel
from tactile_studio.ui.arrow_field import ArrowField
from tactile_studio.ui.heatmap import HeatmapView
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.settings import SETTINGS_ENV
from tactile_studio.ui.stripchart import StripChart

LAY = SHEARSENSE_6X6
BASE = np.linspace(25000, 35000, LAY.n_channels)


@pytest.fixture(autouse=True)
def isolated_settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


@pytest.fixture
def heat(qtbot):
    h = HeatmapView()
    h.set_layout(LAY)
    qtbot.addWidget(h)
    h.resize(700, 600)
    h.show()
    return h


def _raw(pressed: dict[tuple[int, int], float]) -> np.ndarray:
    """Raw counts: every channel of taxel (r, c) changed by ``rel`` (+ pressed, - lifted)."""
    raw = BASE.copy()
    for (r, c), rel in pressed.items():
        t = LAY.taxel_at(r, c)
        for role in (CENTRE, X_NEG, X_POS, Y_NEG, Y_POS):
            ch = LAY.channel(t, role)
            raw[ch] = BASE[ch] * (1.0 - rel)
    return raw


def _show(heat: HeatmapView, raw: np.ndarray) -> None:
    st = FrameDecoder(LAY, BASE).decode(raw)
    heat.set_frame(st.normal[0], st.shear_x[0], st.shear_y[0], st.units)


def test_stress_below_baseline_shows_only_with_the_diverging_map(heat):
    # C3 pressed, C4 lifted: its counts rise above the baseline -> negative normal stress
    raw = _raw({(2, 2): 0.04, (2, 3): -0.01})
    _show(heat, raw)
    img = heat.image_data()
    assert img[2, 2] > 1.0 and img[2, 3] < -0.05 and img[0, 0] == pytest.approx(0, abs=1e-6)
    colors = heat.image.colors()
    # sequential (default): 0..max, below baseline is painted like zero
    assert heat.color_scheme == "sequential" and heat.levels()[0] == 0.0
    assert colors[2, 3] == colors[0, 0]

    heat.set_color_scheme("diverging")
    lo, hi = heat.levels()
    assert lo < 0 < hi and heat.colorbar.axis.range[0] < 0  # the bar shows the negative range
    colors = heat.image.colors()
    assert colors[2, 3] != colors[0, 0] and colors[2, 2] != colors[0, 0]
    red, green, blue = (int(colors[2, 3]) >> s & 0xFF for s in (16, 8, 0))
    assert blue > red  # below baseline is blue, load is red
    red, green, blue = (int(colors[2, 2]) >> s & 0xFF for s in (16, 8, 0))
    assert red > blue

    # auto range keeps the negative side and zero white
    heat.set_range(None)
    _show(heat, raw)
    lo, hi = heat.levels()
    assert lo < 0 < hi
    zero = int(heat.image.colors()[0, 0])
    assert min(zero >> 16 & 0xFF, zero >> 8 & 0xFF, zero & 0xFF) > 230


# ---- the colour range ----
def frame(**kpa: float) -> np.ndarray:
    """A 6x6 normal-stress frame with a little noise and the named taxels loaded."""
    normal = np.random.default_rng(0).normal(0.0, 0.08, (6, 6)).astype(np.float32)
    for name, value in kpa.items():
        r, c = LAY.taxel_rc(parse_taxel(LAY, name))
        normal[r, c] = value
    return normal


def brightness(heat: HeatmapView, name: str) -> int:
    r, c = LAY.taxel_rc(parse_taxel(LAY, name))
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
    w = MainWindow(device="simulated", settings={"gesture": "idle"}, persist=False)
    qtbot.addWidget(w)
    assert w.heatmap.fixed_max is None and w.heatmap.auto_range.isChecked()


def _shear_frame(vectors: dict[tuple[int, int], tuple[float, float]]):
    sx = np.zeros((6, 6), np.float32)
    sy = np.zeros((6, 6), np.float32)
    for (r, c), (x, y) in vectors.items():
        sx[r, c], sy[r, c] = x, y
    return np.zeros((6, 6), np.float32), sx, sy


def test_all_arrows_are_one_item_that_follows_the_shear_field(heat):
    arrow_items = [i for i in heat.plot.items if isinstance(i, ArrowField)]
    assert arrow_items == [heat.arrows]
    heat.set_arrow_scale(0.5)
    normal, sx, sy = _shear_frame({(1, 2): (2.0, 0.0), (4, 4): (0.0, -3.0),
                                   (3, 0): (0.1, 0.0)})  # the last is below 0.3 kPa: hidden
    heat.set_frame(normal, sx, sy)
    assert heat.arrows.count() == 2
    g = heat.arrows.geometry
    tails = {tuple(p) for p in g["dots"]}
    assert tails == {(2.0, 1.0), (4.0, 4.0)}  # (x = column, y = row) of the taxels
    tips = {tuple(np.round(h[0], 6)) for h in g["heads"]}
    assert tips == {(3.0, 1.0), (4.0, 2.5)}   # centre + 0.5 pitch/kPa x shear
    # the field changes: the same item, new geometry
    normal, sx, sy = _shear_frame({(0, 0): (-1.0, 1.0)})
    heat.set_frame(normal, sx, sy)
    assert heat.arrows.count() == 1 and [i for i in heat.plot.items
                                         if isinstance(i, ArrowField)] == [heat.arrows]
    assert tuple(heat.arrows.geometry["dots"][0]) == (0.0, 0.0)
    heat.set_arrows_visible(False)
    heat.set_frame(normal, sx, sy)
    assert heat.arrows.count() == 0


def test_short_arrows_keep_their_dot_and_lose_the_head(heat):
    heat.set_arrow_scale(0.1)
    normal, sx, sy = _shear_frame({(2, 2): (0.5, 0.0), (3, 3): (8.0, 0.0)})
    heat.set_frame(normal, sx, sy)
    g = heat.arrows.geometry
    assert heat.arrows.count() == 2 and len(g["dots"]) == 2
    assert len(g["heads"]) == 1 and g["heads"][0][0][0] == pytest.approx(3 + 0.8)


def test_frames_create_no_scene_items(qtbot, heat):
    rng = np.random.default_rng(0)
    heat.set_color_scheme("diverging")
    heat.set_range(None)
    _show(heat, _raw({(2, 2): 0.03}))
    qtbot.wait(20)
    before = len(heat.view.scene().items())
    for k in range(60):
        raw = BASE * (1.0 - rng.uniform(-0.02, 0.06, LAY.n_channels))
        _show(heat, raw)
        if k % 10 == 0:
            qtbot.wait(5)  # let it paint now and then
    assert len(heat.view.scene().items()) == before

    chart = StripChart(seconds=10.0)
    qtbot.addWidget(chart)
    chart.show()
    names = ["A1", "B2", "C3", "D4", "E5", "F6", "A6", "F1"]

    def history(n: int) -> History:
        t = np.linspace(-10, 0, n)
        return History(t, rng.normal(size=(n, 8)).astype(np.float32), names, "normal", "kPa")

    chart.set_history(history(50))
    before = len(chart.plot_widget.scene().items())
    for n in range(60, 600, 20):
        chart.set_history(history(n))
    assert len(chart.plot_widget.scene().items()) == before
    assert chart.curve_names() == names
    t, v = chart.line_data("C3")
    assert len(t) == 580 and t[-1] == 0.0 and t[0] == -10.0


def test_hover_names_the_cell_under_the_pointer_with_either_map(qtbot, heat):
    _show(heat, _raw({(2, 2): 0.04, (2, 3): -0.01}))
    qtbot.waitExposed(heat)
    hovered = []
    heat.cellHovered.connect(lambda r, c: hovered.append((r, c)))

    tries = [0]
    for scheme, cell in (("sequential", (2, 3)), ("diverging", (4, 1))):
        heat.set_color_scheme(scheme)
        qtbot.waitUntil(lambda: point_at_cell(qtbot, heat, *cell, tries), timeout=5000)
        assert hovered[-1] == cell


def test_colour_scheme_persists_and_the_live_readout_still_works(qtbot):
    w1 = MainWindow()
    qtbot.addWidget(w1)
    w1.heatmap.set_color_scheme("diverging")
    w1.close()  # saves
    w2 = MainWindow(device="simulated", settings={"rate": "200", "gesture": "idle",
                                                  "noise": "0", "drift": "0"})
    qtbot.addWidget(w2)
    w2.show()
    assert w2.heatmap.color_scheme == "diverging"
    assert w2.heatmap.scheme_box.currentData() == "diverging"
    assert w2.panel.connect_device()
    engine = w2.acquisition.engine
    qtbot.waitUntil(lambda: engine.baseline is not None, timeout=15000)
    qtbot.waitUntil(lambda: w2.heatmap.image_data() is not None, timeout=5000)
    w2.hover_taxel("C4")
    qtbot.waitUntil(lambda: w2.heatmap.readout.text().startswith("C4 "), timeout=5000)
    assert w2.heatmap.levels()[0] < 0
    w2.shutdown()


def test_paint_pacer_paints_at_once_but_never_above_the_display_rate():
    p = PaintPacer(display_hz=50.0)  # 20 ms period
    assert p.delay(0.0) == 0.0
    p.painted(0.0)
    assert p.delay(0.005) == pytest.approx(0.015)
    assert p.delay(0.020) == pytest.approx(0.0, abs=1e-9)
    # a 1 kHz device: paints late by a few ms keep the 20 ms cadence (no drift)
    t = 0.0
    for k in range(1, 50):
        t = 0.020 * k + 0.003 * (k % 3)  # jitter
        assert p.delay(t) == pytest.approx(0.0, abs=1e-9)
        p.painted(t)
    assert p.delay(t) == pytest.approx(0.020 * 50 - t)
    # a slow device (a frame every 23 ms): each is painted on arrival
    p.reset()
    for k in range(20):
        assert p.delay(0.023 * k + 5.0) == 0.0
        p.painted(0.023 * k + 5.0)
