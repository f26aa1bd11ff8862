"""The sensor engineer's outputs under faults: a `wellness --report` or `calibrate --out`
that could not be written is refused before the device is touched (one line naming the
file, exit 1, nothing measured or stored), never after a check or calibration was
measured and stored; `calibrate --out CAL.html` would have been overwritten by its own
HTML report (exit 0, the calibration file gone)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tactile_studio.cli import main
from tactile_studio.storage.books.logbook import Logbook

SIM = ["--device", "simulated", "--set", "speed=0", "--sensor", "sim-0", "--auto"]


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))
    return tmp_path / "data"


def errors(capsys) -> list[str]:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return [ln for ln in err.splitlines() if ln.startswith("tactile-studio:")]


def stored(kind: str) -> int:
    with Logbook() as book:
        if "sim-0" not in book.sensor_ids():
            return 0
        return len(book.checks("sim-0") if kind == "checks" else book.calibrations("sim-0"))


def calibrate(out, *extra) -> int:
    return main(["calibrate", *SIM, "--loads-g", "20,50,100", "--taxels", "B2", "--out",
                 str(out), *extra])


def test_calibrate_out_named_html_is_refused_not_overwritten_by_its_report(tmp_path, capsys):
    out = tmp_path / "cal.html"
    assert calibrate(out) == 1
    (line,) = errors(capsys)
    assert "cal.html" in line and "cal.json" in line
    assert not out.exists() and stored("calibrations") == 0


def test_calibrate_out_that_is_a_folder_is_refused_before_measuring(tmp_path, capsys):
    (tmp_path / "cal").mkdir()
    assert calibrate(tmp_path / "cal") == 1
    assert stored("calibrations") == 0  # it had been measured, stored and made active
    (line,) = errors(capsys)
    assert str(tmp_path / "cal") in line and "is a folder" in line
    assert not (tmp_path / "cal.tmp").exists()
    # its report's place too (cal.json beside a folder cal.html)
    (tmp_path / "c2.html").mkdir()
    assert calibrate(tmp_path / "c2.json") == 1
    (line,) = errors(capsys)
    assert "c2.html" in line and "is a folder" in line and stored("calibrations") == 0


def test_wellness_report_that_cannot_be_written_is_refused_before_the_check(tmp_path,
                                                                           capsys):
    (tmp_path / "check.html").mkdir()
    code = main(["wellness", *SIM, "--weight-g", "200", "--report",
                 str(tmp_path / "check.html")])
    assert code == 1
    assert stored("checks") == 0  # it had been run and stored, then 'cannot open'
    (line,) = errors(capsys)
    assert str(tmp_path / "check.html") in line and "is a folder" in line
    (tmp_path / "afile").write_text("")
    code = main(["wellness", *SIM, "--weight-g", "200", "--report",
                 str(tmp_path / "afile" / "check.html")])
    assert code == 1
    (line,) = errors(capsys)
    assert "afile" in line and "does not exist" in line and stored("checks") == 0


def test_a_calibration_file_that_fails_after_the_store_says_what_is_kept(tmp_path, capsys):
    """The place passed the check before measuring, then failed at the end (here another
    process writes the file then; a disk filling up does the same): the line names the
    file and says the calibration is in the logbook, active."""
    holder = subprocess.Popen([sys.executable, "-c", "import sys; from tactile_studio."
                               "file_claims import claim; c = claim(sys.argv[1]); "
                               "print('held', flush=True); sys.stdin.read()",
                               str(tmp_path / "cal.json")], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        assert calibrate(tmp_path / "cal.json") == 1
    finally:
        holder.communicate("", timeout=30)
    (line,) = errors(capsys)
    assert str(tmp_path / "cal.json") in line
    assert "calibration #1 of sim-0 is stored in the logbook (active)" in line
    assert stored("calibrations") == 1 and not (tmp_path / "cal.json").exists()


def test_an_output_named_like_a_recording_is_refused_and_the_recording_kept(tmp_path,
                                                                             capsys):
    """A session file typed as --out or --report was replaced by the calibration JSON or
    the HTML report, silently (exit 0 / 4): the recording was gone."""
    session = tmp_path / "P01.h5"
    assert main(["record", "--device", "simulated", "--set", "speed=0", "--seconds", "0.5",
                 "--out", str(session)]) == 0
    before = session.read_bytes()
    capsys.readouterr()
    assert calibrate(session) == 1
    (line,) = errors(capsys)
    assert str(session) in line and "is not a calibration file" in line
    assert main(["wellness", *SIM, "--weight-g", "200", "--report", str(session)]) == 1
    (line,) = errors(capsys)
    assert str(session) in line and "is not an HTML report" in line
    assert session.read_bytes() == before
    assert stored("calibrations") == 0 and stored("checks") == 0
    # an earlier calibration and its report are replaced, as before
    assert calibrate(tmp_path / "cal.json") == 0 and calibrate(tmp_path / "cal.json") == 0
    assert stored("calibrations") == 2
