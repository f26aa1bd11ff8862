"""XDF out (``export --format xdf``) and in (``import xdf``): real files read back by
pyxdf and by our importer, with clock offsets, a reconnect gap, trials as markers and
auxiliary signals.

Budget: ~5 s. Sessions are written in tmp_path with SessionWriter; no LSL needed.
"""

from __future__ import annotations

import json
import struct

import numpy as np
import pyxdf

from tactile_studio.cli import main
from tactile_studio.sensor.channels import RAW, frame_channels
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage import SessionFile, SessionWriter
from tactile_studio.storage.exchange.xdf_export import export_xdf
from tactile_studio.storage.format.aux_signals import AuxSignal

RATE = 43.0
T0 = 1.7e9


def gap_session(path, lsl=True, aux=True):
    """400 frames at 43 Hz with a 3 s reconnect gap after row 200, LSL turned on at row 0
    and its offset moved (an NTP step) at row 300, two trials (one redone), an EDA signal."""
    rng = np.random.default_rng(7)
    raw = rng.integers(30000, 30200, size=(400, 180)).astype(np.uint16)
    host = T0 + np.arange(400) / RATE
    host[200:] += 3.0
    signals = [AuxSignal("EDA-1", T0 + np.arange(120) / 4.0, rng.normal(2, 0.1, (120, 1)),
                         ["eda"], "uS", 4.0, "EDA", "shimmer-1")] if aux else None
    meta = {"participant": "P03", "gestures": ["Poke", "Stroke"]}
    with SessionWriter(path, SHEARSENSE_6X6, {"plugin": "simulated", "nominal_rate_hz": RATE,
                                              "settings": {"rate": RATE}}, meta,
                       aux=signals) as w:
        if lsl:
            w.add_event("lsl_clock", 0, host[0], streaming=True, offset_s=-1.6e9 + 0.25,
                        uncertainty_s=1e-6)
        w.append_frames(raw[:200], host[:200] - T0, host[:200])
        w.add_event("disconnect", 200, host[199] + 0.1)
        w.add_event("gap", 200, host[200], seconds=3.0, cause="reconnect")
        w.append_frames(raw[200:], host[200:] - T0, host[200:])
        if lsl:
            w.add_event("lsl_clock", 300, host[300], streaming=True, offset_s=-1.6e9 + 0.75,
                        uncertainty_s=1e-6)
        for i, (g, k, a) in enumerate([("Poke", "p", 50), ("Stroke", "s", 250)]):
            w.add_trial({"index": i, "block": 0, "gesture": g, "key": k, "start_sample": a,
                         "end_sample": a + 40, "status": "ok", "reason": None, "flags": []})
        w.update_trial(0, status="redone", reason="too soft")
    return path, raw, host


def load(path, **kw):
    streams, header = pyxdf.load_xdf(str(path), **kw)
    return {s["info"]["name"][0]: s for s in streams}, header


