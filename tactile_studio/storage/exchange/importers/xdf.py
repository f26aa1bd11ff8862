"""XDF files (LabRecorder's, or our own export) -> sessions: ``import xdf``.

The file's chunks are checked first (storage/exchange/xdf_scan.py: what it claims against what it
holds, a cut or damaged file imported with what it holds and said), then read with pyxdf,
clock synchronisation and jitter removal on, so every stream is on the file's common
clock. Each tactile stream becomes one session:

* a Tactile Studio frame stream (``desc/tactile_studio`` names its layout, raw content);
* else, a regular numeric stream of type Tactile/Touch/Pressure (or none) whose channel
  count implies a layout (180 -> shearsense-6x6, N*N with N >= 4 -> grid-NxN);
* or the stream named with ``stream`` (and ``layout``, else from its channel count).

Frames keep the file's timestamps as both ``device_time`` and ``host_time`` (metadata
``clock: xdf``). A frame the layout cannot store as it is (NaN, 1e9 or 12.75 as 16-bit
counts) or whose time is not finite or goes back is left out and counted
(``malformed_by_kind``), never cast. Every string stream is read as markers at the frame
nearest each timestamp (exchange/importers/xdf_markers.py: only our own marker streams' JSON
becomes our events, trials and baselines; anything else is a ``marker`` event with its
text). Every other numeric stream (EDA, ECG, ...) is kept as an auxiliary signal
(storage/format/aux_signals.py). Participant and session come from BIDS entities in the file
name (``sub-P01_ses-S1_task-T_run-1``), else ``participant``, else the stream's own.
What the import could not take whole is said in :class:`XdfReport`; the session then
carries metadata ``source_incomplete`` (``info``: cut short).

Two passes, so that a study of many large files never sits in memory at once: every
file's streams are planned from its checked headers first (a file without a tactile
stream, an output that exists, two files making one output: refused before anything is
written), then each file is read with pyxdf and its sessions written before the next is
read (exchange/importers/xdf_session.py builds each session).
"""

from __future__ import annotations

import logging
import os
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.foreign import file_part
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.sensor.layout import Layout
from tactile_studio.storage.exchange.importers._common import (
    ImportFormatError,
    NoFramesError,
    check_outputs,
    distinct_paths,
    refuse_shared_outputs,
    run_jobs,
)
from tactile_studio.storage.exchange.importers.xdf_info import (
    aux_signal,
    bids_entities,
    stream_name,
    tactile_layout,
    text,
)
from tactile_studio.storage.exchange.importers.xdf_session import (
    XdfReport,
    XdfStreamSource,
    session_job,
)
from tactile_studio.storage.exchange.input_files import check_input_file, file_sha256
from tactile_studio.storage.exchange.xdf_scan import XdfScan, checked_file, scan_xdf
from tactile_studio.terminal import shown

# jitter removal fits a line per segment: a pause longer than max(BREAK_S, BREAK_SAMPLES
# sample intervals) starts a new one (pyxdf's default, 500 samples, would smooth a
# reconnect gap of seconds away)
BREAK_S, BREAK_SAMPLES = 0.2, 5


@contextmanager
def _pyxdf_quiet() -> Iterator[None]:
    """pyxdf logs what it finds odd (segments and clock segments differ, ...) and
    numpy warns of its divisions by zero, on stderr: what matters is said in our own
    lines, once (a time that came out NaN is a frame left out and counted)."""
    logs = [logging.getLogger(name) for name in ("pyxdf", "pyxdf.pyxdf")]
    was = [log.disabled for log in logs]
    for log in logs:
        log.disabled = True
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            yield
    finally:
        for log, state in zip(logs, was):
            log.disabled = state


def scan_input(path: Path) -> XdfScan:
    """``path`` checked as an input file and its chunks walked (storage/exchange/xdf_scan.py)."""
    check_input_file(path, "an XDF file", ImportFormatError)
    try:
        return scan_xdf(path)
    except ValueError as exc:
        raise ImportFormatError(f"{path}: {exc}") from None


def load_xdf(scan: XdfScan) -> list[dict[str, Any]]:
    """pyxdf's streams of the scanned file (clocks synchronised, jitter removed), read
    from the chunks that hold what they claim; or one line."""
    import pyxdf

    try:
        with _pyxdf_quiet(), checked_file(scan) as fh:
            streams, _ = pyxdf.load_xdf(fh, synchronize_clocks=True,
                                        dejitter_timestamps=True,
                                        jitter_break_threshold_seconds=BREAK_S,
                                        jitter_break_threshold_samples=BREAK_SAMPLES)
    except MemoryError:
        raise ImportFormatError(f"{scan.path}: its streams do not fit in memory") from None
    except Exception as exc:  # noqa: BLE001 - pyxdf raises anything on a bad file
        why = shown(str(exc).strip() or type(exc).__name__, 120)
        raise ImportFormatError(f"{scan.path}: not a readable XDF file ({why})") from None
    return streams


def _output_name(path: Path, s: dict[str, Any], several: bool) -> str:
    return f"{path.stem}_{file_part(stream_name(s))}.h5" if several else f"{path.stem}.h5"


@dataclass(frozen=True)
class XdfChoice:
    """What the user chose for the files' sessions: the ``participant`` recorded (None:
    the file's own), the tactile ``stream`` by name and the ``layout`` its channels
    follow (None: found from the file's headers)."""

    participant: str | None = None
    stream: str | None = None
    layout: str | None = None


@dataclass
class _FilePlan:
    """One file's sessions, planned from its headers: (stream id, layout, output)."""

    path: Path
    scan: XdfScan
    sessions: list[tuple[int, Layout, Path]]
    meta: dict[str, Any]
    sha: str


