"""Resuming a killed collection keeps one device clock and the device's rate, counts the
resume as a gap, refuses another sensor unless told why, and ``info`` never counts a
resume backup's trials twice (the real commands, a real SIGKILL)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from tactile_studio.cli import main
from tactile_studio.errors import SessionFileError
from tactile_studio.storage.format.session_check import check_file
from tactile_studio.storage.format.session_file import SessionFile

EXE = str(Path(sys.executable).parent / "tactile-studio")
WAIT_S = 60.0  # safety net only


def _ok_trials(path: Path) -> int:
    try:
        with SessionFile(path) as s:
            return sum(1 for t in s.trials if t.status == "ok")
    except SessionFileError:  # between creating the file and its first flush
        return 0


def _killed_session(out: Path, trials: int = 3) -> Path:
    """A shear9 block on sensor sim-5 (order seed 5 too) killed with SIGKILL once
    ``trials`` trials are in the file."""
    proc = subprocess.Popen([EXE, "collect", "--protocol", "shear9", "--participant", "P05",
                             "--virtual-participant", "--speed", "20", "--blocks", "1",
                             "--seed", "5", "--set", "seed=5", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + WAIT_S
    try:
        while not list(out.glob("*.h5")) or _ok_trials(next(out.glob("*.h5"))) < trials:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no progress"
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.communicate()
    return next(out.glob("*.h5"))


def _resume(capsys, path: Path, *extra: str) -> tuple[int, str]:
    code = main(["collect", "--resume", str(path), "--virtual-participant", "--speed", "40",
                 *extra])
    return code, capsys.readouterr().err


def test_resume_continues_the_device_clock_and_refuses_another_sensor(
        tmp_path: Path, capsys) -> None:
    path = _killed_session(tmp_path)
    with SessionFile(path) as s:
        n_old, last_old = s.n_frames, float(s.column("device_time")[-1])
    # another sensor (the simulator's seed is its identity): one line, the file untouched
    code, err = _resume(capsys, path, "--set", "seed=7")
    assert code == 1 and err.count("\n") == 1
    assert "recorded on sensor sim-5, but the device is sensor sim-7" in err
    assert not list(tmp_path.glob("*.bak-*.h5"))

    code, err = _resume(capsys, path)
    assert code == 0, err
    result = check_file(path)
    assert result.ok, result.violations
    with SessionFile(path) as s:
        dev = s.column("device_time")
        resume = next(e for e in s.events if e["kind"] == "resume" and "from_file" in e)
        starts = [t.start_time for t in s.trials]
        rate = 1.0 / s.metadata["device"]["nominal_rate_hz"]
        tares = [e for e in s.events if e["kind"] == "tare"]
    # the resumed run's clock goes on one frame period after the old file's last frame
    assert resume["frame"] == n_old and resume["device_time_offset"] == last_old + rate
    assert dev[n_old] == last_old + rate and np.all(np.diff(dev) >= 0)
    assert len(starts) == 9 and starts == sorted(starts)
    # each run's auto-tare names the rows it averaged (file rows: the resumed run's
    # first 100 frames, not the engine's frames 0..99, which are the old run's rows)
    assert len(tares) == 2 and tares[1]["first_frame"] == n_old
    assert all(e["first_frame"] + e["frames"] <= e["frame"] for e in tares)

    assert main(["info", "--json", str(path)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert abs(info["rate_hz"] - 43.0) < 0.5  # the device's rate, not 64-151 Hz
    assert info["gaps"] == 1 and info["segments"] == 2  # the resume is a gap

    # named explicitly, the backup is marked and its trials are not counted again
    backup = next(tmp_path.glob("*.bak-1.h5"))
    assert main(["info", str(path), str(backup)]) == 0
    out = capsys.readouterr().out
    assert "resume backup" in out and "ok trials: 9 of 9 gestures (1 each)" in out
    # named alone it says so too, and which file the session continues in
    assert main(["info", str(backup)]) == 0
    out = capsys.readouterr().out
    assert f"backup:     a resume backup: the session continues in {path.name}" in out


def test_resume_on_another_sensor_with_a_note_keeps_the_note(tmp_path: Path, capsys) -> None:
    path = _killed_session(tmp_path, trials=2)
    code, err = _resume(capsys, path, "--set", "seed=7", "--allow-other-sensor",
                        "sim-5 cable broke; same participant on sim-7")
    assert code == 0, err
    with SessionFile(path) as s:
        other = s.metadata["other_sensor"]
        notes = [e for e in s.events if e["kind"] == "note"]
    assert other[0]["sensor_id"] == "sim-7" and "sim-5" in other[0]["why"]
    assert other[0]["note"] == "sim-5 cable broke; same participant on sim-7"
    assert "cable broke" in notes[0]["text"] and "cable broke" in s.metadata["notes"]
    assert check_file(path).ok


def test_the_console_refuses_a_resume_on_another_sensor_in_one_line(
        qtbot, tmp_path: Path, monkeypatch) -> None:
    from tactile_studio.ui.collect.console import CollectConsole

    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    (tmp_path / "data").mkdir()
    path = _killed_session(tmp_path / "data", trials=1)
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    setup = console.setup
    setup.device.setCurrentIndex(setup.device.findData("simulated"))
    seed = setup.device_form.fields["seed"].editor
    seed.clear()
    qtbot.keyClicks(seed, "7")
    assert not console.resume_from(path)
    text = setup.error.text()
    assert "recorded on sensor sim-5, but the device is sensor sim-7" in text
    assert "\n" not in text and console.stack.currentIndex() == 0
    assert not list(path.parent.glob("*.bak-*.h5"))


def test_the_console_resumes_on_the_file_s_device(qtbot, tmp_path: Path, monkeypatch) -> None:
    from tactile_studio.ui.collect.console import CollectConsole

    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    (tmp_path / "data").mkdir()
    path = _killed_session(tmp_path / "data", trials=1)
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    setup = console.setup
    setup.device.setCurrentIndex(setup.device.findData("simulated"))
    seed = setup.device_form.fields["seed"].editor
    seed.clear()
    qtbot.keyClicks(seed, "7")  # the form's device is another sensor than the file's
    setup.set_resume_mode(True)
    setup.resume_file.setText(str(path))
    setup.continue_button.click()  # the form takes the file's device, then resumes
    assert console.session is not None, setup.error.text()
    assert console.engine.sensor_id() == "sim-5"
    assert setup.device_form.changed_values().get("seed") in (5, "5")
    console.close_session()


def test_the_console_says_the_sensor_differs_and_resumes_on_it_with_a_note(
        qtbot, tmp_path: Path, monkeypatch) -> None:
    from PySide6.QtCore import Qt

    from tactile_studio.ui.collect.console import CollectConsole

    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    (tmp_path / "data").mkdir()
    path = _killed_session(tmp_path / "data", trials=1)
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    setup = console.setup
    setup.set_resume_mode(True)
    setup.resume_file.setText(str(path))
    setup.device_from_file(str(path))  # what choosing the file does: the file's sim-5
    assert setup.other_sensor_button.isHidden() and setup.other_sensor_info.text() == ""
    seed = setup.device_form.fields["seed"].editor
    seed.clear()
    qtbot.keyClicks(seed, "7")  # the experimenter picks another sensor, after the file
    # the setup says so before anything is tried, and offers the explicit choice
    info = setup.other_sensor_info.text()
    assert "The simulated device's settings differ from the file's (seed 5 there, 7 here)" \
        in info, info
    assert not setup.other_sensor_button.isHidden()
    console.grab().save(str(tmp_path / "resume_other_sensor.png"))

    # plain Resume keeps the chosen device and is refused in one line, the file untouched
    setup.continue_button.click()
    assert console.session is None and console.stack.currentIndex() == 0
    error = setup.error.text()
    assert "recorded on sensor sim-5, but the device is sensor sim-7" in error
    assert "\n" not in error and "--allow-other-sensor" not in error  # no CLI option here
    assert setup.device_form.values().get("seed") == "7"
    assert not setup.other_sensor_button.isHidden()
    assert not list(path.parent.glob("*.bak-*.h5"))

    # "Resume on this other sensor…" asks why; no note, no resume
    setup.other_sensor_button.click()
    dialog = console.dialog
    assert dialog is not None and "sim-5" in dialog.label.text()
    qtbot.mouseClick(dialog.buttons.buttons()[0], Qt.MouseButton.LeftButton)
    assert console.session is None and dialog.isVisible()
    qtbot.keyClicks(dialog.edit.lineEdit(), "sim-5 cable broke; same participant on sim-7")
    qtbot.mouseClick(dialog.buttons.buttons()[0], Qt.MouseButton.LeftButton)
    assert console.session is not None, setup.error.text()
    assert console.engine.sensor_id() == "sim-7"
    console.close_session()
    # stored exactly as collect --allow-other-sensor stores it
    with SessionFile(path) as s:
        other = s.metadata["other_sensor"]
        notes = [e["text"] for e in s.events if e["kind"] == "note"]
    assert other[0]["sensor_id"] == "sim-7" and "sim-5" in other[0]["why"]
    assert other[0]["note"] == "sim-5 cable broke; same participant on sim-7"
    assert any("resumed on another sensor" in n and "cable broke" in n for n in notes)
    assert check_file(path).ok

    # resumed again, the file's device is now sim-7 (the form shows it): no second note
    setup.resume_file.setText(str(path))
    setup.device_from_file(str(path))
    assert setup.device_form.values().get("seed") == "7" and setup.other_sensor_info.isHidden()
    setup.continue_button.click()
    assert console.session is not None, setup.error.text()
    console.close_session()
    with SessionFile(path) as s:
        assert len(s.metadata["other_sensor"]) == 1 and s.metadata["resumes"] == 2
    assert check_file(path).ok


def test_device_differences_names_what_is_not_the_file_s() -> None:
    from tactile_studio.protocol.collect import device_differences

    info = {"device": {"plugin": "simulated",
                       "settings": {"seed": 5, "speed": 20.0, "gesture": "idle"}}}
    # the same sensor, whatever the virtual participant's speed or the scripted gesture
    assert device_differences(info, "simulated", {"seed": "5", "speed": "1"}) is None
    assert device_differences(info, "simulated", {"seed": "7"}) == (
        "the simulated device's settings differ from the file's (seed 5 there, 7 here)")
    assert device_differences(info, "serial", {}) == (
        "the file was recorded with device simulated, not serial")
    # not to be told before the device opens: the live device, a value the form refuses
    assert device_differences(info, None, {}) is None
    assert device_differences(info, "simulated", {"seed": "x"}) is None


def test_a_resume_at_another_frame_rate_is_refused_unless_told_why(
        tmp_path: Path, capsys) -> None:
    """One file, one frame rate: a resume whose device runs at another rate (the same
    sensor ID) would have mixed 43 Hz and 100 Hz frames under metadata saying 100 Hz,
    and ``info`` would have read 79 Hz, a rate no frame was recorded at."""
    path = _killed_session(tmp_path, trials=1)
    code, err = _resume(capsys, path, "--set", "rate=100")
    assert code == 1 and err.count("\n") == 1, err
    assert "recorded at 43 Hz, but the device runs at 100 Hz" in err
    assert not list(tmp_path.glob("*.bak-*.h5"))  # the file untouched

    code, err = _resume(capsys, path, "--set", "rate=100", "--allow-other-sensor",
                        "firmware update: the receiver now sends 100 frames/s")
    assert code == 0, err
    with SessionFile(path) as s:
        other = s.metadata["other_sensor"]
    assert "recorded at 43 Hz" in other[0]["why"] and "firmware" in other[0]["note"]
    assert check_file(path).ok


def test_a_resumed_device_whose_clock_runs_on_keeps_its_own_times(tmp_path: Path) -> None:
    """A serial receiver sends no clock: its frames carry host times, which run on
    between two runs by themselves. A resume shifted them by the file's last time all
    the same (3.6e9 s after it, the year 2083: in device times, trial times and a CSV
    export's time column). A clock that starts again (the simulator's) is still
    continued one frame after the file's last (the first test)."""
    from collect_fixtures import mini_protocol
    from waiting import wait_until

    from tactile_studio.devices import AcquisitionEngine, create_device
    from tactile_studio.devices.serial_emulator import SerialEmulator, array_source
    from tactile_studio.protocol.collect import (
        CollectionSettings,
        open_collection,
        resume_collection,
    )
    from tactile_studio.protocol.trial_runner import StreamClock

    emu = SerialEmulator(array_source(np.full((997, 180), 30000, dtype=np.uint16)),
                         rate_hz=200, link=tmp_path / "port", reader_grace=0.05)
    emu.open()
    emu.start()

    def run(resume: Path | None = None) -> Path:
        engine = AcquisitionEngine(create_device("serial", {"port": emu.port}))
        session = (resume_collection(resume, engine, clock=StreamClock(engine)) if resume
                   else open_collection(CollectionSettings(mini_protocol(), "P01", tmp_path),
                                        engine, clock=StreamClock(engine)))
        first = session.recorder.row_offset
        try:
            engine.start()
            wait_until(lambda: session.recorder.rows_written >= first + 30,
                       what="30 frames in the file")
        finally:
            session.close()
            engine.stop()
        return session.path

    try:
        path = run(run())
    finally:
        emu.close()
    assert check_file(path).ok
    with SessionFile(path) as s:
        dev, host = s.column("device_time"), s.column("host_time")
        resume = next(e for e in s.events if e["kind"] == "resume" and "from_file" in e)
    assert resume["device_time_offset"] == 0.0
    np.testing.assert_array_equal(dev, host)  # the frames' own times, on both sides


