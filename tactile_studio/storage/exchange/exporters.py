"""Exporting sessions for other tools: the old ShearSense CSV, per-trial NPZ arrays, a
tidy per-trial CSV for statistics, and XDF (storage/exchange/xdf_export.py) for LSL labs.

Only trials with status ``ok`` are exported unless ``all_trials`` is set. Every export
is a long job (``progress``, ``cancel``); a cancelled export keeps the files it finished
and removes the one it was writing. See docs/import-export.md.
"""

from __future__ import annotations

import csv
import os
import re
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.sensor.decode import decode
from tactile_studio.sensor.gesture_metrics import gesture_metrics
from tactile_studio.storage.exchange.importers._common import (
    check_outputs,
    frame_interval,
    naming_the_file,
    write_through_part,
)
from tactile_studio.storage.exchange.importers.maps import normalise_participant
from tactile_studio.storage.exchange.shearsense import (
    N_CHANNELS,
    parse_shearsense_name,
    write_shearsense_csv,
)
from tactile_studio.storage.format.file_names import check_name
from tactile_studio.storage.format.session_file import SessionFile, user_block
from tactile_studio.storage.format.trial_checks import CSV_COLUMNS, csv_fields
from tactile_studio.storage.format.trials import TrialRecord, trial_number

FORMATS = ("shearsense-csv", "npz", "csv-trials", "xdf")
GRIDS = ("auto", "virtual", "physical")
TRIAL_COLUMNS = ["session", "participant", "condition", "protocol", "index", "block",
                 "gesture", "label", "key", "status", "reason", "flags", "start_sample",
                 "end_sample", "start_time", "end_time", "n_frames", "duration_s"]
CHECKED = ("check", "decision", "performed")  # stored by the trial checks when set
FEATURE_COLUMNS = ["peak_normal", "mean_normal", "mean_abs_shear", "contact_area",
                   "dominant_hz", "centroid_speed", "spread_change", "divergence", "curl",
                   "coherence", "movement"]


def selected_trials(session: SessionFile, all_trials: bool = False) -> list[TrialRecord]:
    """The trials to export: ``ok`` ones, or all of them, cut to the frames on disk."""
    out = []
    for t in session.trials:
        if not all_trials and not t.ok:
            continue
        s, e = t.start_sample, min(t.end_sample, session.n_frames)
        if e > s >= 0:
            out.append(t.with_changes(start_sample=s, end_sample=e))
    return out


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "-", text).strip("-").lower() or "gesture"


# ---- ShearSense CSV ------------------------------------------------------------------
def shearsense_csv_name(session: SessionFile) -> str:
    """The session's name, with participant and condition added where the old naming
    (``P<participant>...<FLAT|PILLOW>.csv``) needs them, so re-importing finds them."""
    name = session.path.stem
    participant = str(session.metadata.get("participant") or "")
    condition = str(session.metadata.get("condition") or "")
    for what, value in (("participant", participant), ("condition", condition)):
        if value:  # the file's say: one name, never a path out of the folder given
            check_name(f"{session.path}: {what}", value)
    named = parse_shearsense_name(f"{name}.csv")[0]
    if participant and normalise_participant(named) != normalise_participant(participant):
        name = f"{participant}_{name}"
    if condition and parse_shearsense_name(f"{name}.csv")[1] != condition.upper():
        name = f"{name}_{condition.upper()}"
    return f"{name}.csv"


def export_shearsense_csv(path: str | os.PathLike, out_dir: str | os.PathLike,
                          all_trials: bool = False, progress: ProgressFn | None = None,
                          cancel: CancelToken | None = None, force: bool = False) -> Path:
    """The old collection software's CSV: baseline row, frames, trial keys as labels."""
    progress = progress or no_progress
    with SessionFile(path) as s:
        if s.layout.n_channels != N_CHANNELS or not s.layout.has_shear:
            raise UserError(f"{s.path}: layout {s.layout.name} cannot be written as "
                            f"ShearSense CSV (needs shearsense-6x6)")
        out = Path(out_dir) / shearsense_csv_name(s)
        check_outputs([out], force)
        labels = np.zeros(s.n_frames, dtype=np.int64)
        for t in selected_trials(s, all_trials):
            key = str(t.key or "")
            if len(key) != 1:
                raise UserError(f"{s.path}: trial {trial_number(t.index)} has no one-letter key "
                                f"({key!r}); the ShearSense CSV labels rows by key")
            labels[t.start_sample:t.end_sample] = ord(key)
        raw, baseline = s.raw(), s.baseline(0)
        times = _frame_times(s)
    shown = naming_the_file(progress)
    return write_through_part(out, lambda tmp: write_shearsense_csv(
        tmp, raw, times, labels, baseline, progress=shown, cancel=cancel))


