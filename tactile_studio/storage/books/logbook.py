"""The sensor logbook: identity, hours of use, wellness checks, calibrations, notes.

Session files are the record of data; the logbook is the record of sensors. It is an
embedded SQLite database (stdlib ``sqlite3``) in :func:`tactile_studio.paths.data_dir`,
in WAL mode, and every write is one transaction: a process killed in the middle of a
write leaves the previous consistent state (a check is stored with all its spots or not
at all). The schema is versioned; :data:`MIGRATIONS` brings any older file up to date.
The file is checked when opened and backed up (``logbook_file``): a damaged logbook is
never written into.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tactile_studio import paths
from tactile_studio.errors import UserError
from tactile_studio.storage.books import logbook_file
from tactile_studio.storage.books.logbook_file import (  # noqa: F401 - re-exported for callers
    LogbookDamaged,
    LogbookUnavailable,
)

FILE_NAME = "logbook.sqlite"
NOTE_KINDS = ("note", "repair", "replaced", "re-covered")

MIGRATIONS: tuple[str, ...] = (
    # 1: the first schema
    """
    CREATE TABLE sensors (
        id TEXT PRIMARY KEY, created TEXT NOT NULL, layout TEXT NOT NULL DEFAULT '',
        description TEXT NOT NULL DEFAULT '');
    CREATE TABLE usage (
        id INTEGER PRIMARY KEY, sensor_id TEXT NOT NULL REFERENCES sensors(id),
        at TEXT NOT NULL, seconds REAL NOT NULL, source TEXT NOT NULL DEFAULT '');
    CREATE TABLE checks (
        id INTEGER PRIMARY KEY, sensor_id TEXT NOT NULL REFERENCES sensors(id),
        at TEXT NOT NULL, verdict TEXT NOT NULL, weight_g REAL NOT NULL,
        hours REAL NOT NULL, n_spots INTEGER NOT NULL, result TEXT NOT NULL);
    CREATE TABLE check_spots (
        check_id INTEGER NOT NULL REFERENCES checks(id), taxel TEXT NOT NULL,
        normal_kpa REAL NOT NULL, shear_kpa REAL NOT NULL, ratio REAL,
        verdict TEXT NOT NULL);
    CREATE TABLE calibrations (
        id INTEGER PRIMARY KEY, sensor_id TEXT NOT NULL REFERENCES sensors(id),
        at TEXT NOT NULL, kind TEXT NOT NULL, rms_pct REAL NOT NULL,
        active INTEGER NOT NULL DEFAULT 0, data TEXT NOT NULL);
    CREATE TABLE notes (
        id INTEGER PRIMARY KEY, sensor_id TEXT NOT NULL REFERENCES sensors(id),
        at TEXT NOT NULL, kind TEXT NOT NULL, text TEXT NOT NULL);
    """,
)


class UnknownSensor(UserError):
    """A sensor ID that the logbook has never seen."""


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def default_path() -> Path:
    """Where the logbook lives (``$TACTILE_STUDIO_DATA_DIR`` overrides the folder)."""
    return paths.data_dir() / FILE_NAME


@dataclass(frozen=True)
class SensorSummary:
    """One line of ``tactile-studio sensors``."""

    id: str
    hours: float
    last_verdict: str | None
    last_check_at: str | None
    last_check_id: int | None
    active_calibration: int | None

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


class Logbook:
    """The sensor logbook. Cheap to open; use as a context manager or call close()."""

    def __init__(self, path: str | os.PathLike | None = None, *,
                 on_damage: str = "refuse") -> None:
        """Open (or start) the logbook after checking its file (``logbook_file``). A
        damaged file is never written into: ``on_damage="refuse"`` raises LogbookDamaged
        (one line naming it), ``"replace"`` moves it aside and carries on with its
        backup or a new logbook, saying so once (also in :attr:`notice`)."""
        self.path = Path(path) if path is not None else default_path()
        self.notice: str | None = None  # what was done about a damaged file
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            problem = logbook_file.problem_of(self.path)
            if problem is not None:
                if on_damage != "replace":
                    raise logbook_file.refusal(self.path, problem)
                self.notice = logbook_file.set_aside(self.path, problem)
                logbook_file.say_once(self.notice)
            self._db = sqlite3.connect(self.path, timeout=10.0, isolation_level=None,
                                       check_same_thread=False,
                                       factory=logbook_file.CheckedConnection)
            self._db.logbook_path = self.path
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.execute("PRAGMA foreign_keys=ON")
            self._wrote = False
            self._refuse_if_newer()
            self._migrate()
            logbook_file.refresh_backup(self._db, self.path, only_if_missing=not self._wrote)
            self._wrote = False
        except sqlite3.DatabaseError as exc:
            raise UserError(f"{self.path}: cannot open the sensor logbook ({exc})") from None
        except OSError as exc:
            raise logbook_file.LogbookUnavailable(
                f"{self.path}: cannot open the sensor logbook ({exc.strerror or exc})"
            ) from None

    # ---- plumbing --------------------------------------------------------------------
    def close(self) -> None:
        """Close; after writes, refresh the backup first (``logbook_file``)."""
        if self._wrote:
            self._wrote = False
            logbook_file.refresh_backup(self._db, self.path)
        self._db.close()

    def __enter__(self) -> Logbook:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One transaction: everything inside lands together or not at all."""
        self._db.execute("BEGIN IMMEDIATE")
        try:
            yield self._db
        except BaseException:
            try:
                self._db.execute("ROLLBACK")
            except (sqlite3.Error, UserError):
                pass  # the error that stopped the write says more than its rollback
            raise
        self._db.execute("COMMIT")
        self._wrote = True

    @property
    def schema_version(self) -> int:
        row = self._db.execute("SELECT MAX(version) FROM schema_version").fetchone()
        return int(row[0] or 0)

    def _refuse_if_newer(self) -> None:
        """A logbook a newer Tactile Studio wrote is left as it is: this version does not
        know its tables, and writing to it (a recording's hours, a check) could break
        what the newer one keeps there."""
        known = self._db.execute("SELECT name FROM sqlite_master WHERE type='table' "
                                 "AND name='schema_version'").fetchone()
        if known is None or self.schema_version <= len(MIGRATIONS):
            return
        version = self.schema_version
        self._db.close()
        raise UserError(f"{self.path}: the sensor logbook was written by a newer Tactile "
                        f"Studio (schema {version}; this one knows up to {len(MIGRATIONS)}): "
                        "update Tactile Studio; the file is left as it is")

    def _migrate(self) -> None:
        self._db.execute("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)")
        for version, script in enumerate(MIGRATIONS, start=1):
            if self.schema_version >= version:
                continue
            with self._write() as db:
                for statement in filter(str.strip, script.split(";")):
                    db.execute(statement)
                db.execute("INSERT INTO schema_version (version) VALUES (?)", (version,))

    # ---- sensors ---------------------------------------------------------------------
    def ensure_sensor(self, sensor_id: str, layout: str = "", description: str = "") -> None:
        """Register a sensor the first time it is seen (no-op afterwards)."""
        sensor_id = check_sensor_id(sensor_id)
        with self._write() as db:
            db.execute("INSERT OR IGNORE INTO sensors (id, created, layout, description) "
                       "VALUES (?, ?, ?, ?)", (sensor_id, _now(), layout, description))

    def sensor_ids(self) -> list[str]:
        return [r[0] for r in self._db.execute("SELECT id FROM sensors ORDER BY id")]

    def require(self, sensor_id: str) -> str:
        """The ID if known, else UnknownSensor naming the known ones."""
        if self._db.execute("SELECT 1 FROM sensors WHERE id=?", (sensor_id,)).fetchone():
            return sensor_id
        known = ", ".join(self.sensor_ids()) or "none yet"
        raise UnknownSensor(f"unknown sensor {sensor_id!r} in {self.path} (known: {known})")

    # ---- hours of use ----------------------------------------------------------------
    def add_usage(self, sensor_id: str, seconds: float, source: str = "") -> None:
        """A recording of ``seconds`` used the sensor (registers it if new)."""
        sensor_id = check_sensor_id(sensor_id)
        with self._write() as db:
            db.execute("INSERT OR IGNORE INTO sensors (id, created) VALUES (?, ?)",
                       (sensor_id, _now()))
            db.execute("INSERT INTO usage (sensor_id, at, seconds, source) VALUES (?, ?, ?, ?)",
                       (sensor_id, _now(), float(max(seconds, 0.0)), str(source)))

    def hours(self, sensor_id: str) -> float:
        row = self._db.execute("SELECT COALESCE(SUM(seconds), 0) FROM usage WHERE sensor_id=?",
                               (sensor_id,)).fetchone()
        return float(row[0]) / 3600.0

    # ---- wellness checks -------------------------------------------------------------
    def add_check(self, sensor_id: str, result: dict[str, Any]) -> int:
        """Store a wellness check (its spots in the same transaction); returns its ID."""
        spots = result.get("spots", [])
        with self._write() as db:
            self.require(sensor_id)
            cur = db.execute(
                "INSERT INTO checks (sensor_id, at, verdict, weight_g, hours, n_spots, result) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (sensor_id, _now(), result["verdict"], float(result.get("weight_g", 0.0)),
                 self.hours(sensor_id), len(spots), json.dumps(result)))
            check_id = int(cur.lastrowid)
            db.executemany(
                "INSERT INTO check_spots (check_id, taxel, normal_kpa, shear_kpa, ratio, verdict)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                [(check_id, s["taxel"], s["normal_kpa"], s["shear_kpa"], s.get("ratio"),
                  s["verdict"]) for s in spots])
        return check_id

    def checks(self, sensor_id: str) -> list[dict[str, Any]]:
        """Every check of a sensor, oldest first, with its stored result."""
        rows = self._db.execute(
            "SELECT id, at, verdict, weight_g, hours, result FROM checks WHERE sensor_id=? "
            "ORDER BY id", (sensor_id,)).fetchall()
        return [{"id": r[0], "at": r[1], "verdict": r[2], "weight_g": r[3], "hours": r[4],
                 "result": json.loads(r[5])} for r in rows]

    def last_check(self, sensor_id: str) -> dict[str, Any] | None:
        rows = self.checks(sensor_id)
        return rows[-1] if rows else None

    # ---- calibrations ----------------------------------------------------------------
    def add_calibration(self, sensor_id: str, kind: str, rms_pct: float,
                        data: dict[str, Any], activate: bool = True) -> int:
        """Store a calibration version; by default it becomes the active one."""
        with self._write() as db:
            self.require(sensor_id)
            if activate:
                db.execute("UPDATE calibrations SET active=0 WHERE sensor_id=?", (sensor_id,))
            cur = db.execute(
                "INSERT INTO calibrations (sensor_id, at, kind, rms_pct, active, data) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (sensor_id, _now(), kind, float(rms_pct), int(activate), json.dumps(data)))
            return int(cur.lastrowid)

    def update_calibration(self, calibration_id: int, rms_pct: float,
                           data: dict[str, Any]) -> None:
        """Rewrite a stored version's data (a merge the user then chose to replace)."""
        with self._write() as db:
            cur = db.execute("UPDATE calibrations SET rms_pct=?, data=? WHERE id=?",
                             (float(rms_pct), json.dumps(data), int(calibration_id)))
            if cur.rowcount != 1:
                raise UserError(f"no calibration {calibration_id} in {self.path}")

    def calibrations(self, sensor_id: str) -> list[dict[str, Any]]:
        """Each version with what it covers (``taxels`` of ``of``, ``measured``, ``kept``
        from earlier calibrations it merged with: see sensor/calibration.py)."""
        rows = self._db.execute(
            "SELECT id, at, kind, rms_pct, active, data FROM calibrations WHERE sensor_id=? "
            "ORDER BY id", (sensor_id,)).fetchall()
        return [{"id": r[0], "at": r[1], "kind": r[2], "rms_pct": r[3], "active": bool(r[4]),
                 **_coverage(r[5])} for r in rows]

    def calibration(self, calibration_id: int) -> dict[str, Any]:
        row = self._db.execute("SELECT sensor_id, data FROM calibrations WHERE id=?",
                               (int(calibration_id),)).fetchone()
        if row is None:
            raise UserError(f"no calibration {calibration_id} in {self.path}")
        return {"sensor_id": row[0], **json.loads(row[1])}

    def active_calibration(self, sensor_id: str) -> int | None:
        row = self._db.execute("SELECT id FROM calibrations WHERE sensor_id=? AND active=1",
                               (sensor_id,)).fetchone()
        return int(row[0]) if row else None

    # ---- notes -----------------------------------------------------------------------
    def add_note(self, sensor_id: str, text: str, kind: str = "note") -> int:
        if kind not in NOTE_KINDS:
            raise UserError(f"unknown note kind {kind!r} (known: {', '.join(NOTE_KINDS)})")
        with self._write() as db:
            self.require(sensor_id)
            cur = db.execute("INSERT INTO notes (sensor_id, at, kind, text) VALUES (?, ?, ?, ?)",
                             (sensor_id, _now(), kind, text))
            return int(cur.lastrowid)

    def notes(self, sensor_id: str) -> list[dict[str, Any]]:
        rows = self._db.execute("SELECT id, at, kind, text FROM notes WHERE sensor_id=? "
                                "ORDER BY id", (sensor_id,)).fetchall()
        return [{"id": r[0], "at": r[1], "kind": r[2], "text": r[3]} for r in rows]

    # ---- summaries -------------------------------------------------------------------
    def summary(self, sensor_id: str) -> SensorSummary:
        last = self.last_check(sensor_id)
        return SensorSummary(
            id=sensor_id, hours=round(self.hours(sensor_id), 4),
            last_verdict=last["verdict"] if last else None,
            last_check_at=last["at"] if last else None,
            last_check_id=last["id"] if last else None,
            active_calibration=self.active_calibration(sensor_id))

    def history(self, sensor_id: str) -> dict[str, Any]:
        """Everything about one sensor (``tactile-studio sensor ID``)."""
        self.require(sensor_id)
        row = self._db.execute("SELECT created, layout, description FROM sensors WHERE id=?",
                               (sensor_id,)).fetchone()
        checks = [{k: v for k, v in c.items() if k != "result"} | {
            k: c["result"].get(k, d) for k, d in (
                ("spots", []), ("reasons", []), ("reference_check", None),
                ("reference_calibration", None), ("active_calibration", None))}
            for c in self.checks(sensor_id)]
        return {**self.summary(sensor_id).to_dict(), "created": row[0], "layout": row[1],
                "description": row[2], "checks": checks,
                "calibrations": self.calibrations(sensor_id), "notes": self.notes(sensor_id)}


def _coverage(data: str) -> dict[str, Any]:
    from tactile_studio.sensor.calibration import coverage
    from tactile_studio.sensor.layout import get_layout

    try:
        cal = json.loads(data)
        n = get_layout(cal.get("layout")).n_taxels
    except (ValueError, TypeError, KeyError, AttributeError, UserError):
        return {"taxels": None, "of": None, "measured": [], "kept": {}}
    return coverage(n, cal)


def check_sensor_id(sensor_id: str) -> str:
    """A usable sensor ID: non-empty, printable, at most 64 characters."""
    text = str(sensor_id or "").strip()
    if not text or len(text) > 64 or not text.isprintable():
        raise UserError(f"bad sensor ID {sensor_id!r}: use 1-64 printable characters")
    return text


def age_text(iso: str | None, now: _dt.datetime | None = None) -> str:
    """'3 h ago', '2 d ago' from an ISO time (for the console and the sensor list)."""
    if not iso:
        return "never"
    then = _dt.datetime.fromisoformat(iso)
    now = now or _dt.datetime.now(_dt.timezone.utc)
    s = max((now - then).total_seconds(), 0.0)
    if s < 3600:
        return f"{int(s // 60)} min ago"
    if s < 86400 * 2:
        return f"{s / 3600:.1f} h ago"
    return f"{s / 86400:.0f} d ago"


def age_hours(iso: str | None) -> float | None:
    if not iso:
        return None
    then = _dt.datetime.fromisoformat(iso)
    return (_dt.datetime.now(_dt.timezone.utc) - then).total_seconds() / 3600.0