def test_export_xdf_round_trips_through_pyxdf_with_clock_offsets_and_a_gap(tmp_path):
    src, raw, host = gap_session(tmp_path / "s.h5")
    out = export_xdf(src, tmp_path)
    assert out == tmp_path / "s.xdf"
    streams, header = load(out, synchronize_clocks=True, dejitter_timestamps=False)
    assert header["info"]["version"] == ["1.0"]
    frames = streams["TactileStudio-simulated"]
    assert frames["info"]["type"] == ["Tactile"]
    assert frames["info"]["channel_format"] == ["int32"]
    assert float(frames["info"]["nominal_srate"][0]) == RATE
    np.testing.assert_array_equal(frames["time_series"], raw.astype(np.int32))
    # LSL time: each row with the offset in force (rows 300.. moved by 0.5 s)
    offset = np.where(np.arange(400) < 300, -1.6e9 + 0.25, -1.6e9 + 0.75)
    np.testing.assert_allclose(frames["time_stamps"], host + offset, rtol=0, atol=1e-6)
    chans = frames["info"]["desc"][0]["channels"][0]["channel"]
    assert [c["label"][0] for c in chans] == [c["label"]
                                              for c in frame_channels(SHEARSENSE_6X6, RAW)]
    ts = frames["info"]["desc"][0]["tactile_studio"][0]
    assert ts["layout"][0]["name"] == ["shearsense-6x6"] and ts["participant"] == ["P03"]

    markers = streams["TactileStudio-simulated-markers"]
    texts = [json.loads(m[0]) for m in markers["time_series"]]
    kinds = [m["kind"] for m in texts]
    assert "lsl_clock" not in kinds and {"disconnect", "gap"} <= set(kinds)
    ends = [m for m in texts if m["kind"] == "trial_end"]
    assert [(m["gesture"], m["status"]) for m in ends] == [("Poke", "redone"), ("Stroke", "ok")]
    starts = [i for i, m in enumerate(texts) if m["kind"] == "trial_start"]
    assert markers["time_stamps"][starts[1]] == frames["time_stamps"][250]
    assert markers["time_stamps"][[i for i, m in enumerate(texts) if m["kind"] == "trial_end"][1]] \
        == frames["time_stamps"][289]

    eda = streams["EDA-1"]
    assert eda["info"]["type"] == ["EDA"] and eda["time_series"].shape == (120, 1)
    np.testing.assert_allclose(eda["time_stamps"], T0 + np.arange(120) / 4.0 - 1.6e9 + 0.25,
                               atol=1e-6)
    assert eda["info"]["desc"][0]["channels"][0]["channel"][0]["unit"] == ["uS"]

    # with jitter removal on (how labs load files) the samples stay and the gap splits
    streams, _ = load(out, jitter_break_threshold_samples=40)
    frames = streams["TactileStudio-simulated"]
    assert len(frames["time_stamps"]) == 400
    assert len(frames["info"]["segments"]) == 2


def test_export_xdf_without_lsl_is_on_host_time_and_the_cli_writes_it(tmp_path, capsys):
    src, raw, host = gap_session(tmp_path / "plain.h5", lsl=False, aux=False)
    out = tmp_path / "out"
    out.mkdir()
    assert main(["export", str(src), "--format", "xdf", "--out", str(out)]) == 0
    said = capsys.readouterr()
    assert "wrote" in said.out
    assert ".part" not in said.err and "plain.xdf: " in said.err  # the file, not its temporary
    streams, _ = load(out / "plain.xdf", dejitter_timestamps=False)
    np.testing.assert_allclose(streams["TactileStudio-simulated"]["time_stamps"], host, atol=1e-6)
    assert set(streams) == {"TactileStudio-simulated", "TactileStudio-simulated-markers"}
    with SessionFile(src) as s:
        assert s.aux_signals() == []


# ---- import ----------------------------------------------------------------------------
def chunk(tag, content, stream_id=None):
    """One XDF chunk by hand (independent of our writer): length, tag, [id], content."""
    head = b"" if stream_id is None else struct.pack("<I", stream_id)
    body = struct.pack("<H", tag) + head + content
    return b"\x04" + struct.pack("<I", len(body)) + body


def header_xml(name, type_, n, rate, fmt, extra=""):
    return (f'<?xml version="1.0"?><info><name>{name}</name><type>{type_}</type>'
            f"<channel_count>{n}</channel_count><nominal_srate>{rate}</nominal_srate>"
            f"<channel_format>{fmt}</channel_format><source_id>{name}-src</source_id>"
            f"<desc>{extra}</desc></info>").encode()


def footer(stream_id, n, first=0.0, last=0.0):
    """A StreamFooter chunk (LabRecorder writes one per stream when it stops; a file
    without them is a recording that did not end)."""
    xml = (f'<?xml version="1.0"?><info><first_timestamp>{first}</first_timestamp>'
           f"<last_timestamp>{last}</last_timestamp><sample_count>{n}</sample_count>"
           "<clock_offsets></clock_offsets></info>").encode()
    return chunk(6, xml, stream_id)