def test_a_resume_on_a_running_engine_keeps_the_earlier_rows_baselines(tmp_path: Path) -> None:
    """The console may resume on an engine that is already running and tared: its
    baseline went into the file at row 0, so the earlier run's first rows (before that
    run's own tare) decoded against the new run's baseline."""
    from waiting import wait_until

    from tactile_studio.devices import AcquisitionEngine, create_device
    from tactile_studio.protocol.collect import resume_collection
    from tactile_studio.protocol.trial_runner import StreamClock

    path = _killed_session(tmp_path, trials=1)
    with SessionFile(path) as s:
        n_old = s.n_frames
        before = [s.baseline(row) for row in (0, 50, n_old - 1)]
    engine = AcquisitionEngine(create_device("simulated", {"seed": 5, "speed": 20,
                                                          "drift": 0.05}))
    engine.start()
    try:
        wait_until(lambda: engine.baseline is not None and engine.frames > 300,
                   what="a tared engine")
        session = resume_collection(path, engine, clock=StreamClock(engine))
        wait_until(lambda: session.recorder.rows_written >= n_old + 20, what="new rows")
        session.close()
        new_baseline = np.asarray(engine.baseline, dtype=np.float64)
    finally:
        engine.stop()
    with SessionFile(path) as s:
        after = [s.baseline(row) for row in (0, 50, n_old - 1)]
        assert np.array_equal(s.baseline(n_old), new_baseline)
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a, b)
