"""``import cost`` and ``import haart``: public touch-gesture datasets to sessions.

One session per subject (per input file for HAART, whose training and test files are
kept apart), one ``ok`` trial per capture. The values are the datasets' own pressure
units; the recorded baseline is zero so exports show them unchanged.

Column assumptions (see docs/import-export.md):

* CoST: ``subject, variant, gesture, frame, ch1..ch64`` (names matched loosely, leading
  spaces ignored). Gestures are numbered 1..14 in CoST's public order or given by name.
  A capture ends when subject, variant or gesture changes or the frame number does not
  increase.
* HAART: ``subject|participant, [substrate], cover, gesture, [Sequence], ch1..ch64``;
  without a header 67 columns are read as subject, cover, gesture + 64 channels and 68 as
  subject, cover, gesture, sequence + 64 channels. Gestures are names (``notouch``,
  ``No touch`` ...) or numbers 1..7 in the order constant, notouch, pat, rub, scratch,
  stroke, tickle. A capture ends when any id column changes; without a Sequence or frame
  column a run of identical ids is cut every 432 frames. 100 channels (the full 10x10)
  are cropped to the 8x8 centre.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.participant_id import PARTICIPANT_RE
from tactile_studio.sensor.layout import COST_8X8, HAART_8X8, Layout
from tactile_studio.storage.exchange.importers._common import (
    ImportedSession,
    check_outputs,
    distinct_paths,
    import_session_id,
    load_protocol_or_none,
    norm_name,
    participant_id,
    refuse_shared_outputs,
    run_jobs,
    slice_progress,
    write_session,
)
from tactile_studio.storage.exchange.importers.table import Table, read_table
from tactile_studio.storage.exchange.input_files import plain_stem
from tactile_studio.storage.format.file_names import shown_name
from tactile_studio.storage.format.trials import TrialRecord

# The corpora's own numbering. CoST's README numbers its gestures alphabetically: 1 grab,
# 2 hit, 3 massage, 4 pat, 5 pinch, 6 poke, 7 press, 8 rub, 9 scratch, 10 slap, 11 squeeze,
# 12 stroke, 13 tap, 14 tickle (its mean pressures agree: 11, a squeeze, presses hardest).
# HAART names its seven gestures in its files; numbers, where a copy has them, follow the
# challenge's alphabetical list.
COST_GESTURES = ("grab", "hit", "massage", "pat", "pinch", "poke", "press", "rub", "scratch",
                 "slap", "squeeze", "stroke", "tap", "tickle")
HAART_GESTURES = ("constant", "notouch", "pat", "rub", "scratch", "stroke", "tickle")
HAART_CAPTURE_FRAMES = 432

_SUBJECT = ("subject", "subj", "subjectno", "subjectnumber", "subjectid", "participant",
            "participantno", "participantnumber", "participantid", "pid")
_GESTURE = ("gesture", "gestureclass", "gesturelabel", "label", "class")
_FRAME = ("frame", "frameno", "framenumber", "frameindex")


@dataclass(frozen=True)
class DatasetSpec:
    name: str                     # "cost" / "haart"
    what: str                     # shown in errors: "CoST" / "HAART"
    layout: Layout
    rate_hz: float
    protocol: str
    numbered: tuple[str, ...]     # gesture names by the dataset's numbering (1-based)
    roles: dict[str, tuple[str, ...]]
    id_roles: tuple[str, ...]     # columns whose change ends a capture (besides subject)
    capture_frames: int | None = None


COST = DatasetSpec(
    "cost", "CoST", COST_8X8, 135.0, "cost14", COST_GESTURES,
    {"subject": _SUBJECT, "variant": ("variant", "var"), "gesture": _GESTURE, "frame": _FRAME},
    ("variant", "gesture"))
HAART = DatasetSpec(
    "haart", "HAART", HAART_8X8, 54.0, "haart7", HAART_GESTURES,
    {"subject": _SUBJECT, "substrate": ("substrate",), "cover": ("cover", "covering"),
     "gesture": _GESTURE, "sequence": ("sequence", "seq", "sequenceno", "sequenceid"),
     "frame": _FRAME},
    ("substrate", "cover", "gesture", "sequence"), HAART_CAPTURE_FRAMES)


def _cost_headerless(n: int) -> list[str] | None:
    return ["subject", "variant", "gesture", "frame"] if n == 68 else None


def _haart_headerless(n: int) -> list[str] | None:
    return {67: ["subject", "cover", "gesture"],
            68: ["subject", "cover", "gesture", "sequence"]}.get(n)


def read_dataset(spec: DatasetSpec, path: str | os.PathLike, progress: ProgressFn | None = None,
                 cancel: CancelToken | None = None, digest: bool = False) -> Table:
    headerless = _cost_headerless if spec is COST else _haart_headerless
    n_channels = (64,) if spec is COST else (64, 100)
    table = read_table(path, spec.what, spec.roles, ("subject", "gesture"), headerless,
                       n_channels, progress, cancel, digest)
    if table.channels.shape[1] == 100:  # full HAART 10x10: keep the 8x8 centre
        n = table.n_rows
        table.channels = np.ascontiguousarray(
            table.channels.reshape(n, 10, 10)[:, 1:9, 1:9].reshape(n, 64))
    return table


def capture_bounds(table: Table, spec: DatasetSpec) -> list[tuple[int, int]]:
    """[start, end) row ranges of the captures, in file order."""
    n = table.n_rows
    cut = np.zeros(n, dtype=bool)
    cut[0] = True
    ids = ["subject", *(r for r in spec.id_roles if r in table.meta)]
    frame_like = table.meta.get("frame")
    if "sequence" in table.meta:
        seq = table.meta["sequence"]
        runs = 1 + int((seq[1:] != seq[:-1]).sum())
        if runs > n // 2 and n > 2:  # it changes on (nearly) every row: a frame counter
            ids.remove("sequence")
            frame_like = seq if frame_like is None else frame_like
    for role in ids:
        v = table.meta[role]
        cut[1:] |= v[1:] != v[:-1]
    if frame_like is not None:
        try:
            f = frame_like.astype(np.float64)
            cut[1:] |= f[1:] <= f[:-1]
        except ValueError:
            pass
    starts = np.flatnonzero(cut).tolist()
    bounds = list(zip(starts, starts[1:] + [n]))
    fixed = spec.capture_frames
    if fixed and frame_like is None and "sequence" not in ids:
        bounds = [(a, min(a + fixed, e)) for s, e in bounds for a in range(s, e, fixed)]
    return bounds


def _gesture_namer(spec: DatasetSpec, protocol: Any):  # noqa: ANN202
    names = list(protocol.gesture_names) if protocol is not None else list(spec.numbered)
    by_norm = {norm_name(n): n for n in names}

    def name_of(value: str) -> str:
        v = value.strip()
        try:
            k = float(v)
        except ValueError:
            return by_norm.get(norm_name(v), v)
        if k == int(k) and 1 <= int(k) <= len(spec.numbered):
            return by_norm.get(norm_name(spec.numbered[int(k) - 1]), spec.numbered[int(k) - 1])
        return v
    return name_of, names


def numbering_line(spec: DatasetSpec) -> str:
    """The label map an import applies, said where it comes from (printed by the CLI and
    shown by the import dialog)."""
    return (f"gesture labels: {spec.what}'s published numbering: "
            + ", ".join(f"{i}={n}" for i, n in enumerate(spec.numbered, 1))
            + "; names in the file are kept as named")


def _participant_of(path: Path, subject: str) -> str:
    """A subject's participant id, which names its session file: a dataset from
    elsewhere may hold any text there (a path, ``..``, control characters), so it must be
    an id as collected ones are, or the import is refused before anything is written."""
    pid = participant_id(subject)
    if not PARTICIPANT_RE.match(pid):
        raise UserError(f"{path}: subject {shown_name(subject)} cannot name a participant: "
                        "an id is letters, digits, '_', '-' or '.', at most 64, starting "
                        "with a letter or digit")
    return pid


def import_dataset(spec: DatasetSpec, path: str | os.PathLike, out_dir: str | os.PathLike,
                   progress: ProgressFn | None = None, cancel: CancelToken | None = None,
                   force: bool = False,
                   on_done: Callable[[Path], None] | None = None) -> list[Path]:
    """Import one CoST or HAART CSV; returns the session files (one per subject)."""
    path, out_dir = Path(path), Path(out_dir)
    progress = progress or no_progress
    if not out_dir.is_dir():
        raise UserError(f"{out_dir}: output folder does not exist")
    table = read_dataset(spec, path, slice_progress(progress, 0.0, 0.5), cancel, digest=True)
    bounds = capture_bounds(table, spec)
    protocol = load_protocol_or_none(spec.protocol)
    name_of, gestures = _gesture_namer(spec, protocol)
    keys = {g.name: g.key for g in protocol.gestures} if protocol is not None else {}
    subjects = table.meta["subject"]
    order = list(dict.fromkeys(subjects[s] for s, _ in bounds))
    prefix = spec.name if spec is COST else f"{spec.name}_{plain_stem(path)}"
    people = {s: _participant_of(path, s) for s in order}
    # two subjects alike ("1" and "1.0" are both P01) never write one file twice
    outputs = dict(zip(order, distinct_paths(
        [out_dir / f"{prefix}_{people[s]}.h5" for s in order])))
    check_outputs(list(outputs.values()), force)
    extra = [r for r in ("variant", "substrate", "cover") if r in table.meta]
    malformed = sum(table.malformed_by_kind.values())
    sha = table.sha256  # of the content: a .csv and its .csv.xz are one source

    def job(subject: str):  # noqa: ANN202
        mine = [(s, e) for s, e in bounds if subjects[s] == subject]
        rows = np.concatenate([np.arange(s, e) for s, e in mine])
        trials, row, reps = [], 0, Counter()
        for i, (s, e) in enumerate(mine):
            gesture = name_of(str(table.meta["gesture"][s]))
            what = tuple(str(table.meta[r][s]) for r in extra) + (gesture,)
            flags = ["short_capture"] if spec.capture_frames and e - s < spec.capture_frames else []
            trials.append(TrialRecord(
                index=i, block=reps[what], gesture=gesture, key=keys.get(gesture, ""),
                start_sample=row, end_sample=row + e - s, start_time=row / spec.rate_hz,
                end_time=(row + e - s) / spec.rate_hz, flags=tuple(flags),
                extra={r: str(table.meta[r][s]) for r in extra},
            ).to_dict())
            reps[what] += 1
            row += e - s
        times = np.arange(len(rows), dtype=np.float64) / spec.rate_hz
        participant = people[subject]
        metadata = {
            "session_id": import_session_id(spec.name, sha, str(subject)),
            "participant": participant, "subject": subject, "condition": "",
            "protocol": spec.protocol if protocol is not None else "",
            "gestures": gestures + sorted({t["gesture"] for t in trials} - set(gestures)),
            "source": f"import:{spec.name}", "original_file": path.name,
            "malformed_rows": malformed,
            **{f"{r}s": sorted({str(v) for v in table.meta[r][rows]}) for r in extra},
        }
        device = {"plugin": "import", "format": spec.name, "file": str(path),
                  "rate_hz": spec.rate_hz}
        session = ImportedSession(
            spec.layout, device, metadata, table.channels[rows], times, trials,
            baseline=np.zeros(spec.layout.n_channels),
            counters={"malformed_by_kind": dict(table.malformed_by_kind)})
        return lambda p: write_session(outputs[subject], session, progress=p, cancel=cancel,
                                       overwrite=force)

    return run_jobs([job(s) for s in order], progress, 0.5, 1.0, on_done)


def import_cost(path: str | os.PathLike, out_dir: str | os.PathLike,
                progress: ProgressFn | None = None, cancel: CancelToken | None = None,
                force: bool = False,
                on_done: Callable[[Path], None] | None = None) -> list[Path]:
    """CoST.csv -> one session per subject (layout cost-8x8, 135 Hz)."""
    return import_dataset(COST, path, out_dir, progress, cancel, force, on_done)


def import_haart(paths: list[str | os.PathLike] | str | os.PathLike, out_dir: str | os.PathLike,
                 progress: ProgressFn | None = None, cancel: CancelToken | None = None,
                 force: bool = False,
                 on_done: Callable[[Path], None] | None = None) -> list[Path]:
    """HAART training.csv / testWITHLABELS.csv -> one session per (file, subject)."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    # a/training.csv and b/training.csv both make haart_training_P01.h5 ...
    refuse_shared_outputs([(Path(p), Path(out_dir) / f"{HAART.name}_{plain_stem(p)}_"
                                        "<participant>.h5") for p in paths])
    progress = progress or no_progress
    out: list[Path] = []
    for i, p in enumerate(paths):
        part = slice_progress(progress, i / len(paths), (i + 1) / len(paths))
        out += import_dataset(HAART, p, out_dir, part, cancel, force, on_done)
    progress(1.0, f"{len(out)} session(s)")
    return out
