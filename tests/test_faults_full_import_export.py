"""A full disk part way through ``import`` or ``export`` (issue 33's follow-up): the
output being written is removed (a cut session, CSV or XDF would pass for a whole one;
its source is still there), those finished before it stay, and the one line names the
file: exit 3 when some were kept, 1 when none. Through the real command in a subprocess
under ``RLIMIT_FSIZE`` (per file: a short P01 fits under the limit, a long P02 does not).
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest
from csv_fixtures import labelled_csv

from tactile_studio.cli import main
from tactile_studio.errors import EXIT_ERROR, EXIT_INCOMPLETE
from tactile_studio.storage import SessionFile

LIMIT = 400 * 1024  # above everything P01 makes, below everything P02 makes
GESTURES = "r=Rub,p=Poke,z=Zap"


def _cli(args: list[str], cwd: Path, limit: int) -> subprocess.CompletedProcess:
    env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(cwd / "data"),
           "TACTILE_STUDIO_CACHE_DIR": str(cwd / "cache")}

    def limit_file_size() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))

    return subprocess.run([sys.executable, "-m", "tactile_studio", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, preexec_fn=limit_file_size,
                          timeout=180)


def _error_line(proc: subprocess.CompletedProcess) -> str:
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("tactile-studio: error:")]
    assert len(lines) == 1, proc.stderr[-3000:]
    return lines[0]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    """P01 (140 frames) and P02 (1860 frames) as old CSVs, as sessions and as XDF."""
    d = tmp_path_factory.mktemp("full")
    (d / "csv").mkdir()
    labelled_csv(d / "csv", "P01_FLAT.csv", 1, "rp")
    labelled_csv(d / "csv", "P02_FLAT.csv", 2, "rpz" * 15)
    assert main(["import", "shearsense", *map(str, sorted((d / "csv").glob("*.csv"))),
                 "--gestures", GESTURES, "--out", str(d / "sessions")]) == 0
    assert main(["export", *map(str, sorted((d / "sessions").glob("*.h5"))),
                 "--format", "xdf", "--out", str(d / "xdf")]) == 0
    return d


def _files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())  # a leftover .part shows here


@pytest.mark.parametrize("fmt, sources", [("shearsense", "csv"), ("xdf", "xdf")])
def test_an_import_that_fills_the_disk_keeps_the_sessions_it_finished(fmt, sources, inputs,
                                                                       tmp_path):
    out = tmp_path / "out"
    extra = ["--gestures", GESTURES] if fmt == "shearsense" else []
    proc = _cli(["import", fmt, *map(str, sorted((inputs / sources).iterdir())), *extra,
                 "--out", str(out)], tmp_path, LIMIT)
    assert proc.returncode == EXIT_INCOMPLETE, proc.stderr[-3000:]
    line = _error_line(proc)
    assert str(out / "P02_FLAT.h5") in line and "file too large" in line, line
    assert "the 1 session(s) imported before it are kept" in line, line
    assert _files(out) == ["P01_FLAT.h5"]  # the cut P02 is gone, not passed off as whole
    with SessionFile(out / "P01_FLAT.h5") as s:
        assert s.closed_cleanly and s.n_frames == 140


@pytest.mark.parametrize("fmt, suffix", [("xdf", "xdf"), ("shearsense-csv", "csv")])
def test_an_export_that_fills_the_disk_keeps_the_files_it_finished(fmt, suffix, inputs,
                                                                    tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    proc = _cli(["export", *map(str, sorted((inputs / "sessions").glob("*.h5"))),
                 "--format", fmt, "--out", str(out)], tmp_path, LIMIT)
    assert proc.returncode == EXIT_INCOMPLETE, proc.stderr[-3000:]
    line = _error_line(proc)
    assert f"{out / f'P02_FLAT.{suffix}'}: cannot write (File too large)" in line, line
    assert "the 1 file(s) exported before it are kept" in line, line
    assert _files(out) == [f"P01_FLAT.{suffix}"]


def test_an_export_with_no_room_for_its_first_file_exits_1_saying_nothing_was_kept(
        inputs, tmp_path):
    """The write error of ``fh.write`` names no file: it was a traceback."""
    out = tmp_path / "out"
    out.mkdir()
    proc = _cli(["export", str(inputs / "sessions" / "P02_FLAT.h5"), "--format", "xdf",
                 "--out", str(out)], tmp_path, LIMIT)
    assert proc.returncode == EXIT_ERROR, proc.stderr[-3000:]
    line = _error_line(proc)
    assert str(out / "P02_FLAT.xdf") in line and "nothing was exported" in line, line
    assert _files(out) == []


@pytest.mark.parametrize("limit_kb", [700, 800])
def test_an_import_never_passes_off_a_session_cut_at_close_as_imported(limit_kb, inputs,
                                                                        tmp_path):
    """An import's frames reach the disk when its writer closes: a failure there was
    swallowed, and a session of 0 of its 1860 frames was 'imported' with exit 0. Either
    the whole session is there or none of it, and the exit says which."""
    out = tmp_path / "out"
    proc = _cli(["import", "shearsense", str(inputs / "csv" / "P02_FLAT.csv"), "--gestures",
                 GESTURES, "--out", str(out)], tmp_path, limit_kb * 1024)
    if proc.returncode == 0:
        with SessionFile(out / "P02_FLAT.h5") as s:
            assert s.n_frames == 1860
    else:
        assert proc.returncode == EXIT_ERROR, proc.stderr[-3000:]
        assert "nothing was imported" in _error_line(proc)
        assert _files(out) == []