def numeric_samples(stamps, values, code):
    out = [b"\x04" + struct.pack("<I", len(stamps))]
    for t, row in zip(stamps, values):
        out.append(b"\x08" + struct.pack("<d", t) + struct.pack(f"<{len(row)}{code}", *row))
    return b"".join(out)


def string_samples(stamps, texts):
    out = [b"\x04" + struct.pack("<I", len(stamps))]
    for t, text in zip(stamps, texts):
        data = text.encode()
        size = b"\x01" + struct.pack("<B", len(data)) if len(data) < 256 else \
            b"\x04" + struct.pack("<I", len(data))
        out.append(b"\x08" + struct.pack("<d", t) + size + data)
    return b"".join(out)


def foreign_xdf(path):
    """A LabRecorder-like file: a 64-channel pressure mat at 100 Hz whose clock is 0.5 s
    behind the recorder's, an EDA band at 32 Hz (1.25 s behind), plain-text markers."""
    rng = np.random.default_rng(9)
    mat_t = 1000.0 + np.arange(600) / 100.0
    # a stroke: a pressure blob crossing the mat between the markers (1 s .. 4 s)
    pos = np.clip((np.arange(600) - 100) / 300.0, 0, 1) * 7
    on = ((np.arange(600) >= 100) & (np.arange(600) < 400)).astype(np.float32)
    rows, cols = np.divmod(np.arange(64), 8)
    blob = np.exp(-((rows[None] - 3.5) ** 2 + (cols[None] - pos[:, None]) ** 2) / 2.0)
    mat = (100 + 8 * on[:, None] * blob + rng.normal(0, 0.05, (600, 64))).astype(np.float32)
    eda_t = 2000.0 + np.arange(192) / 32.0
    # skin conductance rises a little after the touch begins (an SCR), plus noise
    since = np.clip(eda_t - 2000.0 - 1.25, 0, None)
    eda = (3 + 0.4 * since * np.exp(1 - since / 1.0) * (since > 0) / 1.0
           + rng.normal(0, 0.01, 192))[:, None]
    chans = "".join(f"<channel><label>{lab}</label><unit>uS</unit></channel>" for lab in ["gsr"])
    parts = [b"XDF:", chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>'),
             chunk(2, header_xml("PressureMat", "Pressure", 64, 100, "float32"), 1),
             chunk(2, header_xml("Shimmer-EDA", "EDA", 1, 32, "double64",
                                 f"<channels>{chans}</channels>"), 2),
             chunk(2, header_xml("PsychoPy", "Markers", 1, 0, "string"), 3)]
    for k in range(3):  # interleaved as a recorder writes them
        a, b = k * 200, (k + 1) * 200
        parts.append(chunk(3, numeric_samples(mat_t[a:b], mat[a:b], "f"), 1))
        parts.append(chunk(3, numeric_samples(eda_t[k * 64:(k + 1) * 64],
                                              eda[k * 64:(k + 1) * 64], "d"), 2))
        parts.append(chunk(4, struct.pack("<dd", 1000.5 + 2 * k, 0.5), 1))
        parts.append(chunk(4, struct.pack("<dd", 1000.5 + 2 * k, -998.75), 2))
    parts.append(chunk(3, string_samples([1001.0, 1004.0], ["start", "stop"]), 3))
    parts.append(chunk(4, struct.pack("<dd", 1001.0, 0.0), 3))
    parts += [footer(1, 600), footer(2, 192), footer(3, 2)]
    path.write_bytes(b"".join(parts))
    return mat, eda


