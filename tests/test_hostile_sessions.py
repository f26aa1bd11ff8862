"""Hostile session files (issue 33, item 11): datasets that claim 10^12 rows, raw of shape
(4608, 10^9), device_time stored as text, raw as a compound type, a file that does hold
6.6 GiB of (compressed) frames, a FIFO and a /dev/zero link named *.h5.

``info``, ``export``, ``record --device replay`` and ``train`` run in a subprocess limited
to 4 GB of address space (RLIMIT_AS) with a timeout: each ends with one line naming the
file and a non-zero exit, never a MemoryError traceback or a hang. Folder scans list the
files they skip with the reason. The files are made with h5py directly from one small
simulated session (a resized chunked dataset costs nothing on disk).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest
from learn_fixtures import write_participant

from tactile_studio.storage.format.session_compress import wait_for_compression

pytestmark = pytest.mark.damaged_files  # the files are hostile on purpose

GESTURES = ("Poke", "Heavy Pat")
LIMIT = 4 * 2**30

# Runs each argv through the real CLI entry in one process (one interpreter start per
# file), with the address space limited; prints [exit code, stderr] per command as JSON.
DRIVER = textwrap.dedent("""
    import contextlib, io, json, resource, sys, traceback
    resource.setrlimit(resource.RLIMIT_AS, (@LIMIT@, @LIMIT@))
    from tactile_studio.cli import main
    out = []
    for argv in json.loads(sys.argv[1]):
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code
            except BaseException:
                traceback.print_exc()
                code = "raised"
        out.append([code, err.getvalue()])
    print(json.dumps(out))
