"""Foreign XDF files that lie, are cut short or carry hostile markers (issue 43): through
the real ``import xdf`` command, each ends in its one line and documented exit status,
what the file held is imported as it was, and every session written passes ``check``
(the suite's autouse check).

Files are made with our XDF writer (storage/exchange/xdf_writer.py) and, where a file must lie,
with raw chunks. Budget: ~6 s; the 10^9-channel file runs in a child process whose
address space is limited, so a regression ends in a MemoryError instead of 8 GB."""

from __future__ import annotations

import json
import os
import resource
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_xdf import chunk, footer, header_xml, numeric_samples

from tactile_studio.cli import main
from tactile_studio.errors import EXIT_ERROR, EXIT_INCOMPLETE, EXIT_OK
from tactile_studio.storage import SessionFile, SessionWriter
from tactile_studio.storage.exchange.xdf_writer import XdfWriter

T0 = 1000.0
RATE = 43.0
N = 400
MARKERS_DESC = {"tactile_studio": {"format": "json", "frame_stream": "Mat"}}


def counts(n: int = N) -> np.ndarray:
    return (30000 + np.arange(n)[:, None] + np.arange(180)[None, :] % 7).astype(np.int32)


def write_xdf(path: Path, values: np.ndarray | None = None, fmt: str = "int32",
              rate: float = RATE, stamps: np.ndarray | None = None,
              markers: list[list[str]] = (), marker_channels: int = 1,
              ours: bool = True, footers: bool = True) -> Path:
    """A LabRecorder-like file: a 180-channel tactile stream ``Mat`` in 4 chunks with
    clock offsets and boundaries, a marker stream (ours: declared as Tactile Studio's
    JSON markers) with ``markers`` one per second from T0 + 1, and every footer."""
    values = counts() if values is None else values
    n = len(values)
    stamps = T0 + np.arange(n) / RATE if stamps is None else stamps
    with open(path, "wb") as fh:
        w = XdfWriter(fh)
        w.file_header()
        w.stream_header(1, "Mat", "Tactile", 180, rate, fmt, "mat-1", T0)
        w.stream_header(2, "Mat-markers", "Markers", marker_channels, 0.0, "string", "mk-1",
                        T0, MARKERS_DESC if ours else None)
        for k in range(4):
            a, b = k * n // 4, (k + 1) * n // 4
            w.samples(1, fmt, stamps[a:b], values[a:b])
            w.clock_offset(1, T0 + k, 0.0)
            w.boundary()
        mt = T0 + 1.0 + np.arange(len(markers))
        if len(markers):
            w.samples(2, "string", mt, markers)
        w.clock_offset(2, T0, 0.0)
        if footers:
            w.stream_footer(1, float(stamps[0]), float(stamps[-1]), n, [(T0, 0.0)])
            w.stream_footer(2, T0, T0, len(markers), [(T0, 0.0)])
    return path


def run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err


def error_line(err: str) -> str:
    (line,) = [ln for ln in err.splitlines() if ln.startswith("tactile-studio:")]
    return line


def info(path: Path) -> dict:
    with SessionFile(path) as s:
        return s.summary()


# ---- what a marker says is content (case 2, 16) -----------------------------------------
def test_a_markers_type_key_never_rewrites_our_records(tmp_path, capsys):
    """``"type": "trial"`` invented a trial, ``"stimulus"`` made the marker vanish,
    ``"metadata"`` replaced the session's metadata (then ``info`` and ``check`` crashed).
    Now each is a ``marker`` event holding its text; a real trial pair still is a trial."""
    bad = [{"kind": "note", "source": "app", "type": "trial", "index": 5, "gesture": "Poke",
            "start_sample": 0, "end_sample": 10},
           {"kind": "note", "source": "app", "type": "stimulus"},
           {"kind": "note", "source": "app", "type": "metadata", "update": {"layout": "x"}}]
    good = [{"kind": "trial_start", "source": "collect", "index": 0, "gesture": "Twist"},
            {"kind": "trial_end", "source": "collect", "index": 0, "gesture": "Twist",
             "block": 0, "status": "ok"}]
    texts = [json.dumps(m) for m in bad + good]
    src = write_xdf(tmp_path / "typed.xdf", markers=[[t] for t in texts])
    code, out, err = run(capsys, "import", "xdf", src, "--out", tmp_path)
    assert code == EXIT_OK, err
    assert ("3 markers kept as text, not read as Tactile Studio markers (it carries 'type', "
            "a field of our own records)") in out
    s = info(tmp_path / "typed.h5")
    assert s["layout"] == "shearsense-6x6" and s["metadata"]["stream"] == "Mat"
    assert [(t["index"], t["gesture"]) for t in s["trials"]] == [(0, "Twist")]
    marks = [e["text"] for e in s["events"] if e["kind"] == "marker"]
    assert marks == texts[:3]
    assert main(["info", str(tmp_path / "typed.h5")]) == 0


