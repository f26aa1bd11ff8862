"""A place that cannot be written is the environment's fault: one line, not a traceback.

A read-only or full disk, a folder the user may not write, a path through a file, a
name too long: every command and window that writes meets these the same way, so they
are told apart here once. :func:`fault_line` turns such an ``OSError`` into the line the
user sees, naming the file (a writer's temporary ``.NAME.part`` / ``NAME.tmp`` is named
as the file it was becoming). The CLI's ``main()`` and the GUI's file actions
(``ui/write_errors.py``) both call it. An ``OSError`` that names no file, or has another
errno, is not the user's to fix and keeps its traceback.
"""

from __future__ import annotations

import errno
import os
import re
from collections.abc import Callable, Iterator, Sized
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path

from tactile_studio.errors import IncompleteError, UserError
from tactile_studio.file_claims import FileBusy, final_name

# the place, not the program: the user can fix these by choosing another place
ENVIRONMENT_ERRNOS = frozenset({
    errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT, errno.EFBIG,
    errno.ENOENT, errno.ENOTDIR, errno.EISDIR, errno.ENAMETOOLONG, errno.EEXIST})
# these only ever come from writing
WRITE_ERRNOS = frozenset({errno.EROFS, errno.ENOSPC, errno.EDQUOT, errno.EFBIG})
# the place ran out of room part way: a disk full, a quota, the file-size limit
FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})

# h5py reports a failed create/open with errno set but the file only in its message
_H5PY_OPEN = re.compile(r"unable to (?:open|create) file: name = '(?P<name>.+?)', "
                        r"errno = \d+, error message = '(?P<message>[^']*)'")


class WriteFault(UserError):
    """An output file or folder cannot be written (read-only, full, permission...)."""


def fault_line(exc: BaseException) -> str | None:
    """``'<file>: cannot write (<cause>)'`` for an environment fault, else None.

    "cannot write" when the error can only come from writing or the file did not exist
    yet (it was being created); "cannot open" when an existing file was refused, since
    that may have been a read."""
    if not isinstance(exc, OSError) or exc.errno not in ENVIRONMENT_ERRNOS:
        return None
    name, cause = exc.filename, exc.strerror or os.strerror(exc.errno)
    if name is None:
        match = _H5PY_OPEN.search(str(exc))
        if match is None:
            return None
        name, cause = match["name"], match["message"] or cause
    path = Path(os.fsdecode(name))
    target = _final_name(path)
    if exc.errno == errno.ENOENT and not _probe(os.path.isdir, path.parent):
        return f"{target}: folder {path.parent} does not exist"
    if exc.errno == errno.EEXIST and _probe(os.path.lexists, path) \
            and not _probe(os.path.isdir, path):
        return f"{target}: cannot write (exists and is not a folder)"  # mkdir of a file
    if exc.errno == errno.ENOENT:
        verb = "cannot open"
    elif exc.errno in WRITE_ERRNOS or not _probe(os.path.lexists, path):
        verb = "cannot write"
    else:
        verb = "cannot open"
    return f"{target}: {verb} ({cause})"


def _probe(test: Callable[[Path], bool], path: Path) -> bool:
    """``os.path.isdir``/``lexists`` that answer False for a path the system refuses to
    look at (too long, a loop...): describing a fault must not raise another."""
    try:
        return bool(test(path))
    except (OSError, ValueError):
        return False


def _final_name(path: Path) -> Path:
    """The file a writer's temporary was becoming (``.x.csv.<pid>-<hex>.part`` ->
    ``x.csv``), or a claim's lock file is for (``file_claims``)."""
    claimed = final_name(path)
    if claimed is not None:
        return claimed
    name = path.name
    for pattern in (r"^\.(.+)\.(?:part|compressing)$", r"^(.+)\.tmp\d*$"):
        match = re.match(pattern, name)
        if match:
            return path.with_name(match[1])
    return path


def as_user_error(exc: BaseException) -> WriteFault | None:
    """The ``WriteFault`` to raise instead of ``exc`` (None: not an environment fault)."""
    line = fault_line(exc)
    return WriteFault(line) if line is not None else None


def out_of_room(exc: BaseException) -> bool:
    """A write failed for want of room (``FULL_ERRNOS``): an ``OSError`` or a session
    writer's ``WriteFailed``, which carries the errno of its cause."""
    return getattr(exc, "errno", None) in FULL_ERRNOS


