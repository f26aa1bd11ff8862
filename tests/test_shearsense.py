"""ShearSense CSV reading and writing: exact values, malformed rows, errors, speed paths.

Budget: ~3 s (small hand-written files; one hypothesis test with few examples).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_studio.errors import Cancelled, UserError
from tactile_studio.jobs import CancelToken
from tactile_studio.storage.exchange import shearsense as ss
from tactile_studio.storage.exchange.shearsense import (
    ShearSenseError,
    parse_shearsense_name,
    read_shearsense_csv,
    write_shearsense_csv,
)

HEADER = ",".join(f'"{h}"' for h in ["time (s)", *(f"Channel{i}" for i in range(180)),
                                      "touched", "label"])


def q(values) -> str:
    return ",".join(f'"{v}"' for v in values)


def make_file(tmp_path, n=40, seed=0, name="P03_demo_FLAT.csv", newline="\n"):
    """A realistic file: float baseline row, frames with two labelled runs, and one row
    of every malformed kind between them. Returns (path, expected arrays, kinds)."""
    rng = np.random.default_rng(seed)
    raw = rng.integers(0, 65536, size=(n, 180))
    raw[0, :5] = [0, 7, 65535, 10, 100]            # edge values, 1 to 5 digits
    times = 1690000000.0 + np.arange(n) / 43.0 + rng.random(n) * 1e-3
    labels = np.zeros(n, dtype=int)
    labels[5:12] = ord("r")
    labels[20:30] = ord("p")
    touched = (labels > 0).astype(int)
    baseline = rng.random(180) * 1000 + 30000     # a mean: decimals
    good = [q([0, *[repr(float(b)) for b in baseline], 0, 0])]
    for i in range(n):
        good.append(q([repr(float(times[i])), *raw[i], touched[i], labels[i]]))
    chans = [str(v) for v in range(180)]
    bad = {
        "short_row": [q([1690000000.5, 3, 114]),                      # 3 fields only
                      q([1690000000.5, *chans[:178], 0]),             # 180 fields
                      q([1690000000.5, *chans[:179], 0]),             # 181 fields
                      q([1690000000.5, *chans[:179], 0, 0])],         # 182 fields
        "long_row": [q([1690000000.5, *chans, 0, 0, 0])],
        "merged_number": [q([1690000000.5, *chans[:179], "3456734512", 0, 0]),
                          q([1690000000.5, *chans[:178], "4567812345", 0, 0]),  # 182 fields
                          q([1690000000.5, *chans[:179], "65536", 0, 0])],
        "unparsable": [q([1690000000.5, *chans[:179], "12a", 0, 0]),
                       q([1690000000.5, *chans[:179], "", 0, 0]),
                       q([1690000000.5, *chans[:179], "1.2.3", 0, 0]),
                       q(["x", *chans, 0, 0]),
                       q([".", *chans, 0, 0]),
                       q([1690000000.5, *chans[:179], "-5", 0, 0])],
    }
    lines = [HEADER, good[0]]
    malformed = [row for rows in bad.values() for row in rows]
    for i, row in enumerate(good[1:]):
        lines.append(row)
        if i % 3 == 1 and malformed:
            lines.append(malformed.pop())
    lines += malformed + [""]   # leftovers at the end, then a blank line
    path = tmp_path / name
    path.write_bytes(newline.join(lines).encode() + newline.encode())
    kinds = {k: len(v) for k, v in bad.items()}
    return path, dict(raw=raw, times=times, labels=labels, touched=touched > 0,
                      baseline=baseline), kinds


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_reads_values_exactly_and_counts_malformed_rows_by_kind(tmp_path, newline):
    path, exp, kinds = make_file(tmp_path, newline=newline)
    d = read_shearsense_csv(path)
    assert d.malformed_by_kind == kinds
    assert d.n_malformed == sum(kinds.values())
    assert d.baseline_from_row
    assert d.raw.dtype == np.uint16 and d.raw.shape == exp["raw"].shape
    np.testing.assert_array_equal(d.raw, exp["raw"])
    np.testing.assert_array_equal(d.times, exp["times"])        # bit-exact
    np.testing.assert_array_equal(d.labels, exp["labels"])
    np.testing.assert_array_equal(d.touched, exp["touched"])
    np.testing.assert_array_equal(d.baseline, exp["baseline"])  # bit-exact decimals


def test_blocks_smaller_than_a_row_still_parse_identically(tmp_path, monkeypatch):
    path, exp, kinds = make_file(tmp_path, n=25, seed=3)
    monkeypatch.setattr(ss, "_BLOCK_BYTES", 1000)   # rows (~1.3 kB) straddle every block
    d = read_shearsense_csv(path)
    assert d.malformed_by_kind == kinds
    np.testing.assert_array_equal(d.raw, exp["raw"])
    np.testing.assert_array_equal(d.times, exp["times"])


def test_write_then_read_round_trips_and_file_is_byte_stable(tmp_path):
    rng = np.random.default_rng(5)
    raw = rng.integers(0, 65536, size=(300, 180)).astype(np.uint16)
    times = 1.7e9 + np.cumsum(rng.random(300) * 0.05)
    labels = np.where(rng.random(300) < 0.3, ord("t"), 0)
    baseline = raw[:50].mean(axis=0)
    a = write_shearsense_csv(tmp_path / "a.csv", raw, times, labels, baseline)
    d = read_shearsense_csv(a)
    np.testing.assert_array_equal(d.raw, raw)
    np.testing.assert_array_equal(d.times, times)
    np.testing.assert_array_equal(d.labels, labels)
    np.testing.assert_array_equal(d.baseline, baseline)
    np.testing.assert_array_equal(d.touched, (raw < 0.97 * baseline).any(axis=1))
    b = write_shearsense_csv(tmp_path / "b.csv", d.raw, d.times, d.labels, d.baseline, d.touched)
    assert a.read_bytes() == b.read_bytes()
    first = a.read_text().splitlines()
    assert first[0] == HEADER and first[1].startswith('"0","') and first[1].endswith('"0","0"')


def test_without_a_baseline_row_the_first_100_frames_are_the_baseline(tmp_path):
    raw = np.arange(150 * 180).reshape(150, 180) % 60000
    lines = [HEADER] + [q([1690000000 + i, *raw[i], 0, 0]) for i in range(150)]
    path = tmp_path / "nobase.csv"
    path.write_text("\n".join(lines))                 # no final newline either
    d = read_shearsense_csv(path)
    assert not d.baseline_from_row and d.n_frames == 150
    np.testing.assert_allclose(d.baseline, raw[:100].mean(axis=0))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 6))
def test_parser_agrees_with_plain_python_on_any_counts(seed, n_rows):
    """Integer fields of every length, zero-padded or not, parse like int()."""
    rng = np.random.default_rng(seed)
    digits = rng.integers(1, 9, size=(n_rows, 180))
    rows = rng.integers(0, 10 ** digits)                  # 1..8 digit numbers
    rows[rng.random(n_rows) < 0.5] %= 65536               # about half the rows valid
    pad = rng.integers(0, 4, size=(n_rows, 180))
    text = [HEADER, q([0, *([1] * 180), 0, 0])]
    for i in range(n_rows):
        fields = (f'"{"0" * p}{v}"' for p, v in zip(pad[i], rows[i]))
        text.append(",".join([f'"{1.7e9 + i}"', *fields, '"1"', '"97"']))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "h.csv"
        path.write_text("\n".join(text) + "\n")
        d = read_shearsense_csv(path)
    ok = rows.max(axis=1) <= 65535
    assert d.n_frames == int(ok.sum())
    assert d.malformed_by_kind.get("merged_number", 0) == int((~ok).sum())
    np.testing.assert_array_equal(d.raw, rows[ok])


@pytest.mark.parametrize("content, problem", [
    (None, "no such file"),
    (b"", "empty file"),
    (b"a,b,c\n1,2,3\n", "not a ShearSense CSV"),
    (b'"time (s)","Channel0","touched","label"\n', "not a ShearSense CSV"),
    (HEADER.encode() + b"\n" + q([1, 2, 3]).encode() + b"\n", "no readable rows"),
])
def test_bad_files_give_one_line_errors_naming_the_file(tmp_path, content, problem):
    path = tmp_path / "bad.csv"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(ShearSenseError) as info:
        read_shearsense_csv(path)
    msg = str(info.value)
    assert isinstance(info.value, UserError)
    assert str(path) in msg and problem in msg and "\n" not in msg


def test_a_cancelled_read_raises_cancelled(tmp_path):
    path, _, _ = make_file(tmp_path)
    token = CancelToken()
    token.cancel()
    with pytest.raises(Cancelled):
        read_shearsense_csv(path, cancel=token)


def test_progress_is_reported_and_ends_at_one(tmp_path, monkeypatch):
    path, _, _ = make_file(tmp_path, n=30)
    monkeypatch.setattr(ss, "_BLOCK_BYTES", 4096)
    seen: list[float] = []
    said: list[str] = []
    read_shearsense_csv(path, progress=lambda f, m="": (seen.append(f), said.append(m)))
    assert len(seen) > 3 and seen == sorted(seen) and seen[-1] == 1.0 and seen.count(1.0) == 1
    # a file under a megabyte (a 12 s performance is ~0.8 MB) still shows how far it is
    size = path.stat().st_size / (1 << 20)
    assert said[0] == f"{path.name}: 0.0 of {size:.1f} MB" and size < 1, said[:2]


@pytest.mark.parametrize("name, expected", [
    ("P07_2023-05-01_PILLOW.csv", ("P07", "PILLOW")),
    ("P3flat.csv", ("P3", "FLAT")),
    ("p12 session Flat.csv", ("P12", "FLAT")),
    ("/data/P05-x-y-PILLOW.csv", ("P05", "PILLOW")),
    ("PA1_FLAT.csv", ("PA1", "FLAT")),
    ("recording.csv", ("", "")),
])
def test_participant_and_condition_come_from_the_file_name(name, expected):
    assert parse_shearsense_name(name) == expected


def test_writer_refuses_data_that_is_not_180_counts(tmp_path):
    with pytest.raises(UserError, match="180"):
        write_shearsense_csv(tmp_path / "x.csv", np.zeros((3, 64)), np.zeros(3), np.zeros(3),
                             np.ones(64))
