"""The old collection software's CSV ("ShearSense CSV"): read fast, write compatibly.

Format (DESIGN.md): a header ``"time (s)","Channel0".."Channel179","touched","label"``,
every value quoted; the first data row is the baseline (time 0, touched 0, label 0);
then one row per frame: Unix time, 180 raw counts, touched 0/1 and the label as an ASCII
code (0 = none, 114 = 'r').

This module reads (the block parser is in shearsense_parse.py, the writer in
shearsense_write.py, the layout constants in shearsense_format.py; all importable from
here). Real files hold ~100k rows, so parsing is vectorised over byte blocks (numpy digit
arithmetic instead of per-value ``float()``; see benchmarks/bench_import.py), including
the old software's decimal counts ("1491.0") and other short decimals, exactly as
``float()`` reads them. Only fields the word arithmetic cannot take (more than 15
digits, e.g. a baseline mean) go through Python's ``float``; times are read with numpy's
correctly rounded text cast, so values round-trip exactly. ``FAST_DECIMALS = False``
selects the reference path (every field with a decimal point through ``float``), which
tests compare against.

Malformed rows are skipped and counted by kind:

* ``unparsable`` -- a field that is empty or not a plain non-negative number;
* ``merged_number`` -- a channel value above 65535 (two counts run together);
* ``short_row`` / ``long_row`` -- fewer / more than 183 fields otherwise (a "line" of
  more than 1 MiB too: storage/input_files.LineBlocks).
"""

from __future__ import annotations

import os
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.storage.exchange.input_files import InputFile, LineBlocks, plain_stem
from tactile_studio.storage.exchange.shearsense_format import (
    HEADER,
    MALFORMED_KINDS,
    MAX_COUNT,
    N_CHANNELS,
    N_FIELDS,
)
from tactile_studio.storage.exchange.shearsense_parse import parse_block
from tactile_studio.storage.exchange.shearsense_write import write_shearsense_csv

__all__ = ["HEADER", "MALFORMED_KINDS", "MAX_COUNT", "N_CHANNELS", "N_FIELDS",
           "ShearSenseData", "ShearSenseError", "parse_shearsense_name", "read_shearsense_csv",
           "write_shearsense_csv"]

_BLOCK_BYTES = 1 << 20
FAST_DECIMALS = True  # False: every field with a point goes through float() (the reference)


class ShearSenseError(UserError):
    """A ShearSense CSV that cannot be read at all (missing, empty, wrong header)."""


@dataclass
class ShearSenseData:
    """One parsed ShearSense CSV. ``raw`` (N, 180) uint16; ``times`` Unix seconds."""

    path: Path
    raw: np.ndarray
    times: np.ndarray
    touched: np.ndarray
    labels: np.ndarray
    baseline: np.ndarray
    malformed_by_kind: dict[str, int] = field(default_factory=dict)
    baseline_from_row: bool = True  # False: no baseline row, mean of first 100 frames used
    sha256: str = ""  # of the file's bytes when asked for (imports derive the session id)

    @property
    def n_frames(self) -> int:
        return int(self.raw.shape[0])

    @property
    def n_malformed(self) -> int:
        return int(sum(self.malformed_by_kind.values()))


def parse_shearsense_name(path: str | os.PathLike) -> tuple[str, str]:
    """(participant, condition) from names like ``P07_anything_PILLOW.csv``.

    Participant keeps the file's spelling with an upper-case P ("P07"); condition is
    "FLAT", "PILLOW" or "" when the name has neither. Participant is "" when the name
    does not start with P and a number/id.
    """
    stem = plain_stem(path)
    m = re.match(r"[Pp](\d+|[A-Za-z0-9]+?)(?=$|[^A-Za-z0-9]|FLAT|PILLOW|flat|pillow)", stem)
    participant = f"P{m.group(1)}" if m else ""
    conds = re.findall(r"flat|pillow", stem, flags=re.IGNORECASE)
    return participant, (conds[-1].upper() if conds else "")


# ---- reading -------------------------------------------------------------------------
def _megabytes(done: int, size: int) -> str:
    """"3 of 120 MB"; one decimal under 10 MB, so a 0.8 MB file is not "0 of 0 MB"."""
    digits = 1 if size < 10 << 20 else 0
    return f"{done / (1 << 20):.{digits}f} of {size / (1 << 20):.{digits}f} MB"


