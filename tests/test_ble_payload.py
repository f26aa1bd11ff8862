"""The BLE payload: fragments, reassembly, validation, sequence gaps; fuzzed."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactile_studio.devices.ble_payload import (
    FRAG_HEADER,
    KINDS,
    Reassembler,
    crc16,
    encode_body,
    encode_packets,
)


def frames(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 65536, (n, 180)).astype(np.uint16)


def run(r: Reassembler, packets: list[bytes]) -> tuple[list[int], list[np.ndarray]]:
    seqs, out = [], []
    for p in packets:
        done = r.feed(p)
        if done is not None:
            seqs.append(done[0])
            out.append(done[1])
    return seqs, out


def test_crc_is_ccitt_false():
    assert crc16(b"123456789") == 0x29B1  # the standard check value


@pytest.mark.parametrize("mtu, fragments", [(23, 23), (185, 3), (247, 2), (373, 1), (517, 1)])
def test_round_trip_at_each_mtu(mtu, fragments):
    f = frames(20)
    packets = [p for i, row in enumerate(f) for p in encode_packets(100 + i, row, mtu)]
    assert len(packets) == 20 * fragments
    assert max(len(p) for p in packets) <= mtu - 3
    r = Reassembler()
    seqs, out = run(r, packets)
    assert seqs == list(range(100, 120))
    np.testing.assert_array_equal(np.stack(out), f)
    assert not r.bad and r.gaps == 0


def test_lost_fragment_makes_one_incomplete_frame_and_a_gap():
    f = frames(5)
    packets = [encode_packets(i, row, 23) for i, row in enumerate(f)]
    del packets[2][7]  # one notification of frame 2 lost
    r = Reassembler()
    seqs, out = run(r, [p for ps in packets for p in ps])
    assert seqs == [0, 1, 3, 4]
    assert r.bad == Counter({"incomplete": 1})
    assert (r.gaps, r.missing) == (1, 1)


def test_missed_start_and_cut_end_are_each_counted_once():
    f = frames(4)
    packets = [encode_packets(i, row, 23) for i, row in enumerate(f)]
    stream = packets[0][5:] + packets[1][:-1] + packets[2] + packets[3]
    r = Reassembler()
    seqs, _ = run(r, stream)
    assert seqs == [2, 3] and r.bad == Counter({"incomplete": 2})


def test_corrupt_payload_wrong_length_version_and_bad_fragments():
    row = frames(1)[0]
    r = Reassembler()
    good = encode_packets(0, row, 247)
    flipped = bytearray(good[1])
    flipped[10] ^= 0x40
    run(r, [good[0], bytes(flipped)])
    assert r.bad == Counter({"bad_crc": 1})
    run(r, encode_packets(1, row[:64], 247))  # a 64-channel frame on a 180-channel link
    body = bytearray(encode_body(row))
    body[0] = 9
    run(r, [FRAG_HEADER.pack(2, 0, 1) + bytes(body)])
    run(r, [b"\x01\x02", FRAG_HEADER.pack(3, 2, 2) + b"x", FRAG_HEADER.pack(3, 0, 0)])
    assert r.bad == Counter({"bad_crc": 1, "bad_length": 1, "bad_version": 1,
                             "bad_fragment": 3})
    assert r.frames == 0


def test_duplicates_and_stale_frames_are_dropped_and_wraparound_is_seamless():
    f = frames(6)
    order = [65534, 65535, 65535, 0, 65000, 1]
    r = Reassembler()
    seqs, _ = run(r, [p for s, row in zip(order, f) for p in encode_packets(s, row, 512)])
    assert seqs == [65534, 65535, 65536, 65537]
    assert r.bad == Counter({"duplicate": 1, "out_of_order": 1})
    assert r.gaps == 0


def test_new_connection_continues_numbering_without_a_false_gap():
    f = frames(4)
    r = Reassembler()
    run(r, encode_packets(10, f[0], 23)[:3])  # a frame cut short ...
    seqs, _ = run(r, encode_packets(9, f[1], 512))  # ... by the next one starting
    assert seqs == [9] and r.bad == Counter({"incomplete": 1})
    run(r, encode_packets(10, f[2], 23)[:3])  # cut by the disconnect: not counted
    r.new_connection()  # the peripheral restarted its numbering at 0
    seqs, out = run(r, [p for s, row in zip((0, 1), f[2:]) for p in encode_packets(s, row, 23)])
    assert seqs == [10, 11] and r.gaps == 0
    assert r.bad == Counter({"incomplete": 1})
    np.testing.assert_array_equal(np.stack(out), f[2:])


@settings(max_examples=100, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=60),
                          st.builds(lambda s, i, c, b: FRAG_HEADER.pack(s, i, c) + b,
                                    st.integers(0, 65535), st.integers(0, 255),
                                    st.integers(0, 255), st.binary(max_size=40))),
                max_size=40))
def test_fuzz_arbitrary_notifications_never_crash(packets):
    r = Reassembler()
    for p in packets:
        done = r.feed(p)
        if done is not None:
            assert done[1].shape == (180,)
    assert set(r.bad) <= set(KINDS)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(23, 600), st.lists(st.integers(0, 400)))
def test_fuzz_lossy_links_deliver_only_intact_frames(seed, mtu, drops):
    f = frames(8, seed)
    packets = [p for i, row in enumerate(f) for p in encode_packets(i, row, mtu)]
    for d in sorted({d % len(packets) for d in drops}, reverse=True):
        del packets[d]
    r = Reassembler()
    seqs, out = run(r, packets)
    for seq, row in zip(seqs, out):  # the first frame ever keeps the device's number
        np.testing.assert_array_equal(row, f[seq])
    assert len(seqs) + r.bad["incomplete"] <= 8
    if not drops:
        assert len(seqs) == 8
