"""The old collection software's CSV ("ShearSense CSV"): read fast, write compatibly.

Format (DESIGN.md): a header ``"time (s)","Channel0".."Channel179","touched","label"``,
every value quoted; the first data row is the baseline (time 0, touched 0, label 0);
then one row per frame: Unix time, 180 raw counts, touched 0/1 and the label as an ASCII
code (0 = none, 114 = 'r').

Real files hold ~100k rows, so parsing is vectorised over byte blocks (numpy digit
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
* ``short_row`` / ``long_row`` -- fewer / more than 183 fields otherwise.
"""

from __future__ import annotations

import hashlib
import os
import re
import threading
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.storage.input_files import check_input_file

N_CHANNELS = 180
N_FIELDS = N_CHANNELS + 3  # time, channels, touched, label
MAX_COUNT = 65535
HEADER = ["time (s)", *(f"Channel{i}" for i in range(N_CHANNELS)), "touched", "label"]
MALFORMED_KINDS = ("short_row", "long_row", "merged_number", "unparsable")

_BLOCK_BYTES = 1 << 20
_COMMA, _NL, _DOT, _ZERO = 44, 10, 46, 48
_ALLOWED = np.zeros(256, dtype=bool)
_ALLOWED[48:58] = True
_ALLOWED[[_COMMA, _NL, _DOT]] = True
_U64 = np.uint64


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
    stem = Path(path).stem
    m = re.match(r"[Pp](\d+|[A-Za-z0-9]+?)(?=$|[^A-Za-z0-9]|FLAT|PILLOW|flat|pillow)", stem)
    participant = f"P{m.group(1)}" if m else ""
    conds = re.findall(r"flat|pillow", stem, flags=re.IGNORECASE)
    return participant, (conds[-1].upper() if conds else "")


# ---- reading -------------------------------------------------------------------------
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


