"""The fast parse of decimal counts ("1491.0", as the old software wrote them) gives
exactly what the reference path (every decimal through ``float()``) and a plain
per-line Python reading give: frames, times, labels, baseline and malformed counts."""

from __future__ import annotations

import hashlib
import re
from collections import Counter

import numpy as np
import pytest

from tactile_studio.storage.exchange import shearsense as ss
from tactile_studio.storage.exchange.shearsense import (
    HEADER,
    MAX_COUNT,
    N_FIELDS,
    read_shearsense_csv,
)


def _q(values) -> str:
    return ",".join(f'"{v}"' for v in values)


def tricky_csv(path, rows: int = 400, seed: int = 0):
    """Real-format rows (quoted decimals) with every oddity the parser must agree on."""
    rng = np.random.default_rng(seed)
    lines = [_q(HEADER)]
    base = rng.uniform(20000, 40000, 180)
    lines.append(_q(["0.0", *[repr(float(v)) for v in base], "0.0", "0.0"]))
    odd_counts = ["1491.5", "1491.25", ".5", "5.", "0.0", ".0", "0001491.0", "1491",
                  "1491.123456789012345", "65535.0", "65535.4", "12345678.0",
                  "1234567.12345678"]
    for i in range(rows):
        t = 1.69e9 + i / 44.0
        counts = [f"{c}.0" for c in rng.integers(0, 65536, 180)]
        label = "114.0" if 100 <= i < 200 else "0.0"
        touched = "1.0" if label != "0.0" else "0"
        if i % 7 == 3:
            counts[i % 180] = odd_counts[i % len(odd_counts)]
        time_text = "1690000001.0" if i == 5 else repr(t)
        lines.append(_q([time_text, *counts, touched, label]))
        bad = {10: _q([repr(t), "1491.0", "1502.0"]),                         # short
               20: _q([repr(t), *counts, "0", "0", "7.0"]),                     # long
               30: _q([repr(t), *counts[:90], "14911502.0", *counts[91:], "0", "0"]),
               40: _q([repr(t), *counts[:90], "149115020000.0", *counts[91:], "0", "0"]),
               50: _q([repr(t), *counts[:5], "1.2.0", *counts[6:], "0", "0"]),
               60: _q([repr(t), *counts[:5], "1..0", *counts[6:], "0", "0"]),
               70: _q([repr(t), *counts[:5], ".", *counts[6:], "0", "0"]),
               80: _q([repr(t), *counts[:5], "", *counts[6:], "0", "0"]),
               90: _q([repr(t), *counts[:5], "abc", *counts[6:], "0", "0"]),
               95: _q([repr(t), *counts[:5], "-5.0", *counts[6:], "0", "0"]),
               110: _q([repr(t), *counts, "1", "114.5"]),                       # bad label
               120: _q(["1690000000.5.0", *counts, "0", "0"]),                  # two dots in time
               130: ",".join([repr(t), *counts, "0", "114.0"]),                  # unquoted, fine
               140: ""}                                                         # blank line
        if i in bad:
            lines.append(bad[i])
    path.write_text("\n".join(lines) + "\n")
    return path


def python_reading(path):
    """The format's rules, one line at a time in plain Python."""
    rows, kinds = [], Counter()
    for line in path.read_text().splitlines()[1:]:
        line = line.replace('"', "").replace(" ", "").replace("\r", "")
        if not line:
            continue
        parts = line.split(",")
        if not all(re.fullmatch(r"[0-9]*\.?[0-9]*", p) and re.search("[0-9]", p)
                   for p in parts):
            kinds["unparsable"] += 1
            continue
        values = [float(p) for p in parts]
        if any(v > MAX_COUNT for v in values[1:-2]):
            kinds["merged_number"] += 1
        elif len(parts) != N_FIELDS:
            kinds["short_row" if len(parts) < N_FIELDS else "long_row"] += 1
        elif values[-1] != int(values[-1]) or values[-1] > 0x10FFFF:
            kinds["unparsable"] += 1
        else:
            rows.append(values)
    return np.array(rows), dict(kinds)


@pytest.mark.parametrize("block_bytes", [1 << 20, 5000])
def test_fast_decimals_equal_the_reference_and_plain_python(tmp_path, monkeypatch, block_bytes):
    path = tricky_csv(tmp_path / "P01_tricky_FLAT.csv")
    monkeypatch.setattr(ss, "_BLOCK_BYTES", block_bytes)
    fast = read_shearsense_csv(path, digest=True)
    monkeypatch.setattr(ss, "FAST_DECIMALS", False)
    ref = read_shearsense_csv(path, digest=True)
    for name in ("raw", "times", "touched", "labels", "baseline"):
        a, b = getattr(fast, name), getattr(ref, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert fast.malformed_by_kind == ref.malformed_by_kind
    assert fast.baseline_from_row and fast.sha256 == ref.sha256
    assert fast.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()

    rows, kinds = python_reading(path)
    assert fast.malformed_by_kind == kinds
    # the input really holds every kind (odd counts above 65535 add merged rows)
    assert (kinds["short_row"], kinds["long_row"], kinds["unparsable"]) == (1, 1, 8)
    assert kinds["merged_number"] > 2
    assert fast.times.tobytes() == rows[1:, 0].tobytes()  # bit for bit
    np.testing.assert_array_equal(fast.raw, np.rint(rows[1:, 1:181]).astype(np.uint16))
    np.testing.assert_array_equal(fast.labels, rows[1:, -1].astype(np.int64))
    assert fast.baseline.tobytes() == rows[0, 1:181].tobytes()
    assert fast.n_frames == len(rows) - 1 > 350  # the unquoted row is read too


def test_decimal_values_are_read_bit_for_bit():
    """The digits-over-power-of-ten rule equals float() on awkward decimals."""
    rng = np.random.default_rng(1)
    texts = [f"{a}.{b:0{k}d}" for a, b, k in zip(rng.integers(0, 65535, 3000),
                                                   rng.integers(0, 10**6, 3000),
                                                   rng.integers(1, 9, 3000))]
    texts += ["0.1", "0.3", "1491.7", "65534.99999999", "65534.9999999999", ".1", "7."]
    row_fields = ["1690000000.25", *(["1.0"] * 180), "0", "0"]
    lines = []
    for i in range(0, len(texts), 180):
        chunk = texts[i:i + 180]
        fields = list(row_fields)
        fields[1:1 + len(chunk)] = chunk
        lines.append(",".join(fields))
    data = ("\n".join(lines) + "\n").encode()
    kinds: Counter = Counter()
    out = ss._parse_block(data, kinds)
    assert sum(kinds.values()) == 0 and len(out) == len(lines)
    got = out[:, 1:181].ravel()[:len(texts)]
    assert got.tobytes() == np.array([float(t) for t in texts]).tobytes()