def _check_header(path: Path, line: bytes) -> None:
    text = line.decode("utf-8", errors="replace").lstrip("\ufeff").strip()
    names = [n.strip().strip('"').strip() for n in text.split(",")]
    if names and names[-1] == "":
        names = names[:-1]
    if not names or names[0].lower() != "time (s)":
        shown = text[:40] + ("..." if len(text) > 40 else "")
        raise ShearSenseError(f"{path}: not a ShearSense CSV (header starts {shown!r}, "
                              f"expected \"time (s)\",\"Channel0\",...)")
    if [n.lower() for n in names] != [h.lower() for h in HEADER]:
        raise ShearSenseError(f"{path}: not a ShearSense CSV (header has {len(names)} columns, "
                              f"expected time, Channel0..Channel179, touched, label)")


def _parse_block(data: bytes, kinds: Counter) -> np.ndarray:
    """shearsense_parse.parse_block on this module's ``FAST_DECIMALS`` setting."""
    return parse_block(data, kinds, fast_decimals=FAST_DECIMALS)


class _Rows:
    """Parsed rows collected block by block in their compact final types."""

    def __init__(self) -> None:
        self.raw: list[np.ndarray] = []
        self.times: list[np.ndarray] = []
        self.touched: list[np.ndarray] = []
        self.labels: list[np.ndarray] = []
        self.first: np.ndarray | None = None  # first good row, exact (baseline candidate)
        self.kinds: Counter = Counter()

    def add(self, data: bytes) -> None:
        v = _parse_block(data, self.kinds)
        if not len(v):
            return
        if self.first is None:
            self.first = v[0].copy()
        self.raw.append(np.rint(v[:, 1:N_CHANNELS + 1]).astype(np.uint16))
        self.times.append(v[:, 0].copy())
        self.touched.append(v[:, N_CHANNELS + 1] != 0)
        self.labels.append(v[:, N_CHANNELS + 2].astype(np.int64))

    def joined(self, name: str, empty: np.ndarray) -> np.ndarray:
        parts = getattr(self, name)
        return np.concatenate(parts) if parts else empty


def read_shearsense_csv(path: str | os.PathLike, progress: ProgressFn | None = None,
                        cancel: CancelToken | None = None,
                        digest: bool = False) -> ShearSenseData:
    """Read a ShearSense CSV; malformed rows are skipped and counted by kind.

    ``path`` may be compressed (``.csv.xz``, ``.csv.gz``, ``.csv.bz2``: read as it is
    decompressed, storage/input_files.InputFile). ``digest``: also hash the content
    (``sha256``; imports derive the session id from it)."""
    path = Path(path)
    progress = progress or no_progress
    rows = _Rows()
    with InputFile(path, "a ShearSense CSV", ShearSenseError, digest) as src:
        lines = LineBlocks(src, _BLOCK_BYTES)
        _check_header(path, lines.first_line())
        for data in lines.blocks():
            if cancel is not None:
                cancel.check()
            rows.add(data if data.endswith(b"\n") else data + b"\n")
            progress(min(src.done / src.size, 0.99), f"{path.name}: "
                     f"{_megabytes(src.done, src.size)}")
        if lines.overlong:
            rows.kinds["long_row"] += lines.overlong
        sha256 = src.sha256()
    raw = rows.joined("raw", np.empty((0, N_CHANNELS), dtype=np.uint16))
    times = rows.joined("times", np.empty(0))
    touched = rows.joined("touched", np.empty(0, dtype=bool))
    labels = rows.joined("labels", np.empty(0, dtype=np.int64))
    first = rows.first
    if first is None:
        raise ShearSenseError(f"{path}: ShearSense CSV has no readable rows"
                              f" ({sum(rows.kinds.values())} malformed)")
    baseline_from_row = bool(first[0] == 0 and first[-1] == 0)
    if baseline_from_row:
        baseline = first[1:N_CHANNELS + 1].copy()
        raw, times, touched, labels = raw[1:], times[1:], touched[1:], labels[1:]
    else:
        baseline = raw[:100].mean(axis=0)
    progress(1.0, f"{path.name}: {len(raw)} frames")
    return ShearSenseData(
        path=path, raw=raw, times=times, touched=touched, labels=labels,
        baseline=baseline.astype(np.float64),
        malformed_by_kind={k: int(rows.kinds[k]) for k in MALFORMED_KINDS if rows.kinds[k]},
        baseline_from_row=baseline_from_row, sha256=sha256,
    )
