"""benchmarks/real_data.py, the development set's access (issue 45): found beside the
repository or where $TACTILE_STUDIO_DEV_SET says, imported once into the user's cache
(never into the repository), skipped in one line where absent. A small stand-in set made
here (two compressed CSVs). Budget: ~3 s."""

from __future__ import annotations

import lzma
import subprocess
import sys

from test_import_export import shearsense_csv
from test_learn_data import code_package

from benchmarks import real_data
from tactile_studio.storage import SessionFile


def stand_in(tmp_path):
    folder = tmp_path / "shearsense-dev"
    folder.mkdir()
    for name in ("P01_a_FLAT.csv", "P02_b_PILLOW.csv"):
        plain = shearsense_csv(tmp_path, name)
        (folder / f"{name}.xz").write_bytes(lzma.compress(plain.read_bytes()))
    return folder


def test_imported_once_into_the_cache_and_reused(tmp_path, monkeypatch):
    folder = stand_in(tmp_path)
    monkeypatch.setenv(real_data.ENV, str(folder))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert real_data.dev_set() == folder
    first = real_data.dev_sessions()
    assert first.parent == tmp_path / "cache" / "tactile-studio" / "shearsense-dev"
    names = sorted(p.name for p in first.glob("*.h5"))
    assert names == ["P01_a_FLAT.h5", "P02_b_PILLOW.h5"]
    with SessionFile(first / names[0]) as s:
        assert s.metadata["participant"] == "P01" and s.metadata["condition"] == "FLAT"
    stamp = (first / names[0]).stat().st_mtime_ns
    assert real_data.dev_sessions() == first  # reused, not imported again
    assert (first / names[0]).stat().st_mtime_ns == stamp
    assert [p.name for p in first.parent.iterdir()] == [first.name]  # no staging left
    # a changed set (another file, or a size) imports into a folder of its own
    (folder / "P01_a_FLAT.csv.xz").write_bytes(
        (folder / "P01_a_FLAT.csv.xz").read_bytes() + lzma.compress(b""))
    assert real_data.dev_sessions() != first


def test_a_new_importer_imports_again(tmp_path, monkeypatch):
    """Sessions made by an older importer are not reused: its version is in the key."""
    folder = stand_in(tmp_path)
    monkeypatch.setenv(real_data.ENV, str(folder))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert "tactile_studio.storage.exchange" in real_data.IMPORT_CODE
    name, edit = code_package(tmp_path, monkeypatch, "stand_in_importer")
    monkeypatch.setattr(real_data, "IMPORT_CODE", (*real_data.IMPORT_CODE, name))
    first = real_data.dev_sessions()
    assert real_data.dev_sessions() == first
    edit()
    again = real_data.dev_sessions()
    assert again != first and sorted(p.name for p in again.glob("*.h5")) == \
        ["P01_a_FLAT.h5", "P02_b_PILLOW.h5"]


def test_absent_set_is_one_line(tmp_path, monkeypatch):
    missing = tmp_path / "nowhere"
    monkeypatch.setenv(real_data.ENV, str(missing))
    assert real_data.dev_set() is None
    assert real_data.skip_reason() == f"development set not found at {missing}"
    proc = subprocess.run([sys.executable, "-m", "benchmarks.bench_real", "--models", "rf"],
                          capture_output=True, text=True, timeout=120, cwd=real_data.REPO)
    assert proc.returncode == 0 and proc.stdout.strip() == \
        f"skipped: development set not found at {missing}", proc


def test_a_worktree_finds_the_set_beside_the_main_checkout(tmp_path, monkeypatch):
    main = tmp_path / "main"
    (main / ".git" / "worktrees" / "wt1").mkdir(parents=True)
    wt = tmp_path / "wt" / "wt1"
    wt.mkdir(parents=True)
    (wt / ".git").write_text(f"gitdir: {main / '.git' / 'worktrees' / 'wt1'}\n")
    assert real_data._checkouts(wt) == [wt, main]
    assert real_data._checkouts(main) == [main]
    monkeypatch.delenv(real_data.ENV, raising=False)
    assert real_data.skip_reason() == \
        "development set not found at ../shared/data/shearsense-dev"
