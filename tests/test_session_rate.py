"""A session's measured rate is the device's, whatever happened between its frames: the
time a device was gone before it reconnected is no frame time (as a resume's is not)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_writer import SessionWriter

RATE = 43.0


def _session(path, outage_s: float, *, reconnect_event: bool):
    raw = np.full((400, 180), 30000, dtype=np.uint16)
    t = np.arange(400) / RATE
    t[200:] += outage_s
    with SessionWriter(path, SHEARSENSE_6X6, {"plugin": "serial", "nominal_rate_hz": RATE},
                       {"participant": "P01"}) as w:
        w.append_frames(raw[:200], t[:200], 1e9 + t[:200])
        w.add_event("gap", 200, 1e9 + t[200], seconds=outage_s, cause="reconnect")
        if reconnect_event:
            w.add_event("reconnect", 200, 1e9 + t[200], gap_s=outage_s, attempts=3)
        w.append_frames(raw[200:], t[200:], 1e9 + t[200:])
    return path


@pytest.mark.parametrize("reconnect_event", [True, False])
def test_a_reconnect_outage_is_not_frame_time(tmp_path, reconnect_event):
    path = _session(tmp_path / "s.h5", 3.0, reconnect_event=reconnect_event)
    with SessionFile(path) as s:
        summary = s.summary()
    assert summary["rate_hz"] == pytest.approx(RATE, rel=1e-3)  # was 32.5 over the outage
    assert summary["duration_s"] == pytest.approx(400 / RATE, rel=1e-3)
    assert summary["segments"] == 1  # an outage is no resume


def test_a_break_an_xdf_import_found_is_no_frame_time(tmp_path, capsys):
    """A LabRecorder file whose tactile stream paused 5 s (no marker of ours says why):
    the import finds the break and records it as a gap (``cause: xdf``), yet ``info``
    measured 27.9 Hz over 14.3 s for a 43 Hz stream of 9.3 s."""
    import json

    from tactile_studio.cli import main

    raw = np.full((400, 180), 30000, dtype=np.uint16)
    host = 1.7e9 + np.arange(400) / RATE
    host[200:] += 5.0
    src = tmp_path / "paused.h5"
    with SessionWriter(src, SHEARSENSE_6X6, {"plugin": "serial", "nominal_rate_hz": RATE},
                       {"participant": "P01"}) as w:
        w.append_frames(raw, host, host)
    out = tmp_path / "out"
    out.mkdir()
    assert main(["export", str(src), "--format", "xdf", "--out", str(out)]) == 0
    assert main(["import", "xdf", str(out / "paused.xdf"), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["info", "--json", str(out / "paused.h5")]) == 0
    info = json.loads(capsys.readouterr().out)
    assert [e["cause"] for e in info["events"] if e["kind"] == "gap"] == ["xdf"]
    assert info["rate_hz"] == pytest.approx(RATE, rel=1e-3)
    assert info["duration_s"] == pytest.approx(400 / RATE, rel=1e-3)


def test_a_pause_in_an_old_shearsense_csv_is_a_gap_and_no_frame_time(tmp_path, capsys):
    """The old software's CSV has times only: a 5 s pause in them (its serial link
    stalled) made ``info`` say 27.9 Hz over 14.3 s for 43 Hz over 9.3 s, with no gap.
    The import now records the pause as a gap (``cause: import``), left out of the rate."""
    import json

    from tactile_studio.cli import main
    from tactile_studio.storage.exchange.shearsense import write_shearsense_csv

    raw = np.full((400, 180), 30000, dtype=np.uint16)
    times = 1.69e9 + np.arange(400) / RATE
    times[200:] += 5.0
    labels = np.zeros(400, dtype=np.int64)
    labels[50:80] = ord("p")
    csv = tmp_path / "P04_paused_FLAT.csv"
    write_shearsense_csv(csv, raw, times, labels, np.full(180, 30000.0))
    assert main(["import", "shearsense", str(csv), "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    assert main(["info", "--json", str(tmp_path / "P04_paused_FLAT.h5")]) == 0
    info = json.loads(capsys.readouterr().out)
    gaps = [e for e in info["events"] if e["kind"] == "gap"]
    assert [(g["frame"], g["cause"], g["seconds"]) for g in gaps] == [(200, "import", 5.023256)]
    assert info["gaps"] == 1
    assert info["rate_hz"] == pytest.approx(RATE, rel=1e-3)
    assert info["duration_s"] == pytest.approx(400 / RATE, rel=1e-3)
    assert info["metadata"]["device"]["rate_hz"] == pytest.approx(RATE, rel=1e-3)


def test_frames_a_device_skipped_are_at_their_row_and_no_frame_time(tmp_path):
    """A device that numbers its frames and skips some (a BLE link dropping packets):
    each ``gap`` event was put at the first row of the batch it came in, not at the
    jump, and the rate counted the missing frames' time as frame time (980 Hz for a
    1000 Hz device missing 2%)."""
    from plugin_fixtures import CountingDevice
    from waiting import wait_until

    from tactile_studio.devices.engine import FINISHED, AcquisitionEngine
    from tactile_studio.storage.recording.recorder import Recorder

    engine = AcquisitionEngine(CountingDevice(frames=300, skip_every=50), capacity=1024)
    rec = Recorder(engine, tmp_path / "skips.h5")
    engine.start()
    wait_until(lambda: engine.state == FINISHED, what="the device to finish")
    rec.stop()
    engine.stop()
    with SessionFile(tmp_path / "skips.h5") as s:
        seq = s.column("seq")
        gaps = [e for e in s.events if e["kind"] == "gap"]
        summary = s.summary()
    assert len(gaps) == 6
    for g in gaps:  # the row of the first frame after the jump
        assert seq[g["frame"]] == g["after_seq"] + g["missing"] + 1
    assert summary["rate_hz"] == pytest.approx(1000.0, rel=1e-3)
    assert summary["frames_lost"] == {"overrun": 0, "missing": 6}
