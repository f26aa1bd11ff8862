"""LiveView / the main window's LiveAcquisition: what the live screen shows, checked
without any widget.

Real engine and real simulated sensor; waits poll the engine, never sleep-and-assert.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactile_studio.acquisition import LiveAcquisition
from tactile_studio.devices import AcquisitionEngine, create_device
from tactile_studio.errors import SettingsError, UserError
from tactile_studio.live import (
    LatencyMeter,
    LiveView,
    RateMeter,
    parse_taxel_name,
)
from tactile_studio.live.view import _Trail
from tactile_studio.sensor import SHEARSENSE_6X6, decode
from tactile_studio.storage import SessionFile


@pytest.fixture
def engine():
    """A simulated sensor run as fast as possible, stopped before the test looks."""
    eng = AcquisitionEngine(create_device("simulated", {"speed": 0, "gesture": "Twist",
                                                        "rate": 200}))
    eng.start()
    assert eng.wait_frames(1200, timeout=20)
    eng.stop()
    assert eng.baseline is not None
    return eng


def test_no_engine_or_no_frames_gives_nothing():
    lv = LiveView()
    assert lv.latest() is None and lv.readout(0, 0) is None and lv.grid_shape() is None
    h = lv.history([(0, 0)])
    assert h.t.size == 0


def test_latest_decodes_the_newest_frame_on_both_grids(engine):
    lv = LiveView(engine)
    frame = lv.latest()
    newest = engine.latest()
    assert frame.index == engine.frames - 1 == newest.start
    assert frame.host_time == pytest.approx(float(newest.host_time[-1]))
    expected = decode(engine.layout, newest.raw, engine.baseline)
    np.testing.assert_allclose(frame.normal, expected.normal[0])
    np.testing.assert_allclose(frame.shear_x, expected.shear_x[0])
    assert frame.normal.shape == (6, 6) and frame.contact.shape == (6, 6)
    assert frame.units == "kPa" and not frame.provisional_baseline
    assert lv.latest() is frame  # cached until a new frame comes
    lv.virtual = True
    v = lv.latest()
    assert v.normal.shape == v.shear_x.shape == (11, 11) and v.virtual
    assert lv.grid_shape() == (11, 11)


def test_readout_names_values_and_raw_channels(engine):
    lv = LiveView(engine)
    r = lv.readout(2, 3)
    assert r.name == "C4" and r.virtual_between == ()
    frame = lv.latest()
    assert r.normal == pytest.approx(float(frame.normal[2, 3]))
    assert r.shear_y == pytest.approx(float(frame.shear_y[2, 3]))
    taxel = SHEARSENSE_6X6.taxel_at(2, 3)
    assert r.raw == {"C4": tuple(int(v) for v in engine.latest().raw[0, 5 * taxel:5 * taxel + 5])}
    assert r.text().startswith("C4") and "kPa" in r.text()
    assert lv.readout(6, 0) is None


def test_virtual_readout_says_which_taxels_it_lies_between(engine):
    lv = LiveView(engine, virtual=True)
    assert lv.readout(4, 6).name == "C4"
    between_two = lv.readout(4, 7)
    assert between_two.virtual_between == ("C4", "C5") and between_two.name == "C4-C5"
    four = lv.readout(1, 1)
    assert four.virtual_between == ("A1", "A2", "B1", "B2")
    assert "between A1, A2, B1, B2" in four.text()
    assert set(four.raw) == {"A1", "A2", "B1", "B2"}
    assert lv.nearest_taxel(5, 7) == (2, 3)


def test_history_is_decoded_relative_and_thinned(engine):
    lv = LiveView(engine, history_s=10.0, max_points=500)
    h = lv.history([(2, 2), (3, 3)], "normal")
    assert h.names == ["C3", "D4"] and h.units == "kPa"
    assert h.values.shape == (h.t.size, 2)
    assert h.t[-1] == 0.0 and h.t[0] >= -10.0 and np.all(np.diff(h.t) > 0)
    assert h.t.size <= 520  # 10 s thinned to about max_points
    # each point is the decoded value of the frame at that device time
    chunk = engine.read_since(0)
    rows = np.searchsorted(chunk.device_time, h.t + h.t_end - 1e-9)
    full = decode(engine.layout, chunk.raw[rows], engine.baseline)
    np.testing.assert_allclose(h.values[:, 0], full.normal[:, 2, 2], rtol=1e-5, atol=1e-4)
    shear = lv.history([(2, 2)], "shear")
    np.testing.assert_allclose(
        shear.values[:, 0], np.hypot(full.shear_x[:, 2, 2], full.shear_y[:, 2, 2]),
        rtol=1e-4, atol=1e-4)
    with pytest.raises(ValueError):
        lv.history([(0, 0)], "pressure")


def test_history_follows_new_frames_and_a_new_baseline():
    eng = AcquisitionEngine(create_device("simulated", {"rate": 400, "gesture": "idle"}))
    lv = LiveView(eng)
    eng.start()
    try:
        assert eng.wait_frames(150, timeout=20)
        first = lv.history([(0, 0)])
        n = eng.frames
        assert eng.wait_frames(n + 40, timeout=20)
        later = lv.history([(0, 0)])
        assert later.t.size > first.t.size
        old_baseline = eng.baseline
        eng.tare(20)
        assert eng.wait_frames(eng.frames + 40, timeout=20)
        assert eng.baseline is not old_baseline
        again = lv.history([(0, 0)])
        assert again.t.size > 0
    finally:
        eng.stop()


def test_provisional_baseline_before_the_first_tare():
    eng = AcquisitionEngine(create_device("simulated", {"rate": 100, "gesture": "idle"}),
                            baseline_frames=10_000)
    lv = LiveView(eng)
    eng.start()
    try:
        assert eng.wait_frames(5, timeout=20)
        frame = lv.latest()
        assert frame is not None and frame.provisional_baseline
        assert np.all(np.isfinite(frame.normal))
    finally:
        eng.stop()


def test_trail_starts_over_when_the_device_clock_goes_back():
    trail = _Trail((1,), window_s=1.0, max_points=10)
    trail.append(np.arange(0, 2, 0.01), np.zeros((200, 1), np.float32))
    t, _, end = trail.window(1.0)
    assert t.size <= 12 and t[-1] == 0.0 and end == pytest.approx(1.9)
    trail.append(np.array([0.5]), np.ones((1, 1), np.float32))
    t, v, _ = trail.window(1.0)
    assert t.tolist() == [0.0] and v[0, 0] == 1.0


def test_parse_taxel_name():
    assert parse_taxel_name(SHEARSENSE_6X6, "c4") == (2, 3)
    assert parse_taxel_name(SHEARSENSE_6X6, "F6") == (5, 5)
    with pytest.raises(UserError, match=r"A1\.\.F6"):
        parse_taxel_name(SHEARSENSE_6X6, "G1")


def test_meters():
    rate = RateMeter(window_s=1.0)
    for k in range(31):
        rate.tick(100.0 + k / 30)
    assert rate.rate(101.0) == pytest.approx(30.0, rel=0.05)
    assert rate.rate(200.0) == 0.0
    lat = LatencyMeter(keep=3)
    assert lat.percentile(50) is None
    for d in (0.010, 0.020, 0.030, 0.040):
        lat.record(1000.0, 1000.0 + d)
    assert lat.values.tolist() == pytest.approx([0.02, 0.03, 0.04])
    assert lat.percentile(50) == pytest.approx(0.03)
    assert lat.percentile(50, last=1) == pytest.approx(0.04)


def test_controller_connect_record_disconnect(tmp_path):
    c = LiveAcquisition(compress_in_background=True)
    assert c.status().state == "disconnected"
    with pytest.raises(SettingsError):
        c.connect("simulated", {"rate": "fast"})
    with pytest.raises(UserError):
        c.start_recording(tmp_path / "x.h5")
    eng = c.connect("simulated", {"rate": "400"})
    try:
        assert eng.wait_frames(50, timeout=20)
        rec = c.start_recording(tmp_path / "live.h5")
        n = eng.frames
        assert eng.wait_frames(n + 50, timeout=20)
        st = c.status()
        assert st.device == "simulated" and st.state == "running" and st.recording
        assert st.measured_rate_hz > 0 and st.error is None
        path = c.stop_recording()
        assert path == str(rec.path) and c.recorder is None
    finally:
        c.disconnect()
    assert c.status().state == "stopped"
    with SessionFile(path) as s:
        assert s.n_frames >= 50
