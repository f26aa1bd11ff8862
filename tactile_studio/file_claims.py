"""One writer per file: a claim on a name, and temporary names no other writer shares.

Why: ``record --out x.h5`` run twice at once both passed the "exists?" check (the check
and the file's creation were two steps), both wrote into one file and both could report
success; their compressions shared one ``.x.h5.compressing`` temporary file. A killed
import left a 0-frame session at its final name.

The mechanism, used by every writer of a session file, export, run folder or output
(``SessionWriter``, :func:`written_whole`, :func:`claim_folder`):

* **A claim** (:func:`claim`) is an ``fcntl.flock`` on a lock file beside the claimed
  path, ``.NAME.lock``. The kernel drops it when its process dies, however it dies, so a
  lock file left by a killed process never blocks: it is simply locked again. Two claims
  exclude each other between processes and within one (each claim opens its own file
  description: a second window of the app is refused too). A refused claim is one line
  naming the file and the holder (:class:`FileBusy`), before anything is written.
* **Names** the claim does not cover are made unique per process: a temporary file is
  ``.NAME.<pid>-<random>.<kind>`` (:func:`temp_beside`), never shared by two writers.
* **Whole or not at all**: a file that must not be seen half written (an import, an
  export) is written to a temporary and then published under the claim
  (:meth:`Claim.publish`): ``os.replace`` to overwrite, else a hard link that fails if
  the name was taken (no overwrite, even by a program that does not claim).
* **Inside a claimed folder** (a run's JSON files) or where the last whole copy may win
  (a cache entry), :func:`replace_whole` writes through a temporary without a claim.
* **Leftovers**: every temporary of NAME is made under NAME's claim, so one found while
  holding the claim belongs to a dead process and is removed (a killed import's
  ``.part``), and so is the lock file itself when the claim is released.

The release removes the lock file while still holding the lock; a claimer that opened
the old file before the removal finds, once it gets the lock, that its file is no longer
the one at the name (inode check) and starts again, so two holders can never coexist.
"""

from __future__ import annotations

import errno
import fcntl
import os
import re
import secrets
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from tactile_studio.errors import UserError

T = TypeVar("T")

LOCK_SUFFIX = ".lock"
# a temporary made by temp_beside: .NAME.<pid>-<hex>.<kind>
_TEMP = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)-[0-9a-f]{8}\.(?P<kind>[a-z]+)$")


class FileBusy(UserError):
    """Another writer (another process, or another window of this one) holds the file's
    claim: refused before anything is written; the other writer goes on untouched."""


class NameTaken(UserError):
    """The name exists already and the writer was not asked to replace it."""


def lock_path(path: str | os.PathLike) -> Path:
    """The lock file of ``path``'s claim: ``.NAME.lock`` beside it."""
    p = Path(path)
    return p.with_name(f".{p.name}{LOCK_SUFFIX}")


def temp_beside(path: str | os.PathLike, kind: str) -> Path:
    """A temporary name beside ``path`` that no other writer uses: the pid and 32 random
    bits (two writers in one process differ too). ``kind`` says what it is (``part``,
    ``compressing``...); :func:`final_name` maps it back to ``path``."""
    p = Path(path)
    return p.with_name(f".{p.name}.{os.getpid()}-{secrets.token_hex(4)}.{kind}")


def final_name(path: str | os.PathLike) -> Path | None:
    """The file a temporary (:func:`temp_beside`) or lock file belongs to; None for
    another name."""
    p = Path(path)
    m = _TEMP.match(p.name)
    if m:
        return p.with_name(m["name"])
    if p.name.startswith(".") and p.name.endswith(LOCK_SUFFIX) and len(p.name) > 6:
        return p.with_name(p.name[1:-len(LOCK_SUFFIX)])
    return None


# a temporary's name where a name begins (after a separator, a space, a quote...)
_TEMP_IN_TEXT = re.compile(r"(?<![^\s/'\"(\[])\.([^/]+?)\.\d+-[0-9a-f]{8}\.[a-z]+\b")


