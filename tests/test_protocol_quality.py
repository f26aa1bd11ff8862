"""Quality flags on frames from the simulated sensor, and the info trial table."""

from __future__ import annotations

import numpy as np

from tactile_studio.protocol.quality import (
    FLAG_TEXT,
    FLAGS,
    FrameTiming,
    QualitySettings,
    describe,
    in_centre,
    load_centroid,
    trial_flags,
)
from tactile_studio.protocol.report import trial_table
from tactile_studio.sensor.decode import compute_baseline
from tactile_studio.sensor.layout import COST_8X8, SHEARSENSE_6X6
from tactile_studio.simulate import SensorSimulator

N = 86


def _trial(gesture: str | None = "Twist", press: tuple | None = None, **cfg) -> tuple:
    sim = SensorSimulator(gesture="idle", seed=3, **{"difficulty": "easy", **cfg})
    base = compute_baseline(sim.step(100))
    if gesture:
        sim.perform(gesture, 2.0, at_frame=110)
    if press:
        sim.press(*press, at_frame=110)
    sim.step(10)
    seq = np.arange(sim.frame, sim.frame + N)
    return sim.step(N), base, seq


def test_a_good_gesture_has_no_flags() -> None:
    for gesture in ("Poke", "Twist", "Tickle", "Constant Touch"):
        raw, base, seq = _trial(gesture)
        timing = FrameTiming(seq / 43.0, seq, 43.0)
        assert trial_flags(SHEARSENSE_6X6, raw, base, timing=timing) == [], gesture


def test_each_flag_from_its_cause() -> None:
    lay = SHEARSENSE_6X6
    raw, base, seq = _trial(None)
    assert trial_flags(lay, raw, base) == ["no_contact"]
    raw, base, _ = _trial("Twist", fault="stuck_channel")
    assert "stuck_channel" in trial_flags(lay, raw, base)
    raw, base, _ = _trial("Twist")
    hot = raw.copy()
    hot[40, 7] = 65535
    assert trial_flags(lay, hot, base) == ["saturated"]
    hot[40, 7] = 0
    assert trial_flags(lay, hot, base) == ["saturated"]
    jumped = seq.copy()
    jumped[50:] += 3
    assert trial_flags(lay, raw, base, timing=FrameTiming(seq=jumped)) == ["gap"]
    t = seq / 43.0
    t[60:] += 0.5
    assert trial_flags(lay, raw, base, timing=FrameTiming(t, rate_hz=43.0)) == ["gap"]
    assert trial_flags(lay, raw, base, timing=FrameTiming(gap_events=1)) == ["gap"]
    assert trial_flags(lay, raw, base, timing=FrameTiming(lost_frames=4)) == ["dropped_frames"]
    assert trial_flags(lay, raw[:0], base) == ["dropped_frames"]
    raw, base, _ = _trial(None, press=(4.0, 40.0, 20.0))  # left edge, middle row
    assert trial_flags(lay, raw, base) == ["off_centre"]
    r, c = load_centroid(lay, raw, base)
    assert c < 1.0 and 1.5 < r < 3.5
    raw, base, _ = _trial(None, press=(40.0, 40.0, 20.0))
    assert trial_flags(lay, raw, base) == []
    assert in_centre(lay, load_centroid(lay, raw, base), 0.7)


def test_flags_on_a_pressure_grid() -> None:
    base = np.full(64, 100.0)
    raw = np.tile(base, (N, 1))
    assert trial_flags(COST_8X8, raw, base) == ["no_contact"]
    raw[:, 27] += 300  # a press near the middle, rising counts
    raw[:, 28] += np.linspace(0, 50, N)
    assert trial_flags(COST_8X8, raw, base) == []
    raw[10, 27] = COST_8X8.raw_max
    assert trial_flags(COST_8X8, raw, base) == ["saturated"]