def ran_out_of_room(exc: BaseException, kept: int, noun: str, verb: str) -> UserError | None:
    """The one line for a command that writes several outputs in turn (``import``,
    ``export``) and runs out of room part way, or None when ``exc`` is another fault.

    The output being written is removed (a cut session, CSV or XDF passes for a whole
    one, and its source is still there to do again); the ``kept`` ones finished before
    it stay. Some kept: ``IncompleteError`` (exit 3); none: ``WriteFault`` (exit 1)."""
    if not out_of_room(exc):
        return None
    line = fault_line(exc) or str(exc)
    if kept:
        return IncompleteError(f"{line}; that {noun} was removed, the {kept} {noun}(s) "
                               f"{verb} before it are kept")
    return WriteFault(f"{line}; that {noun} was removed, nothing was {verb}")


@contextmanager
def kept_when_full(written: Sized, noun: str, verb: str) -> Iterator[None]:
    """Run a command that writes several outputs in turn, ``written`` holding those
    finished: a full disk part way ends in :func:`ran_out_of_room`'s line (exit 3 when
    some were kept, else 1). The CLI's import/export and the GUI's import dialogs."""
    try:
        yield
    except (OSError, UserError) as exc:
        error = ran_out_of_room(exc, len(written), noun, verb)
        if error is None:
            raise
        raise error from None


def require_writable_folder(folder: str | os.PathLike, purpose: str) -> None:
    """Refuse before any work when ``folder`` cannot be written: a real probe (a temporary
    file made and removed there), since permission bits say nothing of a read-only mount,
    a full disk or root. ``purpose`` says why the folder is written (``"where evaluate
    saves rescore.json"``). An error that is not the place's fault keeps its traceback."""
    cause = _write_refused(folder)
    if cause is not None:
        raise WriteFault(f"{os.fsdecode(folder)}: cannot write in this folder, "
                         f"{purpose} ({cause})")


def _write_refused(folder: str | os.PathLike) -> str | None:
    """Why ``folder`` cannot be written, by a real probe (a temporary file made and
    removed there); None when it can."""
    import tempfile

    try:
        fd, probe = tempfile.mkstemp(prefix=".write-probe-", dir=folder)
    except OSError as exc:
        if fault_line(exc) is None:
            raise
        return exc.strerror or os.strerror(exc.errno)
    os.close(fd)
    os.unlink(probe)
    return None


def require_writable_file(path: str | os.PathLike, purpose: str,
                          replaces: tuple[bytes, str] | None = None) -> None:
    """Refuse before any work when the file ``path`` could not be written at the end: a
    folder stands in its place, its folder does not exist, or that folder cannot be
    written (:func:`require_writable_folder`'s real probe). A check or calibration that
    ran for minutes, and was stored, must not end in "cannot open" for its output.

    ``replaces`` = (signature, noun): a file already there is replaced only when its
    first bytes hold ``signature`` (an earlier output of the same kind), so a name typed
    wrong (a session .h5, the logbook) is refused and left as it is, not overwritten."""
    name = os.fsdecode(path)
    target = Path(path).absolute()
    if _probe(os.path.isdir, target):
        raise WriteFault(f"{name}: is a folder; {purpose} needs a file name")
    if replaces is not None and _probe(os.path.isfile, target):
        try:
            with open(target, "rb") as f:
                head = f.read(512)
        except OSError:
            head = b""  # unreadable: the probe below or the write says why
        if head and replaces[0] not in head:
            raise WriteFault(f"{name}: exists and is not {replaces[1]}; it is left as it "
                             f"is: choose another name for {purpose}")
    if not _probe(os.path.isdir, target.parent):
        raise WriteFault(f"{name}: folder {target.parent} does not exist")
    cause = _write_refused(target.parent)
    if cause is not None:  # the line names the file the user typed, as a write would
        raise WriteFault(f"{name}: cannot write ({cause})")


# what an earlier output of each kind begins with (``require_writable_file``'s replaces)
HTML_REPORT = (b"<html", "an HTML report")
CALIBRATION_FILE = (b'"tactile-studio-calibration"', "a calibration file")


@contextmanager
def said_on_fault(error: Callable[[str], UserError],
                  also: tuple[type[UserError], ...] = ()) -> Iterator[None]:
    """Run writes whose failure must say what is kept: an OSError that is the place's
    fault (:func:`fault_line`), or one of the user errors ``also`` names, ends as
    ``error(line)``, the one line with what the caller adds; any other error keeps its
    traceback."""
    try:
        yield
    except also as exc:
        raise error(str(exc)) from None
    except OSError as exc:
        line = fault_line(exc)
        if line is None:
            raise
        raise error(line) from None


def stored_already(what: str) -> AbstractContextManager[None]:
    """Write an output after the result itself was stored (a check or calibration in the
    logbook): a place that fails then (or a file another writer holds: ``FileBusy``)
    still ends in one line naming the file, which also says what is kept (``what``), so
    the user does not measure it all again."""
    return said_on_fault(lambda line: WriteFault(f"{line}; {what}"), also=(FileBusy,))