@pytest.mark.parametrize("marker, why", [
    ({"kind": "trial_end", "source": "collect", "index": "abc"},
     'its index "abc" is not a trial number'),
    ({"kind": "trial_end", "source": "collect", "index": 1, "end_sample": "zz"},
     'its end_sample "zz" is not a row'),
    ({"kind": "tare", "source": "engine", "baseline": ["a"]},
     "its baseline is not 180 finite numbers"),
    ({"kind": "trial_end", "source": "collect", "index": 2, "status": "great"},
     'its status "great" is not one of discarded, ok, redone'),
])
def test_a_marker_with_a_bad_value_is_kept_as_text_not_a_traceback(tmp_path, capsys,
                                                                    marker, why):
    src = write_xdf(tmp_path / "bad.xdf", markers=[[json.dumps(marker)]])
    code, out, err = run(capsys, "import", "xdf", src, "--out", tmp_path)
    assert code == EXIT_OK, err
    assert f"1 marker kept as text, not read as Tactile Studio markers ({why})" in out
    s = info(tmp_path / "bad.h5")
    assert s["trials"] == [] and [e["text"] for e in s["events"]
                                  if e["kind"] == "marker"] == [json.dumps(marker)]


def test_trials_over_each_others_rows_or_ended_twice_stay_text(tmp_path, capsys):
    """Markers whose trials overlap, or a trial ended twice: the first is the trial, the
    others are their text (``check`` forbids trials over each other's rows)."""
    def m(kind, index):
        return [json.dumps({"kind": kind, "source": "collect", "index": index,
                            "gesture": "Poke", "block": 0})]
    markers = [m("trial_start", 0), m("trial_start", 1), m("trial_end", 0), m("trial_end", 1),
               m("trial_end", 0)]
    src = write_xdf(tmp_path / "overlap.xdf", markers=markers)
    code, out, err = run(capsys, "import", "xdf", src, "--out", tmp_path)
    assert code == EXIT_OK, err
    assert "2 markers kept as text, not read as Tactile Studio markers (" in out
    s = info(tmp_path / "overlap.h5")
    assert [t["index"] for t in s["trials"]] == [0]
    assert [e["text"] for e in s["events"] if e["kind"] == "marker"] == [
        markers[3][0], markers[4][0]]


def test_json_of_another_program_is_text(tmp_path, capsys):
    """A marker stream that does not declare itself ours: its JSON is that program's
    text, even when it has our words (kind, source, index)."""
    m = {"kind": "trial_end", "source": "psychopy", "index": 0, "gesture": "Poke"}
    src = write_xdf(tmp_path / "psychopy.xdf", markers=[[json.dumps(m)]], ours=False)
    assert run(capsys, "import", "xdf", src, "--out", tmp_path)[0] == EXIT_OK
    s = info(tmp_path / "psychopy.h5")
    assert s["trials"] == [] and s["events"][0]["text"] == json.dumps(m)


def test_a_marker_stream_of_two_channels_keeps_both(tmp_path, capsys):
    src = write_xdf(tmp_path / "two.xdf", markers=[["cue", "left"], ["cue", "right"]],
                    marker_channels=2, ours=False)
    assert run(capsys, "import", "xdf", src, "--out", tmp_path)[0] == EXIT_OK
    marks = [e for e in info(tmp_path / "two.h5")["events"] if e["kind"] == "marker"]
    assert [(m["text"], m["channels"]) for m in marks] == [
        ("cue | left", ["cue", "left"]), ("cue | right", ["cue", "right"])]


