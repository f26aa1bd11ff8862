"""Session files: round trip, crash safety under SIGKILL, one-line errors on bad files."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from plugin_fixtures import LAYOUT, CountingDevice

from tactile_studio.cli import main
from tactile_studio.devices.engine import FINISHED, AcquisitionEngine
from tactile_studio.errors import SessionFileError
from tactile_studio.storage import Recorder, SessionFile, SessionWriter
from tactile_studio.storage.format.trials import TrialRecord, TrialStatus

TESTS = Path(__file__).parent


def make_session(path: Path, n: int = 200) -> None:
    w = SessionWriter(path, LAYOUT, {"plugin": "counting"}, {"participant": "P07"})
    raw = np.arange(n * 4, dtype=np.float32).reshape(n, 4)
    t = np.arange(n) / 100.0
    w.add_baseline(raw[:10].mean(axis=0), 0)
    w.append_frames(raw, t, t + 1000.0, np.arange(n))
    w.add_event("marker", frame=50, label="hello")
    w.add_trial({"index": 0, "block": 0, "gesture": "Poke", "key": "p", "start_sample": 10,
                 "end_sample": 60, "status": "ok", "flags": []})
    w.update_trial(0, status="discarded", reason="sneezed")
    w.set_counters({"malformed_by_kind": {"short": 2, "long": 1}})
    w.update_metadata(notes="calm")
    w.close()


def test_round_trip_of_frames_journal_and_readable_copies(tmp_path):
    p = tmp_path / "s.h5"
    make_session(p)
    with SessionFile(p) as s:
        assert s.n_frames == 200 and s.layout.name == "grid-2x2"
        assert np.array_equal(s.raw(5, 7), np.arange(20, 28, dtype=np.float32).reshape(2, 4))
        assert s.metadata["participant"] == "P07" and s.metadata["notes"] == "calm"
        stored = [{"index": 0, "block": 0, "gesture": "Poke", "key": "p", "start_sample": 10,
                   "end_sample": 60, "status": "discarded", "flags": [], "reason": "sneezed"}]
        assert s.journal.trials == stored  # the file's form, as written
        assert s.trials == [TrialRecord.from_dict(stored[0])]  # read typed, in one place
        assert s.trials[0].status == TrialStatus.DISCARDED and not s.trials[0].usable
        summary = s.summary()
        assert s.closed_cleanly
        assert np.allclose(s.baseline(100), np.arange(40, dtype=np.float32).reshape(10, 4).mean(0))
    assert summary["frames"] == 200 and summary["rate_hz"] == pytest.approx(100.0)
    assert summary["duration_s"] == pytest.approx(2.0)
    assert summary["malformed"] == 3 and summary["malformed_by_kind"] == {"short": 2, "long": 1}
    assert summary["participant"] == "P07" and summary["events"][0]["label"] == "hello"
    with h5py.File(p, "r") as f:  # other tools see plain attributes after a clean close
        assert json.loads(f.attrs["trials_json"])[0]["status"] == "discarded"
        assert f.attrs["format"] == "tactile-studio-session"


def test_recorder_writes_every_engine_frame_and_event(tmp_path):
    eng = AcquisitionEngine(CountingDevice(frames=3000, skip_every=1000, malformed_every=500))
    rec = Recorder(eng, tmp_path / "r.h5").start()  # before start: nothing can be missed
    eng.start()
    deadline = time.monotonic() + 60
    while eng.state != FINISHED:
        assert time.monotonic() < deadline, f"the engine never finished ({eng.state})"
        time.sleep(0.01)
    eng.stop()
    rec.stop()
    with SessionFile(tmp_path / "r.h5") as s:
        raw, seq, idx = s.raw(), s.column("seq"), s.column("index")
        summary = s.summary()
    assert len(raw) == 3000 and np.array_equal(idx, np.arange(3000))
    assert np.array_equal(raw[:, 0], seq.astype(np.float32))
    assert summary["gaps"] == eng.gaps == 3
    assert summary["malformed_by_kind"] == {"short": 6} and summary["malformed"] == 6
    kinds = [e["kind"] for e in summary["events"]]
    assert kinds[0] == "connect" and "tare" in kinds and kinds[-1] == "finished"
    with SessionFile(tmp_path / "r.h5") as s:
        assert np.allclose(s.baseline(0), raw[:100].mean(axis=0))


KILL_SCRIPT = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, {tests!r})
    from plugin_fixtures import CountingDevice
    from tactile_studio.devices.engine import AcquisitionEngine
    from tactile_studio.storage import Recorder

    class OnDemand(CountingDevice):
        # frames made as fast as they are read: held to the recorder's pace, so a
        # loaded machine cannot lap the recorder (a real-time source would, counted)
        waits_for_reader = True

    eng = AcquisitionEngine(OnDemand(frames=0))
    eng.start(); eng.wait_frames(1)
    Recorder(eng, sys.argv[1], poll_s=0.02).start()
    print("recording", flush=True)
    while True:
        time.sleep(1)
""")


