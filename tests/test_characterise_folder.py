"""`characterise` into a folder that already holds a run: refused unless --overwrite (one
line naming the folder and what it holds); with --overwrite the old run's files go first,
so two runs are never mixed. The user's own files in the folder are left alone."""

from __future__ import annotations

import json

from tactile_studio.cli import main
from tactile_studio.storage.format.session_file import SessionFile

QUICK = ["characterise", "--set", "speed=0", "--set", "gesture=idle", "--sequence", "normal",
         "--param", "dwell_s=0.5", "--param", "normal_steps=4", "--param", "settle_s=0.5"]


def error_lines(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if not ln.startswith("characterise [")]


def taxels_in(out):
    with SessionFile(out / "session.h5") as s:
        return [e["taxel"] for e in s.events if e["kind"] == "char_taxel"]


def test_a_finished_run_is_refused_then_replaced_with_overwrite(tmp_path, capsys):
    out = tmp_path / "run"
    assert main([*QUICK, "--taxels", "B2,B3", "--out", str(out)]) == 0
    (out / "notes.txt").write_text("the user's own file")
    before = (out / "session.h5").stat()
    capsys.readouterr()

    assert main([*QUICK, "--taxels", "C4", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    lines = error_lines(err)
    assert len(lines) == 1 and "Traceback" not in err
    assert str(out) in lines[0] and "a finished characterisation of 2 taxel(s)" in lines[0]
    assert "--overwrite" in lines[0]
    assert (out / "session.h5").stat().st_mtime_ns == before.st_mtime_ns  # untouched
    assert sorted(p.name for p in (out / "raw").iterdir()) == ["B2.json", "B3.json"]

    assert main([*QUICK, "--taxels", "C4", "--overwrite", "--out", str(out)]) == 0
    assert sorted(p.name for p in (out / "raw").iterdir()) == ["C4.json"]
    assert sorted(p.name for p in (out / "figures").iterdir()) == ["C4.png", "maps.png"]
    saved = json.loads((out / "characterisation.json").read_text())
    assert list(saved["taxels"]) == ["C4"] and saved["complete"] is True
    assert taxels_in(out) == ["C4"]
    assert (out / "notes.txt").read_text() == "the user's own file"


def test_an_aborted_run_is_refused_too(tmp_path, capsys):
    out = tmp_path / "run"
    # the first taxel is begun, then the stage refuses a move below its floor (a run that
    # failed at homing measured nothing, and its folder is free: test_characterise_setup_error)
    assert main([*QUICK, "--taxels", "B2", "--param", "normal_depth_mm=50",
                 "--out", str(out)]) == 1
    capsys.readouterr()
    assert main([*QUICK, "--taxels", "B2", "--out", str(out)]) == 1
    lines = error_lines(capsys.readouterr().err)
    assert len(lines) == 1 and "an aborted characterisation (0 of 1 taxel(s) done" in lines[0]
    assert json.loads((out / "characterisation.json").read_text())["aborted"]


def test_files_of_a_run_without_its_json_are_a_run(tmp_path, capsys):
    out = tmp_path / "run"
    (out / "raw").mkdir(parents=True)
    (out / "raw" / "A1.json").write_text("{}")
    assert main([*QUICK, "--taxels", "B2", "--out", str(out)]) == 1
    lines = error_lines(capsys.readouterr().err)
    assert len(lines) == 1 and "files of an earlier characterisation (1 file(s))" in lines[0]
    assert main([*QUICK, "--taxels", "B2", "--overwrite", "--out", str(out)]) == 0
    assert sorted(p.name for p in (out / "raw").iterdir()) == ["B2.json"]


def test_an_empty_or_foreign_folder_is_used_as_is(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "other.h5").write_bytes(b"not ours")
    assert main([*QUICK, "--taxels", "B2", "--out", str(out)]) == 0
    assert (out / "other.h5").read_bytes() == b"not ours"