def test_naming_a_text_stream_as_the_tactile_one_is_one_line(tmp_path, capsys):
    src = write_xdf(tmp_path / "s.xdf", markers=[["x"]])
    code, _, err = run(capsys, "import", "xdf", src, "--out", tmp_path, "--stream",
                       "Mat-markers")
    assert code == EXIT_ERROR and error_line(err) == (
        f"tactile-studio: error: {src}: stream 'Mat-markers' is a text (marker) stream, not "
        "a tactile one: name a numeric stream with --stream")
    code, _, err = run(capsys, "import", "xdf", src, "--out", tmp_path, "--stream", "Mat",
                       "--layout", "grid-0x5")
    assert code == EXIT_ERROR and error_line(err) == (
        f"tactile-studio: error: {src}: grid layout needs positive rows and columns, got 0x5")
    assert not list(tmp_path.glob("*.h5"))


# ---- samples are stored as they are, or left out and said (case 5) ------------------------
def test_float_samples_that_are_no_counts_are_left_out_and_counted(tmp_path, capsys):
    values = counts().astype(np.float32)
    values[5, 0], values[6, 1], values[7, 2], values[8, 3] = np.nan, 1e9, -3.5, 12.75
    src = write_xdf(tmp_path / "floats.xdf", values, fmt="float32")
    code, _, err = run(capsys, "import", "xdf", src, "--out", tmp_path)
    assert code == EXIT_INCOMPLETE
    assert error_line(err) == (
        f"tactile-studio: error: {src}: stream 'Mat': 4 of {N} frames left out: values or "
        "times it cannot store as they are (NaN or infinite 1, beyond the layout's range 2, "
        "not whole counts 1)")
    kept = np.delete(np.arange(N), [5, 6, 7, 8])
    with SessionFile(tmp_path / "floats.h5") as s:
        np.testing.assert_array_equal(s.raw(), counts()[kept])
        assert s.summary()["malformed_by_kind"] == {"not_finite": 1, "out_of_range": 2,
                                                    "not_whole": 1}


# ---- rates a recording cannot have (case 9) ---------------------------------------------
def test_an_implausible_nominal_rate_is_refused(tmp_path, capsys):
    src = write_xdf(tmp_path / "fast.xdf", rate=1e300)
    code, _, err = run(capsys, "import", "xdf", src, "--out", tmp_path)
    assert code == EXIT_ERROR
    assert ("stream 'Mat' not read: nominal_srate 1e+300 Hz is not a plausible rate "
            "(0 = irregular, at most 100,000 Hz)") in error_line(err)
    assert not list(tmp_path.glob("*.h5"))


def test_timestamps_that_imply_an_implausible_rate_are_refused(tmp_path, capsys):
    src = write_xdf(tmp_path / "dense.xdf", stamps=T0 + np.arange(N) * 1e-7)
    code, _, err = run(capsys, "import", "xdf", src, "--out", tmp_path)
    assert code == EXIT_ERROR
    line = error_line(err)
    assert f"{src}: stream 'Mat': its timestamps put 400 frames in" in line
    assert "not a plausible rate (at most 100,000 Hz)" in line
    assert not list(tmp_path.glob("*.h5"))


# ---- cut short: what it held, marked (case 4) -------------------------------------------
def exported(tmp_path: Path, n: int = 3000) -> tuple[Path, np.ndarray]:
    """Our own export of a session of ``n`` frames (one chunk per 10 s, footers last)."""
    raw = (30000 + np.random.default_rng(4).integers(0, 200, (n, 180))).astype(np.uint16)
    host = 1.7e9 + np.arange(n) / RATE
    src = tmp_path / "whole.h5"
    with SessionWriter(src, _layout(), {"plugin": "simulated", "nominal_rate_hz": RATE},
                       {"participant": "P01"}) as w:
        w.append_frames(raw, host - host[0], host)
    assert main(["export", str(src), "--format", "xdf", "--out", str(tmp_path)]) == 0
    return tmp_path / "whole.xdf", raw


def _layout():
    from tactile_studio.sensor.layout import SHEARSENSE_6X6
    return SHEARSENSE_6X6


