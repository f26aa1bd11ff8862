"""What the research workspace lists: session files (one row each) and run folders.

Both scans are defensive: a damaged session or a run folder of another layout becomes a
row with an ``error`` text instead of stopping the scan, so one bad file never hides the
others.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.evaluation.summary import shots_curve
from tactile_studio.learn.experiments.runfolder import CONFIG, METRICS, read_json, run_problems
from tactile_studio.storage.format.session_set import (
    SessionKey,
    choose,
    is_resume_backup,
    session_key,
)
from tactile_studio.storage.format.trials import TrialStatus


@dataclass
class SessionRow:
    path: str
    participant: str = ""
    condition: str = ""
    protocol: str = ""
    sensor: str = ""
    date: str = ""
    per_gesture: dict[str, int] = field(default_factory=dict)  # ok trials per gesture
    ok: int = 0
    flagged: int = 0
    discarded: int = 0
    error: str = ""  # the file cannot be read: not listed for training
    violations: list[str] = field(default_factory=list)  # what ``check`` finds wrong
    checked: bool = False  # ``violations`` is known (a scan may leave the check for later)
    folder: str = ""  # the file's folder, relative to what the listing holds
    key: SessionKey | None = None  # its session and recording (storage.session_set)
    left_out: str = ""  # why a dataset of the whole listing skips it ("resume backup"...)
    kept_instead: str = ""  # the listed file read instead (its folder/name)
    pilot: bool = False  # a rehearsal (storage/session_set.is_pilot): not selected by default

    @property
    def problem(self) -> str:
        """Why the file is not to be trusted as it is ("" when it is)."""
        from tactile_studio.storage.format.session_check import verdict_text

        if self.error or self.violations:
            return self.error or verdict_text(self.violations)
        return "pilot (a rehearsal): select it to train on it" if self.pilot else ""

    @property
    def note(self) -> str:
        """Why the whole listing's dataset leaves the file out, in words; "" if it does
        not ("copy of data/P01.h5 (same frames)")."""
        if not self.left_out:
            return ""
        return {"resume backup": f"resume backup of {self.kept_instead}",
                "duplicate session": f"same session as {self.kept_instead}",
                "same recording": f"copy of {self.kept_instead} (same frames)"}[self.left_out]

    def matches(self, text: str) -> bool:
        """Case-insensitive filter over the visible fields."""
        hay = " ".join([self.path, self.participant, self.condition, self.protocol,
                        self.sensor, self.date, self.note]).lower()
        return all(word in hay for word in text.lower().split())


def scan_sessions(folders: list[str | os.PathLike], check: bool = True) -> list[SessionRow]:
    """One row per ``*.h5`` under the folders (or the files given), each checked
    (``session_check``: it reads the journal and the two time columns, not the frames)
    unless ``check`` is False: then :func:`check_sessions` checks them later, so a window
    can list a folder of long sessions at once."""
    from tactile_studio.storage.format.session_check import check_session
    from tactile_studio.storage.format.session_file import SessionFile
    from tactile_studio.storage.format.session_set import is_pilot, session_files_under

    files: list[Path] = []
    for f in map(Path, folders):
        files.extend(session_files_under(f) if f.is_dir() else [f] if f.is_file() else [])
    rows = []
    for path in sorted(set(files)):
        row = SessionRow(str(path))
        try:
            with SessionFile(path) as s:
                row.key = session_key(path, s)
                meta = s.metadata
                row.participant = str(meta.get("participant") or path.stem)
                row.condition = str(meta.get("condition") or "")
                row.protocol = str(meta.get("protocol") or "")
                row.sensor = s.layout.name
                row.date = str(meta.get("created") or "")[:16].replace("T", " ")
                row.pilot = is_pilot(meta)
                counts: Counter[str] = Counter()
                for t in s.trials:
                    if t.usable:
                        counts[t.gesture] += 1
                        row.ok += 1
                    row.discarded += t.status == TrialStatus.DISCARDED
                    row.flagged += bool(t.flags)
                row.per_gesture = dict(counts)
                if check:
                    row.violations, row.checked = check_session(s), True
        except (UserError, OSError, KeyError, ValueError) as exc:
            row.error = str(exc).splitlines()[0]
        rows.append(row)
    _mark_copies(rows)
    return rows


def _mark_copies(rows: list[SessionRow]) -> None:
    """Each row's folder, and why a dataset of the whole listing would leave it out
    (``session_set.choose``, what ``train`` applies): the same file name in two folders
    is then told apart, and a resume backup or a re-import says what it repeats."""
    paths = [Path(r.path) for r in rows]
    root = Path(os.path.commonpath([p.parent for p in paths])) if paths else None

    def shown(p: Path) -> str:
        rel = p.parent.relative_to(root).as_posix() if root else ""
        return rel if rel != "." else p.parent.name

    for row, p in zip(rows, paths):
        row.folder = shown(p)
    by_path = {Path(r.path): r for r in rows}
    _, left = choose([r.key for r in rows if r.key is not None and not r.error])
    for path, why, kept in left:
        by_path[path].left_out = copy_kind(path, why)
        by_path[path].kept_instead = f"{shown(kept)}/{kept.name}"


def chosen_rows(rows: Sequence[SessionRow]) -> tuple[list[SessionRow], list[str]]:
    """(read, why each other one is left out) when ``rows`` alone (a selection) make a
    dataset: one file per session and per recording, readable files only."""
    readable = [r for r in rows if r.key is not None and not r.error]
    kept, left = choose([r.key for r in readable])
    keep = set(kept)
    return ([r for r in readable if Path(r.path) in keep],
            [copy_kind(path, why) for path, why, _ in left])


def copy_kind(path: Path, why: str) -> str:
    """``choose``'s reason as the listing says it: a resume backup is named so."""
    return "resume backup" if why == "duplicate session" and is_resume_backup(path) else why