def shearsense_status_note(path: str | os.PathLike, all_trials: bool) -> str | None:
    """What a ShearSense CSV export with ``all_trials`` cannot keep, in one line (None when
    nothing): its rows are labelled by key, with no status, so redone and discarded
    trials (practice too) read back as ok ones."""
    if not all_trials:
        return None
    with SessionFile(path) as s:
        trials = selected_trials(s, all_trials=True)
    other = Counter(t.status.value for t in trials if not t.ok)
    if not other:
        return None
    kinds = ", ".join(f"{n} {status}" for status, n in sorted(other.items()))
    return (f"{sum(other.values())} of {len(trials)} trials exported are not ok ({kinds}); "
            "the ShearSense CSV has no status, so they read back as ok")


# ---- NPZ per trial -------------------------------------------------------------------
def trial_stack(s: SessionFile, trial: TrialRecord, virtual: bool) -> np.ndarray:
    """(3, T, R, C) float32 normal, shear x, shear y of one trial (zeros for no shear)."""
    a, b = trial.start_sample, trial.end_sample
    return decode(s.layout, s.raw(a, b), s.baseline(a), virtual=virtual).stack()


def export_npz(path: str | os.PathLike, out_dir: str | os.PathLike, all_trials: bool = False,
               grid: str = "auto", progress: ProgressFn | None = None,
               cancel: CancelToken | None = None, force: bool = False,
               done: Callable[[Path], None] | None = None) -> list[Path]:
    """One ``.npz`` per trial: ``x`` (3, T, R, C) plus label, gesture, participant, index.

    ``grid``: ``virtual`` (the paper's 11x11 for the 6x6 sensor), ``physical``, or
    ``auto`` (virtual when the layout has shear, physical for pressure-only grids).
    ``done`` hears of each finished file (they stay when a later one fails).
    """
    if grid not in GRIDS:
        raise UserError(f"unknown grid {grid!r} (choose from {', '.join(GRIDS)})")
    progress = progress or no_progress
    out_dir = Path(out_dir)
    written: list[Path] = []
    with SessionFile(path) as s:
        virtual = grid == "virtual" or (grid == "auto" and s.layout.has_shear)
        trials = selected_trials(s, all_trials)
        names = [out_dir / f"{s.path.stem}_t{t.index:04d}_{_slug(t.gesture)}.npz"
                 for t in trials]
        check_outputs(names, force)
        labels = s.gesture_order()
        meta = s.metadata
        rate = 1.0 / frame_interval(s.column("device_time"), 1.0)
        for i, (t, name) in enumerate(zip(trials, names)):
            if cancel is not None:
                cancel.check()
            x = trial_stack(s, t, virtual)
            gesture = t.gesture
            fields = dict(
                x=x, label=np.int64(labels.index(gesture)), gesture=np.str_(gesture),
                participant=np.str_(meta.get("participant") or ""),
                condition=np.str_(meta.get("condition") or ""),
                index=np.int64(t.index), block=np.int64(user_block(t.block)),
                status=np.str_(t.status.value), key=np.str_(t.key or ""),
                start_sample=np.int64(t.start_sample), end_sample=np.int64(t.end_sample),
                gestures=np.array(labels, dtype=str), session=np.str_(s.path.name),
                channels=np.array(["normal", "shear_x", "shear_y"]), units=np.str_(s.layout.units),
                grid=np.str_("virtual" if virtual else "physical"), rate_hz=np.float64(rate))
            written.append(write_through_part(name, lambda tmp, f=fields: _savez(tmp, f)))
            if done is not None:
                done(written[-1])
            progress(min((i + 1) / max(len(trials), 1), 0.99), f"{name.name}")
    progress(1.0, f"{len(written)} trials")
    return written


def _savez(tmp: Path, fields: dict[str, Any]) -> None:
    with open(tmp, "wb") as fh:
        np.savez(fh, **fields)


