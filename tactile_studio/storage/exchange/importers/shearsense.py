"""``import shearsense``: old collection-software CSVs to session files, one per CSV."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.paths import make_out_dir
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage.exchange.importers._common import (
    ImportedSession,
    NoFramesError,
    check_outputs,
    frame_interval,
    import_session_id,
    labelled_runs,
    load_protocol_or_none,
    pause_gaps,
    refuse_shared_outputs,
    run_jobs,
    slice_progress,
    write_session,
)
from tactile_studio.storage.exchange.importers.maps import (
    gesture_key_map,
    gesture_map_source,
    normalise_participant,
    participant_map,
)
from tactile_studio.storage.exchange.input_files import plain_stem
from tactile_studio.storage.exchange.shearsense import (
    ShearSenseData,
    ShearSenseError,
    parse_shearsense_name,
    read_shearsense_csv,
)
from tactile_studio.storage.format.protocol_file import list_protocols
from tactile_studio.storage.format.segments import segmented_rate_hz
from tactile_studio.storage.format.trials import TrialRecord

PROTOCOL = "shear9"
RATE_HZ = 43.0  # the paper's nominal rate, only used when a file has < 2 frames


@dataclass
class ShearSenseImport:
    """What an import did, for the summary the user reads: the participant each file
    name became, files without a labelled run, and keys no gesture name was given for."""

    participants: dict[str, str] = field(default_factory=dict)  # as spelled -> id used
    empty_files: list[str] = field(default_factory=list)
    no_frames: list[str] = field(default_factory=list)  # one line per file not imported
    unmapped_keys: dict[str, list[str]] = field(default_factory=dict)  # key -> files
    key_names: dict[str, str] = field(default_factory=dict)  # the gesture map used
    custom_keys: bool = False  # key_names came from --gestures, not shear9
    named_keys: set[str] = field(default_factory=set)  # keys seen that the map named
    key_source: str = ""  # where a given map came from ("protocol cost14", "file x.toml")

    def lines(self) -> list[str]:
        """The summary as printed by ``import shearsense``: always the key map applied and
        where it came from, "guessed" when none was given (shear9's names may be wrong)."""
        out = []
        shown = ", ".join(f"{k}={v}" for k, v in self.key_names.items())
        if self.custom_keys:
            out.append(f"gesture keys (from {self.key_source or 'the map given'}): {shown}")
        elif self.key_names:
            out.append(f"gesture keys guessed (no map given, {PROTOCOL}'s keys assumed): "
                       f"{shown}")
        if self.participants:
            shown = ", ".join(f"{k} -> {v}" if k != v else v
                              for k, v in sorted(self.participants.items()))
            out.append(f"participants: {shown}")
        out += self.no_frames
        if self.empty_files:
            out.append(f"{len(self.empty_files)} file(s) with no labelled runs (0 trials): "
                       + ", ".join(self.empty_files))
        for key, files in sorted(self.unmapped_keys.items()):
            out.append(f"key {key!r} (code {ord(key) if len(key) == 1 else key}) has no "
                       f"gesture name, trials keep the key: {len(files)} file(s) "
                       f"({', '.join(files[:3])}{', ...' if len(files) > 3 else ''})")
        if self.unmapped_keys and not self.custom_keys:
            # a study with more gestures than shear9 (cost14 shares 7 of its letters) would
            # otherwise be silently half-named with shear9's names
            shared = ", ".join(sorted(self.named_keys))
            out.append(f"the files use {len(self.unmapped_keys) + len(self.named_keys)} "
                       f"gesture keys, {PROTOCOL}'s map names {len(self.named_keys)}"
                       + (f" ({shared}), perhaps wrongly" if shared else "")
                       + ": if they were recorded with another protocol, give its keys "
                       f"with --gestures ({', '.join(list_protocols())}, a .toml file or "
                       "key=Name,...)")
        return out


def default_key_names(protocol: Any = None) -> dict[str, str]:
    """The shear9 protocol's key -> gesture name map (empty if it cannot be loaded)."""
    protocol = protocol if protocol is not None else load_protocol_or_none(PROTOCOL)
    return {g.key: g.name for g in protocol.gestures} if protocol is not None else {}


def _key_text(code: int) -> str:
    return chr(code) if 0 < code < 0x110000 else str(code)


def shearsense_trials(data: ShearSenseData, protocol: Any = None,
                      key_names: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """One ok trial per labelled run; ``key_names`` (default: ``protocol``'s keys) names
    the gesture of the run's key; a key without a name keeps the key as its gesture.

    ``block`` is the running count of runs: the old CSV does not record blocks.
    """
    if key_names is None:
        key_names = default_key_names(protocol) if protocol is not None else {}
    dt = frame_interval(data.times, 1.0 / RATE_HZ)
    trials = []
    for i, (s, e, code) in enumerate(labelled_runs(data.labels)):
        key = _key_text(code)
        name = key_names.get(key) or key_names.get(key.lower())
        trials.append(TrialRecord(
            index=i, block=i, gesture=name or key, key=key, start_sample=s, end_sample=e,
            start_time=float(data.times[s]), end_time=float(data.times[e - 1]) + dt,
        ).to_dict())
    return trials


def session_name(csv: Path) -> str:
    """``P08_x_FLAT.csv`` and ``P08_x_FLAT.csv.xz`` alike -> ``P08_x_FLAT.h5``."""
    return f"{plain_stem(csv)}.h5"


def file_participant(csv: Path, participant_map: dict[str, str] | None = None
                     ) -> tuple[str, str]:
    """(as spelled in the file name, participant id): normalised (case, zero padding)
    and then mapped; the file's stem when its name names no participant."""
    spelled = parse_shearsense_name(csv)[0]
    base = normalise_participant(spelled) if spelled else plain_stem(csv)
    pid = (participant_map or {}).get(normalise_participant(base), base)
    return spelled or plain_stem(csv), pid


def import_shearsense_file(csv: str | os.PathLike, out: str | os.PathLike,
                           progress: ProgressFn | None = None,
                           cancel: CancelToken | None = None,
                           key_names: dict[str, str] | None = None,
                           participant_map: dict[str, str] | None = None,
                           report: ShearSenseImport | None = None,
                           force: bool = False) -> Path:
    """One ShearSense CSV -> one session file at ``out`` (an existing one is replaced
    only with ``force``).

    ``key_names``: key -> gesture name (default: the shear9 protocol's);
    ``participant_map``: normalised file-name participant -> id; ``report`` collects
    what the summary prints."""
    csv, out = Path(csv), Path(out)
    progress = progress or no_progress
    data = read_shearsense_csv(csv, slice_progress(progress, 0.0, 0.7), cancel, digest=True)
    if data.n_frames == 0:  # the header and the baseline row only: no 0-frame session
        raise NoFramesError(f"{csv}: no frames after the baseline row, nothing imported")
    protocol = load_protocol_or_none(PROTOCOL)
    custom = key_names is not None
    names = dict(key_names) if custom else default_key_names(protocol)
    spelled, participant = file_participant(csv, participant_map)
    condition = parse_shearsense_name(csv)[1]
    trials = shearsense_trials(data, protocol, names)
    unmapped = sorted({t["key"] for t in trials if t["gesture"] == t["key"]
                       and t["key"] not in names and t["key"].lower() not in names})
    if custom:
        gestures = list(dict.fromkeys(names.values()))
    else:
        gestures = list(protocol.gesture_names) if protocol is not None else []
    gestures += sorted({t["gesture"] for t in trials} - set(gestures))
    metadata = {
        "session_id": import_session_id("shearsense", data.sha256),
        "participant": participant, "participant_as_named": spelled, "condition": condition,
        "protocol": PROTOCOL if protocol is not None and not custom else "",
        "gestures": gestures, "gesture_keys": names, "unmapped_keys": unmapped,
        "source": "import:shearsense", "original_file": csv.name,
        "malformed_rows": data.n_malformed, "baseline_from_row": data.baseline_from_row,
    }
    # a pause in the times (the old software's link stalled) is a gap, no frame time;
    # the same measured figure `info` shows in its header: frames over the time spanned
    gaps = pause_gaps(data.times, "import")
    device = {"plugin": "import", "format": "shearsense-csv", "file": str(csv),
              "rate_hz": round(segmented_rate_hz(data.times, [g[1] for g in gaps])
                               or RATE_HZ, 3)}
    session = ImportedSession(SHEARSENSE_6X6, device, metadata, data.raw, data.times, trials,
                              baseline=data.baseline, events=gaps,
                              counters={"malformed_by_kind": dict(data.malformed_by_kind)})
    write_session(out, session, progress=slice_progress(progress, 0.7, 1.0), cancel=cancel,
                  overwrite=force)
    if report is not None:
        report.key_names, report.custom_keys = names, custom
        report.participants[spelled] = participant
        if not trials:
            report.empty_files.append(csv.name)
        for key in unmapped:
            report.unmapped_keys.setdefault(key, []).append(csv.name)
        report.named_keys |= {t["key"] for t in trials} - set(unmapped)
    progress(1.0, f"{out.name}: {data.n_frames} frames, {len(trials)} trials")
    return out


def import_shearsense(files: Sequence[str | os.PathLike], out_dir: str | os.PathLike,
                      progress: ProgressFn | None = None, cancel: CancelToken | None = None,
                      force: bool = False,
                      on_done: Callable[[Path], None] | None = None,
                      key_names: dict[str, str] | None = None,
                      participant_map: dict[str, str] | None = None,
                      report: ShearSenseImport | None = None) -> list[Path]:
    """Import CSVs in order; on cancel the sessions finished so far stay on disk. A CSV
    without frames writes nothing: with a ``report`` it is listed in ``report.no_frames``
    and the others are imported, without one its ``NoFramesError`` is raised.
    See :func:`import_shearsense_file` for ``key_names``, ``participant_map``, ``report``."""
    out_dir = Path(out_dir)
    for f in files:
        if not Path(f).is_file():
            raise ShearSenseError(f"{f}: no such file" if not Path(f).exists()
                                  else f"{f}: is a folder, not a ShearSense CSV")
    pairs = [(Path(f), out_dir / session_name(Path(f))) for f in files]
    targets = [o for _, o in pairs]
    refuse_shared_outputs(pairs)
    check_outputs(targets, force)
    jobs = [lambda p, c=c, o=o: import_shearsense_file(c, o, p, cancel, key_names,
                                                       participant_map, report, force)
            for c, o in pairs]
    return run_jobs(jobs, progress, on_done=on_done,
                    skipped=report.no_frames if report is not None else None)


def import_shearsense_study(files: Sequence[str | os.PathLike], out_dir: str | os.PathLike,
                            gestures: str | None = None, participants: str | None = None,
                            progress: ProgressFn | None = None,
                            cancel: CancelToken | None = None, force: bool = False,
                            on_done: Callable[[Path], None] | None = None,
                            ) -> tuple[list[Path], ShearSenseImport]:
    """What ``import shearsense`` does, for the CLI and the research workspace alike: the
    maps as the user typed them (``--gestures``, ``--participant-map``; empty: the
    defaults), the output folder made, every file imported, and the summary to show.
    Files without frames are listed in the summary (``report.no_frames``); when no file
    had any, ``NoFramesError`` says so and nothing is written."""
    keys = gesture_key_map(gestures) if gestures else None
    people = participant_map(participants) if participants else None
    make_out_dir(out_dir)
    report = ShearSenseImport(key_source=gesture_map_source(gestures) if gestures else "")
    paths = import_shearsense(files, out_dir, progress, cancel, force, on_done,
                              key_names=keys, participant_map=people, report=report)
    if not paths and report.no_frames:
        if len(report.no_frames) == 1:
            raise NoFramesError(report.no_frames[0])
        raise NoFramesError(f"nothing imported: none of the {len(report.no_frames)} files "
                            "has frames after its baseline row "
                            f"({', '.join(Path(f).name for f in files)})")
    return paths, report
