"""What every importer shares: writing a finished session atomically, labelled runs,
gesture names from the shipped protocols, progress slices.

Every importer writes its sessions through :func:`import_writer`: the output is claimed
(one writer per file, tactile_studio/file_claims.py: a second import of the same name is
refused in one line) and written under a temporary name that appears at the final name
whole, when the writer closes cleanly, or not at all (cancelled, failed, killed)."""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.file_claims import final_names_in, written_whole
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.sensor.layout import Layout
from tactile_studio.storage.format.aux_signals import AuxSignal
from tactile_studio.storage.format.protocol_file import load_protocol
from tactile_studio.storage.format.segments import pauses
from tactile_studio.storage.format.session_writer import SessionWriter, WriteFailed

WRITE_CHUNK = 8192


class ImportFormatError(UserError):
    """An input file that is not in the format the importer was asked for."""


class NoFramesError(ImportFormatError):
    """An input file that holds no frames: nothing is written for it (a 0-frame session
    would be listed, counted and trained on as if something had been imported)."""


def slice_progress(progress: ProgressFn, lo: float, hi: float) -> ProgressFn:
    """Map a sub-job's 0..1 onto ``lo..hi`` of the whole job's progress. Never reports
    1.0: only the whole job says it is done (a terminal bar ends its line there)."""
    def inner(fraction: float, message: str = "") -> None:
        progress(min(lo + (hi - lo) * min(max(fraction, 0.0), 1.0), 0.999), message)
    return inner


def check_outputs(paths: Sequence[Path], force: bool) -> None:
    """Refuse before any work if an output exists (unless ``force``) or its folder is missing."""
    for p in paths:
        if not p.parent.is_dir():
            raise UserError(f"{p.parent}: output folder does not exist")
        if p.exists() and not force:
            raise UserError(f"{p}: already exists (use --force to overwrite)")


def refuse_shared_outputs(pairs: Sequence[tuple[Path, Path]]) -> None:
    """Refuse, before any work, two inputs that would write one output (``day1/run1.xdf``
    and ``day2/run1.xdf`` both make ``run1.h5``: the second was written over the first,
    and the import said it made two sessions; one file given twice, likewise)."""
    seen: dict[Path, Path] = {}
    for source, out in pairs:
        if out in seen:
            raise UserError(f"{source}: same file name as {seen[out]}; both would be "
                            f"written to {out}")
        seen.setdefault(out, source)


def distinct_paths(paths: Sequence[Path]) -> list[Path]:
    """``paths`` with any repeated one numbered ``-2``, ``-3``...: two sources named
    alike (subjects "1" and "1.0" both P01, two XDF streams both "Mat") would
    otherwise write one file twice, the second over the first."""
    seen: set[Path] = set()
    out = []
    for p in paths:
        q, k = p, 1
        while q in seen:
            k += 1
            q = p.with_name(f"{p.stem}-{k}{p.suffix}")
        seen.add(q)
        out.append(q)
    return out


def labelled_runs(labels: np.ndarray) -> list[tuple[int, int, int]]:
    """(start, end, label) of each run of equal non-zero labels; end is exclusive."""
    labels = np.asarray(labels)
    if labels.size == 0:
        return []
    change = np.flatnonzero(np.diff(labels)) + 1
    starts = np.concatenate(([0], change))
    ends = np.concatenate((change, [labels.size]))
    return [(int(s), int(e), int(labels[s])) for s, e in zip(starts, ends) if labels[s] != 0]


def frame_interval(times: np.ndarray, default: float) -> float:
    """Median positive frame interval of ``times`` (``default`` if there is none)."""
    d = np.diff(np.asarray(times, dtype=np.float64))
    d = d[d > 0]
    return float(np.median(d)) if d.size else default


def norm_name(text: str) -> str:
    """Lower case, letters and digits only: 'No touch' == 'notouch' == 'NO_TOUCH'."""
    return re.sub(r"[^a-z0-9]", "", str(text).lower())


def load_protocol_or_none(name: str) -> Any:
    """The shipped protocol ``name`` or None when it is missing or broken."""
    try:
        return load_protocol(name)
    except UserError:
        return None


def import_session_id(fmt: str, sha256: str, part: str = "") -> str:
    """The deterministic session id of an import: the same source file (and subject,
    for datasets split per subject) imported twice gets the same id, so datasets
    recognise the second copy."""
    from tactile_studio.storage.format.session_file import derived_session_id

    return derived_session_id(f"import:{fmt}:{sha256}:{part}")


def participant_id(subject: str) -> str:
    """Dataset subject -> participant: numbers become P01, P02 ...; other ids are kept."""
    s = str(subject).strip()
    try:
        value = float(s)
    except ValueError:
        return s if s.upper().startswith("P") else f"P{s}"
    return f"P{int(value):02d}" if value == int(value) else f"P{s}"


def pause_gaps(times: np.ndarray, cause: str) -> list[tuple[str, int, float, dict[str, Any]]]:
    """A ``gap`` event (``cause``, ``seconds``) at each of :func:`pauses`' rows."""
    return [("gap", a, float(times[a]),
             {"cause": cause, "seconds": round(float(times[a] - times[a - 1]), 6)})
            for a in pauses(times)]


def import_writer(path: Path, layout: Layout, device_info: dict[str, Any],
                  metadata: dict[str, Any], overwrite: bool = False,
                  aux: list[AuxSignal] | None = None) -> SessionWriter:
    """The one way an importer opens its output: claimed (``FileBusy`` while another
    writer has the name), staged under a temporary name and published whole by
    :func:`close_complete`; an existing file is replaced only with ``overwrite``
    (``--force``). Flushed only at close: the file is hidden until it is complete."""
    return SessionWriter(path, layout, device_info, metadata, flush_interval=1e9, aux=aux,
                         overwrite=overwrite, staged=True)