def check_sessions(paths: Sequence[str], on_result: Callable[[int, list[str], str], None],
                   progress: ProgressFn = no_progress,
                   cancel: CancelToken | None = None) -> int:
    """``check`` each file in turn, telling ``on_result(k, violations, error)`` of the
    ``k``-th as soon as it is known (``error``: the file could not be read); the slow
    half of :func:`scan_sessions`, for a background thread. Returns the files checked."""
    from tactile_studio.storage.format.session_check import check_file

    for k, path in enumerate(paths):
        if cancel is not None:
            cancel.check()
        try:
            violations, error = check_file(path).violations, ""
        except (UserError, OSError, KeyError, ValueError) as exc:
            violations, error = [], str(exc).splitlines()[0]
        on_result(k, violations, error)
        progress((k + 1) / max(len(paths), 1), Path(path).name)
    return len(paths)


@dataclass
class RunRow:
    path: str
    model: str = ""
    channels: str = ""
    evaluation: str = ""
    preset: str = ""
    grid: str = ""
    accuracy: float | None = None
    trial_accuracy: float | None = None
    f1_macro: float | None = None
    balanced_accuracy: float | None = None
    shots: str = ""  # a few-shot run's curve, "K=0 0.61, K=1 0.70" (per trial)
    folds: int = 0
    complete: bool = False
    created: str = ""
    config: dict[str, Any] = field(default_factory=dict)
    error: str = ""

    @property
    def name(self) -> str:
        return Path(self.path).name

    @property
    def ran_config(self) -> dict[str, Any]:
        """The config with the channel set the run used (its metrics say which when
        train left it to the model): what ``config_difference`` compares."""
        from tactile_studio.learn.results.compare import as_ran

        return as_ran(self.config, self.channels if self.channels != "all" else None)


def _number(m: dict[str, Any], *keys: str) -> float | None:
    """The first of ``keys`` that holds a number (old and new metrics.json spell
    trial-level accuracy differently)."""
    for k in keys:
        v = m.get(k)
        if isinstance(v, dict):
            v = v.get("accuracy") if "accuracy" in v else v.get("value")
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return float(v)
    return None


def read_run_row(path: str | os.PathLike) -> RunRow:
    """One run folder as a row; a damaged one (runfolder.run_problems: a fold without its
    model, a metrics.json of another shape...) is a row whose ``error`` says why."""
    row = RunRow(str(path))
    problems, cfg, _ = run_problems(path)
    if cfg is not None:
        config = cfg["config"]
        row.config = config
        row.model = str(config.get("model", ""))
        row.channels = str(config.get("channels") or "all")
        row.evaluation = str(config.get("evaluation", ""))
        row.preset = str(config.get("preset", ""))
        row.grid = str(config.get("grid", ""))
        row.created = str(cfg["resolved"].get("created", ""))[:16].replace("T", " ")
    row.folds = sum(1 for _ in (Path(path) / "folds").glob("*/fold.json"))
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        inside = str(Path(path)) + os.sep  # the row is the run: its own path is not news
        first = problems[0].replace(inside, "")
        row.error = (first if "damaged" in first else "damaged: " + first) + more
        return row
    if not (Path(path) / METRICS).is_file():
        row.error = "no metrics.json (interrupted before a fold finished?)"
        return row
    try:
        m = read_json(Path(path) / METRICS)  # its shape was checked by run_problems
    except UserError as exc:  # removed or changed since
        row.error = str(exc)
        return row
    row.accuracy = _number(m, "accuracy")
    row.trial_accuracy = _number(m, "trial_accuracy")
    row.f1_macro = _number(m, "f1_macro")
    row.balanced_accuracy = _number(m, "balanced_accuracy")
    row.shots = shots_curve(m.get("shots") if isinstance(m.get("shots"), list) else None)
    row.complete = m.get("complete") is True
    row.channels = str(m.get("channels") or row.channels)
    return row


def scan_runs(root: str | os.PathLike) -> list[RunRow]:
    """Every folder under ``root`` (itself included) that holds a ``config.json``."""
    root = Path(root)
    if not root.is_dir():
        raise UserError(f"{root}: no such folder")
    found = sorted({p.parent for p in root.rglob(CONFIG)})
    return [read_run_row(p) for p in found if (p / "folds").is_dir() or (p / METRICS).is_file()]
