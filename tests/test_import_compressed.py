"""Compressed imports (issue 45): ``import shearsense``, ``haart`` and ``cost`` read
``.csv.xz``, ``.csv.gz`` and ``.csv.bz2`` as labs archive them (storage/input_files.InputFile),
the same sessions as from the plain file; a damaged archive is one line, nothing written.

Budget: ~5 s. Small files made here; one test reads a few real files of the development
set (skipped with one line where ../shared is absent).
"""

from __future__ import annotations

import bz2
import gzip
import lzma

import numpy as np
import pytest
from test_import_export import haart_csvs, shearsense_csv

from tactile_studio.cli import main
from tactile_studio.storage import SessionFile

COMPRESS = {".xz": lzma.compress, ".gz": gzip.compress, ".bz2": bz2.compress}


def compressed(path, suffix):
    """``path`` archived beside itself as ``<name><suffix>`` (the plain one kept)."""
    out = path.with_name(path.name + suffix)
    out.write_bytes(COMPRESS[suffix](path.read_bytes()))
    return out


def same_session(a, b):
    with SessionFile(a) as s, SessionFile(b) as t:
        assert np.array_equal(s.raw(), t.raw())
        assert s.trials == t.trials
        for key in ("session_id", "participant", "condition", "gestures", "malformed_rows"):
            assert s.metadata[key] == t.metadata[key], key
        return dict(t.metadata)


@pytest.mark.parametrize("suffix", [".xz", ".gz", ".bz2"])
def test_shearsense_archive_imports_as_its_plain_file(tmp_path, capsys, suffix):
    plain = shearsense_csv(tmp_path)
    packed = compressed(plain, suffix)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert main(["import", "shearsense", str(plain), "--out", str(tmp_path / "a")]) == 0
    assert main(["import", "shearsense", str(packed), "--out", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "key map" in out.lower() or "keys" in out.lower()  # the summary as for a plain file
    # named without both suffixes; the same frames, trials and session id (of the content)
    meta = same_session(tmp_path / "a" / "P04_lab_PILLOW.h5", tmp_path / "b" / "P04_lab_PILLOW.h5")
    assert meta["participant"] == "P04" and meta["condition"] == "PILLOW"
    assert meta["original_file"] == packed.name
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == ["P04_lab_PILLOW.h5"]


def test_archive_progress_runs_over_the_file_on_disk(tmp_path):
    from tactile_studio.storage.exchange.shearsense import read_shearsense_csv

    packed = compressed(shearsense_csv(tmp_path), ".gz")
    seen = []
    data = read_shearsense_csv(packed, lambda f, m="": seen.append((f, m)))
    assert data.n_frames > 390
    assert seen[-1][0] == 1.0 and all(0 <= f <= 1 for f, _ in seen)
    # the message counts the archive's megabytes, not the larger content's
    size = f"{packed.stat().st_size / (1 << 20):.1f} MB"
    assert any(size in m for _, m in seen[:-1]), seen


@pytest.mark.parametrize("suffix", [".xz", ".gz", ".bz2"])
def test_haart_archive_imports_as_its_plain_file(tmp_path, suffix):
    train, _ = haart_csvs(tmp_path)
    packed = compressed(train, suffix)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert main(["import", "haart", str(train), "--out", str(tmp_path / "a")]) == 0
    assert main(["import", "haart", str(packed), "--out", str(tmp_path / "b")]) == 0
    names = sorted(p.name for p in (tmp_path / "b").iterdir())
    assert names == ["haart_training_P01.h5", "haart_training_P02.h5"]
    for name in names:
        same_session(tmp_path / "a" / name, tmp_path / "b" / name)


@pytest.mark.parametrize("suffix", [".xz", ".gz", ".bz2"])
@pytest.mark.parametrize("fmt", ["shearsense", "haart"])
def test_damaged_archive_is_one_line_and_nothing_written(tmp_path, capsys, suffix, fmt):
    plain = shearsense_csv(tmp_path) if fmt == "shearsense" else haart_csvs(tmp_path)[0]
    packed = compressed(plain, suffix)
    data = packed.read_bytes()
    cut = packed.with_name("cut_" + packed.name)
    cut.write_bytes(data[:len(data) // 2])  # cut short, as an interrupted copy leaves it
    garbled = packed.with_name("bad_" + packed.name)
    garbled.write_bytes(data[:40] + bytes(200) + data[240:])  # damaged inside
    for victim in (cut, garbled):
        out = tmp_path / f"out_{victim.name}"
        out.mkdir()
        assert main(["import", fmt, str(victim), "--out", str(out)]) == 1
        err = capsys.readouterr().err
        assert "Traceback" not in err
        (line,) = [ln for ln in err.splitlines() if ln.startswith("tactile-studio:")]
        kind = {".xz": "xz", ".gz": "gzip", ".bz2": "bzip2"}[suffix]
        assert f"{victim}: damaged {kind} archive" in line, line
        assert list(out.iterdir()) == []  # no session, no staged leftover


def test_a_plain_file_named_as_an_archive_is_one_line(tmp_path, capsys):
    fake = tmp_path / "P01_FLAT.csv.xz"
    fake.write_bytes(shearsense_csv(tmp_path).read_bytes())
    assert main(["import", "shearsense", str(fake), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and f"{fake}: damaged xz archive" in err
    assert not any((tmp_path / "o").iterdir())


def test_real_development_files_import_compressed(dev_set, tmp_path):
    """A handful of the real .csv.xz files, straight through ``import shearsense``."""
    from tactile_studio.storage.exchange.importers.shearsense import import_shearsense_study

    files = sorted(dev_set.glob("*.csv.xz"))
    files = ([f for f in files if "FLAT" in f.name][:2]
             + [f for f in files if "PILLOW" in f.name][:1])
    paths, _ = import_shearsense_study(files, tmp_path)
    assert [p.name for p in paths] == [f.name[:-len(".csv.xz")] + ".h5" for f in files]
    for path, source in zip(paths, files):
        with SessionFile(path) as s:
            assert s.metadata["participant"].startswith("P")
            assert s.metadata["condition"] in source.name
            assert len(s.trials) == 1 and s.n_frames > 400  # one ~12 s performance
            assert s.trials[0].gesture
