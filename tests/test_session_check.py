"""``tactile-studio check``: a session file's facts must agree, and a file whose facts
do not is named with each violation (real HDF5 files, the real command)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.errors import EXIT_CHECK_FAIL, EXIT_ERROR
from tactile_studio.sensor.layout import get_layout
from tactile_studio.storage.format.session_check import check_file
from tactile_studio.storage.format.session_writer import SessionWriter


def _record(path: Path, capsys) -> Path:
    assert main(["record", "--seconds", "0.3", "--set", "speed=10", "--out", str(path)]) == 0
    capsys.readouterr()
    return path


def _bad_session(path: Path) -> Path:
    """A session whose clock, trials, events and counters disagree, one way each."""
    layout = get_layout("shearsense-6x6")
    n = 40
    dev = np.arange(n) / 43.0
    dev[20:] -= 0.3                          # the device clock goes back at row 20
    host = 1e9 + np.arange(n) / 43.0
    with SessionWriter(path, layout, {"plugin": "simulated", "layout": layout.name},
                       {"source": "collect", "block_order": [["Poke"], ["Twist"]],
                        "calibration_id": 3}) as w:
        w.append_frames(np.zeros((n, layout.n_channels), np.uint16), dev, host)
        w.add_event("block_start", frame=0, block=0)
        w.add_event("block_start", frame=30, block=1)   # after block 1's first trial
        w.add_event("session_end", frame=12)            # before the last trial ends
        w.add_trial({"index": 0, "block": 0, "gesture": "Poke", "start_sample": 2,
                     "end_sample": 10, "start_time": 2 / 43, "end_time": 10 / 43,
                     "status": "ok"})
        w.add_trial({"index": 1, "block": 1, "gesture": "Twist", "start_sample": 25,
                     "end_sample": 50, "start_time": 0.01, "end_time": 0.2,
                     "status": "maybe"})
        w.set_counters({"gaps": 2, "reconnects": 0, "dropped": 0, "malformed_by_kind": {}})
    return path


def _names_each(violations: list[str], expected: tuple[str, ...]) -> None:
    """Each expected text in one of the violations, and no other violation."""
    for text in expected:
        assert any(text in line for line in violations), (text, violations)
    assert len(violations) == len(expected), violations


def test_a_recorded_file_passes(tmp_path: Path, capsys) -> None:
    path = _record(tmp_path / "rec.h5", capsys)
    assert main(["check", str(path)]) == 0
    out, err = capsys.readouterr()
    assert out.strip() == f"{path}: ok" and err == ""
    # a group check does not know (an XDF auxiliary signal) is not a violation
    with h5py.File(path, "r+") as f:
        f.create_group("aux").create_dataset("emg", data=np.zeros((5, 2)))
    assert check_file(path).ok


@pytest.mark.damaged_files
def test_every_violation_is_named_and_the_exit_status_is_5(tmp_path: Path, capsys) -> None:
    bad = _bad_session(tmp_path / "bad.h5")
    good = _record(tmp_path / "good.h5", capsys)
    assert main(["check", str(good), str(bad)]) == EXIT_CHECK_FAIL
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("tactile-studio: error: 1 of 2 session ")
    assert "device_time goes back at row 20" in err  # the first violation, in the line
    v = check_file(bad).violations
    expected = ("device_time goes back at row 20",
                "trial 1: status 'maybe'",
                "trial 1: rows 25..50 end past the 40 frames",
                "trial 1 starts at 0.01 s, before trial 0",
                "block_start of block 1 at frame 30 is after its first trial 1 starts (row 25)",
                "session_end at frame 12 is before trial 1 ends (row 50)",
                "counters say 2 gaps but the journal has 0 gap events",
                "calibration_id 3 without a sensor_id")
    _names_each(v, expected)
    assert f"{bad}: {len(v)} violation(s)" in out and f"{good}: ok" in out

    assert main(["check", "--json", str(good), str(bad)]) == EXIT_CHECK_FAIL
    listed = json.loads(capsys.readouterr().out)
    assert [(r["path"], r["ok"]) for r in listed] == [(str(good), True), (str(bad), False)]
    assert listed[1]["violations"] == v and listed[0]["violations"] == []


@pytest.mark.damaged_files
def test_an_unreadable_file_is_one_line_and_exit_1(tmp_path: Path, capsys) -> None:
    junk = tmp_path / "junk.h5"
    junk.write_text("not a session")
    assert main(["check", str(junk)]) == EXIT_ERROR
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and str(junk) in err and "Traceback" not in err


@pytest.mark.damaged_files
def test_a_clock_going_back_is_named_with_times_one_can_tell_apart(tmp_path: Path) -> None:
    """Two Unix times 23 ms apart (an old CSV's swapped rows) were both shown as
    '1.7957e+09': the line now gives them to the microsecond and by how much."""
    layout = get_layout("shearsense-6x6")
    t = 1795704932.0 + np.arange(10) / 43.0
    t[[4, 5]] = t[[5, 4]]
    path = tmp_path / "swapped.h5"
    with SessionWriter(path, layout, {"plugin": "import"}, {}) as w:
        w.append_frames(np.zeros((10, layout.n_channels), np.uint16), t, t)
    v = check_file(path).violations
    assert v[0] == ("device_time goes back at row 5: 1795704932.116279 -> "
                    "1795704932.093023 s (0.023256 s back)"), v


@pytest.mark.damaged_files
def test_times_rates_and_baselines_that_are_not_finite_are_named(tmp_path: Path,
                                                                  capsys) -> None:
    """Issue 43, case 7: NaN and infinity compare false with everything, so host and
    device times (and trial times, event times, baselines, rates) that were not numbers
    passed every ordering rule and `check` said ok."""
    layout = get_layout("shearsense-6x6")
    n = 40
    dev = np.arange(n) / 43.0
    host = 1e9 + np.arange(n) / 43.0
    dev[5] = np.nan
    host[7:9] = np.inf
    path = tmp_path / "nan.h5"
    nan, inf = float("nan"), float("inf")
    with SessionWriter(path, layout, {"plugin": "simulated", "layout": layout.name,
                                      "nominal_rate_hz": nan},
                       {"source": "import", "rate_hz": -inf, "sensor_id": "S-1",
                        "calibration_id": 2.5}) as w:
        w.append_frames(np.full((n, layout.n_channels), 1000, np.uint16), dev, host)
        w.add_trial({"index": 0, "gesture": "Poke", "start_sample": 2, "end_sample": 10,
                     "start_time": nan, "end_time": 10 / 43})
        w.add_event("note", frame=3, time_s=inf, text="x")
        w.add_event("lsl_clock", frame=0, offset_s=nan)
        w.add_event("force", frame=4, t=[0.1, nan], f=[[0, 0, 1], [0, 0, 1]])
        w.add_baseline(np.full(layout.n_channels, 1000.0), 0)
        w.add_baseline(np.r_[np.full(layout.n_channels - 1, 1000.0), nan], 10)
        w.add_baseline(np.full(3, 1000.0), 20)
        w.add_baseline(np.full(layout.n_channels, 1000.0), 99)
    v = check_file(path).violations
    expected = ("device_time is not a finite number at row 5 (nan)",
                "host_time is not a finite number at row 7 (inf) (2 rows, the last 8)",
                "trial 0: start_time nan is not a finite number",
                "event note at frame 3: time inf is not a finite number",
                "event lsl_clock at frame 0: offset_s nan is not a finite number",
                "event force at frame 4: t nan is not a finite number",
                "baseline at frame 10: channel 179 is nan, not a finite number",
                "baseline at frame 20: 3 values for the layout's 180 channels",
                "baseline at frame 99: not a row of the 40 frames",
                "metadata device.nominal_rate_hz nan is not a finite number",
                "metadata rate_hz -inf is not a finite number",
                "metadata calibration_id 2.5 is not a whole number")
    _names_each(v, expected)  # inf -> finite is not also "going back"
    assert main(["check", str(path)]) == EXIT_CHECK_FAIL
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "device_time is not a finite number at row 5" in err


@pytest.mark.damaged_files
def test_frame_columns_of_different_lengths_in_a_closed_file_are_named(tmp_path: Path,
                                                                        capsys) -> None:
    """docs/session-format.md: /frames holds one row per frame, all the same length; the
    reader reads the shortest (after a crash they may be one flush apart), so a cleanly
    closed file whose seq column lost rows had passed check with 40 frames shown as 30."""
    path = _record(tmp_path / "rec.h5", capsys)
    with h5py.File(path, "r+") as f:
        seq = f["frames/seq"][:]
        del f["frames/seq"]
        f.create_dataset("frames/seq", data=seq[:30], maxshape=(None,))
    v = check_file(path).violations
    assert any(line.startswith("frame columns differ in length: raw ") and "seq 30" in line
               for line in v), v
