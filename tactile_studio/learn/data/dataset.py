"""Trial datasets: session files -> decoded, labelled trials grouped by participant.

A :class:`TrialDataset` holds every ``ok`` trial of a set of session files, decoded with
the session's baseline at the trial start to normal / shear-x / shear-y stress on the
physical or virtual grid (pressure-only layouts such as CoST and HAART keep their single
pressure channel). Trials keep their own length: the views in
:mod:`tactile_studio.learn.data.views` turn them into fixed-size model inputs later. Channel
sets (``normal``, ``shear``, ``both``) are selected with :meth:`TrialDataset.select`,
which slices without copying, so one decoded (and cached) dataset serves an ablation.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.choices import CHANNEL_SETS, GRIDS
from tactile_studio.learn.data import cache
from tactile_studio.sensor.decode import decode
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_set import SessionSet, describe_skipped, select_sessions
from tactile_studio.storage.format.trials import TrialRecord, label_order

# Slices into the decoded (normal, shear-x, shear-y) stack; pressure-only data has 1 channel.
_CHANNEL_SLICES = {"normal": slice(0, 1), "shear": slice(1, 3), "both": slice(0, 3)}
_CHANNEL_NAMES = {"normal": ["normal"], "shear": ["shear_x", "shear_y"],
                  "both": ["normal", "shear_x", "shear_y"]}
DEFAULT_RATE_HZ = 43.0


@dataclass
class TrialDataset:
    """Decoded trials. ``trials[i]`` is float32 ``(C, N_i, R, X)`` (N_i varies per trial).

    ``labels[i]`` indexes ``label_names``; ``participants[i]`` is the participant id;
    ``uids[i]`` names the trial stably (session path relative to the data root + ``#`` +
    trial index) so run folders can find it again; ``rates[i]`` is its frame rate (Hz).
    """

    trials: list[np.ndarray]
    labels: np.ndarray
    participants: np.ndarray
    uids: list[str]
    rates: np.ndarray
    label_names: list[str]
    layout: str
    grid: str
    has_shear: bool
    channels: str = "all"
    channel_names: list[str] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)
    fingerprint: str = ""
    skipped: list[dict] = field(default_factory=list)  # resume backups, duplicate sessions
    trial_s: float = 0.0  # the protocol's trial length (s) when the sessions agree, else 0
    # each trial's session ``condition`` (the surface: FLAT, PILLOW, ...; "" when unnamed)
    conditions: np.ndarray = field(default_factory=lambda: np.array([], dtype=str))

    def __len__(self) -> int:
        return len(self.trials)

    @property
    def n_classes(self) -> int:
        return len(self.label_names)

    @property
    def n_channels(self) -> int:
        return int(self.trials[0].shape[0]) if self.trials else len(self.channel_names)

    @property
    def grid_shape(self) -> tuple[int, int]:
        return int(self.trials[0].shape[2]), int(self.trials[0].shape[3])

    def trial_conditions(self) -> np.ndarray:
        """Each trial's condition ("" for all when the sessions name none)."""
        if len(self.conditions) == len(self):
            return self.conditions
        return np.full(len(self), "", dtype=str)

    @property
    def participant_names(self) -> list[str]:
        return sorted(set(self.participants.tolist()))

    def lengths(self) -> np.ndarray:
        return np.array([t.shape[1] for t in self.trials], dtype=np.int64)

    def resolve_channels(self, channels: str | None) -> str:
        """``None`` means every channel the data has: ``both`` with shear, else ``normal``."""
        if channels is None:
            return "both" if self.has_shear else "normal"
        if channels not in CHANNEL_SETS:
            raise UserError(f"unknown channel set {channels!r} "
                            f"(available: {', '.join(CHANNEL_SETS)})")
        if not self.has_shear and channels != "normal":
            raise UserError(f"layout {self.layout} has pressure only, no shear: "
                            f"--channels {channels} is not possible (use normal)")
        return channels

    def select(self, channels: str | None) -> TrialDataset:
        """The same trials restricted to a channel set (views into the decoded arrays)."""
        channels = self.resolve_channels(channels)
        if self.has_shear and self.n_channels != 3:
            raise ValueError(f"select() needs all 3 decoded channels, this dataset has "
                             f"{self.channels}")
        if not self.has_shear:
            return replace(self, channels="normal", channel_names=["pressure"])
        sl = _CHANNEL_SLICES[channels]
        return replace(self, trials=[t[sl] for t in self.trials], channels=channels,
                       channel_names=list(_CHANNEL_NAMES[channels]))

    def subset(self, idx: Sequence[int] | np.ndarray) -> TrialDataset:
        idx = np.asarray(idx, dtype=np.int64)
        return replace(self, trials=[self.trials[i] for i in idx], labels=self.labels[idx],
                       participants=self.participants[idx],
                       uids=[self.uids[i] for i in idx], rates=self.rates[idx],
                       conditions=self.trial_conditions()[idx])

    def summary(self) -> dict:
        counts = np.bincount(self.labels, minlength=self.n_classes)
        lengths = self.lengths()
        return {
            "trials": len(self), "participants": self.participant_names,
            "labels": self.label_names, "per_label": dict(zip(self.label_names, counts.tolist())),
            "layout": self.layout, "grid": self.grid, "grid_shape": list(self.grid_shape),
            "channels": self.channels, "channel_names": self.channel_names,
            "frames_min": int(lengths.min()), "frames_max": int(lengths.max()),
            "trial_s": self.trial_s, "fingerprint": self.fingerprint,
            "skipped": list(self.skipped), "skipped_text": describe_skipped(self.skipped),
        }