def _plan(path: Path, scan: XdfScan, out_dir: Path, choice: XdfChoice, said: XdfReport,
          strict: bool) -> _FilePlan:
    """Which streams of ``path`` become which sessions (module doc), from its headers;
    a tactile stream without samples is listed in ``said.skipped`` (``strict``: raised)."""
    participant, stream, layout = choice.participant, choice.stream, choice.layout
    headers = [{"info": {**d.info, "stream_id": d.id}} for d in scan.streams.values()]
    refused = scan.refused_name(stream) if stream else ""
    if refused:
        raise ImportFormatError(f"{path}: {refused}")
    try:
        tactile = [(h, lay) for h in headers
                   if (lay := tactile_layout(h, stream, layout)) is not None]
    except UserError as exc:  # the named stream or layout does not fit: say which file
        raise ImportFormatError(f"{path}: {exc}") from None
    if not tactile:
        names = ", ".join(f"{shown(stream_name(h))} ({int(text(h['info'], 'channel_count'))}"
                          " ch)" for h in headers) or "none"
        what = f"no stream named '{shown(stream)}'" if stream else "no tactile stream"
        why = "".join(f"; {line}" for line in scan.refused.values())
        raise ImportFormatError(f"{path}: {what} (streams: {names}{why}); name one with "
                                "--stream NAME --layout L")
    meta = bids_entities(path.name)
    if not meta.get("participant") and participant:
        meta["participant"] = participant
    problems = [line.removeprefix(f"{path}: ") for line in scan.problems()]
    if problems:
        meta["source_incomplete"] = "; ".join(problems)
        said.short.extend(scan.problems())
    outs = distinct_paths([out_dir / _output_name(path, h, len(tactile) > 1)
                           for h, _ in tactile])
    sessions = []
    for (h, lay), out in zip(tactile, outs):
        sid = h["info"]["stream_id"]
        if not scan.streams[sid].samples:
            why = "; ".join(problems)
            line = (f"{path}: stream '{shown(stream_name(h))}' has no samples, nothing "
                    "imported" + (f" ({why})" if why else ""))
            if strict:
                raise NoFramesError(line)
            said.skipped.append(line)
            continue
        sessions.append((sid, lay, out))
    return _FilePlan(path, scan, sessions, meta, file_sha256(path))


def _file_jobs(plan: _FilePlan, said: XdfReport, cancel: CancelToken | None,
               force: bool = False) -> list[Callable[[ProgressFn], Path]]:
    """A job per session of ``plan``: the first reads the file (pyxdf), the last lets
    its streams go, so one file's samples are in memory at a time."""
    loaded: dict[str, Any] = {}

    def job(k: int) -> Callable[[ProgressFn], Path]:
        sid, lay, out = plan.sessions[k]

        def run(progress: ProgressFn) -> Path:
            if "streams" not in loaded:
                progress(0.0, f"{plan.path.name}: reading")
                loaded["streams"] = load_xdf(plan.scan)
            streams = loaded["streams"]
            try:
                s = next(x for x in streams if x["info"]["stream_id"] == sid)
                chosen = {i for i, _, _ in plan.sessions}
                strings = [x for x in streams if text(x["info"], "channel_format") == "string"]
                aux = [aux_signal(x) for x in streams
                       if x["info"]["stream_id"] not in chosen
                       and text(x["info"], "channel_format") != "string"
                       and len(x["time_stamps"])]
                names = {stream_name(x) for x in streams if x["info"]["stream_id"] in chosen}
                source = XdfStreamSource(plan.path, plan.sha, plan.meta, s, lay, strings,
                                         aux, names)
                write = session_job(source, out, said, cancel, force)
                return write(progress)
            finally:
                if k == len(plan.sessions) - 1:
                    loaded.clear()

        return run

    return [job(k) for k in range(len(plan.sessions))]


def import_xdf(paths: Sequence[str | os.PathLike], out_dir: str | os.PathLike,
               choice: XdfChoice = XdfChoice(), progress: ProgressFn | None = None,
               cancel: CancelToken | None = None, force: bool = False,
               on_done: Callable[[Path], None] | None = None,
               report: XdfReport | None = None) -> list[Path]:
    """Each tactile stream of each file -> ``<file>[_<stream>].h5`` in ``out_dir``.

    A tactile stream without samples (or none it can store, or timestamps no recording
    has) writes no session: with a ``report`` its line goes to ``report.skipped`` and
    the other streams are imported (``NoFramesError`` when none were); without one
    ``NoFramesError`` is raised. What was imported short of the file (cut, damaged,
    frames left out) goes to ``report.short``, and each such session carries
    ``source_incomplete``."""
    progress = progress or no_progress
    said = report or XdfReport()
    plans: list[_FilePlan] = []
    sources: list[tuple[Path, Path]] = []  # (input, output) of every file
    for k, p in enumerate(paths):
        path = Path(p)
        plan = _plan(path, scan_input(path), Path(out_dir), choice, said,
                     strict=report is None)
        progress(0.1 * (k + 1) / len(paths), f"{path.name}: {len(plan.sessions)} "
                                              "tactile stream(s)")
        sources += [(path, out) for _, _, out in plan.sessions]
        refuse_shared_outputs(sources)
        check_outputs([out for _, _, out in plan.sessions], force)
        plans.append(plan)
    jobs = [job for plan in plans for job in _file_jobs(plan, said, cancel, force)]
    skipped = said.skipped if report is not None else None
    out = run_jobs(jobs, progress, 0.1, 1.0, on_done, skipped)
    if not out and said.skipped:
        raise NoFramesError(said.skipped[0] if len(said.skipped) == 1 else
                            f"nothing imported: none of the {len(said.skipped)} tactile "
                            "streams has frames to store ("
                            + ", ".join(Path(p).name for p in paths) + ")")
    return out
