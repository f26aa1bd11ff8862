"""Names that files from elsewhere choose, made into our file names (issue 43, the hunt):
a CoST or HAART subject and a session's participant or condition must be one name, never
a path out of the folder given, nor control characters in a file name. Real CSVs and
sessions through the real commands; each refusal is one line naming the file, exit 1, and
nothing is written anywhere."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.errors import EXIT_ERROR
from tactile_studio.sensor.layout import get_layout
from tactile_studio.storage.format.session_writer import SessionWriter

HEADER = "subject, variant, gesture, frame, " + ", ".join(f"ch{i}" for i in range(1, 65))


def _cost_csv(path: Path, subject: str) -> Path:
    rows = [HEADER] + [f"{subject}, gentle, 6, {f}, " + ", ".join(["500"] * 64)
                       for f in range(1, 31)]
    path.write_text("\n".join(rows) + "\n")
    return path


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*") if p.is_file()}


@pytest.mark.parametrize("subject", ["../../escaped", "/tmp/escaped", "a/b",
                                     "P1\x1b]0;owned\x07", "x" * 80])
def test_a_dataset_subject_that_is_not_a_participant_id_is_refused(tmp_path: Path, capsys,
                                                                    subject: str) -> None:
    """It named the session file: ``cost_P../../escaped.h5`` (outside --out wherever such
    a folder existed), ``cost_P1<ESC>]0;owned<BEL>.h5``, or a name too long to create."""
    csv = _cost_csv(tmp_path / "CoST.csv", subject)
    out = tmp_path / "out" / "deep"
    out.mkdir(parents=True)
    before = _files(tmp_path)
    assert main(["import", "cost", str(csv), "--out", str(out)]) == EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"tactile-studio: error: {csv}: subject ")
    assert "cannot name a participant" in err[-1] and "\x1b" not in err[-1]
    assert _files(tmp_path) == before


def _session(path: Path, participant: str, condition: str = "") -> Path:
    layout = get_layout("shearsense-6x6")
    n = 40
    with SessionWriter(path, layout, {"plugin": "simulated", "layout": layout.name,
                                      "nominal_rate_hz": 43.0},
                       {"source": "collect", "participant": participant,
                        "condition": condition}) as w:
        w.append_frames(np.full((n, layout.n_channels), 1000, np.uint16), np.arange(n) / 43,
                        1e9 + np.arange(n) / 43)
        w.add_trial({"index": 0, "gesture": "Poke", "key": "p", "start_sample": 2,
                     "end_sample": 10, "start_time": 0.0, "end_time": 0.2})
    return path


@pytest.mark.parametrize(("participant", "condition", "why"), [
    ("../../escaped", "", "participant '../../escaped' cannot name a file: it holds a path"),
    ("ABS", "", "participant '/"),  # the rest: cut in the line
    ("P01", "x/../../escaped", "condition 'x/../../escaped' cannot name a file"),
    ("P01\r\x1b[2J", "", "participant 'P01\\r\\x1b[2J' cannot name a file: it holds a control"),
])
def test_export_names_built_from_metadata_never_leave_the_folder(tmp_path: Path, capsys,
                                                                participant: str,
                                                                condition: str,
                                                                why: str) -> None:
    """The ShearSense CSV's name takes the session's participant and condition: a session
    whose participant was ``/tmp/x`` exported to ``/tmp/x_<session>.csv``, ``../../x``
    two folders above --out."""
    if participant == "ABS":
        participant = str(tmp_path / "escaped")
    path = _session(tmp_path / "s.h5", participant, condition)
    out = tmp_path / "out" / "deep"
    out.mkdir(parents=True)
    before = _files(tmp_path)
    code = main(["export", str(path), "--format", "shearsense-csv", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == EXIT_ERROR
    assert err[-1].startswith(f"tactile-studio: error: {path}: " + why.format(tmp=tmp_path))
    assert _files(tmp_path) == before