def find_session_files(paths: Sequence[str | os.PathLike]) -> tuple[list[Path], Path | None]:
    """Session files from folders (recursive ``*.h5``) and files, without resume
    backups and duplicate sessions (see :mod:`tactile_studio.storage.format.session_set`); also
    the common root folder that trial uids are made relative to."""
    chosen = select_sessions(paths)
    return chosen.files, chosen.root


def _trial_rate(session: SessionFile, trial: TrialRecord, start: int, stop: int) -> float:
    """Frames per second of one trial from the device clock, else the trial's times."""
    n = stop - start
    if n >= 2:
        t = session.column("device_time", start, stop)
        span = float(t[-1] - t[0])
        if span > 0:
            return (n - 1) / span
    span = float(trial.end_time or 0) - float(trial.start_time or 0)
    return n / span if span > 0 and n > 0 else DEFAULT_RATE_HZ


def read_sessions(paths: Sequence[str | os.PathLike], grid: str = "physical",
                  progress: ProgressFn = no_progress,
                  cancel: CancelToken | None = None,
                  chosen: SessionSet | None = None) -> TrialDataset:
    """Decode every ``ok`` trial of the session files (no cache; see :func:`build_dataset`).

    ``chosen``: the files already selected from ``paths`` (:func:`select_sessions`)."""
    if grid not in GRIDS:
        raise UserError(f"unknown grid {grid!r} (available: {', '.join(GRIDS)})")
    chosen = chosen or select_sessions(paths)
    files = chosen.files
    virtual = grid == "virtual"
    layout_name: str | None = None
    first_file: Path | None = None
    trials, gestures, participants, uids, rates, metas = [], [], [], [], [], []
    conditions: list[str] = []
    for k, path in enumerate(files):
        if cancel is not None:
            cancel.check()
        progress(k / len(files), f"reading {path.name}")
        with SessionFile(path) as s:
            if layout_name is None:
                layout_name, first_file = s.layout.name, path
            elif s.layout.name != layout_name:
                raise UserError(f"mismatched layouts: {first_file} is {layout_name}, "
                                f"{path} is {s.layout.name}")
            has_shear = s.layout.has_shear
            meta = s.metadata
            metas.append(meta)
            participant = str(meta.get("participant") or path.stem)
            condition = str(meta.get("condition") or "")
            ok = [t for t in s.trials if t.usable]
            if not ok:
                continue
            raw = s.raw()
            rel = chosen.name(path)
            for t in ok:
                start = max(0, t.start_sample)
                stop = min(t.end_sample, s.n_frames)
                if stop - start < 1:
                    continue
                frames = decode(s.layout, raw[start:stop], s.baseline(start), virtual=virtual)
                stack = frames.stack() if s.layout.has_shear else frames.normal[None]
                trials.append(np.ascontiguousarray(stack, dtype=np.float32))
                gestures.append(t.gesture)
                participants.append(participant)
                conditions.append(condition)
                uids.append(t.uid(rel))
                rates.append(_trial_rate(s, t, start, stop))
    progress(1.0, f"decoded {len(trials)} trials of {len(files)} session(s)")
    if not trials:
        where = ", ".join(str(p) for p in paths)
        raise UserError(f"{where}: no trials with status ok in {len(files)} session file(s)")
    label_names = label_order(metas, gestures, keep_unseen=False)
    lengths = {float((m.get("protocol_spec") or {}).get("trial_s") or 0) for m in metas}
    index = {g: i for i, g in enumerate(label_names)}
    return TrialDataset(
        trials=trials, labels=np.array([index[g] for g in gestures], dtype=np.int64),
        participants=np.array(participants), uids=uids, rates=np.array(rates, dtype=np.float64),
        label_names=label_names, layout=str(layout_name), grid=grid, has_shear=has_shear,
        sources=[str(f) for f in files], skipped=list(chosen.skipped),
        trial_s=lengths.pop() if len(lengths) == 1 else 0.0, conditions=np.array(conditions))


