"""Session files are compressed on close, and files written before that still open."""

from __future__ import annotations

import json

import h5py
import numpy as np

from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.simulate.simulator import SensorSimulator
from tactile_studio.storage import SessionFile, SessionWriter
from tactile_studio.storage.format.session_compress import FILTERS, chunk_rows, read_rows


def _frames(n: int) -> np.ndarray:
    return SensorSimulator().step(n)


def test_closed_session_is_compressed_with_chunks_sized_to_the_data(tmp_path):
    raw = _frames(1300)
    t = 1.69e9 + np.arange(1300) / 43.0
    p = tmp_path / "s.h5"
    with SessionWriter(p, SHEARSENSE_6X6, {"plugin": "test"}, {"participant": "P01"}) as w:
        w.add_trial({"index": 0, "gesture": "Poke", "start_sample": 5, "end_sample": 91})
        for i in range(0, 1300, 22):  # the recorder's pace: ~0.5 s per append
            j = min(1300, i + 22)
            w.append_frames(raw[i:j], t[i:j], t[i:j], np.arange(i, j))
            w.flush()
    with h5py.File(p, "r") as f:
        ds = f["frames/raw"]
        assert ds.compression == "gzip" and ds.shuffle
        assert ds.chunks[0] <= 1300 and ds.chunks[1] == 180
        assert f["frames/device_time"].compression == "gzip"
        assert f["frames/seq"].chunks[0] <= 1300
        assert ds.id.get_storage_size() < raw.nbytes / 1.5
        assert json.loads(f.attrs["trials_json"])[0]["gesture"] == "Poke"
    assert not list(tmp_path.glob(".*compressing"))
    with SessionFile(p) as s:
        assert s.n_frames == 1300 and s.closed_cleanly
        assert np.array_equal(s.raw(), raw)
        assert np.array_equal(s.column("device_time"), t)
        assert np.array_equal(s.column("seq"), np.arange(1300))
        assert s.metadata["participant"] == "P01" and s.trials[0].end_sample == 91


def test_an_empty_session_closes_and_opens(tmp_path):
    p = tmp_path / "empty.h5"
    SessionWriter(p, SHEARSENSE_6X6, {"plugin": "test"}).close()
    with SessionFile(p) as s:
        assert s.n_frames == 0 and s.closed_cleanly


def _write_old_format(path, raw, t) -> None:
    """Exactly what the writer produced before compression: uncompressed, fixed chunks."""
    n = len(raw)
    journal = (json.dumps({"type": "metadata", "update": {
        "layout": SHEARSENSE_6X6.to_dict(), "participant": "P09"}}) + "\n"
        + json.dumps({"type": "closed", "time": 0.0}) + "\n").encode()
    with h5py.File(path, "w", libver="latest") as f:
        f.attrs.update({"format": "tactile-studio-session", "schema_version": 1,
                        "app_version": "0.1.0", "layout": SHEARSENSE_6X6.name})
        g = f.create_group("frames")
        g.create_dataset("raw", data=raw, maxshape=(None, 180), chunks=(256, 180))
        for name, values in (("device_time", t), ("host_time", t), ("seq", np.arange(n)),
                             ("index", np.arange(n))):
            g.create_dataset(name, data=values, maxshape=(None,), chunks=(4096,))
        f.create_dataset("journal", data=np.frombuffer(journal, np.uint8), maxshape=(None,),
                         chunks=(16384,))


def test_a_file_written_the_old_uncompressed_way_still_opens(tmp_path):
    raw, t = _frames(500), np.arange(500) / 43.0
    p = tmp_path / "old.h5"
    _write_old_format(p, raw, t)
    with h5py.File(p, "r") as f:
        assert f["frames/raw"].compression is None
    with SessionFile(p) as s:
        assert s.n_frames == 500 and s.metadata["participant"] == "P09"
        assert np.array_equal(s.raw(100, 200), raw[100:200])
        assert s.summary()["rate_hz"] > 42.9


def test_chunk_rows_follow_the_row_size_and_the_data_length():
    assert chunk_rows(360) == 728  # 180 uint16 channels: ~256 KiB per chunk
    assert chunk_rows(8, n_rows=1300) == 1300
    assert chunk_rows(360, n_rows=0) == 1
    assert chunk_rows(10**9) == 64


def test_parallel_chunk_reader_equals_h5py_on_any_slice(tmp_path):
    """read_rows inflates gzip+shuffle chunks itself; every slice must equal h5py's."""
    rng = np.random.default_rng(4)
    raw = (1500 + rng.normal(0, 30, (5000, 180))).astype(np.uint16)
    times = np.cumsum(rng.uniform(0.02, 0.03, 5000))
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f.create_dataset("raw", data=raw, chunks=(333, 180), **FILTERS)
        f.create_dataset("t", data=times, chunks=(700,), **FILTERS)
        f.create_dataset("plain", data=raw, chunks=(333, 180))
    with h5py.File(tmp_path / "c.h5", "r") as f:
        for a, b in [(0, 5000), (1, 4999), (332, 333 * 7 + 1), (4000, 9000), (10, 20)]:
            assert np.array_equal(read_rows(f["raw"], a, b), raw[a:b])
            assert np.array_equal(read_rows(f["t"], a, b), times[a:b])
            assert np.array_equal(read_rows(f["plain"], a, b), raw[a:b])


def test_background_compression_keeps_the_file_whole_and_guards_the_name(tmp_path):
    """The GUI compresses a stopped recording on a worker thread: the file is complete
    before and after, and a new writer at the same name waits so the swap cannot land on
    the newer recording."""
    from tactile_studio.storage.format.session_compress import wait_for_compression

    raw = np.tile(_frames(2000), (10, 1))  # ~0.2 s to compress: the writer comes first
    t = 1.69e9 + np.arange(20000) / 43.0
    p = tmp_path / "s.h5"
    w = SessionWriter(p, SHEARSENSE_6X6, {"plugin": "test"}, {"participant": "P01"})
    w.append_frames(raw, t, t, np.arange(20000))
    w.close(background=True)
    with SessionFile(p) as s:  # readable at once, whichever copy is in place
        assert s.n_frames == 20000
    with SessionWriter(p, SHEARSENSE_6X6, {"plugin": "test"}, {"participant": "P02"},
                       overwrite=True) as w2:
        w2.append_frames(raw[:10], t[:10], t[:10], np.arange(10))
    assert wait_for_compression(timeout=30)
    with SessionFile(p) as s:  # the newer recording, not the older one swapped over it
        assert s.n_frames == 10 and s.metadata["participant"] == "P02"
    with h5py.File(p, "r") as f:
        assert f["frames/raw"].compression == "gzip"
    assert not list(tmp_path.glob(".*compressing"))


def test_background_compression_ends_compressed(tmp_path):
    from tactile_studio.storage.format.session_compress import wait_for_compression

    raw = _frames(500)
    t = 1.69e9 + np.arange(500) / 43.0
    p = tmp_path / "s.h5"
    w = SessionWriter(p, SHEARSENSE_6X6, {"plugin": "test"}, {})
    w.append_frames(raw, t, t, np.arange(500))
    w.close(background=True)
    assert wait_for_compression(p, timeout=30)
    with h5py.File(p, "r") as f:
        assert f["frames/raw"].compression == "gzip"
        np.testing.assert_array_equal(f["frames/raw"][:], raw)
