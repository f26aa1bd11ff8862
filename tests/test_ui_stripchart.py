"""The strip chart at display rate: thinned to the screen's pixel columns without losing a
peak, and no plot items created per frame, alone and in the running main window.

Offscreen Qt (tests/conftest.py); the main window runs the simulated sensor at 1 kHz.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactile_studio.live import History
from tactile_studio.live.view import decimate_minmax
from tactile_studio.ui.main_window import MainWindow
from tactile_studio.ui.settings import SETTINGS_ENV
from tactile_studio.ui.stripchart import StripChart

NAMES = ["A1", "B2", "C3", "D4", "E5", "F6", "A6", "F1"]
STRIP_8 = [(1, 1), (1, 4), (2, 2), (2, 3), (3, 2), (3, 3), (4, 1), (4, 4)]


@pytest.fixture(autouse=True)
def isolated_settings(tmp_path, monkeypatch):
    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))


def _spiky(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Noise with one-sample spikes up and down: what thinning by skipping would lose."""
    rng = np.random.default_rng(seed)
    t = np.linspace(-10.0, 0.0, n)
    v = rng.normal(0.0, 0.1, (n, len(NAMES))).astype(np.float32)
    for k in range(len(NAMES)):
        at = rng.choice(n, 12, replace=False)
        v[at[:6], k] += 5.0 + k
        v[at[6:], k] -= 4.0 + k
    return t, v


def _columns(t: np.ndarray, columns: int) -> np.ndarray:
    """The pixel column of each time in -10..0 s, computed here independently."""
    return np.minimum(np.floor((t + 10.0) * (columns / 10.0)), columns - 1).astype(int)


def test_decimation_keeps_every_columns_min_and_max():
    t, v = _spiky(20_000)
    columns = 300
    dt, dv = decimate_minmax(t, v, -10.0, 0.0, columns)
    assert len(dt) <= 2 * columns < len(t)
    assert np.all(np.diff(dt) >= 0)  # still in time order
    cols, dcols = _columns(t, columns), _columns(dt, columns)
    for c in np.unique(cols):
        here = v[cols == c]
        drawn = dv[dcols == c]
        assert np.array_equal(drawn.min(axis=0), here.min(axis=0))
        assert np.array_equal(drawn.max(axis=0), here.max(axis=0))
    # few samples a column: nothing is thinned
    st, sv = decimate_minmax(t[:500], v[:500], -10.0, 0.0, columns)
    assert st is t[:500] or np.array_equal(st, t[:500])
    assert np.array_equal(sv, v[:500])


def test_a_narrow_chart_draws_two_points_a_column_and_every_spike(qtbot):
    chart = StripChart(seconds=10.0)
    qtbot.addWidget(chart)
    chart.resize(360, 200)
    chart.show()
    qtbot.waitExposed(chart)
    t, v = _spiky(5000, seed=1)
    chart.set_history(History(t, v, NAMES, "normal", "kPa"))
    columns = chart.pixel_columns()
    assert 100 < columns <= chart.plot_widget.width()
    for k, name in enumerate(NAMES):
        dt, dv = chart.line_data(name)
        assert len(dt) <= 2 * columns < len(t)
        # the spikes survive: the drawn line reaches the true extremes
        assert dv.max() == v[:, k].max() and dv.min() == v[:, k].min()
        cols, dcols = _columns(t, columns), _columns(dt, columns)
        for c in np.unique(cols)[::7]:
            assert dv[dcols == c].max() == v[cols == c, k].max()
            assert dv[dcols == c].min() == v[cols == c, k].min()


def test_the_running_window_creates_no_plot_items_per_frame(qtbot):
    w = MainWindow(device="simulated", settings={"rate": "1000", "gesture": "Twist"},
                   connect=True, persist=False)
    qtbot.addWidget(w)
    try:
        w.set_strip_taxels(STRIP_8)
        w.show()
        qtbot.waitUntil(lambda: "C3" in w.strip.curve_names()
                        and len(w.strip.line_data("C3")[0]) > 50, timeout=10_000)
        strip_scene, heat_scene = w.strip.plot_widget.scene(), w.heatmap.view.scene()
        strip_items, heat_items = len(strip_scene.items()), len(heat_scene.items())
        strip_plot_items = len(w.strip.plot.items)
        painted, first = w._painted_index, w.strip.line_data("C3")[1].copy()
        # many frames painted and the chart redrawn with new samples
        qtbot.waitUntil(lambda: w._painted_index > painted + 2000
                        and not np.array_equal(w.strip.line_data("C3")[1][-len(first):],
                                               first), timeout=10_000)
        assert w.strip.curve_names() == [w.live.layout.taxel_name(r, c) for r, c in STRIP_8]
        assert len(strip_scene.items()) == strip_items
        assert len(w.strip.plot.items) == strip_plot_items
        assert len(heat_scene.items()) == heat_items
    finally:
        w.shutdown()


def test_eight_names_fit_a_short_chart(qtbot):
    """With 8 taxels the legend takes two columns, so every name stays inside the plot
    of a chart docked at its usual height (one column ran off its bottom edge)."""
    chart = StripChart()
    qtbot.addWidget(chart)
    chart.resize(1000, 220)
    chart.show()
    t, v = _spiky(2_000)
    for names in (NAMES[:3], NAMES):
        chart.set_history(History(t, v[:, :len(names)], list(names), "normal", "kPa"))
        qtbot.wait(50)
        legend = chart.legend.sceneBoundingRect()
        plot = chart.plot.vb.sceneBoundingRect()
        assert plot.contains(legend), (len(names), legend, plot)