def test_describe_and_trial_table() -> None:
    assert describe(["no_contact", "off_centre"]) == "no contact, contact off the sensor centre"
    assert set(FLAGS) == {"no_contact", "short_contact", "saturated", "stuck_channel",
                          "dead_taxel", "dropped_frames", "gap", "off_centre", "too_light",
                          "too_heavy", "release_overlap", "model_mismatch"}
    assert set(FLAG_TEXT) == set(FLAGS)
    trials = [
        {"index": 0, "block": -1, "gesture": "Poke", "status": "discarded", "flags": []},
        {"index": 1, "block": 0, "gesture": "Twist", "status": "ok", "flags": []},
        {"index": 2, "block": 0, "gesture": "Poke", "status": "redone", "flags": ["no_contact"]},
        {"index": 3, "block": 0, "gesture": "Poke", "status": "ok", "flags": []},
        {"index": 4, "block": 1, "gesture": "Poke", "status": "discarded", "flags": ["gap"]},
    ]
    table = trial_table(trials, ["Poke", "Twist", "Tickle"])
    lines = table.splitlines()
    assert lines[0].split() == ["gesture", "ok", "redone", "discarded", "flagged"]
    assert lines[1].split() == ["Poke", "1", "1", "1", "2"]
    assert lines[2].split() == ["Twist", "1", "0", "0", "0"]
    assert lines[3].split() == ["Tickle", "0", "0", "0", "0"]
    assert lines[4].split() == ["total", "2", "1", "1", "2"]
    assert "flags: no_contact 1, gap 1" in table
    assert "blocks: 2 (1..2)" in table and "practice trials: 1" in table
    assert trial_table([]) == "no trials"


def test_the_issue_46_signal_checks_from_their_causes() -> None:
    lay = SHEARSENSE_6X6
    # a wide press over a taxel that reads nothing (the simulator's dead_taxel, C3)
    raw, base, _ = _trial(None, press=(40.0, 40.0, 15.0, 25.0), fault="dead_taxel")
    assert "dead_taxel" in trial_flags(lay, raw, base)
    raw, base, _ = _trial(None, press=(40.0, 40.0, 15.0, 25.0))
    assert "dead_taxel" not in trial_flags(lay, raw, base)
    # force against the gesture's declared force
    raw, base, _ = _trial(None, press=(40.0, 40.0, 2.0, 12.0))  # ~1.3 kPa at its peak
    assert trial_flags(lay, raw, base, force="natural") == ["too_light"]
    assert trial_flags(lay, raw, base, force="light") == []
    assert trial_flags(lay, raw, base) == []  # no force declared: not checked
    raw, base, _ = _trial(None, press=(40.0, 40.0, 40.0, 12.0))  # ~25 kPa
    assert trial_flags(lay, raw, base, force="light") == ["too_heavy"]
    assert trial_flags(lay, raw, base, force="natural") == []  # natural: up to 30 kPa
    assert trial_flags(lay, raw, base, force="heavy") == []
    # contact for a share of the trial below the protocol's setting
    raw, base, _ = _trial("Poke")
    short = QualitySettings(min_contact_share=0.9)
    assert trial_flags(lay, raw, base, settings=short) == ["short_contact"]
    assert trial_flags(lay, raw, base) == []


def test_a_trial_begun_during_the_previous_release_is_flagged() -> None:
    sim = SensorSimulator(gesture="idle", seed=3, difficulty="easy")
    base = compute_baseline(sim.step(100))
    sim.press(40.0, 40.0, 12.0, duration_s=1.0, at_frame=105)  # ends at frame 148
    sim.step(45)  # the next trial's first frame: the press is letting go
    sim.perform("Poke", 1.0, at_frame=165)  # and the trial's own gesture
    raw = sim.step(N)
    assert "release_overlap" in trial_flags(SHEARSENSE_6X6, raw, base)
    assert "release_overlap" not in trial_flags(SHEARSENSE_6X6, *_trial("Heavy Pat")[:2])
