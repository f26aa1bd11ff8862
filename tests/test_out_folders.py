"""One rule for an output folder that does not exist (issue 47 item 12): the console,
`collect --out` and `record --out` each did something else (refused without offering,
made it, refused). Every one now makes it (with its parents); the commands' last line
names what they wrote there, the console says so under the folder field before anything
is written."""

from __future__ import annotations

from pathlib import Path

from console_helpers import open_console_session

from tactile_studio.cli import main
from tactile_studio.ui.collect.console import CollectConsole


def test_record_and_collect_make_a_missing_folder(tmp_path: Path, capsys) -> None:
    target = tmp_path / "new" / "deeper" / "s.h5"
    assert main(["record", "--seconds", "0.2", "--set", "speed=10", "--out", str(target)]) == 0
    assert target.is_file()
    assert f"wrote {target}:" in capsys.readouterr().out  # the last line names it
    out = tmp_path / "sessions" / "P01"
    assert main(["collect", "--protocol", "shear9", "--participant", "P01", "--blocks", "1",
                 "--virtual-participant", "--speed", "0", "--out", str(out)]) == 0
    assert Path(capsys.readouterr().out.strip().splitlines()[-1]).parent == out


def test_the_console_says_a_missing_folder_will_be_made_and_makes_it(
        qtbot, tmp_path: Path, monkeypatch, qapp) -> None:
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    out = tmp_path / "study" / "P07"
    s = console.setup
    s.out_dir.setText(str(out))
    assert s.out_note.isVisibleTo(s)
    assert s.out_note.text() == f"{out} does not exist yet: it will be made when the session opens."
    s.out_dir.setText(str(tmp_path))
    assert not s.out_note.isVisibleTo(s)
    s.out_dir.setText(str(out))
    path = open_console_session(qtbot, console, out, "P07", make_folder=False)
    assert path.parent == out and path.is_file()
    console.close()