@pytest.mark.parametrize("fraction", [0.5, 0.6, 0.7])
def test_a_cut_file_imports_what_it_held_as_cut_short(tmp_path, capsys, fraction):
    whole, raw = exported(tmp_path)
    data = whole.read_bytes()
    cut = tmp_path / f"cut{int(fraction * 100)}.xdf"
    cut.write_bytes(data[:int(len(data) * fraction)])
    out = tmp_path / "out"
    capsys.readouterr()
    code, stdout, err = run(capsys, "import", "xdf", cut, "--out", out)
    assert code == EXIT_INCOMPLETE
    assert error_line(err).startswith(f"tactile-studio: error: {cut}: cut short: the file "
                                      f"ends at byte {int(len(data) * fraction):,}, inside a "
                                      "chunk")
    assert f"wrote {out / cut.stem}.h5" in stdout
    with SessionFile(out / f"{cut.stem}.h5") as s:
        n = s.n_frames
        # what a byte count of frames can hold, less a chunk's header and the streams'
        assert 0.5 * fraction * len(raw) < n < fraction * len(raw)
        np.testing.assert_array_equal(s.raw(), raw[:n])  # every frame it held, exactly
        summary = s.summary()
        assert summary["cut_short"] and summary["closed_cleanly"]
        assert summary["metadata"]["source_incomplete"].startswith("cut short: the file ends")


def test_a_file_without_footers_is_a_recording_that_did_not_end(tmp_path, capsys):
    # a LabRecorder killed before it stopped: every chunk whole, no footers
    src = write_xdf(tmp_path / "nofooter.xdf", footers=False)
    code, _, err = run(capsys, "import", "xdf", src, "--out", tmp_path / "o")
    assert code == EXIT_INCOMPLETE
    assert error_line(err).startswith(f"tactile-studio: error: {src}: cut short: no stream "
                                      "footer for Mat, Mat-markers")
    assert info(tmp_path / "o" / "nofooter.h5")["frames"] == N


def test_a_huge_chunk_length_is_where_the_file_was_cut(tmp_path, capsys):
    """Was ``not a readable XDF file ()`` (a MemoryError's empty text)."""
    body = write_xdf(tmp_path / "full.xdf").read_bytes()
    src = tmp_path / "huge.xdf"
    src.write_bytes(body + b"\x08" + struct.pack("<Q", 2**40) + struct.pack("<H", 3)
                    + b"\x01\x00\x00\x00")
    code, _, err = run(capsys, "import", "xdf", src, "--out", tmp_path / "o")
    assert code == EXIT_INCOMPLETE
    assert error_line(err) == (
        f"tactile-studio: error: {src}: cut short: the file ends at byte {len(body) + 15:,}, "
        f"inside a chunk of 1,099,511,627,776 bytes at byte {len(body):,}")
    assert info(tmp_path / "o" / "huge.h5")["frames"] == N


# ---- declared sizes against what the file holds (case 14) -------------------------------
def lying(path: Path, channels: int, samples: int) -> Path:
    """1.3 KB: a stream header claiming ``channels`` channels and a Samples chunk
    claiming ``samples`` samples in 8 bytes."""
    path.write_bytes(b"XDF:" + chunk(1, b"<info><version>1.0</version></info>")
                     + chunk(2, header_xml("Mat", "Tactile", channels, 43, "float32",
                                           "<x>" + "y" * 900 + "</x>"), 1)
                     + chunk(3, b"\x04" + struct.pack("<I", samples) + b"\x00" * 8, 1)
                     + footer(1, samples))
    return path


def _limited_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, resource.getrlimit(resource.RLIMIT_AS)[1]))


