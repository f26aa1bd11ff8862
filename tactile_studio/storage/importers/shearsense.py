"""``import shearsense``: old collection-software CSVs to session files, one per CSV."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage.importers._common import (
    check_outputs,
    frame_interval,
    import_session_id,
    labelled_runs,
    load_protocol_or_none,
    run_jobs,
    slice_progress,
    write_session,
)
from tactile_studio.storage.session import measured_rate_hz
from tactile_studio.storage.shearsense import (
    ShearSenseData,
    ShearSenseError,
    parse_shearsense_name,
    read_shearsense_csv,
)

PROTOCOL = "shear9"
RATE_HZ = 43.0  # the paper's nominal rate, only used when a file has < 2 frames


def shearsense_trials(data: ShearSenseData, protocol: Any = None) -> list[dict[str, Any]]:
    """One ok trial per labelled run; the label's key names the gesture via ``protocol``.

    ``block`` is the running count of runs: the old CSV does not record blocks.
    """
    dt = frame_interval(data.times, 1.0 / RATE_HZ)
    trials = []
    for i, (s, e, code) in enumerate(labelled_runs(data.labels)):
        key = chr(code) if 0 < code < 0x110000 else str(code)
        g = protocol.gesture_by_key(key) if protocol is not None else None
        trials.append({
            "index": i, "block": i, "gesture": g.name if g is not None else key, "key": key,
            "start_sample": s, "end_sample": e,
            "start_time": float(data.times[s]), "end_time": float(data.times[e - 1]) + dt,
            "status": "ok", "reason": None, "flags": [],
        })
    return trials


def session_name(csv: Path) -> str:
    return f"{csv.stem}.h5"


def import_shearsense_file(csv: str | os.PathLike, out: str | os.PathLike,
                           progress: ProgressFn | None = None,
                           cancel: CancelToken | None = None) -> Path:
    """One ShearSense CSV -> one session file at ``out``."""
    csv, out = Path(csv), Path(out)
    progress = progress or no_progress
    data = read_shearsense_csv(csv, slice_progress(progress, 0.0, 0.7), cancel)
    protocol = load_protocol_or_none(PROTOCOL)
    participant, condition = parse_shearsense_name(csv)
    trials = shearsense_trials(data, protocol)
    gestures = list(protocol.gesture_names) if protocol is not None else []
    gestures += sorted({t["gesture"] for t in trials} - set(gestures))
    metadata = {
        "session_id": import_session_id("shearsense", data.sha256),
        "participant": participant or csv.stem, "condition": condition,
        "protocol": PROTOCOL if protocol is not None else "", "gestures": gestures,
        "source": "import:shearsense", "original_file": csv.name,
        "malformed_rows": data.n_malformed, "baseline_from_row": data.baseline_from_row,
    }
    # the same measured figure `info` shows in its header: frames over the time spanned
    device = {"plugin": "import", "format": "shearsense-csv", "file": str(csv),
              "rate_hz": round(measured_rate_hz(data.times) or RATE_HZ, 3)}
    write_session(out, SHEARSENSE_6X6, device, metadata, data.raw, data.times, data.baseline,
                  trials, counters={"malformed_by_kind": dict(data.malformed_by_kind)},
                  progress=slice_progress(progress, 0.7, 1.0), cancel=cancel)
    progress(1.0, f"{out.name}: {data.n_frames} frames, {len(trials)} trials")
    return out


def import_shearsense(files: Sequence[str | os.PathLike], out_dir: str | os.PathLike,
                      progress: ProgressFn | None = None, cancel: CancelToken | None = None,
                      force: bool = False,
                      on_done: Callable[[Path], None] | None = None) -> list[Path]:
    """Import CSVs in order; on cancel the sessions finished so far stay on disk."""
    out_dir = Path(out_dir)
    for f in files:
        if not Path(f).is_file():
            raise ShearSenseError(f"{f}: no such file" if not Path(f).exists()
                                  else f"{f}: is a folder, not a ShearSense CSV")
    pairs = [(Path(f), out_dir / session_name(Path(f))) for f in files]
    targets = [o for _, o in pairs]
    if len(set(targets)) != len(targets):
        raise _dup_error(pairs)
    check_outputs(targets, force)
    jobs = [lambda p, c=c, o=o: import_shearsense_file(c, o, p, cancel) for c, o in pairs]
    return run_jobs(jobs, progress, on_done=on_done)


def _dup_error(pairs: list[tuple[Path, Path]]) -> UserError:
    seen: dict[Path, Path] = {}
    for c, o in pairs:
        if o in seen:
            return UserError(f"{c}: same file name as {seen[o]}; both would be written to {o}")
        seen[o] = c
    return UserError("duplicate output names")
