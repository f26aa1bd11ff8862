"""Vectorised parsing of ShearSense CSV rows from byte blocks (the reader's hot path).

Works on field boundaries rather than bytes: one pass finds the separators, then every
integer field (up to 8 digits) is read with word-parallel (SWAR) digit arithmetic; short
decimals are joined exactly from their two integer halves; only fields the arithmetic
cannot take go through Python's ``float``, and times through numpy's correctly rounded
text cast, so every value equals ``float(text)`` bit for bit (storage/exchange/shearsense.py).
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from tactile_studio.storage.exchange.shearsense_format import MAX_COUNT, N_CHANNELS, N_FIELDS

_COMMA, _NL, _DOT, _ZERO = 44, 10, 46, 48
_ALLOWED = np.zeros(256, dtype=bool)
_ALLOWED[48:58] = True
_ALLOWED[[_COMMA, _NL, _DOT]] = True
_U64 = np.uint64


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


def parse_block(data: bytes, kinds: Counter, fast_decimals: bool = True) -> np.ndarray:
    """Parse complete lines (each ends in newline) into a (rows, 183) float64 array;
    malformed rows are added to ``kinds``. ``fast_decimals=False`` is the reference path:
    every field with a decimal point goes through ``float()``.

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
    if fast_decimals and b"." in data:
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
    exact = _point_fields(buf, isdot, flat, bad, dot0, exact, starts, ends, fast_decimals)
    exact = exact[exact % N_FIELDS != 0]        # times are all read exactly below
    flat = values.reshape(-1)
    for fi in exact.tolist():
        if not bad[fi // N_FIELDS]:
            flat[fi] = _exact(buf[starts[fi]:ends[fi]])
    values[:, 0] = _times(b, s[:, 0], n[:, 0], bad)
    bad |= np.isnan(values[:, 0])
    bad[exact[np.isnan(flat[exact])] // N_FIELDS] = True
    return _good_rows(values, bad, kinds)


def _point_fields(buf: bytes, isdot: np.ndarray, flat: np.ndarray, bad: np.ndarray,
                  dot0: np.ndarray, exact: np.ndarray, starts: np.ndarray, ends: np.ndarray,
                  fast_decimals: bool) -> np.ndarray:
    """The fields to read exactly, given the decimal points left in kept rows (``isdot``):
    a row with two points in a field, or one beside a ".0" already read, is marked
    ``bad``; other points are read by ``_decimals`` (or all exactly, the reference)."""
    dots = np.flatnonzero(isdot)
    if not len(dots):
        return exact
    cell = np.minimum(np.searchsorted(ends, dots), len(ends) - 1)
    mine = (starts[cell] <= dots) & (ends[cell] > dots)    # dots of kept rows
    cell, dots = cell[mine], dots[mine]
    bad[cell[1:][cell[1:] == cell[:-1]] // N_FIELDS] = True    # two in one field
    bad[cell[dot0[cell]] // N_FIELDS] = True                    # another beside ".0"
    if not fast_decimals:
        return np.union1d(exact, cell)
    slow = _decimals(buf, flat, cell, dots, starts, ends)
    if len(exact):  # rare: long fields; those with a point are handled above
        exact = exact[~np.isin(exact, cell)]
    if len(slow):
        exact = np.union1d(exact, slow)
    return exact


def _good_rows(values: np.ndarray, bad: np.ndarray, kinds: Counter) -> np.ndarray:
    """The rows that parsed, with sane counts and label; the others counted by kind."""
    ok_rows = ~bad
    channels = values[:, 1:N_CHANNELS + 1]
    merged = (channels > MAX_COUNT).any(axis=1) & ok_rows
    label = values[:, -1]
    bad_label = ok_rows & ~merged & ((label != np.rint(label)) | (label > 0x10FFFF))
    kinds["unparsable"] += int((~ok_rows).sum() + bad_label.sum())
    kinds["merged_number"] += int(merged.sum())
    good = ok_rows & ~merged & ~bad_label
    return values[good]