def test_a_foreign_xdf_imports_with_clocks_markers_aux_and_bids_names(tmp_path, capsys):
    src = tmp_path / "sub-P07_ses-S2_task-touch_run-1.xdf"
    mat, eda = foreign_xdf(src)
    out = tmp_path / "out"
    rc = main(["import", "xdf", str(src), "--out", str(out), "--participant", "IGNORED"])
    assert rc == 0, capsys.readouterr().err
    with SessionFile(out / "sub-P07_ses-S2_task-touch_run-1.h5") as s:
        m = s.metadata
        assert (m["participant"], m["session_label"], m["task"], m["run"]) == (
            "P07", "S2", "touch", "1")
        assert s.layout.name == "grid-8x8" and s.n_frames == 600
        np.testing.assert_array_equal(s.raw(), mat.astype(s.layout.raw_dtype))
        times = s.column("host_time")
        np.testing.assert_allclose(times, 1000.5 + np.arange(600) / 100.0, atol=1e-6)
        ev = [(e["kind"], e.get("text"), e["frame"]) for e in s.events if e["kind"] == "marker"]
        assert ev == [("marker", "start", 50), ("marker", "stop", 350)]
        (aux,) = s.aux_signals()
        assert (aux.name, aux.type, aux.labels, aux.unit, aux.rate_hz) == \
            ("Shimmer-EDA", "EDA", ["gsr"], "uS", 32.0)
        assert s.summary()["aux"] == [{"name": "Shimmer-EDA", "type": "EDA", "unit": "uS",
                                       "rate_hz": 32.0, "channels": ["gsr"], "samples": 192}]
        np.testing.assert_allclose(aux.time, 1001.25 + np.arange(192) / 32.0, atol=1e-6)
        np.testing.assert_allclose(aux.values, eda)


def test_info_lists_the_auxiliary_signals_with_their_rates(tmp_path, capsys):
    """``info`` (text) names each /aux signal, its channels, samples and rate measured from
    its own timestamps beside the nominal one; JSON had them, the text did not."""
    src, _, _ = gap_session(tmp_path / "s.h5")
    assert main(["info", str(src)]) == 0
    aux = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("aux:")]
    assert aux == ["aux:        EDA-1 (EDA): 1 channel eda [uS], 120 samples at 4.00 Hz "
                   "(nominal 4 Hz)"]
    plain, _, _ = gap_session(tmp_path / "plain.h5", aux=False)
    assert main(["info", str(plain)]) == 0
    assert "aux:" not in capsys.readouterr().out


def test_our_own_xdf_imports_back_with_trials_events_and_aux(tmp_path, capsys):
    src, raw, host = gap_session(tmp_path / "s.h5")
    xdf = export_xdf(src, tmp_path)
    out = tmp_path / "out"
    assert main(["import", "xdf", str(xdf), "--out", str(out)]) == 0
    with SessionFile(src) as a, SessionFile(out / "s.h5") as b:
        assert b.n_frames == a.n_frames and b.layout.name == "shearsense-6x6"
        np.testing.assert_array_equal(b.raw(), a.raw())
        assert b.metadata["participant"] == "P03"
        t = b.column("host_time")
        assert t[201] - t[199] > 3.0          # the reconnect gap is still there
        assert [(x.gesture, x.status, x.start_sample, x.end_sample, x.block)
                for x in b.trials] == [(x.gesture, x.status, x.start_sample,
                                        x.end_sample, x.block) for x in a.trials]
        assert {"disconnect", "gap"} <= {e["kind"] for e in b.events}
        # end_time is the device time just after a trial's last frame, as collected
        dev = b.column("device_time")
        assert [(x.start_time, x.end_time) for x in b.trials] == [
            (dev[x.start_sample], dev[x.end_sample]) for x in b.trials]
        (aux,) = b.aux_signals()
        assert aux.name == "EDA-1" and aux.values.shape == (120, 1)


