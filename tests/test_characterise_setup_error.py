"""A characterisation that fails before measuring a taxel (an instrument that does not
fit, a typo in --device, a stage that fails to home) says so, and the same --out is used again
without --overwrite: it said '(data so far kept in DIR)' and the fixed command was
refused ('holds an aborted characterisation (0 of 1 taxel(s) done ...)')."""

from __future__ import annotations

import json

import pytest

from tactile_studio.cli import main


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def test_a_setup_error_leaves_the_folder_free_for_the_fixed_command(tmp_path, capsys):
    out = tmp_path / "char"
    args = ["characterise", "--taxels", "B2", "--sequence", "normal", "--out", str(out)]
    # the simulated stage needs the simulated sensor: refused before anything moves
    assert main([*args, "--device", "serial", "--set", "port=/dev/null"]) == 1
    err = capsys.readouterr().err
    (line,) = [ln for ln in err.splitlines() if ln.startswith("tactile-studio:")]
    assert "needs the simulated sensor" in line and "no taxel was measured" in line
    assert main([*args, "--device", "simulated", "--set", "speed=0", "--set",
                 "gesture=idle"]) == 0, capsys.readouterr().err
    assert json.loads((out / "characterisation.json").read_text())["complete"]


def test_a_run_that_recorded_is_still_protected(tmp_path, capsys):
    out = tmp_path / "char"
    args = ["characterise", "--device", "simulated", "--set", "speed=0", "--set",
            "gesture=idle", "--taxels", "B2", "--sequence", "normal", "--out", str(out)]
    assert main(args) == 0
    assert main(args) == 1
    assert "holds a finished characterisation" in capsys.readouterr().err


def test_a_stage_that_fails_to_home_leaves_the_folder_free(tmp_path, capsys):
    """The session was open (a few frames) when homing failed: no taxel was measured."""
    from tactile_studio.instruments.printer_emulator import PrinterEmulator

    out = tmp_path / "char"
    bad = PrinterEmulator(fail_home=True, home_s=0.01)
    bad.open()
    try:
        code = main(["characterise", "--device", "simulated", "--set", "speed=0", "--set",
                     "gesture=idle", "--stage", "gcode", "--stage-set", f"port={bad.port}",
                     "--taxels", "B2", "--sequence", "normal", "--out", str(out)])
    finally:
        bad.stop()
    assert code == 1 and (out / "session.h5").exists()
    err = capsys.readouterr().err
    assert "Homing failed" in err and "no taxel was measured" in err
    assert main(["characterise", "--device", "simulated", "--set", "speed=0", "--set",
                 "gesture=idle", "--taxels", "B2", "--sequence", "normal",
                 "--out", str(out)]) == 0
