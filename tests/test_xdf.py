"""XDF out (``export --format xdf``) and in (``import xdf``): real files read back by
pyxdf and by our importer, with clock offsets, a reconnect gap, trials as markers and
auxiliary signals.

Budget: ~5 s. Sessions are written in tmp_path with SessionWriter; no LSL needed.
"""

from __future__ import annotations

import json

import numpy as np
import pyxdf

from tactile_studio.cli import main
from tactile_studio.sensor.channels import RAW, frame_channels
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage import Session, SessionWriter
from tactile_studio.storage.aux_signals import AuxSignal
from tactile_studio.storage.xdf_export import export_xdf

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
    assert [c["label"][0] for c in chans] == [c["label"] for c in frame_channels(SHEARSENSE_6X6, RAW)]
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
    assert "wrote" in capsys.readouterr().out
    streams, _ = load(out / "plain.xdf", dejitter_timestamps=False)
    np.testing.assert_allclose(streams["TactileStudio-simulated"]["time_stamps"], host, atol=1e-6)
    assert set(streams) == {"TactileStudio-simulated", "TactileStudio-simulated-markers"}
    with Session(src) as s:
        assert s.aux_signals() == []