def test_sigkill_while_recording_keeps_every_flushed_frame(tmp_path):
    p = tmp_path / "killed.h5"
    script = tmp_path / "rec.py"
    script.write_text(KILL_SCRIPT.format(tests=str(TESTS)))
    proc = subprocess.Popen([sys.executable, str(script), str(p)], stdout=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout.readline().strip() == "recording"
        seen = 0
        deadline = time.monotonic() + 30
        while seen < 2000 and time.monotonic() < deadline:
            time.sleep(0.05)
            with SessionFile(p) as s:  # reading while it is being written (SWMR)
                seen = s.n_frames
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    assert seen >= 2000
    with SessionFile(p) as s:
        assert not s.closed_cleanly
        assert s.n_frames >= seen
        raw, seq = s.raw(), s.column("seq")
    assert np.array_equal(raw[:, 0], seq.astype(np.float32))
    assert np.array_equal(np.diff(seq), np.ones(len(seq) - 1))
    assert main(["info", str(p)]) == 0


def test_bad_files_give_one_line_errors(tmp_path, capsys):
    missing = tmp_path / "missing.h5"
    with pytest.raises(SessionFileError, match="no such file"):
        SessionFile(missing)
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"this is not hdf5" * 100)
    with pytest.raises(SessionFileError, match="junk.h5"):
        SessionFile(junk)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = [1, 2, 3]
    with pytest.raises(SessionFileError, match="not a Tactile Studio session"):
        SessionFile(other)
    good = tmp_path / "good.h5"
    make_session(good, n=5000)
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 3])
    for bad in (missing, junk, other, truncated):
        assert main(["info", str(bad)]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("tactile-studio: error:") and "\n" not in err
        assert "Traceback" not in err and bad.name in err


def test_older_trials_read_typed_and_their_file_form_is_unchanged(tmp_path, capsys):
    """Trials as older writers and importers stored them (no status, key or flags, an
    importer's own column) read as records with their extra column kept; info --json,
    the dataset's uids and check see the file as before."""
    from tactile_studio.learn.experiments.trialinfo import session_trial_table
    from tactile_studio.storage.format.session_check import check_file

    p = tmp_path / "old.h5"
    w = SessionWriter(p, LAYOUT, {"plugin": "counting"},
                      {"participant": "P01", "gestures": ["Twist", "Poke"]})
    raw = np.arange(400, dtype=np.float32).reshape(100, 4)
    t = np.arange(100) / 100.0
    w.append_frames(raw, t, t + 1000.0, np.arange(100))
    old = [{"index": 0, "block": 0, "gesture": "Poke", "start_sample": 5, "end_sample": 40,
            "variant": "gentle"},
           {"index": 1, "block": 0, "gesture": "Stroke", "start_sample": 50,
            "end_sample": 90, "status": "discarded"}]
    for trial in old:
        w.add_trial(trial)
    w.close()
    assert check_file(p).ok
    with SessionFile(p) as s:
        assert s.journal.trials == old
        first, second = s.trials
        assert first.usable and first.status == TrialStatus.OK and first.key is None
        assert first.extra == {"variant": "gentle"} and not second.usable
        assert s.gesture_order() == ["Twist", "Poke", "Stroke"]
    assert list(session_trial_table([p])) == ["old.h5#0"]
    assert main(["info", str(p), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["trials"] == [{**o, "block": 1} for o in old]


@pytest.mark.damaged_files
def test_a_trial_the_record_cannot_read_is_one_line_naming_file_and_trial(tmp_path, capsys):
    p = tmp_path / "odd.h5"
    w = SessionWriter(p, LAYOUT, {"plugin": "counting"}, {"participant": "P01"})
    w.append_frames(np.zeros((20, 4), np.float32), np.arange(20) / 100.0, np.arange(20) + 0.0)
    w.add_trial({"index": 3, "block": 0, "gesture": "Poke", "start_sample": 2,
                 "end_sample": 9, "status": "maybe"})
    w.close()
    assert main(["info", str(p)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("tactile-studio: error:") and "\n" not in err
    assert "odd.h5: trial 3:" in err and "maybe" in err and "Traceback" not in err
    assert main(["check", str(p)]) == 5  # still names what is wrong
    assert "status 'maybe'" in capsys.readouterr().out


def test_info_json_has_the_documented_keys(tmp_path, capsys):
    p = tmp_path / "s.h5"
    make_session(p)
    assert main(["info", str(p), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("frames", "duration_s", "rate_hz", "malformed", "malformed_by_kind", "gaps",
                "events", "metadata", "trials", "participant"):
        assert key in out
    assert out["trials"][0]["status"] == "discarded" and out["participant"] == "P07"
    assert main(["info", str(p)]) == 0
    text = capsys.readouterr().out
    assert "frames:     200" in text and "Poke" in text


def test_writer_refuses_a_missing_folder(tmp_path):
    with pytest.raises(SessionFileError, match="does not exist"):
        SessionWriter(tmp_path / "nope" / "s.h5", LAYOUT, {})


def test_events_at_rows_a_truncation_cut_are_kept_at_the_last_row(tmp_path):
    """A collection that ends before the frames its recorder had pulled cuts them
    (SessionWriter.truncate); an event written at one of those rows (a device gone silent
    after the session's end) stays in the file at its last row, not outside its frames."""
    import numpy as np

    from tactile_studio.sensor.layout import SHEARSENSE_6X6
    from tactile_studio.storage import SessionFile
    from tactile_studio.storage.format.session_check import check_file
    from tactile_studio.storage.format.session_writer import SessionWriter
    path = tmp_path / "cut.h5"
    t = np.arange(10) / 43.0
    with SessionWriter(path, SHEARSENSE_6X6, {"plugin": "simulated", "nominal_rate_hz": 43.0},
                       {"participant": "P01"}) as w:
        w.append_frames(np.full((10, 180), 30000, dtype=np.uint16), t, 1e9 + t)
        w.add_event("session_end", 5)
        w.add_event("stream_silent", 8, seconds=2.0)
        w.truncate(6)
    with SessionFile(path) as s:
        assert s.n_frames == 6
        assert [(e["kind"], e["frame"]) for e in s.events] == [("session_end", 5),
                                                                ("stream_silent", 5)]
    assert check_file(path).ok


def test_a_detail_never_overwrites_a_journal_records_own_fields(tmp_path):
    """The mechanism under the importers: whoever hands a writer a detail named like the
    record's own fields (type, kind, frame, time; a trial's type) is told at once, and
    nothing is written."""
    with SessionWriter(tmp_path / "s.h5", LAYOUT, {"plugin": "counting"}) as w:
        w.append_frames(np.zeros((3, 4), np.float32), np.arange(3.0), np.arange(3.0))
        with pytest.raises(ValueError, match="event record: detail would overwrite its own "
                                             "field"):
            w.add_event("note", 1, 1.0, type="metadata", update={"layout": "x"})
        with pytest.raises(ValueError, match="trial record"):
            w.add_trial({"type": "metadata", "index": 0, "gesture": "Poke",
                         "start_sample": 0, "end_sample": 2})
        w.add_event("note", 1, 1.0, text="kept")
    with SessionFile(tmp_path / "s.h5") as s:
        assert s.layout.name == LAYOUT.name and s.trials == []
        assert [e["kind"] for e in s.events] == ["note"]
