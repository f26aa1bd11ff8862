"""An emulator's --link is only ever a link: a file already at that name (a name typed
wrong) was deleted for the link, and the link removed at exit, the file gone; a link in a
folder that does not exist named the pty (/dev/pts/N: No such file or directory), not
the link. Real emulators through the CLI."""

from __future__ import annotations

import pytest
from fault_helpers import one_error_line

from tactile_studio.cli import main


@pytest.mark.parametrize("command", ["emulate-loadcell", "emulate-serial", "emulate-printer"])
def test_a_file_at_the_link_name_is_kept_and_the_command_refused(tmp_path, capsys, command):
    notes = tmp_path / "notes.txt"
    notes.write_text("three hours of bench notes\n")
    assert main([command, "--link", str(notes), "--seconds", "0.2"]) == 1
    assert notes.read_text() == "three hours of bench notes\n"
    assert str(notes) in one_error_line(capsys)  # "a file is there, not a link" (or the
    # serial emulator's own earlier check: "exists and is not a symlink")


def test_a_link_in_a_missing_folder_names_the_link(tmp_path, capsys):
    link = tmp_path / "nowhere" / "lc"
    assert main(["emulate-loadcell", "--link", str(link), "--seconds", "0.2"]) == 1
    assert one_error_line(capsys) == (f"tactile-studio: error: {link}: folder {link.parent} "
                                 "does not exist")
    # and a link of our own is re-pointed as before
    link = tmp_path / "lc"
    assert main(["emulate-loadcell", "--link", str(link), "--seconds", "0.2"]) == 0
    assert main(["emulate-loadcell", "--link", str(link), "--seconds", "0.2"]) == 0
    assert not link.exists()