def test_import_xdf_refuses_a_file_without_tactile_stream_in_one_line(tmp_path, capsys):
    src = tmp_path / "eda_only.xdf"
    src.write_bytes(b"XDF:" + chunk(1, b"<info><version>1.0</version></info>")
                    + chunk(2, header_xml("Shimmer-EDA", "EDA", 1, 32, "double64"), 1)
                    + chunk(3, numeric_samples([1.0, 1.03], [[1.0], [2.0]], "d"), 1)
                    + footer(1, 2))
    rc = main(["import", "xdf", str(src), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if "error:" in ln]
    assert rc == 1 and len(lines) == 1 and err.strip().endswith(lines[0]) and "Traceback" not in err
    assert "eda_only.xdf: no tactile stream (streams: Shimmer-EDA (1 ch))" in err
    rc = main(["import", "xdf", str(src), "--out", str(tmp_path), "--stream", "Shimmer-EDA",
               "--layout", "grid-1x1"])
    assert rc == 0 and (tmp_path / "eda_only.h5").exists()
    (tmp_path / "bad.xdf").write_bytes(b"not an xdf")
    rc = main(["import", "xdf", str(tmp_path / "bad.xdf"), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 1 and "bad.xdf: not an XDF file" in err and "Traceback" not in err


def test_a_session_recorded_while_streaming_exports_the_stamps_the_outlet_sent(tmp_path,
                                                                             capsys):
    """``record --lsl`` with a real inlet listening: the XDF export's frame timestamps are
    exactly the LSL timestamps the live outlet sent for the same frames."""
    from lsl_fixtures import Collector

    got = Collector("name='TactileStudio-simulated'")
    src = tmp_path / "live.h5"
    rc = main(["record", "--device", "simulated", "--set", "rate=100", "--seconds", "1.5",
               "--out", str(src), "--lsl", "--lsl-wait", "10"])
    got.stop()
    assert rc == 0, capsys.readouterr().err
    streams, _ = load(export_xdf(src, tmp_path), synchronize_clocks=True,
                      dejitter_timestamps=False)
    frames = streams["TactileStudio-simulated"]
    with SessionFile(src) as s:
        assert len(frames["time_stamps"]) == s.n_frames == len(got.stamps)
        np.testing.assert_array_equal(frames["time_series"], np.asarray(got.samples))
    np.testing.assert_allclose(frames["time_stamps"], got.stamps, rtol=0, atol=1e-9)


def test_our_own_xdf_imports_back_with_each_break_counted_once(tmp_path, capsys):
    """A reconnect and a resume are breaks in the timestamps that the file's own markers
    already name (``gap``, ``reconnect``, ``resume``). Imported back, pyxdf also sees them
    as jitter segments; each was then counted twice (``info``: gaps 4 instead of 2)."""
    rng = np.random.default_rng(3)
    raw = rng.integers(30000, 30200, size=(300, 180)).astype(np.uint16)
    host = T0 + np.arange(300) / RATE
    host[100:] += 3.0   # a reconnect gap
    host[200:] += 5.0   # the collection was resumed 5 s later
    dev = np.arange(300) / RATE
    src = tmp_path / "breaks.h5"
    with SessionWriter(src, SHEARSENSE_6X6, {"plugin": "simulated", "nominal_rate_hz": RATE},
                       {"participant": "P03"}) as w:
        w.append_frames(raw[:100], dev[:100], host[:100])
        w.add_event("gap", 100, host[100], seconds=3.0, cause="reconnect")
        w.add_event("reconnect", 100, host[100], gap_s=3.0, attempts=2)
        w.append_frames(raw[100:200], dev[100:200], host[100:200])
        w.add_event("resume", 200, host[200], segment=True, device_time_offset=dev[200])
        w.append_frames(raw[200:], dev[200:], host[200:])
    out = tmp_path / "out"
    out.mkdir()
    assert main(["export", str(src), "--format", "xdf", "--out", str(out)]) == 0
    assert main(["import", "xdf", str(out / "breaks.xdf"), "--out", str(out)]) == 0
    capsys.readouterr()
    summaries = []
    for path in (src, out / "breaks.h5"):
        assert main(["info", "--json", str(path)]) == 0
        summaries.append(json.loads(capsys.readouterr().out))
    before, after = summaries
    assert (after["gaps"], after["reconnects"], after["segments"]) == (2, 1, 2)
    assert (before["gaps"], before["reconnects"], before["segments"]) == (2, 1, 2)
    assert abs(after["rate_hz"] - RATE) < 0.05
