"""The sensor logbook's file: checked when opened, set aside when damaged, backed up.

SQLite survives a killed process, not a truncated file or a bad disk block. So the
logbook is checked before it is used (its size, its header, ``PRAGMA quick_check``) and a
damaged one is never written into: it is refused (one line naming it; readers and
recorders), or moved aside under a timestamped name and replaced by its backup or a new
logbook (writers that must store something: ``on_damage="replace"``). A rolling backup
(``logbook.sqlite.bak``: SQLite's backup API into a temporary file, checked, then
renamed) is refreshed whenever a Logbook that wrote is closed (logbook writes are few: a
recording's hours, a check, a calibration), so one bad block costs no history.
``docs/sensor-health.md`` says how to restore it by hand.

Errors SQLite reports while the logbook is in use are told apart here too
(:func:`translated`): a damaged file or a place that cannot be written is a
``UserError`` naming the file; anything else (a wrong statement) keeps its traceback.
"""

from __future__ import annotations

import logging
import os
import shutil
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from tactile_studio.errors import UserError

HEADER = b"SQLite format 3\x00"
# SQLite result codes that mean the file is damaged, or the place is at fault
DAMAGE_CODES = frozenset({"SQLITE_CORRUPT", "SQLITE_NOTADB"})
PLACE_CODES = frozenset({"SQLITE_READONLY", "SQLITE_IOERR", "SQLITE_FULL", "SQLITE_CANTOPEN",
                         "SQLITE_PERM", "SQLITE_BUSY", "SQLITE_LOCKED", "SQLITE_AUTH"})

log = logging.getLogger(__name__)
_said: set[str] = set()


class LogbookDamaged(UserError):
    """The logbook file is empty, not SQLite, or fails its integrity check."""


class LogbookUnavailable(UserError):
    """The logbook cannot be read or written here (permissions, read-only, full, busy)."""


def backup_path(path: Path) -> Path:
    return path.with_name(path.name + ".bak")


def say_once(line: str) -> None:
    """Log ``line`` as a warning the first time this process says it (a recording that
    skips a damaged logbook says so once, not at every open)."""
    if line not in _said:
        _said.add(line)
        log.warning("%s", line)


def problem_of(path: Path) -> str | None:
    """Why the logbook file at ``path`` cannot be trusted; None when it is sound or
    absent. Reads only (a read-only connection: nothing is checkpointed into it)."""
    try:
        with open(path, "rb") as f:
            head = f.read(len(HEADER))
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise LogbookUnavailable(f"{path}: cannot read the sensor logbook "
                                 f"({exc.strerror or exc})") from None
    if not head:
        return "empty: 0 bytes"
    if head != HEADER:
        return "not an SQLite database"
    try:
        db = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
        try:
            rows = db.execute("PRAGMA quick_check").fetchall()
        finally:
            db.close()
    except sqlite3.DatabaseError as exc:
        if _code(exc) in PLACE_CODES:
            raise LogbookUnavailable(f"{path}: cannot read the sensor logbook ({exc})") from None
        return str(exc)
    if rows == [("ok",)]:
        return None
    found = [ln.strip() for row in rows for ln in str(row[0]).splitlines()
             if ln.strip() and not ln.startswith("***")]
    more = f" and {len(found) - 1} more" if len(found) > 1 else ""
    return f"integrity check failed: {found[0] if found else rows[0][0]}{more}"


def refusal(path: Path, problem: str) -> LogbookDamaged:
    """The one line for a damaged logbook that is left as it is."""
    bak = backup_path(path)
    fix = (f"restore its backup {bak.name} (docs/sensor-health.md)" if bak.is_file()
           else "no backup to restore; see docs/sensor-health.md")
    return LogbookDamaged(f"{path}: the sensor logbook is damaged ({problem}); it was left "
                          f"as it is: {fix}")