def command(*argv, limit: bool = False) -> subprocess.CompletedProcess:
    """The real command in a child process (its own stderr: what a terminal shows);
    ``limit``: 3 GiB of address space."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, "-m", "tactile_studio", *map(str, argv)],
                          capture_output=True, text=True, env=env, timeout=120,
                          preexec_fn=_limited_memory if limit else None)


@pytest.mark.parametrize("channels, samples, said", [
    (10**9, 1, "stream 'Mat' not read: channel_count 1,000,000,000 is not 1..65,536"),
    (180, 10**9, "stream 'Mat' has no samples, nothing imported (stream 'Mat': a Samples "
                 "chunk claims 1,000,000,000 samples in 8 bytes (left out)"),
])
def test_declared_counts_are_checked_before_anything_is_allocated(tmp_path, channels,
                                                                   samples, said):
    src = lying(tmp_path / "lies.xdf", channels, samples)
    assert src.stat().st_size < 1400
    done = command("import", "xdf", src, "--out", tmp_path, limit=True)
    assert done.returncode == EXIT_ERROR, done.stderr
    assert "Traceback" not in done.stderr
    assert said in error_line(done.stderr)


# ---- one clear line each (case 18) ------------------------------------------------------
def test_a_fifo_is_named_as_one(tmp_path, capsys):
    fifo = tmp_path / "live.xdf"
    os.mkfifo(fifo)
    code, _, err = run(capsys, "import", "xdf", fifo, "--out", tmp_path)
    assert code == EXIT_ERROR
    assert error_line(err) == f"tactile-studio: error: {fifo}: a FIFO (named pipe), not an XDF file"


def test_pyxdfs_own_log_lines_stay_out_of_the_terminal(tmp_path):
    """pyxdf warned about a header carrying its own stream_id and about a stream without
    clock offsets, on stderr; our lines say what matters."""
    src = tmp_path / "own_id.xdf"
    t = T0 + np.arange(50) / RATE
    src.write_bytes(b"XDF:" + chunk(2, header_xml("Mat", "Tactile", 180, 43, "int32")
                                    .replace(b"</info>", b"<stream_id>9</stream_id></info>"), 1)
                    + chunk(3, numeric_samples(t, counts(50), "i"), 1) + footer(1, 50))
    done = command("import", "xdf", src, "--out", tmp_path)
    assert done.returncode == EXIT_OK, done.stderr
    said = done.stdout + done.stderr
    assert "stream_id" not in said and "clock-segments" not in said


def test_names_from_the_file_reach_the_terminal_escaped(tmp_path, capsys):
    """A stream's name is the file's text: a CR or an 8-bit escape in it is shown, not
    obeyed, in the error line."""
    src = tmp_path / "named.xdf"
    src.write_bytes(b"XDF:" + chunk(2, header_xml("EDA&#13;\x9b2J", "EDA", 1, 32,
                                                  "double64"), 1)
                    + footer(1, 0))
    code, _, err = run(capsys, "import", "xdf", src, "--out", tmp_path)
    assert code == EXIT_ERROR
    assert "(streams: EDA\\r\\x9b2J (1 ch))" in error_line(err)


# ---- a study of many files is read one file at a time -----------------------------------
def eeg_run(path: Path) -> Path:
    """A LabRecorder-like run: a small tactile stream beside 31 MB of 256-channel EEG."""
    t = T0 + np.arange(400) / RATE
    te = T0 + np.arange(15_000) / 500.0
    with open(path, "wb") as fh:
        w = XdfWriter(fh)
        w.file_header()
        w.stream_header(1, "Mat", "Tactile", 180, RATE, "int32", "mat-1", T0)
        w.stream_header(2, "EEG", "EEG", 256, 500.0, "double64", "eeg-1", T0)
        w.samples(1, "int32", t, counts())
        w.samples(2, "double64", te, np.zeros((15_000, 256)))
        w.stream_footer(1, t[0], t[-1], 400, [])
        w.stream_footer(2, te[0], te[-1], 15_000, [])
    return path


def peak_kib(*argv) -> int:
    """The peak resident memory (KiB) of the real command in a child process."""
    code = ("import resource, sys; from tactile_studio.cli import main; rc = main(sys.argv[1:]);"
            " print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss); sys.exit(rc)")
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", code, *map(str, argv)], capture_output=True,
                          text=True, env=env, timeout=300)
    assert done.returncode == EXIT_OK, done.stderr
    return int(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_importing_many_files_holds_one_file_at_a_time(tmp_path):
    """Every file's streams (here 31 MB of EEG each, kept as auxiliary signals) were read
    before the first session was written, so a study of hour-long runs ran out of memory;
    now each file is read, written and let go: six files peak as one does."""
    runs = [eeg_run(tmp_path / f"sub-P0{k}_run-1.xdf") for k in range(1, 7)]
    one = peak_kib("import", "xdf", runs[0], "--out", tmp_path / "one")
    six = peak_kib("import", "xdf", *runs, "--out", tmp_path / "six")
    assert six - one < 40 * 1024, (one, six)  # each file held added its 31 MB
    with SessionFile(tmp_path / "six" / "sub-P06_run-1.h5") as s:
        assert s.n_frames == 400 and s.aux_signals()[0].values.shape == (15_000, 256)