""").replace("@LIMIT@", str(LIMIT))


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("hostile")
    path = write_participant(root / "good.h5", "P01", 101, gestures=GESTURES, blocks=1)
    wait_for_compression(path)  # compressed chunks, as every closed session has
    return path


def _variant(good: Path, folder: Path, name: str, change) -> Path:
    path = folder / f"{name}.h5"
    shutil.copy(good, path)
    with h5py.File(path, "r+") as f:
        change(f["frames"])
    return path


def _huge(g) -> None:
    for name in ("raw", "device_time", "host_time", "seq", "index"):
        g[name].resize(10**12, axis=0)


def _wide(g) -> None:
    del g["raw"]
    g.create_dataset("raw", (4608, 10**9), dtype="u2", chunks=(64, 1000),
                     maxshape=(None, None))


def _text_time(g) -> None:
    n = g["device_time"].shape[0]
    del g["device_time"]
    g.create_dataset("device_time", data=np.array([b"1.0"] * n))


def _compound(g) -> None:
    raw = g["raw"][:]
    del g["raw"]
    dt = np.dtype([(f"c{i}", raw.dtype) for i in range(raw.shape[1])])
    g.create_dataset("raw", data=raw.view(dt).reshape(len(raw)))


def _big_chunks(g) -> None:
    """raw in one chunk of 4M frames (1.4 GiB): nothing stored, yet reading frame 0
    would inflate all of it."""
    n, c = g["raw"].shape
    del g["raw"]
    g.create_dataset("raw", (n, c), maxshape=(None, c), dtype="u2", chunks=(4_000_000, c),
                     compression="gzip")


def _really_big(g) -> None:
    """300 chunks of 65,536 zero frames each, really stored (compressed, 33 MB): 6.6 GiB
    of raw, more than the 4 GB address space, so loading it must end in one line."""
    rows, n = 65536, 300
    for name in ("raw", "device_time", "host_time", "seq", "index"):
        tail, dtype = g[name].shape[1:], g[name].dtype
        del g[name]
        ds = g.create_dataset(name, (rows * n, *tail), maxshape=(None, *tail), dtype=dtype,
                              chunks=(rows, *tail), compression="gzip", compression_opts=1,
                              shuffle=True)
        zeros = np.zeros(rows * int(np.prod(tail)) * dtype.itemsize, np.uint8)
        blob = zlib.compress(zeros.tobytes(), 1)  # shuffled zeros are zeros
        for k in range(n):
            ds.id.write_direct_chunk((k * rows,) + (0,) * len(tail), blob)


def _run(argvs: list[list[str]], cwd: Path) -> list[tuple[object, str]]:
    env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(cwd / "data"),
           "TACTILE_STUDIO_CACHE_DIR": str(cwd / "cache")}
    proc = subprocess.run([sys.executable, "-c", DRIVER, json.dumps(argvs)], cwd=cwd,
                          env=env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return [tuple(r) for r in json.loads(proc.stdout.strip().splitlines()[-1])]


def _commands(path: Path, out: Path) -> list[list[str]]:
    return [["info", str(path)],
            ["export", "--format", "shearsense-csv", "--out", str(out / "csv"), str(path)],
            ["record", "--device", "replay", "--set", f"path={path}", "--set", "speed=0",
             "--seconds", "1", "--out", str(out / "replayed.h5")],
            ["train", "--data", str(path), "--model", "rf", "--preset", "tiny",
             "--out", str(out / "run")]]


def _assert_one_line(result: tuple[object, str], name: str, cause: str, command: str = ""
                     ) -> None:
    code, err = result
    lines = err.strip().splitlines()  # progress lines, then the error on its own line
    assert code == 1 and "Traceback" not in err, (command, err[-2000:])
    assert sum("error" in ln for ln in lines) == 1, (command, err)
    assert lines[-1].startswith("tactile-studio: error:") and name in lines[-1], err
    assert cause in lines[-1], (command, lines[-1])


@pytest.mark.parametrize("name, change, cause", [
    ("huge", _huge, "claims 1,000,000,000,000 rows but the file holds data for at most"),
    ("wide", _wide, "frames/raw claims 4,608 rows"),
    ("text_time", _text_time, "frames/device_time is text"),
    ("compound", _compound, "frames/raw is a compound type"),
    ("big_chunks", _big_chunks, "frames/raw is stored in chunks of 1,373 MiB"),
])
def test_false_claims_end_in_one_line(good, tmp_path, name, change, cause):
    path = _variant(good, tmp_path, name, change)
    cmds = _commands(path, tmp_path)
    for argv, result in zip(cmds, _run(cmds, tmp_path)):
        _assert_one_line(result, f"{name}.h5", cause, argv[0])
    assert not (tmp_path / "replayed.h5").exists() and not (tmp_path / "run").exists()


def test_a_damaged_chunk_ends_in_one_line(good, tmp_path):
    path = tmp_path / "damaged.h5"
    shutil.copy(good, path)
    with h5py.File(path, "r") as f:
        chunk = f["frames/raw"].id.get_chunk_info(0)
        assert f["frames/raw"].compression == "gzip"
    with open(path, "r+b") as fh:  # one bad disk block in the middle of the frames
        fh.seek(chunk.byte_offset + chunk.size // 2)
        fh.write(bytes(64))
    for result in _run(_commands(path, tmp_path)[1:], tmp_path):  # info reads no frames
        _assert_one_line(result, "damaged.h5", "frames/raw rows 0-")
        assert "cannot be read, the file is damaged" in result[1]


def test_a_real_claim_larger_than_memory_ends_in_one_line(good, tmp_path):
    path = _variant(good, tmp_path, "big", _really_big)
    assert path.stat().st_size < 100 * 2**20
    cmds = _commands(path, tmp_path)[1:]  # info reads no frames: it opens the file fine
    for result in _run(cmds, tmp_path):
        _assert_one_line(result, "big.h5", "do not fit in memory")


def test_fifo_and_device_links_are_refused_and_listed(good, tmp_path):
    folder = tmp_path / "study"
    folder.mkdir()
    shutil.copy(good, folder / "P01.h5")
    write_participant(folder / "P02.h5", "P02", 102, gestures=GESTURES, blocks=1)
    os.mkfifo(folder / "x.h5")
    os.symlink("/dev/zero", folder / "zero.h5")
    # named directly: one line each, no hang (the subprocess has a timeout)
    for path in (folder / "x.h5", folder / "zero.h5"):
        results = _run(_commands(path, tmp_path), tmp_path)
        cause = "a FIFO" if path.name == "x.h5" else "a character device"
        for result in results:
            _assert_one_line(result, path.name, cause)
    # in a folder: the workspace's Sessions tab lists them with the reason, info too
    # (exit 1), train says it skipped them
    from tactile_studio.learn.results.workspace_index import scan_sessions

    listed = {Path(r.path).name: r.error for r in scan_sessions([folder])}
    assert listed["x.h5"].endswith("x.h5: a FIFO (named pipe), not a session file")
    assert listed["zero.h5"].endswith("zero.h5: a character device, not a session file")
    assert listed["P01.h5"] == listed["P02.h5"] == ""
    proc = subprocess.run([sys.executable, "-m", "tactile_studio", "info", str(folder)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    rows = {ln.split()[0]: ln for ln in proc.stdout.splitlines() if ".h5" in ln}
    assert "a FIFO (named pipe), not a session file" in rows["x.h5"]
    assert "a character device, not a session file" in rows["zero.h5"]
    assert "P01" in rows["P01.h5"] and "unreadable" not in rows["P02.h5"]
    proc = subprocess.run([sys.executable, "-m", "tactile_studio", "train", "--data",
                           str(folder), "--model", "rf", "--preset", "tiny", "--eval", "lopo",
                           "--out", str(tmp_path / "run")], capture_output=True, text=True,
                          timeout=240, env={**os.environ,
                                            "TACTILE_STUDIO_CACHE_DIR": str(tmp_path / "c")})
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert ("data: skipped 2 files that cannot be read (x.h5: a FIFO (named pipe), not a "
            "session file; zero.h5: a character device, not a session file)") in proc.stdout
