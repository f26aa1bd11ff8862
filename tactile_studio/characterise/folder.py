"""A characterisation's output folder: what an earlier run left there, and clearing it.

A folder holds one run. Writing a second run into it would replace the first's
session.h5 and results while its raw/*.json and figures stayed beside the new ones, so
a folder that holds a run is refused unless the user says to overwrite; then the old
run's files (and only those) are removed first, so two runs are never mixed.
"""

from __future__ import annotations

import json
from pathlib import Path

from tactile_studio.errors import UserError

# every file a run writes (run.py, report.py; and an older version's compression temp:
# today's temporaries are unique per process and swept by the next claim of their file)
RUN_FILES = ("characterisation.json", "calibration.json", "session.h5", "report.html",
             ".session.h5.compressing")
RUN_FOLDERS = {"raw": "*.json", "figures": "*.png"}


def run_files(out_dir: Path) -> list[Path]:
    """The files of an earlier run in ``out_dir`` (empty when it holds none)."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return []
    found = [out_dir / name for name in RUN_FILES if (out_dir / name).is_file()]
    for folder, pattern in RUN_FOLDERS.items():
        if (out_dir / folder).is_dir():
            found += sorted(p for p in (out_dir / folder).glob(pattern) if p.is_file())
    return found


def describe_run(out_dir: Path) -> str | None:
    """What ``out_dir`` holds in words ('a finished run of 6 taxel(s) started ...'), or
    None when it holds no run, or only one that ended before it recorded anything (its
    files are then cleared by the next run without --overwrite)."""
    out_dir = Path(out_dir)
    files = run_files(out_dir)
    if not files:
        return None
    try:
        saved = json.loads((out_dir / "characterisation.json").read_text())
        done, asked = len(saved.get("taxels") or {}), len(saved.get("taxels_requested") or [])
        when = f" started {saved['started']}" if saved.get("started") else ""
    except (OSError, ValueError, AttributeError, TypeError):
        return f"files of an earlier characterisation ({len(files)} file(s))"
    if saved.get("complete"):
        return f"a finished characterisation of {done} taxel(s){when}"
    if not done and not _measured(out_dir / "session.h5"):
        return None  # it ended before measuring a taxel (a setup error): nothing to keep
    return f"an aborted characterisation ({done} of {asked} taxel(s) done{when})"


def _measured(session: Path) -> bool:
    """The session holds a taxel's measurement (begun at its ``char_taxel`` event): one
    that ended at homing holds only the seconds before. Unreadable: kept, to be safe."""
    if not session.exists():
        return False
    from tactile_studio.storage.format.session_file import SessionFile

    try:
        with SessionFile(session) as s:
            return any(e.get("kind") == "char_taxel" for e in s.events)
    except (OSError, UserError, ValueError, KeyError):
        return True


def check_out_dir(out_dir: Path, overwrite: bool) -> None:
    """Refuse a folder that holds a run unless ``overwrite`` (one line naming it)."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise UserError(f"--out {out_dir}: exists and is not a folder")
    held = describe_run(out_dir)
    if held and not overwrite:
        raise UserError(f"{out_dir} holds {held}; choose another folder or pass --overwrite "
                        "to replace it")


def clear_run(out_dir: Path) -> list[Path]:
    """Remove an earlier run's files (nothing else) before a new run; returns them."""
    out_dir = Path(out_dir)
    removed = run_files(out_dir)
    for path in removed:
        path.unlink()
    for folder in RUN_FOLDERS:
        try:
            (out_dir / folder).rmdir()  # only when empty: the user's own files stay
        except OSError:
            pass
    return removed
