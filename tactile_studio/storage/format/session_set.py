"""Choosing the session files of a dataset so that no session counts twice.

A resume keeps the original file as ``NAME.bak-N.h5`` beside the resumed one, and the
same recording can sit in two folders (a copy, the same source imported twice) or come
back under a new ``session_id`` (a session exported and imported again: the importer's
id). Each would put copies of a participant's trials into a dataset, possibly on both
sides of a train/test split. So a folder scan skips resume backups, files sharing a
``session_id`` (see :attr:`SessionFile.session_id`) are reduced to one, and so are files
holding the same recording by content (:attr:`SessionFile.recording`): a non-backup before
a backup, then a recording made here before an import of it, then a cleanly closed
file, then the one with more trials, more frames, the newest modification time and
finally the first path in sort order (:func:`choose`, which the research workspace's
listing uses too). A pilot session (a rehearsal, metadata ``pilot: true``) found
in a folder is left out too: it is never mixed with participants' data unless its file
is named. What was skipped is returned so it can be reported.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tactile_studio.errors import UserError
from tactile_studio.storage.format.file_guards import not_regular
from tactile_studio.storage.format.session_file import SessionFile

BACKUP_RE = re.compile(r"\.bak-\d+$")
PILOT = "pilot session"


def is_resume_backup(path: Path) -> bool:
    """``P01_shear9_...bak-2.h5``: the original a resume kept beside the session."""
    return bool(BACKUP_RE.search(Path(path).stem))


@dataclass
class SessionSet:
    """The files to read, the common root folder and what was left out (and why)."""

    files: list[Path]
    root: Path | None
    skipped: list[dict[str, Any]] = field(default_factory=list)

    def describe_skipped(self) -> str:
        return describe_skipped(self.skipped)

    def name(self, path: Path) -> str:
        """``path`` as trial uids name its session: relative to the set's root."""
        return path.relative_to(self.root).as_posix() if self.root else path.name


def describe_skipped(skipped: list[dict[str, Any]]) -> str:
    """One line: ``skipped 1 resume backup, 1 duplicate session (b.h5: same session_id
    as a.h5)``; empty when nothing was skipped."""
    if not skipped:
        return ""
    backups = [s for s in skipped if s["reason"] == "resume backup"]
    dups = [s for s in skipped if s["reason"] == "duplicate session"]
    same = [s for s in skipped if s["reason"] == "same recording"]
    pilots = [s for s in skipped if s["reason"] == PILOT]
    odd = [s for s in skipped if s["reason"] not in ("resume backup", "duplicate session",
                                                     "same recording", PILOT)]
    parts = []
    if odd:  # a FIFO, a device, a broken link named *.h5: never opened
        parts.append(f"{len(odd)} file{'s' if len(odd) != 1 else ''} that cannot be read ("
                     + "; ".join(f"{s['file']}: {s['reason']}" for s in odd) + ")")
    if backups:
        parts.append(f"{len(backups)} resume backup{'s' if len(backups) != 1 else ''}")
    if pilots:
        parts.append(f"{len(pilots)} pilot session{'s' if len(pilots) != 1 else ''} "
                     "(rehearsals; name a file to use it)")
    if dups:
        shown = "; ".join(f"{d['file']}: same session_id as {d['kept']}" for d in dups[:3])
        more = f"; {len(dups) - 3} more" if len(dups) > 3 else ""
        parts.append(f"{len(dups)} duplicate session{'s' if len(dups) != 1 else ''} "
                     f"({shown}{more})")
    if same:
        shown = "; ".join(f"{d['file']}: the same frames as {d['kept']}" for d in same[:3])
        more = f"; {len(same) - 3} more" if len(same) > 3 else ""
        parts.append(f"{len(same)} cop{'ies' if len(same) != 1 else 'y'} of a recording "
                     f"already in the data ({shown}{more})")
    return "skipped " + ", ".join(parts)


def session_files_under(folder: Path) -> list[Path]:
    """The ``*.h5`` entries below ``folder``, outside hidden folders (``.venv``, ``.git``,
    ``.cache``: a library's test files there are no one's sessions). Entries that are not
    regular files (a FIFO, a device link, a broken link) are listed too, so they are
    reported with their reason instead of silently missing; nothing here opens them."""
    return sorted(q for q in folder.rglob("*.h5") if not q.is_dir() and not any(
        part.startswith(".") for part in q.relative_to(folder).parts[:-1]))


