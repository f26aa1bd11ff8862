"""A damaged sensor logbook is never written into and never costs the history.

A real logbook (sensors, hours, checks, calibrations, notes; ~250 KB) is damaged two ways
(truncated to 0 bytes; 80 KB of random bytes in its middle) and taken through the real
commands: ``sensors`` and ``sensor ID`` refuse in one line (exit 1) and leave it as it
is; ``record`` records anyway, says once that the logbook was not used, and leaves it as
it is; ``wellness`` (which must store its check) moves it aside under a timestamped name,
restores the rolling backup and says so in one line. The backup is a complete logbook.
"""

from __future__ import annotations

import logging
import os
import random
import sqlite3

import pytest

from tactile_studio.cli import main
from tactile_studio.storage.books.logbook import Logbook, LogbookDamaged
from tactile_studio.storage.books.logbook_file import CheckedConnection, problem_of
from tactile_studio.storage.format.session_file import SessionFile

PREFIX = "tactile-studio: error: "
SENSORS = [f"S{i}" for i in range(6)]


def _check(verdict: str = "pass") -> dict:
    return {"verdict": verdict, "weight_g": 200.0, "reasons": [],
            "spots": [{"taxel": t, "normal_kpa": 10.0, "shear_kpa": 0.1, "ratio": 1.0,
                       "verdict": verdict} for t in ("B2", "E5")]}


def history(path) -> dict:
    with Logbook(path) as book:
        return {s: book.history(s) for s in book.sensor_ids()}


@pytest.fixture
def logbook(tmp_path, monkeypatch):
    """A real logbook with every kind of record, large enough to damage in the middle."""
    folder = tmp_path / "appdata"
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(folder))
    with Logbook() as book:
        for sensor in SENSORS:
            book.ensure_sensor(sensor, "shearsense-6x6", "lab sensor " * 50)
            book.add_check(sensor, _check())
            book.add_calibration(sensor, "per-taxel", 0.5, {"fits": [], "pad": "c" * 3000})
            book.add_note(sensor, "re-covered " * 200, "re-covered")
        for k in range(300):
            book.add_usage(SENSORS[k % 6], 60.0, f"session-{k:04d}.h5 " + "u" * 400)
    path = folder / "logbook.sqlite"
    assert path.stat().st_size > 200_000
    return path


def damage(path, how: str) -> bytes:
    if how == "empty":
        path.write_bytes(b"")
    else:
        data = bytearray(path.read_bytes())
        middle = len(data) // 2
        data[middle - 40_000:middle + 40_000] = random.Random(7).randbytes(80_000)
        path.write_bytes(bytes(data))
    return path.read_bytes()


def one_error_line(err: str) -> str:
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith(PREFIX)]
    assert len(lines) == 1, err
    return lines[0][len(PREFIX):]


@pytest.mark.parametrize("how, problem", [
    ("empty", ("empty: 0 bytes",)),
    ("random", ("integrity check failed", "database disk image is malformed"))])
def test_history_commands_refuse_in_one_line_and_touch_nothing(logbook, capsys, how, problem):
    before = history(logbook)
    damaged = damage(logbook, how)
    for argv in (["sensors"], ["sensors", "--json"], ["sensor", "S1"]):
        assert main(argv) == 1
        line = one_error_line(capsys.readouterr().err)
        assert line.startswith(tuple(f"{logbook}: the sensor logbook is damaged ({p}"
                                     for p in problem)), line
        assert "left as it is: restore its backup logbook.sqlite.bak" in line
        assert logbook.read_bytes() == damaged
    # the backup holds the whole history: restoring it is a copy (docs/sensor-health.md)
    assert history(logbook.with_name("logbook.sqlite.bak")) == before


