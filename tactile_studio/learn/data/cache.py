"""Disk cache of decoded datasets, so a second run over the same files starts at once.

The key hashes what decides the decoded values: every session file's path, size and
modification time, the grid, and the code that reads and decodes them
(:func:`code_version` of :data:`DATASET_CODE`: the source bytes of the dataset, decode and
layout modules and of the session format package that reads the files, plus the package
version). Any change makes a new key; stale entries are simply never read again. What
caches an import (``benchmarks/real_data.py``) keys on the importer's
:func:`code_version` the same way. Files are plain ``.npz`` loaded with
``allow_pickle=False`` (no unpickling), written to a temporary name and renamed so a
killed run never leaves half a cache entry.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio import __version__, paths
from tactile_studio.file_claims import replace_whole

CACHE_FORMAT = 2  # 2: each trial's session condition


def default_cache_dir() -> Path:
    """The app's cache folder (:func:`tactile_studio.paths.cache_dir`:
    ``$TACTILE_STUDIO_CACHE_DIR``, else the platform's user cache folder)."""
    return paths.cache_dir()


# The code whose output a cached dataset is: a package stands for every file in it.
DATASET_CODE = ("tactile_studio.learn.data.dataset", "tactile_studio.sensor.decode",
                "tactile_studio.sensor.layout", "tactile_studio.storage.format")


def _sources(name: str) -> list[Path]:
    spec = importlib.util.find_spec(name)
    if spec is None or spec.origin is None:
        raise ModuleNotFoundError(f"no source for {name!r}")
    origin = Path(spec.origin)
    if origin.name != "__init__.py":
        return [origin]
    return sorted(p for p in origin.parent.rglob("*")
                  if p.is_file() and "__pycache__" not in p.parts)


def code_version(modules: Sequence[str]) -> str:
    """The version of the code in ``modules`` (dotted names; a package: every file in it,
    data files included): a hash of the package version and their bytes. Read each time,
    not remembered, so an edited importer or decoder is never mistaken for the old one."""
    h = hashlib.sha256(f"{__version__}/{CACHE_FORMAT}".encode())
    for name in modules:
        for path in _sources(name):
            h.update(f"\0{name}:{path.name}\0".encode())
            h.update(path.read_bytes())
    return h.hexdigest()[:16]


def dataset_key(files: list[Path], grid: str) -> str:
    """Hash of (file paths, sizes, mtimes, grid, the reading code's version)."""
    entries = []
    for f in files:
        st = f.stat()
        entries.append([str(f), st.st_size, st.st_mtime_ns])
    blob = json.dumps({"files": entries, "grid": grid,
                       "code": code_version(DATASET_CODE)},
                      sort_keys=True).encode()
    return hashlib.sha256(blob).hexdigest()[:24]


def _path(key: str, cache_dir: str | os.PathLike | None) -> Path:
    return Path(cache_dir or default_cache_dir()) / "datasets" / f"{key}.npz"


def save(ds, key: str, cache_dir: str | os.PathLike | None = None) -> Path:
    """Write ``ds`` (a TrialDataset with every channel) under ``key``."""
    path = _path(key, cache_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    lengths = ds.lengths()
    meta = {"label_names": ds.label_names, "layout": ds.layout, "grid": ds.grid,
            "has_shear": ds.has_shear, "sources": ds.sources, "format": CACHE_FORMAT,
            "trial_s": ds.trial_s}
    def write(tmp: Path) -> None:  # a full disk's cut file goes (file_claims), one per run
        with open(tmp, "wb") as fh:  # a handle: np.savez would add ".npz" to the name
            np.savez(fh, frames=np.concatenate(ds.trials, axis=1),
                     offsets=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
                     labels=ds.labels, participants=ds.participants.astype(str),
                     uids=np.array(ds.uids, dtype=str), rates=ds.rates,
                     conditions=ds.trial_conditions().astype(str),
                     meta=np.array(json.dumps(meta)))

    replace_whole(path, write)  # a temporary of this process's own: builds never mix
    return path


def load(key: str, cache_dir: str | os.PathLike | None = None,
         factory: Callable[..., Any] | None = None) -> Any:
    """The cached dataset for ``key`` built by ``factory`` (the TrialDataset class, passed
    in so this module does not import the dataset module), or None (missing/unreadable)."""
    if factory is None:
        raise TypeError("load() needs the dataset factory (learn.data.dataset.TrialDataset)")
    path = _path(key, cache_dir)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("format") != CACHE_FORMAT:
                return None
            frames, offsets = z["frames"], z["offsets"]
            trials = [np.ascontiguousarray(frames[:, a:b])
                      for a, b in zip(offsets[:-1], offsets[1:])]
            return factory(
                trials=trials, labels=z["labels"].astype(np.int64),
                participants=z["participants"].astype(str), uids=z["uids"].astype(str).tolist(),
                rates=z["rates"].astype(np.float64), label_names=list(meta["label_names"]),
                layout=meta["layout"], grid=meta["grid"], has_shear=bool(meta["has_shear"]),
                sources=list(meta["sources"]), trial_s=float(meta.get("trial_s", 0.0)),
                conditions=z["conditions"].astype(str))
    except (OSError, ValueError, KeyError):
        return None