def scan_session_files(paths: Sequence[str | os.PathLike]
                       ) -> tuple[list[Path], list[Path]]:
    """(files, backups found in folders): folders recursively (``*.h5``), files as given."""
    if not paths:
        raise UserError("no data given: pass a folder or session files")
    files: list[Path] = []
    backups: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = session_files_under(p)
            if not found:
                if (p / "config.json").is_file() and (p / "folds").is_dir():  # a train run
                    raise UserError(f"{p}: a run folder (trained models), not sessions: "
                                    f"'tactile-studio evaluate {p}' re-scores it, "
                                    "'compare' sets two runs side by side")
                raise UserError(f"{p}: no session files (*.h5) in this folder")
            for q in found:
                (backups if is_resume_backup(q) else files).append(q)
        elif p.is_file():
            files.append(p)
        elif p.exists():  # given by name: a FIFO or device is refused, not skipped
            raise UserError(f"{p}: {not_regular(p)}")
        else:
            raise UserError(f"{p}: no such file or folder")
    # links to sessions count once; a link to a device stays under its own name
    files = sorted({f.resolve() if not not_regular(f) else f.absolute() for f in files})
    backups = sorted({b.resolve() for b in backups} - set(files))
    return files, backups


def is_pilot(metadata: dict[str, Any]) -> bool:
    """A rehearsal (the console's pilot mode, ``collect --pilot``), not a participant's."""
    return metadata.get("pilot") is True


@dataclass(frozen=True)
class SessionKey:
    """What choosing among files needs of one: its session id, its recording by content
    (:attr:`SessionFile.recording`) and its rank (the better copy first)."""

    path: Path
    session_id: str
    recording: str
    rank: tuple


def session_key(path: Path, s: SessionFile) -> SessionKey:
    """``path``'s key, from its open session. The rank prefers a file that is no resume
    backup, then a recording made here over an import of it (an export re-imported keeps
    no protocol, blocks or sensor), then a cleanly closed one, more ok trials, more
    frames, the newest."""
    ok = sum(1 for t in s.trials if t.ok)
    made_here = not str(s.metadata.get("source") or "").startswith("import")
    return SessionKey(path, s.session_id, s.recording,
                      (not is_resume_backup(path), made_here, s.closed_cleanly, ok,
                       s.n_frames, path.stat().st_mtime_ns))


def choose(keys: Sequence[SessionKey]) -> tuple[list[Path], list[tuple[Path, str, Path]]]:
    """(kept, left out): one file per session (``session_id``), then one per recording
    (the same frames under two ids: an export imported back, two imports of one
    recording); each left-out file as (file, reason, the file kept instead), the reason
    "duplicate session" (a resume backup among them: :func:`is_resume_backup`) or "same
    recording"."""
    def best(group: list[SessionKey]) -> list[SessionKey]:
        group = sorted(group, key=lambda k: k.path)          # equal ranks: first path wins
        return sorted(group, key=lambda k: k.rank, reverse=True)

    left: list[tuple[Path, str, Path]] = []
    sessions: dict[str, list[SessionKey]] = {}
    for k in keys:
        sessions.setdefault(k.session_id, []).append(k)
    recordings: dict[str, list[SessionKey]] = {}
    for group in sessions.values():
        first, *rest = best(group)
        recordings.setdefault(first.recording, []).append(first)
        left += [(k.path, "duplicate session", first.path) for k in rest]
    kept = []
    for group in recordings.values():
        first, *rest = best(group)
        kept.append(first.path)
        left += [(k.path, "same recording", first.path) for k in rest]
    return sorted(kept), left


def select_sessions(paths: Sequence[str | os.PathLike]) -> SessionSet:
    """The session files under ``paths`` with resume backups and duplicates (the same
    session, or the same recording under another session id) left out."""
    files, backups = scan_session_files(paths)
    every = files + backups
    shown_root = Path(os.path.commonpath([f.parent for f in every])) if every else None

    def rel(p: Path) -> str:
        return p.relative_to(shown_root).as_posix() if shown_root else p.name

    skipped: list[dict[str, Any]] = [
        {"file": rel(b), "reason": "resume backup"} for b in backups]
    odd = {f: not_regular(f) for f in files}
    skipped += [{"file": rel(f), "reason": why} for f, why in odd.items() if why]
    named = {Path(p).resolve() for p in paths if Path(p).is_file()}
    keys = []
    for f in (f for f in files if not odd[f]):
        with SessionFile(f) as s:
            if is_pilot(s.metadata) and f not in named:  # a rehearsal, found in a folder
                skipped.append({"file": rel(f), "reason": PILOT})
                continue
            keys.append(session_key(f, s))
    keep, left = choose(keys)
    ids = {k.path: k.session_id for k in keys}
    skipped += [{"file": rel(f), "reason": why, "kept": rel(kept),
                 **({"session_id": ids[f]} if why != "same recording" else {})}
                for f, why, kept in left]
    # Trial uids are relative to the kept files' folder, as before backups were skipped.
    root = Path(os.path.commonpath([f.parent for f in keep])) if keep else None
    return SessionSet(keep, root, skipped)


__all__ = ["SessionKey", "SessionSet", "choose", "describe_skipped", "is_pilot",
           "is_resume_backup", "select_sessions", "session_key"]