def final_names_in(text: str) -> str:
    """``text`` with every temporary's name (:func:`temp_beside`) replaced by the name
    of the file it becomes: what a progress line or a message shows the user."""
    return _TEMP_IN_TEXT.sub(r"\1", text)


def _holder_text() -> str:
    """Who holds a claim, as the refusal line names it: pid and command."""
    words = [os.path.basename(sys.argv[0] or "python")]
    words += [a for a in sys.argv[1:3] if not a.startswith("-")][:1]
    return f"pid {os.getpid()}: {' '.join(words)}"


# claims held by this process, by lock file: a second claim in the same process is told
# apart from another process's (the line says "this program")
_HELD: dict[str, int] = {}
_HELD_LOCK = threading.Lock()


class Claim:
    """The one writer's hold on a name; :meth:`release` (or the ``with`` block's end)
    gives it up. Releasing twice does nothing."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path = path
        self.lock = lock_path(path)
        self._fd: int | None = fd

    @property
    def held(self) -> bool:
        return self._fd is not None

    def temp(self, kind: str) -> Path:
        """A temporary of this name (:func:`temp_beside`), made under the claim."""
        return temp_beside(self.path, kind)

    def publish(self, tmp: Path, overwrite: bool) -> Path:
        """Move the finished ``tmp`` to the claimed name: replacing what is there with
        ``overwrite``, else only if the name is free (:class:`NameTaken`; ``tmp`` stays
        for the caller to discard). Atomic: the name holds the old file or the whole new
        one at every instant."""
        if overwrite:
            os.replace(tmp, self.path)
            return self.path
        try:
            os.link(tmp, self.path)  # fails if the name exists, whoever made it
        except FileExistsError:
            raise NameTaken(f"{self.path}: already exists; not overwritten") from None
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV,
                                 errno.EMLINK, errno.ENOSYS):
                raise
            # no hard links here (FAT, some network shares): under the claim no writer
            # of ours can take the name between the check and the rename
            if os.path.lexists(self.path):
                raise NameTaken(f"{self.path}: already exists; not overwritten") from None
            os.replace(tmp, self.path)
            return self.path
        os.unlink(tmp)
        return self.path

    def release(self) -> None:
        fd, self._fd = self._fd, None
        if fd is None:
            return
        with _HELD_LOCK:
            _HELD.pop(os.path.abspath(self.lock), None)
        try:
            os.unlink(self.lock)  # while locked: see the module's docstring
        except OSError:
            pass
        try:
            fcntl.flock(fd, fcntl.LOCK_UN)
        finally:
            os.close(fd)

    def __enter__(self) -> Claim:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __del__(self) -> None:  # a claim dropped without release: never leak the lock
        if getattr(self, "_fd", None) is not None:
            self.release()


def claim(path: str | os.PathLike, what: str = "") -> Claim:
    """Claim ``path`` (a file or a folder) for writing: :class:`FileBusy` (one line) when
    another writer holds it. ``what`` names the thing in that line (``"session file"``).
    Leftover temporaries of ``path`` from dead processes are removed. The folder must
    exist (an ``OSError`` naming the lock file otherwise, which ``output_faults``
    reports as the file's)."""
    path = Path(path)
    lock = lock_path(path)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            raise FileBusy(_busy_line(path, lock, what)) from None
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # released and removed while we waited: claim the new lock file
    try:
        os.ftruncate(fd, 0)
        os.write(fd, _holder_text().encode())
    except OSError:
        pass  # who holds it is a courtesy for the refusal line; the lock is what counts
    with _HELD_LOCK:
        _HELD[os.path.abspath(lock)] = os.getpid()
    held = Claim(path, fd)
    sweep_leftovers(path)
    return held


def _busy_line(path: Path, lock: Path, what: str) -> str:
    noun = f"{what} " if what else ""
    with _HELD_LOCK:
        ours = os.path.abspath(lock) in _HELD
    if ours:
        return (f"{path}: this {noun}is being written already by this program (another "
                "recording, job or window); nothing was written to it")
    try:
        holder = lock.read_text(errors="replace").strip()[:120]
    except OSError:
        holder = ""
    who = f" ({holder})" if re.fullmatch(r"pid \d+: [^\x00-\x1f]*", holder) else ""
    return (f"{path}: this {noun}is being written by another process{who}; nothing was "
            "written to it: wait for it to finish, or choose another name")


def claim_folder(path: str | os.PathLike, what: str = "folder") -> Claim:
    """Claim an output folder for a whole run (``train``/``sweep --out``, a
    characterisation): a second run into it is refused before it reads or clears
    anything. ``--out .`` is made absolute (it needs a name to lock); the parent is made
    first unless something stands there (then the claim's ``OSError`` names the folder)."""
    folder = Path(path)
    if folder.name in ("", ".", ".."):  # the user's spelling otherwise, as lines name it
        folder = Path(os.path.abspath(path))
    if not os.path.lexists(folder.parent):
        folder.parent.mkdir(parents=True, exist_ok=True)
    return claim(folder, what)


def sweep_leftovers(path: str | os.PathLike) -> list[Path]:
    """Remove the temporaries of ``path`` that dead processes left (the caller holds the
    claim, so no living writer has any). Returns them."""
    p = Path(path)
    removed = []
    try:
        names = os.listdir(p.parent)
    except OSError:
        return removed
    prefix = f".{p.name}."
    for n in names:
        if not n.startswith(prefix):
            continue
        m = _TEMP.match(n)
        if m is None or m["name"] != p.name:
            continue
        leftover = p.with_name(n)
        try:
            if leftover.is_dir() and not leftover.is_symlink():
                continue
            leftover.unlink()
            removed.append(leftover)
        except OSError:
            pass
    return removed


def written_whole(path: str | os.PathLike, write: Callable[[Path], Any], *,
                  overwrite: bool = True, what: str = "") -> Path:
    """``write(tmp)`` to a temporary beside ``path`` under ``path``'s claim, then publish
    it there: a cancelled, failed or killed write leaves nothing at ``path`` (a cut file
    would pass for a whole one) and two writers of one name never mix (the second is
    refused, :class:`FileBusy`). A failed write's ``OSError`` names ``path``."""
    path = Path(path)
    with claim(path, what) as held:
        _through_temp(held.temp("part"), path, write,
                      lambda tmp: held.publish(tmp, overwrite))
    return path


def replace_whole(path: str | os.PathLike, write: Callable[[Path], Any]) -> Path:
    """``write(tmp)`` to a temporary of this process's own beside ``path``, then
    ``os.replace`` it there: whole or not at all, without a claim. For files whose
    writer holds its folder's claim already (a run folder's JSON) or where the last whole
    copy may win (a cache entry, a calibration file written after the logbook)."""
    path = Path(path)
    _through_temp(temp_beside(path, "tmp"), path, write, lambda tmp: os.replace(tmp, path))
    return path


def _through_temp(tmp: Path, path: Path, write: Callable[[Path], Any],
                  publish: Callable[[Path], Any]) -> None:
    """Write to ``tmp``, publish it; on any failure the temporary goes and an
    ``OSError`` that names no file (``fh.write``'s) names ``path``."""
    try:
        write(tmp)
        publish(tmp)
    except BaseException as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        if isinstance(exc, OSError) and exc.filename is None:
            exc.filename = str(path)
        raise


def first_free(candidates: Callable[[int], Path], make: Callable[[Path], T],
               tries: int = 1000) -> T:
    """``make(candidates(k))`` for k = 0, 1, 2...: the first name that is neither taken
    nor being written (``NameTaken``, ``FileBusy`` move on to the next). For names a
    program picks itself (a collection's ``P01_shear9_<time>.h5``): two writers that
    picked one name both record, each under its own."""
    for k in range(tries):
        try:
            return make(candidates(k))
        except (NameTaken, FileBusy):
            continue
    raise NameTaken(f"{candidates(0)}: no free name after {tries} tries")