def build_dataset(paths: Sequence[str | os.PathLike], grid: str = "physical",
                  channels: str | None = None, cache_dir: str | os.PathLike | None = None,
                  use_cache: bool = True, progress: ProgressFn = no_progress,
                  cancel: CancelToken | None = None,
                  exclude_flagged: bool = False) -> TrialDataset:
    """The dataset for ``paths``, from the disk cache when its inputs are unchanged.

    The cache holds every decoded channel, so switching ``channels`` reuses it.
    ``exclude_flagged``: trials with quality or model-check flags left out (``train
    --exclude-flagged``); the cache holds them all either way.
    """
    chosen = select_sessions(paths)
    key = cache.dataset_key(chosen.files, grid)
    ds = cache.load(key, cache_dir, TrialDataset) if use_cache else None
    if ds is None:
        ds = read_sessions(paths, grid, progress, cancel, chosen)
        if use_cache:
            try:
                cache.save(ds, key, cache_dir)
            except OSError:
                pass  # a read-only cache folder must not stop training
    else:
        progress(1.0, "dataset from cache")
    ds.fingerprint = key
    ds.skipped = list(chosen.skipped)
    if exclude_flagged:
        ds = _without_flagged(ds, chosen)
    return ds.select(channels)


def _without_flagged(ds: TrialDataset, chosen: SessionSet) -> TrialDataset:
    """``ds`` without the trials stored with flags (their uids, ``rel#index``)."""
    flagged: set[str] = set()
    for path in chosen.files:
        with SessionFile(path) as s:
            flagged.update(t.uid(chosen.name(path)) for t in s.trials if t.flags)
    keep = [i for i, u in enumerate(ds.uids) if u not in flagged]
    if not keep:
        raise UserError("--exclude-flagged: every trial of the data is flagged")
    out = ds.subset(keep) if len(keep) < len(ds) else ds
    out.fingerprint, out.skipped = ds.fingerprint, ds.skipped
    return out


__all__ = ["CHANNEL_SETS", "GRIDS", "TrialDataset", "build_dataset",
           "find_session_files", "read_sessions"]