@dataclass(frozen=True)
class ImportedSession:
    """Everything an importer read for one session, as :func:`write_session` writes it:
    the frames (``raw`` on ``times``) in ``layout``, the device and session metadata, the
    trials; ``baseline`` in force from row 0, ``baselines`` (row, values) from their rows;
    ``events``: (kind, row, time, detail); ``aux``: other instruments' signals."""

    layout: Layout
    device_info: dict[str, Any]
    metadata: dict[str, Any]
    raw: np.ndarray
    times: np.ndarray
    trials: list[dict[str, Any]]
    baseline: np.ndarray | None = None
    counters: dict[str, Any] | None = None
    events: Sequence[tuple[str, int, float, dict[str, Any]]] = ()
    baselines: Sequence[tuple[int, Sequence[float]]] = ()
    aux: list[AuxSignal] | None = None


def write_session(path: Path, session: ImportedSession, progress: ProgressFn | None = None,
                  cancel: CancelToken | None = None, overwrite: bool = False) -> Path:
    """Write one complete session; a cancelled, failed or killed write leaves nothing at
    ``path`` (:func:`import_writer`), and no frames write no file (``NoFramesError``)."""
    progress = progress or no_progress
    s = session
    n = int(s.raw.shape[0])
    if n == 0:
        raise NoFramesError(f"{path.name}: no frames to write, nothing imported")
    writer = import_writer(path, s.layout, s.device_info, s.metadata, overwrite, s.aux)
    try:
        if s.baseline is not None:
            writer.add_baseline(np.asarray(s.baseline, dtype=np.float64), 0)
        for row, values in s.baselines:
            writer.add_baseline(np.asarray(values, dtype=np.float64), row)
        if s.counters:
            writer.set_counters(s.counters)
        append_in_chunks(writer, s.raw, s.times, path.name, progress, cancel)
        for kind, row, t_s, detail in s.events:
            writer.add_event(kind, row, t_s, **detail)
        for t in s.trials:
            writer.add_trial(t)
        close_complete(writer)
    except BaseException:
        _discard(writer, path)
        raise
    progress(1.0, f"{path.name}: {n} frames, {len(s.trials)} trials")
    return path


def close_complete(writer: SessionWriter) -> None:
    """Close an import's writer and raise its write failure: the last frames reach the
    disk only at close (``flush_interval=1e9``), and a failure there (a full disk) would
    otherwise leave a session cut short that says it was imported whole. The staged
    file appears at its name here, whole (``NameTaken`` if the name was taken meanwhile
    and ``--force`` was not given)."""
    writer.close()
    if writer.failed:
        raise WriteFailed(writer.failed, writer.failed_errno)


def naming_the_file(progress: ProgressFn) -> ProgressFn:
    """``progress`` whose messages name the file being written, never its temporary
    (a writer given the temporary's path reports that name)."""
    return lambda fraction, message="": progress(fraction, final_names_in(message))


def write_through_part(path: Path, write: Callable[[Path], Any]) -> Path:
    """``write(tmp)`` to a temporary of this process's own beside ``path``, then publish
    it at ``path`` under its claim (``file_claims.written_whole``): a cancelled, failed or
    killed export leaves no half file (a cut CSV or XDF would pass for a whole one), and
    two exports to one name never share a temporary (the second is refused)."""
    return written_whole(path, write, what="output")


def append_in_chunks(writer: SessionWriter, raw: np.ndarray, times: np.ndarray, name: str,
                     progress: ProgressFn, cancel: CancelToken | None) -> None:
    """Frames (host time = device time, as an import knows them) in chunks of
    ``WRITE_CHUNK``, with progress and a cancel check between chunks."""
    n = int(raw.shape[0])
    for i in range(0, n, WRITE_CHUNK):
        if cancel is not None:
            cancel.check()
        j = min(n, i + WRITE_CHUNK)
        writer.append_frames(raw[i:j], times[i:j], times[i:j])
        progress(min(j / max(n, 1), 0.99), f"{name}: {j} of {n} frames")


def _discard(writer: SessionWriter, path: Path | None = None) -> None:
    """A failed or cancelled import's writer: its staged file goes, nothing appears at
    its name (``path``: unused, kept for callers that name it)."""
    writer.discard()


def run_jobs(jobs: Sequence[Callable[[ProgressFn], Path]], progress: ProgressFn | None,
             lo: float = 0.0, hi: float = 1.0,
             on_done: Callable[[Path], None] | None = None,
             skipped: list[str] | None = None) -> list[Path]:
    """Run per-session jobs in order, each on its share of ``lo..hi``; ``on_done`` hears
    of every finished session (a cancel later keeps them). With a ``skipped`` list, a job
    whose input has no frames adds its one line there and the next job runs."""
    progress = progress or no_progress
    out: list[Path] = []
    k = max(len(jobs), 1)
    for i, job in enumerate(jobs):
        try:
            out.append(job(slice_progress(progress, lo + (hi - lo) * i / k,
                                          lo + (hi - lo) * (i + 1) / k)))
        except NoFramesError as exc:
            if skipped is None:
                raise
            skipped.append(str(exc))
            continue
        if on_done is not None:
            on_done(out[-1])
    progress(hi, f"{len(out)} session(s)")
    return out
