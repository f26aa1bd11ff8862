"""``tactile-studio collect`` as a user runs it: real subprocesses, real files,
SIGKILL mid-session and a resume that loses no completed trial."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tactile_studio.cli import main
from tactile_studio.errors import SessionFileError
from tactile_studio.protocol.randomise import block_orders
from tactile_studio.storage.format.protocol_file import load_protocol
from tactile_studio.storage.format.session_file import SessionFile

EXE = str(Path(sys.executable).parent / "tactile-studio")
WAIT_S = 60.0  # safety net only


def _collect(*args: str, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, "collect", *args], capture_output=True, text=True,
                          timeout=120, **kw)


def _trials_in(path: Path) -> list[dict]:
    try:
        with SessionFile(path) as s:
            return s.journal.trials
    except SessionFileError:  # the writer is between creating and first flush
        return []


def _start(out: Path, *extra: str) -> tuple[subprocess.Popen, Path]:
    proc = subprocess.Popen([EXE, "collect", "--protocol", "shear9", "--participant", "P01",
                             "--device", "simulated", "--virtual-participant", "--out", str(out),
                             *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + WAIT_S
    while not list(out.glob("*.h5")):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    return proc, next(out.glob("*.h5"))


def _wait_trials(proc: subprocess.Popen, path: Path, n: int) -> None:
    deadline = time.monotonic() + WAIT_S
    while len(_trials_in(path)) < n:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "no progress"
        time.sleep(0.05)


def _main(capsys, *args: str) -> tuple[int, str, str]:
    """The real CLI entry point in-process (no interpreter start-up per call)."""
    code = main(["collect", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_headless_session_and_determinism(tmp_path: Path, capsys) -> None:
    runs = []
    for name, seed in (("a", "3"), ("b", "3"), ("c", "4")):
        code, out, err = _main(capsys, "--protocol", "shear9", "--participant", "P01",
                               "--virtual-participant", "--blocks", "1", "--seed", seed,
                               "--speed", "40", "--out", str(tmp_path / name))
        assert code == 0, err
        path = Path(out.strip().splitlines()[-1])
        assert path.parent == tmp_path / name and path.name.startswith("P01_shear9_")
        assert "collect P01" in err  # progress on stderr
        with SessionFile(path) as s:
            runs.append((s.journal.trials, s.raw(0, s.n_frames)))
    (ta, ra), (tb, rb), (tc, _) = runs
    assert len(ta) == 9 and all(t["status"] == "ok" for t in ta)
    assert ta == tb  # same seed: the same trials at the same rows...
    end = ta[-1]["end_sample"]
    assert (ra[:end] == rb[:end]).all()  # ...with the same frames
    assert [t["gesture"] for t in ta] != [t["gesture"] for t in tc]


def test_bad_arguments_are_one_line_errors_before_any_window(tmp_path: Path, capsys) -> None:
    for mode in (["--virtual-participant"], []):  # headless, and the console path
        code, _, err = _main(capsys, "--protocol", "shear10", "--participant", "P01", *mode,
                             "--out", str(tmp_path))
        assert code == 1 and "unknown protocol 'shear10'" in err
        code, _, err = _main(capsys, "--protocol", "shear9", "--participant", "P 1", *mode,
                             "--out", str(tmp_path))
        assert code == 1 and "bad participant id" in err
        code, _, err = _main(capsys, *mode, "--resume", str(tmp_path / "no.h5"))
        assert code == 1 and "no such file" in err
        assert len(err.strip().splitlines()) == 1
    base = ["--protocol", "shear9", "--participant", "P01", "--out", str(tmp_path / "x")]
    for extra, message in ((["--set", "noise=3"], "--set needs --device"),
                           (["--device", "simulated", "--set", "bogus=1"],
                            "unknown setting 'bogus'"),
                           (["--device", "serial", "--speed", "2"],
                            "--speed applies to the simulated"),
                           (["--blocks", "0"], "--blocks must be at least 1")):
        code, _, err = _main(capsys, *base, *extra)
        assert code == 1 and message in err and len(err.strip().splitlines()) == 1, err
    assert not list(tmp_path.glob("**/*.h5"))


def _run_console_cli(capsys, *args: str):
    """``collect`` without --virtual-participant: the real command, its event loop ended
    at once by a timer; returns the exit code, stderr and the console it opened."""
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication

    from tactile_studio.ui.collect.console import CollectConsole

    app = QApplication.instance()
    # Hold the widgets themselves, not their id()s: a wrapper freed meanwhile could hand
    # its address to the new console and hide it.
    before = list(app.topLevelWidgets())
    timer = QTimer(singleShot=True, interval=0)
    timer.timeout.connect(lambda: app.exit(0))  # (quit() would close the windows too)
    timer.start()
    try:
        code, _, err = _main(capsys, *args)
    finally:
        timer.stop()  # an error before the event loop must not end a later test's loop
    opened = [w for w in app.topLevelWidgets()
              if isinstance(w, CollectConsole) and not any(w is b for b in before)
              and w.isVisible()]
    return code, err, opened


def test_without_a_virtual_participant_the_console_opens_pre_filled(
        tmp_path: Path, capsys, qtbot, monkeypatch) -> None:
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    out = tmp_path / "new folder"
    code, err, opened = _run_console_cli(
        capsys, "--protocol", "shear9", "--participant", "P01", "--device", "simulated",
        "--set", "noise=5", "--blocks", "2", "--seed", "7", "--condition", "FLAT",
        "--out", str(out))
    assert code == 0, err
    assert len(opened) == 1
    console = opened[0]
    s = console.setup
    assert s.protocol.currentData() == "shear9" and "9 gestures" in s.protocol_info.text()
    assert s.participant.text() == "P01" and s.condition.text() == "FLAT"
    assert (s.blocks.value(), s.seed.value()) == (2, 7)
    assert s.device.currentData() == "simulated"
    assert s.device_form.fields["noise"].text() == "5"
    assert s.device_form.changed_values() == {"noise": "5"}
    assert s.out_dir.text() == str(out) and not out.exists()  # made when the session opens
    assert s.out_note.text() == \
        f"{out} does not exist yet: it will be made when the session opens."
    assert console.stack.currentIndex() == 0 and console.session is None  # not started
    choice = s.choice()  # what "Open session" would start
    assert (choice.protocol.blocks, choice.seed, choice.device_settings) == \
        (2, 7, {"noise": "5"})
    # the experimenter opens it; then, closed mid-session, the command resumes it
    assert console.start_session(choice)
    path = console.session.path
    assert path.parent == out  # made (one rule for a missing folder: tests/test_out_folders)
    console.close()
    code, err, opened = _run_console_cli(capsys, "--resume", str(path))
    assert code == 0, err
    resumed = opened[0]
    assert resumed.stack.currentIndex() == 1 and resumed.session.path == path
    assert resumed.setup.device.currentData() == "simulated"
    # the file's settings, minus defaults
    assert resumed.setup.device_form.changed_values() == {"noise": "5"}
    assert resumed.runner.participant == "P01"
    resumed.close()
    with SessionFile(path) as sess:
        assert sess.metadata["resumes"] == 1 and sess.metadata["condition"] == "FLAT"
    code, err, opened = _run_console_cli(capsys, "--protocol", "shear9", "--participant", "P01",
                                         "--device", "replay", "--out", str(out))
    assert code == 1 and "cannot run a collection session" in err and not opened


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="X11/Wayland check")
def test_console_without_a_display_is_a_one_line_error(tmp_path: Path, capsys,
                                                        monkeypatch) -> None:
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM"):
        monkeypatch.delenv(name, raising=False)
    code, out, err = _main(capsys, "--protocol", "shear9", "--participant", "P01",
                           "--device", "simulated", "--out", str(tmp_path / "o"))
    assert code == 1 and out == ""
    assert err.count("\n") == 1 and "no display" in err and "--virtual-participant" in err
    assert not (tmp_path / "o").exists()


def test_resume_refuses_a_mismatch_or_a_complete_session(tmp_path: Path, capsys) -> None:
    code, out, err = _main(capsys, "--protocol", "shear9", "--participant", "P02",
                           "--virtual-participant", "--blocks", "1", "--speed", "40",
                           "--out", str(tmp_path))
    assert code == 0, err
    path = out.strip().splitlines()[-1]
    for flag, value in (("--participant", "P03"), ("--protocol", "cost14"), ("--seed", "9")):
        code, _, err = _main(capsys, "--virtual-participant", "--resume", path, flag, value)
        assert code == 1 and value in err, err
    code, _, err = _main(capsys, "--virtual-participant", "--resume", path)
    assert code == 1 and "complete" in err


@pytest.mark.slow
def test_kill_minus_9_then_resume_loses_nothing_and_keeps_the_order(tmp_path: Path) -> None:
    proc, path = _start(tmp_path, "--blocks", "3", "--seed", "5", "--speed", "15")
    _wait_trials(proc, path, 11)  # into block 2
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    kept = _trials_in(path)
    assert len(kept) >= 11
    res = _collect("--virtual-participant", "--resume", str(path), "--speed", "40")
    assert res.returncode == 0, res.stderr
    assert Path(res.stdout.strip().splitlines()[-1]) == path
    backups = list(tmp_path.glob("*.bak-1.h5"))
    assert len(backups) == 1
    assert _trials_in(backups[0]) == kept
    order = block_orders(load_protocol("shear9"), "P01", seed=5, blocks=3)
    with SessionFile(path) as s:
        assert s.closed_cleanly and s.metadata["resumes"] == 1
        trials = s.journal.trials
    assert trials[:len(kept)] == kept  # every completed trial survived, unchanged
    assert [t["index"] for t in trials] == list(range(len(trials)))
    assert all(t["status"] == "ok" for t in trials)
    for b in range(3):
        assert [t["gesture"] for t in trials if t["block"] == b] == order[b]
    assert len(trials) == 27
    for t in trials:
        assert t["end_sample"] - t["start_sample"] == 86


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_ctrl_c_or_sigterm_stops_cleanly_keeping_trials(tmp_path: Path, sig) -> None:
    proc, path = _start(tmp_path, "--blocks", "2", "--speed", "10")
    _wait_trials(proc, path, 2)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "--resume" in err and "Traceback" not in err
    with SessionFile(path) as s:
        assert s.closed_cleanly
        assert 2 <= len(s.journal.trials) < 18
        assert any(e["kind"] == "abort" for e in s.events)


def test_the_console_without_out_keeps_its_own_folder_not_the_current_one(
        tmp_path: Path, capsys, qtbot, monkeypatch) -> None:
    """`collect` without --out opened the console on the folder the command ran in."""
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))
    monkeypatch.chdir(tmp_path)
    code, err, opened = _run_console_cli(capsys, "--protocol", "shear9", "--participant",
                                         "P01", "--device", "simulated")
    assert code == 0, err
    s = opened[0].setup
    assert s.out_dir.text() == str(tmp_path / "data" / "sessions")
    assert s.blocks.value() == 52  # the protocol's own count
    opened[0].close()


def test_the_order_seed_is_not_the_simulated_sensors_seed(tmp_path: Path, capsys) -> None:
    """Issue 47 item 16: `collect --seed 1` also made the simulated sensor sim-1 (a
    different sensor, with its own logbook entry), while the console's "order seed" did
    not. The order seed orders the blocks; `--set seed=N` chooses the sensor."""
    found = {}
    for name, extra in (("a", []), ("b", ["--set", "seed=4"])):
        code, out, err = _main(capsys, "--protocol", "shear9", "--participant", "P01",
                               "--virtual-participant", "--blocks", "1", "--seed", "1",
                               "--speed", "0", "--out", str(tmp_path / name), *extra)
        assert code == 0, err
        with SessionFile(Path(out.strip().splitlines()[-1])) as s:
            found[name] = (s.metadata["sensor_id"], s.metadata["order_seed"],
                           s.metadata["block_order"])
    assert found["a"][0] == "sim-0" and found["b"][0] == "sim-4"
    assert found["a"][1:] == found["b"][1:]  # the same orders on either sensor