# ---- tidy per-trial CSV --------------------------------------------------------------
def trial_row(s: SessionFile, t: TrialRecord, labels: list[str], rate: float) -> dict[str, Any]:
    """One trial's metadata and summary features (physical grid, layout units)."""
    frames = s.raw(t.start_sample, t.end_sample)
    dec = decode(s.layout, frames, s.baseline(t.start_sample), virtual=False)
    if dec.shear_x is not None:
        x, names = dec.stack(), ["normal", "shear_x", "shear_y"]
    else:
        x, names = dec.normal[None], ["normal"]
    metrics = gesture_metrics(x, names, rate)
    meta = s.metadata
    row: dict[str, Any] = {
        "session": s.path.name, "participant": meta.get("participant", ""),
        "condition": meta.get("condition", ""), "protocol": meta.get("protocol", ""),
        "index": t.index, "block": user_block(t.block),
        "gesture": t.gesture,
        "label": labels.index(t.gesture), "key": t.key,
        "status": t.status.value, "reason": t.reason or "",
        "flags": ";".join(t.flags), "start_sample": t.start_sample,
        "end_sample": t.end_sample, "start_time": t.start_time,
        "end_time": t.end_time, "n_frames": len(frames),
        "duration_s": round(len(frames) / rate, 6),
        "peak_normal": float(dec.normal.max()) if len(frames) else 0.0,
    }
    for k in FEATURE_COLUMNS[1:]:
        v = metrics.get(k, "")
        row[k] = round(v, 6) if isinstance(v, float) else v
    return row


def export_csv_trials(path: str | os.PathLike, out_dir: str | os.PathLike,
                      all_trials: bool = False, progress: ProgressFn | None = None,
                      cancel: CancelToken | None = None, force: bool = False) -> Path:
    """``<session>_trials.csv``: one row per trial, metadata then summary features."""
    progress = progress or no_progress
    with SessionFile(path) as s:
        out = Path(out_dir) / f"{s.path.stem}_trials.csv"
        check_outputs([out], force)
        trials = selected_trials(s, all_trials)
        labels = s.gesture_order()
        rate = 1.0 / frame_interval(s.column("device_time"), 1.0)
        stored = [t.to_dict() for t in trials]  # its columns: importers' extra ones too
        extra = sorted({k for t in stored for k in t} - set(TRIAL_COLUMNS) - {"flags"}
                       - set(CHECKED))
        # the trial checks (issue 46) as flat columns, when the session has any
        checked = CSV_COLUMNS if any(k in t for t in stored for k in CHECKED) else []
        rows = []
        for i, (t, d) in enumerate(zip(trials, stored)):
            if cancel is not None:
                cancel.check()
            rows.append({**trial_row(s, t, labels, rate), **{k: d.get(k, "") for k in extra},
                         **(csv_fields(d) if checked else {})})
            progress(min((i + 1) / max(len(trials), 1), 0.99), f"trial {trial_number(t.index)}")

    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=TRIAL_COLUMNS + FEATURE_COLUMNS + checked + extra)
            w.writeheader()
            w.writerows(rows)
    write_through_part(out, write)
    progress(1.0, f"{out.name}: {len(rows)} trials")
    return out


def _frame_times(s: SessionFile) -> np.ndarray:
    """Unix time of each frame on the device's clock, anchored at the first host time.

    For devices without a clock the two are the same; for the simulator or a replay
    running faster than real time this keeps the real spacing of the frames.
    """
    host, dev = s.column("host_time"), s.column("device_time")
    if len(dev) == 0:
        return host
    return host[0] + (dev - dev[0])


def export_session(path: str | os.PathLike, fmt: str, out_dir: str | os.PathLike,
                   all_trials: bool = False, grid: str = "auto",
                   progress: ProgressFn | None = None, cancel: CancelToken | None = None,
                   force: bool = False,
                   done: Callable[[Path], None] | None = None) -> list[Path]:
    """Export one session in ``fmt`` (one of FORMATS) into ``out_dir``; ``done`` hears
    of each finished file (npz writes one per trial: those finished before a failure stay)."""
    if not Path(out_dir).is_dir():
        raise UserError(f"{out_dir}: output folder does not exist")
    if fmt == "npz":
        return export_npz(path, out_dir, all_trials, grid, progress, cancel, force, done)
    if fmt == "shearsense-csv":
        out = export_shearsense_csv(path, out_dir, all_trials, progress, cancel, force)
    elif fmt == "csv-trials":
        out = export_csv_trials(path, out_dir, all_trials, progress, cancel, force)
    elif fmt == "xdf":
        from tactile_studio.storage.exchange.xdf_export import export_xdf

        out = export_xdf(path, out_dir, progress, cancel, force)
    else:
        raise UserError(f"unknown export format {fmt!r} (choose from {', '.join(FORMATS)})")
    if done is not None:
        done(out)
    return [out]
