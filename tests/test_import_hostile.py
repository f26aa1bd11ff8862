"""Foreign CSV and XDF files that a tired lab or an attacker hands ``import`` (issue 43,
"bounded resources for every file we read"): two names alike never write one file
twice, a line with no end never grows without bound, a classic-Mac CSV reads.

Budget: ~6 s (one child process reading a 40 MB file under a 1 GiB address-space limit:
before, it ran out of memory after ~17 s)."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
from csv_fixtures import labelled_csv
from test_xdf_hostile import counts, run

from tactile_studio.errors import EXIT_OK
from tactile_studio.storage import SessionFile
from tactile_studio.storage.exchange.xdf_writer import XdfWriter

COST_HEADER = "subject, variant, gesture, frame, " + ", ".join(f"ch{i}" for i in range(1, 65))


def cost_csv(path: Path, subjects: list[str], n: int = 40) -> Path:
    rows = [f"{s},normal,6,{k}," + ",".join(str(500 + k) for _ in range(64))
            for s in subjects for k in range(n)]
    path.write_text(COST_HEADER + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_two_subjects_named_alike_write_two_files(tmp_path, capsys):
    """Subjects "1" and "1.0" are both P01: the second session was written over the
    first ("imported 2 session(s)", one file)."""
    src = cost_csv(tmp_path / "CoST.csv", ["1", "1.0"])
    out = tmp_path / "out"
    out.mkdir()
    code, said, err = run(capsys, "import", "cost", src, "--out", out)
    assert code == EXIT_OK, err
    assert sorted(p.name for p in out.glob("*.h5")) == ["cost_P01-2.h5", "cost_P01.h5"]
    for name, subject in (("cost_P01.h5", "1"), ("cost_P01-2.h5", "1.0")):
        with SessionFile(out / name) as s:
            assert s.n_frames == 40 and s.metadata["subject"] == subject


def test_a_classic_mac_csv_reads_as_its_windows_twin(tmp_path, capsys):
    """Lines ending in CR alone (Excel's "CSV (Macintosh)") were one header line of
    33,125 columns."""
    crlf = labelled_csv(tmp_path, "P01_a_FLAT.csv", 1)
    cr = tmp_path / "P02_a_FLAT.csv"
    cr.write_bytes(crlf.read_bytes().replace(b"\r\n", b"\n").replace(b"\n", b"\r"))
    assert b"\n" not in cr.read_bytes()
    out = tmp_path / "out"
    code, _, err = run(capsys, "import", "shearsense", crlf, cr, "--out", out)
    assert code == EXIT_OK, err
    with SessionFile(out / "P01_a_FLAT.h5") as a, SessionFile(out / "P02_a_FLAT.h5") as b:
        np.testing.assert_array_equal(a.raw(), b.raw())
        assert [t.gesture for t in a.trials] == [t.gesture for t in b.trials]


def _one_gib() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (1 << 30, resource.getrlimit(resource.RLIMIT_AS)[1]))


def test_a_line_without_end_is_dropped_as_read_not_grown(tmp_path):
    """40 MB of fields with no line end after the rows: the pending "line" grew to the
    file's size, copied with every block, then its parse ran out of memory (a
    traceback after ~17 s under 1 GiB); now it is one ``long_row``, the rows kept."""
    src = labelled_csv(tmp_path, "P03_tail_FLAT.csv", 2)
    with open(src, "ab") as fh:
        fh.write(b'"1",' * 10_000_000)
    out = tmp_path / "out"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-m", "tactile_studio", "import", "shearsense",
                           str(src), "--out", str(out)], capture_output=True, text=True,
                          env=env, preexec_fn=_one_gib, timeout=120)
    assert done.returncode == EXIT_OK, done.stderr
    with SessionFile(out / "P03_tail_FLAT.h5") as s:
        assert s.n_frames == 60 + 40 * 3  # every row (the baseline is a row of its own)
        assert s.summary()["malformed_by_kind"] == {"long_row": 1}


def test_two_xdf_streams_named_alike_write_two_sessions(tmp_path, capsys):
    """Two tactile streams both called "Mat": the second session overwrote the first."""
    src = tmp_path / "twins.xdf"
    t = 1000.0 + np.arange(100) / 43.0
    with open(src, "wb") as fh:
        w = XdfWriter(fh)
        w.file_header()
        for sid in (1, 2):
            w.stream_header(sid, "Mat", "Tactile", 180, 43.0, "int32", f"mat-{sid}", t[0])
        for sid in (1, 2):
            w.samples(sid, "int32", t, counts(100) + sid)
        for sid in (1, 2):
            w.stream_footer(sid, t[0], t[-1], 100, [])
    out = tmp_path / "out"
    code, _, err = run(capsys, "import", "xdf", src, "--out", out)
    assert code == EXIT_OK, err
    for name, sid in (("twins_Mat.h5", 1), ("twins_Mat-2.h5", 2)):
        with SessionFile(out / name) as s:
            np.testing.assert_array_equal(s.raw(), counts(100) + sid)


def test_two_inputs_that_would_write_one_file_are_refused_before_any(tmp_path, capsys):
    """day1/run1.xdf and day2/run1.xdf both made run1.h5: the second overwrote the first
    and the import said "imported 2 session(s)". Now refused in one line, as ShearSense
    CSVs of one name were already; two HAART training.csv files likewise."""
    from test_import_export import haart_csvs
    from test_xdf_hostile import write_xdf

    for day in ("day1", "day2"):
        (tmp_path / day).mkdir()
        write_xdf(tmp_path / day / "run1.xdf")
        haart_csvs(tmp_path / day)
    out = tmp_path / "out"
    out.mkdir()
    for fmt, name, made in (("xdf", "run1.xdf", "run1.h5"),
                            ("haart", "training.csv", "haart_training_<participant>.h5")):
        code, _, err = run(capsys, "import", fmt, tmp_path / "day1" / name,
                           tmp_path / "day2" / name, "--out", out)
        assert code == 1
        (line,) = err.strip().splitlines()[-1:]
        assert line == (f"tactile-studio: error: {tmp_path / 'day2' / name}: same file name "
                        f"as {tmp_path / 'day1' / name}; both would be written to "
                        f"{out / made}")
        assert not list(out.iterdir())
