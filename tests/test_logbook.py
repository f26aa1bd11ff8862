"""The sensor logbook: schema, transactions, hours of use from recordings, SIGKILL safety."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time

import pytest

from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.cli import main
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.errors import UserError
from tactile_studio.plugins.simulated import SimulatedSensor
from tactile_studio.storage.books.logbook import MIGRATIONS, Logbook, UnknownSensor
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.recording.recorder import Recorder


@pytest.fixture
def data_dir(tmp_path, monkeypatch):
    folder = tmp_path / "data"
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(folder))
    return folder


def _check(verdict="pass", spots=("B2", "E5")):
    return {"verdict": verdict, "weight_g": 200.0, "reasons": [f"{spots[0]}: fine"],
            "spots": [{"taxel": t, "normal_kpa": 10.0, "shear_kpa": 0.1, "ratio": 1.0,
                       "verdict": verdict} for t in spots]}


def test_schema_is_versioned_and_reopening_does_not_migrate_twice(data_dir):
    with Logbook() as book:
        assert book.schema_version == len(MIGRATIONS)
        book.ensure_sensor("S1", "shearsense-6x6")
    assert (data_dir / "logbook.sqlite").exists()
    with Logbook() as book:
        assert book.schema_version == len(MIGRATIONS)
        assert book.sensor_ids() == ["S1"]
        rows = book._db.execute("SELECT COUNT(*) FROM schema_version").fetchone()[0]
        assert rows == len(MIGRATIONS)
        assert book._db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_checks_calibrations_notes_and_history(data_dir):
    with Logbook() as book:
        book.ensure_sensor("S1")
        book.add_usage("S1", 1800.0, "a.h5")
        first = book.add_check("S1", _check("pass"))
        book.add_usage("S1", 3600.0, "b.h5")
        second = book.add_check("S1", _check("warn"))
        cal1 = book.add_calibration("S1", "per-taxel", 0.5, {"fits": []})
        cal2 = book.add_calibration("S1", "plate", 0.4, {"fits": []})
        book.add_note("S1", "re-covered the skin", "re-covered")
        hist = book.history("S1")
    assert hist["hours"] == pytest.approx(1.5)
    assert [c["id"] for c in hist["checks"]] == [first, second]
    assert [c["hours"] for c in hist["checks"]] == [pytest.approx(0.5), pytest.approx(1.5)]
    assert hist["last_verdict"] == "warn" and hist["last_check_id"] == second
    assert hist["active_calibration"] == cal2
    assert [c["active"] for c in hist["calibrations"]] == [False, True] and cal1 < cal2
    assert hist["notes"][0]["kind"] == "re-covered"


def test_unknown_sensor_and_bad_note_are_one_line_errors(data_dir):
    with Logbook() as book:
        book.ensure_sensor("S1")
        with pytest.raises(UnknownSensor, match="unknown sensor 'nope'.*known: S1"):
            book.history("nope")
        with pytest.raises(UnknownSensor):
            book.add_check("nope", _check())
        assert book.checks("nope") == []
        with pytest.raises(UserError, match="unknown note kind"):
            book.add_note("S1", "x", "exploded")
        with pytest.raises(UserError, match="bad sensor ID"):
            book.ensure_sensor("  ")


def test_a_failed_write_leaves_nothing_half_written(data_dir):
    bad = _check()
    bad["spots"][1]["normal_kpa"] = None  # NOT NULL: the second spot fails to insert
    with Logbook() as book:
        book.ensure_sensor("S1")
        with pytest.raises(sqlite3.IntegrityError):
            book.add_check("S1", bad)
        assert book.checks("S1") == []
        assert book._db.execute("SELECT COUNT(*) FROM check_spots").fetchone()[0] == 0


def test_recording_stores_sensor_and_calibration_and_adds_hours(data_dir, tmp_path):
    with Logbook() as book:
        book.ensure_sensor("sim-7")
        cal = book.add_calibration("sim-7", "plate", 0.3, {"fits": []})
    acq = LiveAcquisition()  # the session books the sensor; the file writer never does
    engine = acq.use_device(SimulatedSensor(seed=7, speed=0, gesture="idle"))
    acq.start_recording(tmp_path / "s.h5")
    acq.start()
    assert engine.wait_frames(430, timeout=20)
    acq.disconnect()
    with SessionFile(tmp_path / "s.h5") as s:
        meta, frames = s.metadata, s.n_frames
    assert meta["sensor_id"] == "sim-7" and meta["calibration_id"] == cal
    with Logbook() as book:
        assert book.hours("sim-7") * 3600 == pytest.approx(frames / 43.0)


def test_the_file_writer_never_opens_the_logbook(data_dir, tmp_path):
    engine = AcquisitionEngine(SimulatedSensor(seed=7, speed=0, gesture="idle"))
    rec = Recorder(engine, tmp_path / "s.h5").start()
    engine.start()
    assert engine.wait_frames(100, timeout=20)
    engine.stop()
    rec.stop()
    with SessionFile(tmp_path / "s.h5") as s:  # the device's own sensor ID, no calibration
        assert s.metadata["sensor_id"] == "sim-7" and "calibration_id" not in s.metadata
    assert not (data_dir / "logbook.sqlite").exists()


def test_record_cli_with_a_typed_sensor_id(data_dir, tmp_path):
    out = tmp_path / "r.h5"
    assert main(["record", "--set", "speed=0", "--seconds", "0.2", "--out", str(out)]) == 0
    with SessionFile(out) as s:
        assert s.metadata["sensor_id"] == "sim-0"
    with Logbook() as book:
        assert book.hours("sim-0") > 0


def test_sensors_and_sensor_commands(data_dir, capsys):
    with Logbook() as book:
        book.ensure_sensor("S1")
        book.add_usage("S1", 7200.0)
        cid = book.add_check("S1", _check("fail"))
    assert main(["sensors", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows == [{"id": "S1", "hours": 2.0, "last_verdict": "fail",
                     "last_check_at": rows[0]["last_check_at"], "last_check_id": cid,
                     "active_calibration": None}]
    assert main(["sensors"]) == 0
    assert "S1" in capsys.readouterr().out
    assert main(["sensor", "S1", "--json"]) == 0
    hist = json.loads(capsys.readouterr().out)
    assert hist["checks"][0]["spots"][0]["taxel"] == "B2"
    assert main(["sensor", "S1"]) == 0
    assert "FAIL" in capsys.readouterr().out
    assert main(["sensor", "ghost"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown sensor 'ghost'" in err[0]


WRITER = textwrap.dedent("""
    import sys
    from tactile_studio.storage.books.logbook import Logbook
    book = Logbook(sys.argv[1])
    book.ensure_sensor("S1")
    spots = [{"taxel": f"T{i}", "normal_kpa": 1.0, "shear_kpa": 0.0, "ratio": 1.0,
              "verdict": "pass"} for i in range(200)]
    print("writing", flush=True)
    while True:
        book.add_check("S1", {"verdict": "pass", "weight_g": 1.0, "spots": spots,
                              "pad": "x" * 20000})
        book.add_usage("S1", 1.0)
""")


def test_sigkill_during_writes_leaves_a_consistent_logbook(tmp_path):
    path = tmp_path / "book.sqlite"
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(path)], stdout=subprocess.PIPE)
    try:
        assert proc.stdout.readline().strip() == b"writing"
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:  # let it commit some checks, then kill it mid-way
            with Logbook(path) as book:
                if len(book.checks("S1")) >= 5:
                    break
            time.sleep(0.05)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(10)
    with Logbook(path) as book:
        assert book._db.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        counts = book._db.execute(
            "SELECT c.id, c.n_spots, COUNT(s.check_id) FROM checks c "
            "LEFT JOIN check_spots s ON s.check_id = c.id GROUP BY c.id").fetchall()
        assert len(counts) >= 5
        assert all(n == got == 200 for _, n, got in counts)
        orphans = book._db.execute("SELECT COUNT(*) FROM check_spots WHERE check_id NOT IN "
                                   "(SELECT id FROM checks)").fetchone()[0]
        assert orphans == 0
        assert all(c["result"]["pad"] == "x" * 20000 for c in book.checks("S1"))
