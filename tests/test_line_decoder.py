"""The serial line decoder: exact frames, every bad line counted once by kind, no crash."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tactile_studio.devices.line_decoder import KINDS, LineDecoder, classify_line, encode_frame
from tactile_studio.devices.serial_emulator import corrupt_line

C = 180
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def frames(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 65536, (n, C)).astype(np.uint16)


def feed_in_chunks(dec: LineDecoder, data: bytes, cuts: list[int]) -> tuple[np.ndarray, Counter]:
    out, bad, pos = [], Counter(), 0
    for cut in sorted(set(cuts)) + [len(data)]:
        d = dec.feed(data[pos:cut])
        out.append(d.frames)
        bad.update(d.malformed)
        pos = cut
    return np.concatenate(out), bad


def reference(data: bytes, c: int = C) -> tuple[list[list[int]], Counter]:
    """What the decoder must produce, line by line with the reference classifier."""
    good, bad = [], Counter()
    for line in data.split(b"\n")[:-1]:
        kind, vals = classify_line(line, c)
        if kind is None:
            good.append(vals)
        else:
            bad[kind] += 1
    return good, bad


def test_good_lines_decode_exactly_with_and_without_trailing_comma():
    f = frames(50)
    data = b"".join(encode_frame(row, trailing_comma=i % 2 == 0) for i, row in enumerate(f))
    dec = LineDecoder()
    out = dec.feed(data)
    assert out.frames.dtype == np.uint16
    np.testing.assert_array_equal(out.frames, f)
    assert not out.malformed and dec.good == 50


def test_bare_lf_and_extreme_values():
    row = np.zeros(C, dtype=np.uint16)
    row[0], row[-1] = 65535, 0
    out = LineDecoder().feed(encode_frame(row)[:-2] + b"\n")
    np.testing.assert_array_equal(out.frames, row[None, :])


@pytest.mark.parametrize("line, kind", [
    (b"", "empty"),
    (b"\r", "empty"),
    (b"   ", "empty"),
    (b"1,2,3,", "short"),
    (b"1,2,\xff3", "undecodable"),
    (b"1,2,\x00", "undecodable"),
    (b"1,a,3", "non_numeric"),
    (b"1,,3", "non_numeric"),
    (b",".join([b"1"] * (C - 2) + [b"1234567"]), "merged_numbers"),
    (b",".join([b"1"] * (C - 1) + [b"65536"]), "out_of_range"),
    (b",".join([b"1"] * (C - 1) + [b"-1"]), "out_of_range"),
    (b",".join([b"1"] * (2 * C)), "long"),
])
def test_each_kind(line, kind):
    assert classify_line(line, C)[0] == kind
    dec = LineDecoder()
    out = dec.feed(line + b"\r\n")
    assert len(out) == 0 and out.malformed == Counter({kind: 1})


def test_a_good_line_survives_any_bad_neighbour():
    f = frames(len(KINDS) + 1, seed=1)
    rng = np.random.default_rng(2)
    parts = [encode_frame(f[0])]
    for i, kind in enumerate(KINDS):
        parts.append(corrupt_line(kind, frames(2, seed=10 + i), rng))
        parts.append(encode_frame(f[i + 1]))
    out = LineDecoder().feed(b"".join(parts))
    np.testing.assert_array_equal(out.frames, f)
    assert out.malformed == Counter({k: 1 for k in KINDS})


def test_partial_line_kept_and_flushed():
    f = frames(2)
    data = encode_frame(f[0]) + encode_frame(f[1])[:100]
    dec = LineDecoder()
    assert len(dec.feed(data)) == 1
    assert dec.pending_bytes == 100
    tail = dec.flush()
    assert len(tail) == 0 and tail.malformed == Counter({"short": 1})
    assert dec.pending_bytes == 0


def test_runaway_line_without_newline_is_bounded_and_counted_long():
    dec = LineDecoder(max_line_bytes=1000)
    for _ in range(10):
        dec.feed(b"1," * 300)
    assert dec.pending_bytes <= 1000
    f = frames(1)
    out = dec.feed(b"\r\n" + encode_frame(f[0]))
    assert out.malformed == Counter({"long": 1})
    np.testing.assert_array_equal(out.frames, f)


def test_emulator_corruptions_are_classified_as_their_kind():
    rng = np.random.default_rng(0)
    for trailing in (True, False):
        for kind in KINDS:
            for seed in range(40):
                line = corrupt_line(kind, frames(2, seed), rng, trailing_comma=trailing)
                assert line.endswith(b"\r\n") and line.count(b"\n") == 1
                assert classify_line(line[:-1], C)[0] == kind, (kind, line[:80])


def test_small_values_still_make_merged_numbers():
    small = np.ones((2, C), dtype=np.int64)
    line = corrupt_line("merged_numbers", small, np.random.default_rng(0))
    assert classify_line(line[:-1], C)[0] == "merged_numbers"


def test_other_layouts_channel_count_and_maximum():
    dec = LineDecoder(n_channels=64, max_value=1023, dtype="float32")
    good = np.arange(64) * 16
    out = dec.feed(encode_frame(good) + encode_frame(good + 1024) + encode_frame(good[:10]))
    np.testing.assert_array_equal(out.frames, good[None, :].astype(np.float32))
    assert out.malformed == Counter({"out_of_range": 1, "short": 1})


# ---- fuzzing ---------------------------------------------------------------------------
def random_rows(seed: int, n: int) -> np.ndarray:
    """Rows of counts with every digit count (0..65535, extremes included)."""
    rng = np.random.default_rng(seed)
    digits = rng.integers(1, 6, (n, C))
    rows = rng.integers(0, 10 ** digits).clip(0, 65535)
    rows[rng.random((n, C)) < 0.02] = 65535
    return rows


good_rows = st.builds(random_rows, st.integers(0, 2**32 - 1), st.integers(1, 8))


@FUZZ
@given(rows=good_rows, trailing=st.booleans(), crlf=st.booleans(),
       cuts=st.lists(st.integers(0, 12000), max_size=6))
def test_fuzz_random_good_lines_decode_exactly(rows, trailing, crlf, cuts):
    data = b"".join(encode_frame(r, trailing)[:None if crlf else -2]
                    + (b"" if crlf else b"\n") for r in rows)
    got, bad = feed_in_chunks(LineDecoder(), data, [c % (len(data) + 1) for c in cuts])
    np.testing.assert_array_equal(got, rows.astype(np.uint16))
    assert not bad


noise = st.lists(st.one_of(
    st.binary(max_size=40),
    st.sampled_from([b"\n", b"\r\n", b",", b",,", b"-", b"65536", b"99999999999999999999999"]),
    good_rows.map(lambda rows: encode_frame(rows[0])),
    st.builds(lambda kind, seed: corrupt_line(kind, random_rows(seed, 2),
                                              np.random.default_rng(seed)),
              st.sampled_from(KINDS), st.integers(0, 1000)),
), max_size=12).map(b"".join)


@FUZZ
@given(data=noise, cuts=st.lists(st.integers(0, 4000), max_size=5))
def test_fuzz_no_input_crashes_and_matches_the_reference(data, cuts):
    dec = LineDecoder()
    got, bad = feed_in_chunks(dec, data, [c % (len(data) + 1) for c in cuts])
    want_good, want_bad = reference(data)
    assert got.shape == (len(want_good), C)
    if want_good:
        np.testing.assert_array_equal(got, np.array(want_good))
    assert bad == want_bad
    assert set(bad) <= set(KINDS)
    assert dec.pending_bytes == len(data) - (data.rfind(b"\n") + 1)
    dec.flush()  # never raises either