@pytest.mark.parametrize("how", ["empty", "random"])
def test_record_records_anyway_says_so_once_and_writes_nothing_into_it(
        logbook, tmp_path, capsys, caplog, how):
    damaged = damage(logbook, how)
    out = tmp_path / "r.h5"
    with caplog.at_level(logging.WARNING):
        code = main(["record", "--device", "simulated", "--seconds", "0.3", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 0 and "Traceback" not in err
    said = [r.getMessage() for r in caplog.records if "sensor logbook" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith(
        f"sensor logbook not used for this recording: {logbook}: the sensor logbook is damaged")
    assert logbook.read_bytes() == damaged
    with SessionFile(out) as s:
        assert len(s.column("device_time")) > 0 and s.metadata["sensor_id"] == "sim-0"


@pytest.mark.parametrize("how", ["empty", "random"])
def test_wellness_moves_it_aside_restores_the_backup_and_stores_its_check(
        logbook, capsys, caplog, how):
    before = history(logbook)
    damaged = damage(logbook, how)
    with caplog.at_level(logging.WARNING):
        code = main(["wellness", "--device", "simulated", "--set", "speed=0", "--sensor",
                     "sim-0", "--auto", "--weight-g", "200", "--spots", "B2"])
    err = capsys.readouterr().err
    assert code in (0, 4, 5) and "Traceback" not in err  # the check's own verdict
    aside = sorted(logbook.parent.glob("logbook.sqlite.damaged-*[0-9]Z"))
    assert len(aside) == 1 and aside[0].read_bytes() == damaged  # kept as it was
    said = [r.getMessage() for r in caplog.records if "sensor logbook" in r.getMessage()]
    assert said == [f"{logbook}: the sensor logbook was damaged ("
                    f"{problem_of(aside[0])}); kept it as {aside[0].name} and restored its "
                    f"backup of {said[0].rsplit('backup of ', 1)[1]}"]
    now = history(logbook)
    assert {s: now[s] for s in SENSORS} == before  # the history came back from the backup
    assert [c["verdict"] for c in now["sim-0"]["checks"]] in (["pass"], ["warn"])
    assert main(["sensors"]) == 0


def test_no_backup_starts_a_new_logbook_and_keeps_the_old_aside(logbook, caplog):
    logbook.with_name("logbook.sqlite.bak").unlink()
    damaged = damage(logbook, "random")
    with caplog.at_level(logging.WARNING):
        with Logbook(on_damage="replace") as book:
            assert book.sensor_ids() == []
            assert book.notice.endswith("and started a new one (no sound backup)")
    aside = next(logbook.parent.glob("logbook.sqlite.damaged-*[0-9]Z"))
    assert aside.read_bytes() == damaged


def test_the_backup_follows_every_write_and_a_new_logbook_gets_one(logbook):
    bak = logbook.with_name("logbook.sqlite.bak")
    with Logbook() as book:
        book.add_note("S3", "after the backup")
    assert [n["text"] for n in history(bak)["S3"]["notes"]][-1] == "after the backup"
    assert not list(logbook.parent.glob("*.tmp*"))  # written aside, then renamed


def test_damage_found_while_reading_is_one_line_not_a_database_error(logbook):
    damage(logbook, "random")
    db = sqlite3.connect(logbook, factory=CheckedConnection)
    db.logbook_path = logbook
    try:
        with pytest.raises(LogbookDamaged, match="the sensor logbook is damaged"):
            for table in ("usage", "notes", "calibrations", "checks", "sensors"):
                db.execute(f"SELECT * FROM {table}").fetchall()
        with pytest.raises(sqlite3.OperationalError):  # a wrong statement is a bug
            db.execute("SELECT * FROM no_such_table")
    finally:
        db.close()


def test_sensors_window_shows_the_line(qtbot, logbook):
    from tactile_studio.ui.sensors_window import SensorsWindow

    damaged = damage(logbook, "empty")
    w = SensorsWindow()
    qtbot.addWidget(w)
    w.show()
    assert w.problem.isVisible() and "the sensor logbook is damaged (empty: 0 bytes)" in \
        w.problem.text()
    assert w.sensors.count() == 0 and logbook.read_bytes() == damaged


def test_a_logbook_that_cannot_be_read_is_refused(logbook, capsys):
    if os.geteuid() == 0:
        logbook.unlink()
        logbook.mkdir()  # root reads any file: a folder in its place cannot be read
    else:
        logbook.chmod(0)
    assert main(["sensors"]) == 1
    line = one_error_line(capsys.readouterr().err)
    assert line.startswith(f"{logbook}: cannot read the sensor logbook")


def test_the_main_window_records_anyway_and_its_sensor_box_says_why(qtbot, logbook, tmp_path,
                                                                     monkeypatch):
    from tactile_studio.ui.main_window import MainWindow
    from tactile_studio.ui.settings import SETTINGS_ENV

    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    damaged = damage(logbook, "random")
    w = MainWindow(device="simulated", settings={"rate": "200", "gesture": "idle"},
                   persist=False)
    qtbot.addWidget(w)
    w.show()
    box = w.panel.sensor_box
    assert "sensor logbook unavailable" in box.lineEdit().placeholderText()
    assert f"{logbook}: the sensor logbook is damaged" in box.toolTip()
    assert w.panel.connect_device()
    assert w.panel.start_recording(str(tmp_path / "s.h5"))
    qtbot.waitUntil(lambda: w.acquisition.recorder.rows_written > 20, timeout=10000)
    w.panel.stop_recording()
    w.shutdown()
    assert logbook.read_bytes() == damaged
    with SessionFile(tmp_path / "s.h5") as s:
        assert len(s.column("device_time")) > 20


def test_a_logbook_in_a_read_only_folder_is_one_line_and_recording_goes_on():
    """As the unprivileged user (root writes anywhere): the logbook's folder is not ours."""
    import shutil
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    base = Path(tempfile.mkdtemp(prefix="ts-logbook-"))
    try:
        base.chmod(0o777)
        data = base / "appdata"
        data.mkdir()
        with Logbook(data / "logbook.sqlite") as book:
            book.add_usage("sim-0", 60.0)
        data.chmod(0o555)
        exe = [str(Path(sys.executable).with_name("tactile-studio"))]
        if os.geteuid() == 0:
            if shutil.which("setpriv") is None:
                pytest.skip("running as root without setpriv: no way to drop privileges")
            exe = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", *exe]
        elif os.access(data, os.W_OK):
            pytest.skip("this filesystem ignores permissions")
        env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(data), "HOME": str(base),
               "TACTILE_STUDIO_CACHE_DIR": str(base), "MPLCONFIGDIR": str(base)}
        sensors = subprocess.run([*exe, "sensors"], capture_output=True, text=True, env=env,
                                 timeout=120)
        assert sensors.returncode == 1
        assert one_error_line(sensors.stderr).startswith(
            f"{data}/logbook.sqlite: cannot read the sensor logbook")
        record = subprocess.run([*exe, "record", "--device", "simulated", "--seconds", "0.3",
                                 "--out", str(base / "r.h5")], capture_output=True, text=True,
                                env=env, timeout=120)
        assert record.returncode == 0 and "Traceback" not in record.stderr
        said = [ln for ln in record.stderr.splitlines() if "sensor logbook" in ln]
        assert len(said) == 1 and said[0].startswith(
            f"sensor logbook not used for this recording: {data}/logbook.sqlite:")
        with SessionFile(base / "r.h5") as s:
            assert len(s.column("device_time")) > 0
    finally:
        for path in [base, *base.rglob("*")]:
            if path.is_dir():
                path.chmod(0o755)
        shutil.rmtree(base, ignore_errors=True)


def test_the_wellness_wizard_says_it_set_the_logbook_aside(qtbot, logbook):
    from tactile_studio.ui.wellness_wizard import WellnessWizard

    damaged = damage(logbook, "empty")
    w = WellnessWizard("simulated", {"speed": 0, "seed": 21})
    qtbot.addWidget(w)
    w.show()
    w.setup.weight.setValue(200)
    w.next()
    page = w.run_page
    qtbot.waitUntil(lambda: page.run is not None and not page.run.running, timeout=60000)
    page.poll()
    assert page.notice.isVisible()
    assert page.notice.text().startswith(f"{logbook}: the sensor logbook was damaged (empty: "
                                         "0 bytes); kept it as logbook.sqlite.damaged-")
    aside = next(logbook.parent.glob("logbook.sqlite.damaged-*[0-9]Z"))
    assert aside.read_bytes() == damaged
    with Logbook() as book:
        assert set(SENSORS) < set(book.sensor_ids())  # the backup's history, and the check
        assert len(book.checks("sim-21")) == 1


def test_a_logbook_from_a_newer_version_is_refused_and_left_as_it_is(tmp_path, capsys,
                                                                      monkeypatch):
    """A logbook a newer Tactile Studio wrote (a schema this one does not know) is not
    read or written: one line says so, and the file is byte for byte as it was (before,
    it was used without a word, and written into)."""
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path))
    with Logbook() as book:
        book.ensure_sensor("S-1")
        path = book.path
    db = sqlite3.connect(path)
    db.execute("INSERT INTO schema_version (version) VALUES (99)")
    db.commit()
    db.close()
    before = path.read_bytes()
    with pytest.raises(Exception, match="written by a newer Tactile Studio"):
        Logbook()
    assert main(["sensors"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(PREFIX + f"{path}: the sensor logbook was written by a newer")
    assert len(err.splitlines()) == 1 and "schema 99" in err
    assert path.read_bytes() == before
