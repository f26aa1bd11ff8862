"""The simulated sensor: determinism, physics read back through the real decoder, faults,
gestures, and the device plugin through the real acquisition engine."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.errors import SettingsError
from tactile_studio.plugins.simulated import SimulatedSensor
from tactile_studio.sensor.decode import compute_baseline, contact_map, decode
from tactile_studio.sensor.layout import SHEARSENSE_6X6 as LAYOUT
from tactile_studio.simulate import (
    GESTURE_NAMES,
    GESTURES,
    SensorSimulator,
    canonical_gesture,
)

RATE = 43.0
TAXEL = (2, 2)       # row, col of the taxel the presses aim at
TX, TY = 32.0, 32.0  # its centre in mm


def _tared(**kw) -> tuple[SensorSimulator, np.ndarray]:
    """An idle simulator and the baseline of its first 100 frames (the engine's tare)."""
    sim = SensorSimulator(gesture="idle", **{"difficulty": "easy", **kw})  # the original sensor
    return sim, compute_baseline(sim.step(100), 100)


def _held_press(sim: SensorSimulator, base: np.ndarray, frames: int = 260, **press):
    """Decode ``frames`` frames of a press that lasts longer than that."""
    sim.press(duration_s=frames / RATE + 5.0, **press)
    raw = sim.step(frames)
    return raw, decode(LAYOUT, raw, base), decode(LAYOUT, raw, base, virtual=True)


# ---- determinism ---------------------------------------------------------------------

def _scripted(batches: list[int], seed: int = 3) -> np.ndarray:
    sim = SensorSimulator(seed=seed, gesture="auto", style_seed=5)
    sim.perform("Twist", 2.0, at_frame=200)
    sim.perform("tickle", 1.5, intensity=1.4, at_frame=350)
    sim.set_style(9, at_frame=500)
    sim.set_gesture("Heavy Pat", at_frame=600)
    return np.concatenate([sim.step(b) for b in batches])


def test_same_seed_gives_identical_frames_whatever_the_batch_sizes():
    one_go = _scripted([900])
    rng = np.random.default_rng(0)
    sizes = [int(v) for v in rng.integers(1, 40, 30)]
    sizes.append(900 - sum(sizes))
    assert sum(sizes) == 900 and min(sizes) > 0
    assert np.array_equal(one_go, _scripted(sizes))
    assert np.array_equal(one_go, _scripted([1] * 900))
    assert not np.array_equal(one_go, _scripted([900], seed=4))


def test_scheduling_ahead_equals_commanding_on_time():
    ahead = SensorSimulator(seed=1, gesture="idle")
    ahead.perform("Circular Stroke", 2.0, at_frame=150)
    a = ahead.step(300)
    live = SensorSimulator(seed=1, gesture="idle")
    b1 = live.step(150)
    live.perform("circular stroke", 2.0)  # starts at the next frame: 150
    b = np.concatenate([b1, live.step(150)])
    assert np.array_equal(a, b)
    assert live.gesture_at(149) == "idle" and live.gesture_at(150) == "Circular Stroke"
    with pytest.raises(ValueError, match="already generated"):
        live.perform("Poke", at_frame=10)


def test_style_seed_changes_the_performance_but_is_consistent():
    def trial(style: int) -> np.ndarray:
        sim = SensorSimulator(seed=2, gesture="idle", style_seed=style, noise=0.0)
        sim.perform("Poke", 2.0, at_frame=50)
        return sim.step(140)
    assert np.array_equal(trial(1), trial(1))
    assert not np.array_equal(trial(1), trial(2))


# ---- physics through the decoder -----------------------------------------------------

def test_idle_frames_decode_to_about_zero():
    sim, base = _tared()
    d = decode(LAYOUT, sim.step(400), base)
    assert np.abs(d.normal).max() < 0.6
    assert np.abs(d.shear_x).max() < 0.2 and np.abs(d.shear_y).max() < 0.2
    assert sim.current_gesture == "idle"


def test_press_reads_positive_normal_at_the_contact():
    sim, base = _tared()
    raw, d, _ = _held_press(sim, base, x_mm=TX, y_mm=TY, load_kpa=8.0)
    late = d.normal[-20:].mean(axis=0)
    assert 6.5 < late[TAXEL] < 9.5
    assert late[TAXEL] == late.max()
    assert late[5, 5] < 0.5  # far corner untouched
    assert sim.current_gesture == "press"


@pytest.mark.parametrize("sx, sy", [(2.0, 0.0), (-2.0, 0.0), (0.0, 2.0), (0.0, -2.0)])
def test_shear_points_the_way_the_finger_drags(sx, sy):
    sim, base = _tared()
    _, d, _ = _held_press(sim, base, x_mm=TX, y_mm=TY, load_kpa=8.0, shear_x=sx, shear_y=sy)
    got_x = d.shear_x[-20:, TAXEL[0], TAXEL[1]].mean()
    got_y = d.shear_y[-20:, TAXEL[0], TAXEL[1]].mean()
    main, other = (got_x, got_y) if sx else (got_y, got_x)
    want = sx or sy
    assert np.sign(main) == np.sign(want) and 0.75 * abs(want) < abs(main) < 1.25 * abs(want)
    assert abs(other) < 0.15 * abs(want) + 0.1  # crosstalk is ~7%


def test_back_and_forth_rub_shear_follows_the_sliding_finger():
    sim, base = _tared(style_seed=0)
    trial = sim.perform("Back & Forth Rub", 2.0)
    frames = np.arange(trial.start, trial.stop)
    d = decode(LAYOUT, sim.step(trial.frames), base)
    c = sim.contacts(trial, frames)
    vx, vy = np.gradient(c.x[:, 0]), np.gradient(c.y[:, 0])
    drag = d.shear_x.sum(axis=(1, 2)) * vx + d.shear_y.sum(axis=(1, 2)) * vy
    moving = np.hypot(vx, vy) > 0.5 * np.hypot(vx, vy).max()
    assert (drag[moving] > 0).mean() > 0.8


def test_viscoelastic_creep_and_residue_over_about_three_seconds():
    sim, base = _tared()
    sim.press(TX, TY, 10.0, duration_s=8.0, ramp_s=0.0)
    raw = sim.step(round(8.0 * RATE) + round(4.0 * RATE))
    n = decode(LAYOUT, raw, base).normal[:, TAXEL[0], TAXEL[1]]
    early, late = n[round(0.2 * RATE)], n[round(7.5 * RATE)]
    assert late > 1.12 * early  # creeps on under a constant load
    off = round(8.0 * RATE)
    assert n[off + 2] > 0.8  # residue right after release (apparent hysteresis)
    assert n[off + round(3.5 * RATE):].mean() < 0.5 * n[off + 2]  # ... which relaxes


def test_creep_zero_gives_a_flat_response():
    sim, base = _tared(creep=0.0)
    sim.press(TX, TY, 10.0, duration_s=8.0, ramp_s=0.0)
    n = decode(LAYOUT, sim.step(round(8.0 * RATE)), base).normal[:, TAXEL[0], TAXEL[1]]
    assert abs(n[round(7.5 * RATE)] - n[round(0.2 * RATE)]) < 0.3


# ---- virtual taxels (11x11) from the simulator's physics -----------------------------

def test_uniform_load_gives_a_uniform_virtual_map():
    sim, base = _tared()
    _, _, v = _held_press(sim, base, x_mm=40.0, y_mm=40.0, load_kpa=6.0, radius_mm=5000.0)
    m = v.normal[-20:].mean(axis=0)
    assert m.shape == (11, 11)
    assert m.mean() > 4.0 and m.std() / m.mean() < 0.06


def test_load_between_two_taxels_peaks_on_the_virtual_taxel_between_them():
    sim, base = _tared()
    _, d, v = _held_press(sim, base, x_mm=TX + 8.0, y_mm=TY, load_kpa=8.0)
    m = v.normal[-20:].mean(axis=0)
    assert np.unravel_index(m.argmax(), m.shape) == (4, 5)
    assert m[4, 5] > 1.5 * max(m[4, 4], m[4, 6])
    # the physical map alone splits it between two taxels
    phys = d.normal[-20:].mean(axis=0)
    assert abs(phys[2, 2] - phys[2, 3]) < 0.3 * phys[2, 2]


def test_load_on_a_taxel_peaks_there_on_the_virtual_map():
    sim, base = _tared()
    _, _, v = _held_press(sim, base, x_mm=TX, y_mm=TY + 16.0, load_kpa=8.0)
    m = v.normal[-20:].mean(axis=0)
    assert np.unravel_index(m.argmax(), m.shape) == (6, 4)


# ---- faults --------------------------------------------------------------------------

def test_dead_taxel_reads_zero_under_load():
    t = LAYOUT.taxel_at(*TAXEL)
    for fault, expect_dead in (("none", False), ("dead_taxel", True)):
        sim, base = _tared(fault=fault, fault_taxel=t)
        _, d, _ = _held_press(sim, base, x_mm=TX, y_mm=TY, load_kpa=10.0)
        value = d.normal[-20:, TAXEL[0], TAXEL[1]].mean()
        assert (abs(value) < 0.3) if expect_dead else (value > 5.0)


def test_stuck_channel_is_constant_even_under_load():
    t = LAYOUT.taxel_at(*TAXEL)
    sim, base = _tared(fault="stuck_channel", fault_taxel=t)
    raw, _, _ = _held_press(sim, base, x_mm=TX, y_mm=TY, load_kpa=10.0)
    ch = sim.stuck_channel
    assert ch is not None and ch // 5 == t
    assert np.unique(raw[:, ch]).size == 1
    assert np.unique(raw[:, ch + 1]).size > 10  # its neighbours move


def test_worn_taxel_reads_less_than_its_neighbours():
    t = LAYOUT.taxel_at(*TAXEL)
    sim, base = _tared(fault="worn", fault_taxel=t)
    _, d, _ = _held_press(sim, base, x_mm=40.0, y_mm=40.0, load_kpa=6.0, radius_mm=5000.0)
    m = d.normal[-20:].mean(axis=0)
    assert m[TAXEL] < 0.6 * np.median(m)


# ---- gestures ------------------------------------------------------------------------

def test_registry_names_and_case_insensitive_lookup():
    assert list(GESTURES) == list(GESTURE_NAMES) and len(GESTURE_NAMES) == 9
    assert canonical_gesture("back & forth RUB") == "Back & Forth Rub"
    assert canonical_gesture("IDLE") == "idle"
    with pytest.raises(ValueError, match="unknown gesture"):
        canonical_gesture("wave")


@pytest.mark.parametrize("name", GESTURE_NAMES)
def test_every_gesture_makes_contact_and_is_labelled(name):
    sim, base = _tared(seed=7, style_seed=3)
    trial = sim.perform(name, 2.0)
    raw = sim.step(trial.frames)
    d = decode(LAYOUT, raw, base)
    assert contact_map(LAYOUT, raw, base).any(axis=(1, 2)).sum() >= 3
    assert d.normal.max() > 2.0
    assert sim.gesture_at(trial.start) == name == sim.current_gesture
    after = decode(LAYOUT, sim.step(6 * 43), base)  # contact ends with the trial
    assert after.normal[-43:].max() < 0.5 * d.normal.max()


def test_gestures_differ_in_the_expected_ways():
    def stats(name: str) -> tuple[float, float, float]:
        sim, base = _tared(seed=11, noise=0.0)
        trial = sim.perform(name, 2.0)
        d = decode(LAYOUT, sim.step(trial.frames), base)
        area = (d.normal > 1.0).sum(axis=(1, 2)).max()
        shear = np.hypot(d.shear_x, d.shear_y).max()
        return float(area), float(d.normal.max()), float(shear)
    poke, pat, iso, touch = (stats(g) for g in ("Poke", "Heavy Pat", "Isometric Rub",
                                                 "Constant Touch"))
    assert pat[0] > 3 * poke[0] and pat[1] > poke[1]   # a palm, harder
    assert iso[2] > 2 * touch[2]                        # rubbing shears, resting does not


def test_auto_demo_starts_idle_then_cycles_all_gestures():
    sim = SensorSimulator(gesture="auto", seed=4)
    first = [sim.gesture_at(f) for f in range(0, round(3 * RATE))]
    assert set(first) == {"idle"}  # room for the engine's 100-frame tare
    cycle = round(3.5 * RATE)
    seen = [sim.gesture_at(round(3 * RATE) + k * cycle + 10) for k in range(9)]
    assert sorted(seen) == sorted(GESTURE_NAMES)


# ---- the device plugin ---------------------------------------------------------------

def test_plugin_through_the_engine_delivers_consecutive_frames_at_speed_zero():
    dev = SimulatedSensor(speed=0, seed=5, rate=200)
    engine = AcquisitionEngine(dev, capacity=1 << 14)
    engine.start()
    try:
        assert engine.wait_frames(4000, timeout=20)
    finally:
        engine.stop()
    chunk = engine.read_since(0)
    assert len(chunk) >= 4000 and chunk.lost == 0
    assert np.array_equal(chunk.seq, np.arange(len(chunk)))
    assert np.allclose(chunk.device_time, chunk.seq / 200.0)
    assert engine.gaps == 0 and engine.missing_frames == 0
    assert engine.baseline is not None and chunk.raw.dtype == np.uint16
    # and the frames are the pure generator's frames
    assert np.array_equal(chunk.raw, SensorSimulator(seed=5, rate=200).step(len(chunk)))


def test_plugin_controls_schedule_by_frame_and_report_ground_truth():
    dev = SimulatedSensor(speed=0, gesture="idle")
    dev.open()
    try:
        first = dev.read(50)
        assert len(first) == 50 and dev.next_frame == 50 and dev.performing_until == 0
        trial = dev.perform("wide pinch", 1.0, at_frame=60)
        assert trial.gesture == "Wide Pinch" and trial.frames == 43
        assert dev.performing_until == 103  # the frame after its last
        dev.read(15)
        assert dev.current_gesture == "Wide Pinch" and dev.gesture_at(59) == "idle"
        dev.set_gesture("Tickle")
        batch = dev.read(200)
        assert dev.current_gesture == "Tickle"
        assert np.array_equal(batch.seq, np.arange(65, 265))
    finally:
        dev.close()


def test_plugin_real_time_read_returns_frames():
    dev = SimulatedSensor(rate=1000, speed=1.0)
    dev.open()
    try:
        got = sum(len(dev.read(64)) for _ in range(5))
        assert got >= 5  # each read blocks until at least one frame is due
    finally:
        dev.close()


@pytest.mark.parametrize("settings, name", [
    ({"rate": 0}, "rate"), ({"rate": 10000}, "rate"), ({"crosstalk": 0.5}, "crosstalk"),
    ({"fault": "melted"}, "fault"), ({"gesture": "wave"}, "gesture"),
    ({"speed": -1}, "speed"), ({"fault_taxel": 36}, "fault_taxel"),
    ({"intensity": "lots"}, "intensity"), ({"colour": "red"}, "colour"),
])
def test_bad_settings_raise_settings_error_naming_the_setting(settings, name):
    with pytest.raises(SettingsError, match=name):
        SimulatedSensor(**settings)


def test_settings_accept_text_and_any_gesture_case():
    dev = SimulatedSensor(rate="100", gesture="constant TOUCH", fault="worn", seed="3")
    assert dev.settings["gesture"] == "Constant Touch"
    assert dev.nominal_rate_hz == 100.0 and dev.layout is LAYOUT


def test_continuous_gesture_mode_starts_with_idle_then_repeats():
    sim = SensorSimulator(gesture="Heavy Pat", seed=1)
    lead = round(3 * RATE)
    assert {sim.gesture_at(f) for f in range(lead)} == {"idle"}
    assert {sim.gesture_at(f) for f in range(lead, lead + 500)} == {"Heavy Pat"}
    raw = sim.step(lead + 200)
    base = compute_baseline(raw[:100])
    assert np.abs(decode(LAYOUT, raw[:lead], base).normal).max() < 0.6
    assert decode(LAYOUT, raw[lead:], base).normal.max() > 5.0


def test_real_time_reads_come_in_batches_of_five_milliseconds():
    """At 1 kHz the plugin hands out frames 5 at a time, not one per read (the physics
    cost ~0.2 ms per call: frame by frame it took half a core beside the GUI); at the
    real sensor's 43 Hz every frame still comes alone as soon as it is due."""
    from tactile_studio.devices import create_device

    for rate, want in ((1000, 5), (43, 1)):
        device = create_device("simulated", {"rate": rate, "gesture": "idle"})
        device.open()
        try:
            sizes = [len(device.read(1000).raw) for _ in range(12 if rate > 100 else 3)]
        finally:
            device.close()
        assert min(sizes) >= want, (rate, sizes)
