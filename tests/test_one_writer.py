"""One writer per file (issue 43, cases 1 and 8): two real processes that want one file,
a real ``kill -9`` mid-import, and a lock left by a killed process.

The race is forced, never hoped for: the first writer is started and the second one only
once the first holds the file (its lock file, or the file itself, is there), and a
first writer that would finish too soon (an import) is frozen with SIGSTOP while the
second one runs. The second writer must be refused in one line before it writes
anything, and the first one's file must stay whole.

Budget: ~25 s (a handful of real processes, one at a time).
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from waiting import wait_until

from tactile_studio.errors import SessionFileError
from tactile_studio.storage import SessionFile
from tactile_studio.storage.exchange.xdf_writer import XdfWriter
from tactile_studio.streams.remote_control import send_commands

EXE = str(Path(sys.executable).parent / "tactile-studio")
WAIT_S = 60.0  # a safety net for a hung process, never a timing assertion
IMPORT_FRAMES = 60_000  # enough that an import holds its file for a while


def _lock(path: Path) -> Path:
    return path.with_name(f".{path.name}.lock")


def _held(path: Path) -> bool:
    """Some process holds ``path``'s claim now: its lock file's inode is flock'ed in
    /proc/locks (looked up, never locked: a probe that took the lock would refuse the
    writer it watches)."""
    try:
        st = os.stat(_lock(path))
    except FileNotFoundError:
        return False
    dev = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    with open("/proc/locks") as f:
        return any(ln.split()[1] == "FLOCK" and ln.split()[5] == dev for ln in f
                   if len(ln.split()) > 5)


def _begun(path: Path) -> bool:
    """The first writer holds ``path``: its claim (or, without one, the file is there)."""
    return _held(path) or path.exists()


def _frames(path: Path) -> int:
    try:
        with SessionFile(path) as s:
            return s.n_frames
    except SessionFileError:  # between creating the file and its first flush
        return 0


def _one_line(stderr: str) -> str:
    assert "Traceback" not in stderr, stderr
    (line,) = [ln for ln in stderr.splitlines() if ln.startswith("tactile-studio:")]
    return line


def _leftovers(folder: Path) -> list[str]:
    """Hidden files a writer left beside its outputs (temporaries, lock files)."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_a_second_record_of_a_file_being_recorded_is_refused_and_a_killed_ones_lock_never_blocks(
        tmp_path):
    out = tmp_path / "x.h5"
    first = subprocess.Popen([EXE, "record", "--seconds", "600", "--out", str(out),
                              "--notes", "first"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        wait_until(lambda: first.poll() is not None or _frames(out) > 0, WAIT_S,
                   what="the first recording's frames")
        assert first.poll() is None, first.communicate()
        # --force replaces a finished file, never one that is being recorded
        second = subprocess.run([EXE, "record", "--seconds", "1", "--force", "--out",
                                 str(out), "--notes", "second"], capture_output=True,
                                text=True, timeout=WAIT_S)
        assert second.returncode == 1, second.stdout + second.stderr
        assert _one_line(second.stderr) == (
            f"tactile-studio: error: {out}: this session file is being written by another "
            f"process (pid {first.pid}: tactile-studio record); nothing was written to it: wait "
            "for it to finish, or choose another name")
        assert "recording" not in second.stderr and "wrote" not in second.stdout
        assert first.poll() is None  # untouched: it records on
        wait_until(lambda: _frames(out) > 50, WAIT_S, what="more frames of the first")
        first.send_signal(signal.SIGKILL)  # a crash: its lock file stays, unlocked
        first.communicate(timeout=WAIT_S)
    finally:
        if first.poll() is None:
            first.kill()
            first.communicate()
    with SessionFile(out) as s:  # the first recording, recovered, not the refused one
        assert s.metadata["notes"] == "first" and s.n_frames > 50
    assert _lock(out).exists() and not _held(out)  # the stale lock of the killed process
    third = subprocess.run([EXE, "record", "--seconds", "0.5", "--force", "--out", str(out),
                            "--notes", "third"], capture_output=True, text=True,
                           timeout=WAIT_S)
    assert third.returncode == 0, third.stderr  # a stale lock never blocks
    with SessionFile(out) as s:
        assert s.metadata["notes"] == "third" and s.closed_cleanly
    assert _leftovers(tmp_path) == []  # its lock file went with its claim


def test_a_listener_asked_to_record_a_file_another_writer_holds_says_error(tmp_path):
    """``listen`` over a real socket: while another process holds the file's claim (as a
    second listener or ``record`` does between claiming the name and creating the file),
    ``start`` is an ``error:`` reply and nothing is written; once it is let go (its lock
    file left behind, as by a killed process) the same ``start`` records."""
    out = tmp_path / "rec"
    target = out / "sub-P01" / "sub-P01_task-T_tactile.h5"
    target.parent.mkdir(parents=True)
    listener = subprocess.Popen([EXE, "listen", "--set", "rate=200", "--port", "0",
                                 "--out", str(out)], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    fd = os.open(_lock(target), os.O_RDWR | os.O_CREAT)
    try:
        line = listener.stderr.readline()
        port = int(line.split("127.0.0.1:")[1].split()[0])
        fcntl.flock(fd, fcntl.LOCK_EX)  # the other writer's claim, by the documented protocol
        replies = send_commands(["filename {participant:P01} {task:T}", "start", "status"],
                                port)
        assert replies[0] == "OK"
        assert replies[1].startswith(f"error: {target}: this session file is being written "
                                     "by another process"), replies[1]
        assert '"recording":false' in replies[2]
        assert not target.exists()
        os.close(fd)  # let go; the lock file stays
        fd = -1
        assert send_commands(["start"], port) == ["OK"]
        wait_until(lambda: _frames(target) >= 20, WAIT_S, what="frames in the file")
        assert send_commands(["stop"], port) == ["OK"]
    finally:
        if fd >= 0:
            os.close(fd)
        listener.send_signal(signal.SIGINT)
        listener.communicate(timeout=WAIT_S)
    assert listener.returncode in (0, 130)
    with SessionFile(target) as s:
        assert s.closed_cleanly and s.n_frames >= 20
    assert _leftovers(target.parent) == []


def _big_xdf(path: Path, n: int = IMPORT_FRAMES) -> None:
    """A tactile stream of ``n`` 180-channel frames at 43 Hz (our own XDF writer)."""
    rng = np.random.default_rng(3)
    stamps = 100.0 + np.arange(n) / 43.0
    with open(path, "wb") as fh:
        w = XdfWriter(fh)
        w.file_header()
        w.stream_header(1, "Sensor", "Tactile", 180, 43.0, "int16", "sensor-1", 100.0)
        for a in range(0, n, 20_000):
            b = min(n, a + 20_000)
            w.samples(1, "int16", stamps[a:b],
                      rng.integers(20000, 30000, size=(b - a, 180), dtype=np.int16))
        w.stream_footer(1, stamps[0], stamps[-1], n, [])


@pytest.fixture(scope="module")
def big_xdf(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("xdf") / "big.xdf"
    _big_xdf(path)
    return path


def _import(src: Path, out: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([EXE, "import", "xdf", str(src), "--out", str(out), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _whole(path: Path, n: int = IMPORT_FRAMES) -> bool:
    with SessionFile(path) as s:
        return s.closed_cleanly and s.n_frames == n


def test_a_second_import_to_the_name_an_import_is_writing_is_refused(tmp_path, big_xdf):
    out = tmp_path / "sessions"
    out.mkdir()
    target = out / "big.h5"
    first = _import(big_xdf, out)
    try:
        wait_until(lambda: first.poll() is not None or _begun(target), WAIT_S, step=0.001,
                   what="the first import to begin writing")
        first.send_signal(signal.SIGSTOP)  # frozen while it holds the name
        assert first.poll() is None and _held(target), \
            "the first import does not hold its file (it has no claim, or it had finished)"
        second = subprocess.run([EXE, "import", "xdf", str(big_xdf), "--out", str(out),
                                 "--force"], capture_output=True, text=True, timeout=WAIT_S)
        assert second.returncode == 1, second.stdout + second.stderr
        assert _one_line(second.stderr) == (
            f"tactile-studio: error: {target}: this session file is being written by another "
            f"process (pid {first.pid}: tactile-studio import); nothing was written to it: wait "
            "for it to finish, or choose another name")
    finally:
        first.send_signal(signal.SIGCONT)
        stdout, stderr = first.communicate(timeout=WAIT_S)
    assert first.returncode == 0, stderr
    assert _whole(target)
    assert _leftovers(out) == []


def test_an_import_killed_part_way_leaves_nothing_at_its_name_and_imports_again(
        tmp_path, big_xdf):
    out = tmp_path / "sessions"
    out.mkdir()
    target = out / "big.h5"
    first = _import(big_xdf, out)
    wait_until(lambda: first.poll() is not None or _begun(target), WAIT_S, step=0.001,
               what="the import to begin writing")
    first.send_signal(signal.SIGKILL)
    first.communicate(timeout=WAIT_S)
    # nothing at the final name, or (killed after it was published) the whole session
    assert not target.exists() or _whole(target)
    if not target.exists():
        assert _leftovers(out)  # its temporary (and lock file) are what it left
    again = subprocess.run([EXE, "import", "xdf", str(big_xdf), "--out", str(out)],
                           capture_output=True, text=True, timeout=WAIT_S)
    if target.exists() and "already exists" in again.stderr:
        return  # it had finished before the kill: the re-import is refused as it should be
    assert again.returncode == 0, again.stderr
    assert _whole(target)
    assert _leftovers(out) == []  # the dead import's temporary and lock file were swept
