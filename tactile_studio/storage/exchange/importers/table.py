"""A tolerant reader for the public datasets' CSV tables (CoST, HAART).

A table is some metadata columns (subject, gesture, ...) and a contiguous block of
channel columns. Columns are found by header name (case, spaces and punctuation do not
matter; channels are ``ch1``, ``channel1``, ``1`` ...); a file without a header is read
by position through ``headerless``. Rows with the wrong number of fields or a value that
is not a finite number are skipped and counted by kind, like ShearSense rows.
"""

from __future__ import annotations

import io
import itertools
import os
import re
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.storage.exchange.importers._common import ImportFormatError, norm_name
from tactile_studio.storage.exchange.input_files import InputFile, LineBlocks

_CHANNEL = re.compile(r"^(?:ch|channel|c|taxel|sensor)?(\d+)$")
_BLOCK_BYTES = 4 << 20


@dataclass
class Table:
    path: Path
    meta: dict[str, np.ndarray]       # role -> (N,) str
    channels: np.ndarray              # (N, C) float32
    malformed_by_kind: dict[str, int] = field(default_factory=dict)
    header: list[str] | None = None
    sha256: str = ""  # of the content (decompressed), when read with ``digest``

    @property
    def n_rows(self) -> int:
        return int(self.channels.shape[0])


def _looks_like_header(names: list[str], roles: dict[str, Sequence[str]]) -> bool:
    """A header names a known column (subject, gesture ...) or a channel like ``ch1``."""
    alias = {norm_name(a) for names_ in roles.values() for a in names_}
    keys = [norm_name(n) for n in names]
    return any(k in alias or (_CHANNEL.match(k) and not k.isdigit()) for k in keys)


def _columns(path: Path, what: str, names: list[str], roles: dict[str, Sequence[str]],
             required: Sequence[str]) -> tuple[dict[str, int], int, int]:
    """Role -> column index and the channel block [c0, c1) from header names."""
    found: dict[str, int] = {}
    chans: list[int] = []
    alias = {norm_name(a): role for role, names_ in roles.items() for a in names_}
    for i, name in enumerate(names):
        key = norm_name(name)
        if _CHANNEL.match(key):
            chans.append(i)
        elif key in alias and alias[key] not in found:
            found[alias[key]] = i
    shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
    missing = [r for r in required if r not in found]
    if missing:
        raise ImportFormatError(f"{path}: not a {what} CSV: no {missing[0]} column "
                                f"(header: {shown})")
    if not chans:
        raise ImportFormatError(f"{path}: not a {what} CSV: no channel columns like ch1 "
                                f"(header: {shown})")
    if chans != list(range(chans[0], chans[-1] + 1)):
        raise ImportFormatError(f"{path}: {what} channel columns are not side by side")
    return found, chans[0], chans[-1] + 1


def read_table(path: str | os.PathLike[str], what: str, roles: Mapping[str, Sequence[str]],
               required: Sequence[str], headerless: Callable[[int], list[str] | None],
               n_channels: Sequence[int], progress: ProgressFn | None = None,
               cancel: CancelToken | None = None, digest: bool = False) -> Table:
    """Read a dataset table; see the module docstring. ``what`` names the format; the
    file may be compressed (storage/input_files.InputFile); ``digest``: hash its content."""
    path = Path(path)
    progress = progress or no_progress
    with InputFile(path, f"a {what} CSV", ImportFormatError, digest) as src:
        lines = LineBlocks(src, _BLOCK_BYTES)
        first = lines.first_line()
        text = first.decode("utf-8", errors="replace").lstrip("\ufeff").strip()
        if not text:
            raise ImportFormatError(f"{path}: empty file, not a {what} CSV")
        names = [n.strip().strip('"').strip() for n in text.split(",")]
        if not _looks_like_header(names, roles):
            layout = headerless(len(names))
            if layout is None:
                raise ImportFormatError(f"{path}: not a {what} CSV: no header and "
                                        f"{len(names)} columns per row")
            cols = {role: i for i, role in enumerate(layout) if role}
            c0, c1, header = len(layout), len(names), None
            pending = first
        else:
            cols, c0, c1 = _columns(path, what, names, roles, required)
            header, pending = names, b""
        if c1 - c0 not in n_channels:
            expected = " or ".join(str(n) for n in n_channels)
            raise ImportFormatError(f"{path}: {what} CSV has {c1 - c0} channel columns, "
                                    f"expected {expected}")
        ncols = len(names)
        kinds: Counter = Counter()
        metas: dict[str, list[np.ndarray]] = {r: [] for r in cols}
        chans: list[np.ndarray] = []
        for data in itertools.chain([pending], lines.blocks()):
            if cancel is not None:
                cancel.check()
            rows = _parse_lines(data, ncols, cols, c0, c1, kinds)
            if rows is not None:
                for r, v in rows[0].items():
                    metas[r].append(v)
                chans.append(rows[1])
            progress(min(src.done / max(src.size, 1), 1.0),
                     f"{path.name}: {src.done >> 20} MB read")
        if lines.overlong:
            kinds["long_row"] += lines.overlong
        sha256 = src.sha256()
    if not chans:
        raise ImportFormatError(f"{path}: {what} CSV has no readable rows "
                                f"({sum(kinds.values())} malformed)")
    return Table(path, {r: np.concatenate(v) for r, v in metas.items()},
                 np.concatenate(chans), dict(kinds), header, sha256)


def _parse_lines(data: bytes, ncols: int, cols: dict[str, int], c0: int, c1: int,
                 kinds: Counter) -> tuple[dict[str, np.ndarray], np.ndarray] | None:
    meta_rows: list[list[bytes]] = []
    texts: list[bytes] = []
    idx = list(cols.values())
    tail = c1 == ncols and all(i < c0 for i in idx)
    for line in data.split(b"\n"):
        line = line.strip()
        if not line:
            continue
        n = line.count(b",") + 1
        if n != ncols:
            kinds["short_row" if n < ncols else "long_row"] += 1
            continue
        parts = line.split(b",", c0) if tail else line.split(b",")
        meta_rows.append([parts[i] for i in idx])
        texts.append(parts[c0] if tail else b",".join(parts[c0:c1]))
    if not texts:
        return None
    try:
        values = np.loadtxt(io.BytesIO(b"\n".join(texts)), delimiter=",", quotechar='"',
                            dtype=np.float32, ndmin=2)
        good = np.isfinite(values).all(axis=1)
    except ValueError:
        values, good = _parse_slowly(texts)
    kinds["unparsable"] += int((~good).sum())
    if not good.any():
        return None
    keep = np.flatnonzero(good)
    meta = {role: np.array([meta_rows[k][j].strip().strip(b'"').strip().decode("utf-8", "replace")
                            for k in keep.tolist()], dtype=str)
            for j, role in enumerate(cols)}
    return meta, values[keep]


def _parse_slowly(texts: list[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """Row by row, for a block in which some value is not a number."""
    width = texts[0].count(b",") + 1
    values = np.zeros((len(texts), width), dtype=np.float32)
    good = np.zeros(len(texts), dtype=bool)
    for i, t in enumerate(texts):
        try:
            row = [float(v.strip().strip(b'"')) for v in t.split(b",")]
        except ValueError:
            continue
        values[i] = row
        good[i] = bool(np.isfinite(values[i]).all())
    return values, good
