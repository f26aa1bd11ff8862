"""Who each test trial of a run is: participant, session, trial index, condition, span.

Fold records store predictions by dataset trial index (``owner``); comparing runs or
listing the trials behind a confusion-matrix cell needs the trial's identity. New runs
write ``RUN/trials.json`` (one entry per dataset trial, in dataset order); for run
folders made before that file existed, the same table is rebuilt from the sessions named
in the run's config (trial metadata only, nothing is decoded).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tactile_studio.errors import UserError
from tactile_studio.learn.experiments.runfolder import read_json, write_json

TRIALS = "trials.json"


def session_trial_table(paths: Sequence[str | os.PathLike]) -> dict[str, dict[str, Any]]:
    """uid -> identity of every ``ok`` trial in the session files, keyed as the dataset's
    ``uids`` are (session path relative to the common root + ``#`` + trial index)."""
    from tactile_studio.storage.format.session_file import SessionFile
    from tactile_studio.storage.format.session_set import select_sessions

    chosen = select_sessions(paths)
    table: dict[str, dict[str, Any]] = {}
    for path in chosen.files:
        with SessionFile(path) as s:
            meta = s.metadata
            participant = str(meta.get("participant") or path.stem)
            rel = chosen.name(path)
            for t in s.trials:
                if not t.usable:
                    continue
                uid = t.uid(rel)
                table[uid] = {
                    "uid": uid, "participant": participant, "session": rel,
                    "path": str(path), "trial": t.index, "gesture": t.gesture,
                    "condition": str(meta.get("condition") or ""),
                    "start_sample": t.start_sample, "end_sample": t.end_sample,
                }
    return table


def write_trial_table(run: str | os.PathLike, uids: list[str], participants: list[str],
                      data: Sequence[str | os.PathLike]) -> None:
    """Write ``RUN/trials.json`` for a dataset's trials (in dataset order)."""
    try:
        table = session_trial_table(data)
    except (UserError, OSError):
        table = {}
    rows = []
    for uid, participant in zip(uids, participants):
        row = dict(table.get(uid) or {})
        if not row:
            session, _, idx = uid.rpartition("#")
            row = {"uid": uid, "session": session, "trial": int(idx) if idx.isdigit() else idx}
        row["participant"] = str(participant)
        rows.append(row)
    write_json(Path(run) / TRIALS, {"trials": rows})


def load_trial_table(run: str | os.PathLike, data: Sequence[str] | None = None
                     ) -> list[dict[str, Any]]:
    """The run's trials in dataset order (index = ``owner`` in fold predictions)."""
    run = Path(run)
    if (run / TRIALS).is_file():
        table = read_json(run / TRIALS)
        rows = table.get("trials") if isinstance(table, dict) else None
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise UserError(f"{run / TRIALS}: damaged (valid JSON, but not a run's trial "
                            "table)")
        return rows
    cfg = read_json(run / "config.json")
    paths = data or cfg.get("config", {}).get("data") or []
    try:
        table = session_trial_table(paths)
    except UserError as exc:
        raise UserError(f"{run}: the run has no {TRIALS} and its data cannot be read ({exc})") \
            from None
    # read_sessions keeps every ok trial with at least one frame, in file then trial order
    return [table[k] for k in table if table[k]["end_sample"] > table[k]["start_sample"]]