def _classify(line: bytes) -> str:
    """Kind of one row that failed the fast path (rare, so plain Python)."""
    parts = line.split(b",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        return "unparsable"
    if any(not (v == v) or v < 0 or v == float("inf") for v in values):
        return "unparsable"
    if any(v > MAX_COUNT for v in values[1:-2]):
        return "merged_number"
    if len(parts) < N_FIELDS:
        return "short_row"
    if len(parts) > N_FIELDS:
        return "long_row"
    return "unparsable"  # right count but e.g. bad label or two dots


# Masks keeping the last L bytes of a little-endian word, and '0' in those bytes.
_KEEP = np.array([0] + [~((1 << (8 * (8 - n))) - 1) & (2**64 - 1) for n in range(1, 9)],
                 dtype=np.uint64)
_ZEROS = _KEEP & _U64(0x3030303030303030)


def _swar_uint(buf: bytes, ends: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """Integer value of the (up to 8) digits before each separator position.

    Loads the 8 bytes before each of ``ends`` as one little-endian word through an
    unaligned byte-strided view, keeps the field's bytes and folds the digits pairwise
    (SWAR). ``ends`` are byte offsets into ``buf``, at least 8.
    """
    words = np.ndarray(shape=(len(buf) - 7,), dtype="<u8", buffer=buf, strides=(1,))
    n = np.minimum(lens, 8)
    x = words[ends - 8]
    x &= _KEEP[n]
    x -= _ZEROS[n]
    t = np.empty_like(x)
    for shift, scale, mask in ((8, 10, 0x00FF00FF00FF00FF), (16, 100, 0x0000FFFF0000FFFF),
                               (32, 10000, 0xFFFFFFFF)):
        np.right_shift(x, _U64(shift), out=t)
        x *= _U64(scale)
        x += t
        x &= _U64(mask)
    return x


_POW10 = 10.0 ** np.arange(16)
FAST_DECIMALS = True  # False: every field with a point goes through float() (the reference)


def _decimals(buf: bytes, flat: np.ndarray, cell: np.ndarray, dots: np.ndarray,
              starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Fields with one decimal point (other than "N.0") into ``flat``; returns the
    cells left for the exact per-field path.

    The digits on each side of the point are read with the word arithmetic, joined
    into one integer m and divided by 10**k (k digits after the point). With m < 2**53
    both are exact doubles and IEEE division rounds correctly, so the result equals
    ``float(text)`` bit for bit. Longer fields (a baseline mean with many decimals)
    and a lone "." (not a number) take the exact path.
    """
    int_len = dots - starts[cell]
    frac_len = ends[cell] - dots - 1
    digits = int_len + frac_len
    fast = (int_len <= 8) & (frac_len <= 8) & (digits <= 15) & (digits > 0)  # not a lone "."
    c, d = cell[fast], dots[fast]
    whole = _swar_uint(buf, d, int_len[fast])
    frac = _swar_uint(buf, ends[c], frac_len[fast])
    k = frac_len[fast]
    mant = whole * (10 ** k).astype(np.uint64) + frac
    flat[c] = mant.astype(np.float64) / _POW10[k]
    return cell[~fast]


def _exact(text: bytes) -> float:
    try:
        return float(text)
    except ValueError:  # e.g. a lone "."
        return np.nan


def _times(b: np.ndarray, starts: np.ndarray, lens: np.ndarray, skip: np.ndarray) -> np.ndarray:
    """The time fields, parsed exactly (numpy's text-to-float cast is correctly rounded)
    so that written files round-trip bit for bit; NaN where unreadable or ``skip``."""
    width = int(lens.max()) if len(lens) else 1
    if width <= 32:
        cols = np.arange(width)
        text = b[np.minimum(starts[:, None] + cols, len(b) - 1)]
        text[cols >= lens[:, None]] = 0
        try:
            out = text.view(f"S{width}").ravel().astype(np.float64)
        except ValueError:  # e.g. a lone "." somewhere: go row by row
            pass
        else:
            out[skip | (lens == 0)] = np.nan
            return out
    buf = b.tobytes()
    return np.array([np.nan if k else _exact(buf[a:a + m])
                     for a, m, k in zip(starts.tolist(), lens.tolist(), skip.tolist())])


def _parse_block(data: bytes, kinds: Counter) -> np.ndarray:
    """Parse complete lines (each ends in newline) into a (rows, 183) float64 array;
    malformed rows are added to ``kinds``.

    Works on field boundaries rather than bytes: one pass finds the separators, then
    every integer field is read with word-parallel digit arithmetic.
    """
    data = data.translate(None, b'" \r')
    buf = bytes(8) + data + bytes(16 - len(data) % 8)
    b = np.frombuffer(buf, dtype=np.uint8)
    ends = np.flatnonzero((b == _COMMA) | (b == _NL))
    if len(ends) == 0:
        return np.empty((0, N_FIELDS))
    starts = np.empty_like(ends)
    starts[0], starts[1:] = 8, ends[:-1] + 1
    lens = ends - starts
    line_last = np.flatnonzero(b[ends] == _NL)           # last field of every line
    nfields = np.diff(line_last, prepend=-1)
    line_start = starts[line_last - nfields + 1]
    line_end = ends[line_last]
    blank = line_end == line_start
    stray_line = np.zeros(len(line_last), dtype=bool)
    if data.translate(None, b"0123456789,.\n"):            # rare: letters, signs, ...
        stray = np.flatnonzero(~_ALLOWED[b[8:8 + len(data)]]) + 8
        stray_line[np.searchsorted(line_end, stray)] = True
    candidate = ~blank & ~stray_line & (nfields == N_FIELDS)
    for i in np.flatnonzero(~blank & ~candidate).tolist():
        kinds[_classify(buf[line_start[i]:line_end[i]])] += 1
    rows = int(candidate.sum())
    if rows == 0:
        return np.empty((0, N_FIELDS))
    if rows < len(line_last):
        keep = np.repeat(candidate, nfields)
        ends, starts, lens = ends[keep], starts[keep], lens[keep]
    n = lens.reshape(rows, N_FIELDS)
    s = starts.reshape(rows, N_FIELDS)
    # "1491.0" (how the old software wrote every count) is the integer before ".0":
    # read it by moving the field's end two bytes back. Other points: see _decimals.
    isdot = b == _DOT
    if FAST_DECIMALS and b"." in data:
        dot0 = (lens >= 2) & isdot[ends - 2] & (b[ends - 1] == _ZERO)
        shift = 2 * dot0
        values = _swar_uint(buf, ends - shift, lens - shift)
        exact = np.flatnonzero(lens - shift > 8)
        isdot[ends[dot0] - 2] = False        # these points are done with
    else:
        dot0 = np.zeros(len(ends), dtype=bool)
        values = _swar_uint(buf, ends, lens)
        exact = np.flatnonzero(lens > 8)
    values = values.astype(np.float64).reshape(rows, N_FIELDS)
    bad = np.zeros(rows, dtype=bool)
    bad[np.flatnonzero(lens == 0) // N_FIELDS] = True
    # Fields the word arithmetic cannot take are read exactly: more than 8 digits
    # (merged or zero-padded) and, on the reference path, any decimal point.
    flat = values.reshape(-1)
    dots = np.flatnonzero(isdot)
    if len(dots):
        cell = np.minimum(np.searchsorted(ends, dots), len(ends) - 1)
        mine = (starts[cell] <= dots) & (ends[cell] > dots)    # dots of kept rows
        cell, dots = cell[mine], dots[mine]
        bad[cell[1:][cell[1:] == cell[:-1]] // N_FIELDS] = True    # two in one field
        bad[cell[dot0[cell]] // N_FIELDS] = True                    # another beside ".0"
        if FAST_DECIMALS:
            slow = _decimals(buf, flat, cell, dots, starts, ends)
            if len(exact):  # rare: long fields; those with a point are handled above
                exact = exact[~np.isin(exact, cell)]
            if len(slow):
                exact = np.union1d(exact, slow)
        else:
            exact = np.union1d(exact, cell)
    exact = exact[exact % N_FIELDS != 0]        # times are all read exactly below
    flat = values.reshape(-1)
    for fi in exact.tolist():
        if not bad[fi // N_FIELDS]:
            flat[fi] = _exact(buf[starts[fi]:ends[fi]])
    values[:, 0] = _times(b, s[:, 0], n[:, 0], bad)
    bad |= np.isnan(values[:, 0])
    bad[exact[np.isnan(flat[exact])] // N_FIELDS] = True
    ok_rows = ~bad
    channels = values[:, 1:N_CHANNELS + 1]
    merged = (channels > MAX_COUNT).any(axis=1) & ok_rows
    label = values[:, -1]
    bad_label = ok_rows & ~merged & ((label != np.rint(label)) | (label > 0x10FFFF))
    kinds["unparsable"] += int((~ok_rows).sum() + bad_label.sum())
    kinds["merged_number"] += int(merged.sum())
    good = ok_rows & ~merged & ~bad_label
    return values[good]


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


class _FileHash:
    """SHA-256 of a file computed by a thread beside the parse: hashlib releases the GIL,
    and hashing the 150 MB of a real file alone takes ~0.2 s."""

    def __init__(self, path: Path) -> None:
        self._path = path
        self._digest = hashlib.sha256()
        self._error: OSError | None = None
        self._thread = threading.Thread(target=self._run, args=(path,), daemon=True)
        self._thread.start()

    def _run(self, path: Path) -> None:
        try:
            with open(path, "rb") as fh:
                for block in iter(lambda: fh.read(_BLOCK_BYTES), b""):
                    self._digest.update(block)
        except OSError as exc:
            self._error = exc

    def result(self) -> str:
        self._thread.join()
        if self._error is not None:
            raise ShearSenseError(f"{self._path}: cannot be read ({self._error.strerror})")
        return self._digest.hexdigest()


def read_shearsense_csv(path: str | os.PathLike, progress: ProgressFn | None = None,
                        cancel: CancelToken | None = None,
                        digest: bool = False) -> ShearSenseData:
    """Read a ShearSense CSV; malformed rows are skipped and counted by kind.

    ``digest``: also hash the file's bytes (``sha256``; imports derive the session id
    from it), in a thread beside the parse."""
    path = Path(path)
    progress = progress or no_progress
    size = check_input_file(path, "ShearSense CSV", ShearSenseError)
    rows = _Rows()
    try:
        fh = open(path, "rb")
    except OSError as exc:
        raise ShearSenseError(f"{path}: cannot be read ({exc.strerror})") from None
    hasher = _FileHash(path) if digest else None
    with fh:
        header = fh.readline(1 << 20)
        _check_header(path, header)
        done = len(header)
        rest = b""
        while True:
            if cancel is not None:
                cancel.check()
            chunk = fh.read(_BLOCK_BYTES)
            data = rest + chunk
            if not chunk:
                if data.strip():
                    rows.add(data + b"\n")
                break
            cut = data.rfind(b"\n") + 1
            rest = data[cut:]
            if cut:
                rows.add(data[:cut])
            done += len(chunk)
            progress(min(done / size, 0.99), f"{path.name}: {done >> 20} of {size >> 20} MB")
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
        baseline_from_row=baseline_from_row, sha256=hasher.result() if hasher else "",
    )


# ---- writing -------------------------------------------------------------------------
_COUNT_TEXT: np.ndarray | None = None


def _count_text() -> np.ndarray:
    """'"v",' for every 16-bit count as fixed-width bytes (built once, ~0.5 MB)."""
    global _COUNT_TEXT
    if _COUNT_TEXT is None:
        _COUNT_TEXT = np.array([f'"{i}",'.encode() for i in range(MAX_COUNT + 1)], dtype="S8")
    return _COUNT_TEXT


def _number_text(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


def _join_rows(parts: list[np.ndarray]) -> bytes:
    """Concatenate fixed-width byte columns per row, dropping the NUL padding."""
    mats = [p.view(np.uint8).reshape(p.shape[0], -1) for p in parts]
    m = np.concatenate(mats, axis=1)
    return m[m != 0].tobytes()


def write_shearsense_csv(path: str | os.PathLike, raw: np.ndarray, times: np.ndarray,
                         labels: np.ndarray, baseline: np.ndarray,
                         touched: np.ndarray | None = None, progress: ProgressFn | None = None,
                         cancel: CancelToken | None = None) -> Path:
    """Write frames in the old software's format (baseline row first).

    ``touched`` defaults to the old rule: any channel below 0.97 x its baseline.
    """
    path = Path(path)
    progress = progress or no_progress
    raw = np.asarray(raw)
    n = raw.shape[0]
    if raw.ndim != 2 or raw.shape[1] != N_CHANNELS:
        raise UserError(f"{path}: ShearSense CSV needs (N, 180) frames, got {raw.shape}")
    if raw.size and (raw.min() < 0 or raw.max() > MAX_COUNT):
        raise UserError(f"{path}: counts outside 0..65535 cannot be written as ShearSense CSV")
    baseline = np.asarray(baseline, dtype=np.float64)
    labels = np.asarray(labels).astype(np.int64)
    if touched is None:
        touched = (raw < 0.97 * baseline).any(axis=1)
    touched = np.asarray(touched).astype(bool)
    table = _count_text()
    with open(path, "wb") as fh:
        fh.write((",".join(f'"{h}"' for h in HEADER) + "\n").encode())
        base = ",".join(f'"{_number_text(v)}"' for v in baseline)
        fh.write(f'"0",{base},"0","0"\n'.encode())
        step = 4096
        for i in range(0, n, step):
            if cancel is not None:
                cancel.check()
            j = min(n, i + step)
            pre = np.array([f'"{float(t)!r}",'.encode() for t in times[i:j]])
            suf = np.array([f'"{int(t)}","{int(lab)}"\n'.encode()
                            for t, lab in zip(touched[i:j], labels[i:j])])
            fh.write(_join_rows([pre, table[raw[i:j].astype(np.int64)], suf]))
            progress(min(j / max(n, 1), 0.99), f"{path.name}: {j} of {n} frames")
    progress(1.0, f"{path.name}: {n} frames")
    return path