def set_aside(path: Path, problem: str) -> str:
    """Move a damaged logbook (and its -wal/-shm) aside under a timestamped name, put
    its backup in its place when the backup is sound; returns the line saying so."""
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    aside = path.with_name(f"{path.name}.damaged-{stamp}")
    n = 1
    while aside.exists():
        n += 1
        aside = path.with_name(f"{path.name}.damaged-{stamp}-{n}")
    os.replace(path, aside)
    for suffix in ("-wal", "-shm"):
        companion = Path(f"{path}{suffix}")
        if companion.exists():
            os.replace(companion, Path(f"{aside}{suffix}"))
    bak = backup_path(path)
    restored = None
    if bak.is_file() and problem_of(bak) is None:
        tmp = path.with_name(path.name + ".restoring")
        shutil.copyfile(bak, tmp)
        os.replace(tmp, path)
        restored = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(bak.stat().st_mtime))
    then = (f"restored its backup of {restored}" if restored
            else "started a new one (no sound backup)")
    return (f"{path}: the sensor logbook was damaged ({problem}); kept it as {aside.name} "
            f"and {then}")


def refresh_backup(db: sqlite3.Connection, path: Path, only_if_missing: bool = False) -> bool:
    """Copy the logbook to its backup (``only_if_missing``: only when there is none):
    into a temporary file, checked, then renamed over the old backup, so a failed or
    damaged copy never replaces a good one. True when refreshed."""
    bak = backup_path(path)
    if only_if_missing and bak.exists():
        return False
    tmp = bak.with_name(f"{bak.name}.tmp{os.getpid()}")
    try:
        tmp.unlink(missing_ok=True)
        dest = sqlite3.connect(tmp)
        try:
            db.backup(dest)
            dest.execute("PRAGMA journal_mode=DELETE")  # one self-contained file
            ok = dest.execute("PRAGMA quick_check").fetchall() == [("ok",)]
        finally:
            dest.close()
        if not ok:
            raise sqlite3.DatabaseError("the copy failed its integrity check")
        os.replace(tmp, bak)
        return True
    except (sqlite3.Error, OSError) as exc:
        say_once(f"{bak}: sensor logbook backup not refreshed ({exc})")
        tmp.unlink(missing_ok=True)
        return False


def _code(exc: sqlite3.Error) -> str:
    """The primary result code's name ('SQLITE_READONLY' for SQLITE_READONLY_CANTINIT)."""
    return "_".join(str(getattr(exc, "sqlite_errorname", "")).split("_")[:2])


def user_error(exc: sqlite3.Error, path: Path) -> UserError | None:
    """The UserError for an SQLite error that is the file's or the place's fault."""
    name = _code(exc)
    if name in DAMAGE_CODES:
        return LogbookDamaged(f"{path}: the sensor logbook is damaged ({exc}); see "
                              "docs/sensor-health.md to restore its backup")
    if name in PLACE_CODES:
        return LogbookUnavailable(f"{path}: sensor logbook: {exc}")
    return None


@contextmanager
def translated(path: Path) -> Iterator[None]:
    """SQLite errors of the file or the place as one-line UserErrors naming ``path``."""
    try:
        yield
    except sqlite3.Error as exc:
        err = user_error(exc, path)
        if err is None:
            raise
        raise err from None


class CheckedCursor(sqlite3.Cursor):
    """A cursor whose SQLite errors of the file or place become UserErrors."""

    def execute(self, *args: Any) -> CheckedCursor:
        with translated(self.connection.logbook_path):
            return super().execute(*args)

    def executemany(self, *args: Any) -> CheckedCursor:
        with translated(self.connection.logbook_path):
            return super().executemany(*args)

    def fetchone(self) -> Any:
        with translated(self.connection.logbook_path):
            return super().fetchone()

    def fetchall(self) -> list[Any]:
        with translated(self.connection.logbook_path):
            return super().fetchall()

    def __next__(self) -> Any:
        with translated(self.connection.logbook_path):
            return super().__next__()


class CheckedConnection(sqlite3.Connection):
    """``sqlite3.connect(..., factory=CheckedConnection)``: every statement's errors are
    translated (set ``logbook_path`` after connecting)."""

    logbook_path: Path = Path("logbook.sqlite")

    def execute(self, *args: Any) -> CheckedCursor:
        return self.cursor(CheckedCursor).execute(*args)

    def executemany(self, *args: Any) -> CheckedCursor:
        return self.cursor(CheckedCursor).executemany(*args)
