"""The sink protocol (setup, event, close; frames pulled from the engine) and the file
sink's hours of use: booked exactly once however a recording ends, the exit hook too.
Real simulator, real HDF5 files, a real logbook in a tmp folder, real LSL on the loopback.

Budget: ~8 s (a subprocess recording, short recordings, one LSL stream lookup)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import uuid

import pylsl
import pytest
from collect_fixtures import make_rig, mini_protocol, start
from lsl_fixtures import Collector, unique
from waiting import wait_until

from tactile_studio.acquisition import LiveAcquisition
from tactile_studio.acquisition.file_sink import close_file_sink, open_file_sink
from tactile_studio.acquisition.marker_recording import MarkerRecording
from tactile_studio.acquisition.sinks import LslPublishing, Sink
from tactile_studio.characterise.lab import Lab
from tactile_studio.devices.registry import create_device
from tactile_studio.jobs import CancelToken
from tactile_studio.plugins.sim_force import SimulatedForce
from tactile_studio.plugins.sim_stage import SimulatedStage
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.recording.recorder import Recorder


@pytest.fixture
def data_dir(tmp_path, monkeypatch):
    folder = tmp_path / "data"
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(folder))
    return folder


def _usage_rows(sensor: str) -> int:
    with Logbook() as book:
        return book._db.execute("SELECT COUNT(*) FROM usage WHERE sensor_id=?",
                                (sensor,)).fetchone()[0]


def test_the_file_lsl_publishing_and_marker_inlets_are_sinks(tmp_path, data_dir) -> None:
    s = LiveAcquisition()
    engine = s.open("simulated", {"rate": "100", "speed": "0", "gesture": "idle"})
    name = unique("stim")
    outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name, "Markers", 1, pylsl.IRREGULAR_RATE,
                                                 pylsl.cf_string, f"{name}-src"))
    rec = s.start_recording(tmp_path / "s.h5")
    markers = MarkerRecording(engine, [name])
    try:
        assert isinstance(rec, Recorder) and isinstance(rec, Sink)
        assert isinstance(LslPublishing(engine), Sink)
        assert isinstance(markers, Sink)
    finally:
        markers.stop()
        s.close()
        del outlet


def test_a_session_event_reaches_the_file_and_the_lsl_markers(tmp_path, data_dir) -> None:
    s = LiveAcquisition()
    seed = str(uuid.uuid4().int % 100000)  # its own LSL source ID among parallel tests
    engine = s.open("simulated", {"rate": "100", "speed": "4", "seed": seed})
    s.set_lsl(True)
    got = Collector(f"source_id='{s.lsl.source_id}:markers'")
    got.wait_connected()
    s.start_recording(tmp_path / "s.h5")
    s.start()
    try:
        wait_until(lambda: s.recorder.rows_written > 20, what="20 rows")
        s.add_event("condition", name="gloved", time_s=1234.5)
        wait_until(lambda: any(json.loads(m[0])["kind"] == "condition"
                               for m in list(got.samples)), what="the condition marker")
    finally:
        s.close()
        got.stop()
    with SessionFile(tmp_path / "s.h5") as f:
        ev = [e for e in f.events if e["kind"] == "condition"]
    assert len(ev) == 1 and ev[0]["name"] == "gloved" and ev[0]["time"] == 1234.5
    marker = [json.loads(m[0]) for m in got.samples if json.loads(m[0])["kind"] == "condition"]
    assert marker == [{"kind": "condition", "source": "app", "name": "gloved"}]
    assert engine.state == "stopped"


def test_a_session_stop_books_the_hours_of_use_exactly_once(tmp_path, data_dir) -> None:
    s = LiveAcquisition()
    engine = s.open("simulated", {"rate": "100", "speed": "0", "gesture": "idle",
                                  "seed": "31"})
    rec = s.start_recording(tmp_path / "s.h5")
    s.start()
    assert engine.wait_frames(150, timeout=20)
    s.stop_recording()
    close_file_sink(rec)  # a second close (a collection's close()) books nothing more
    rec.stop()
    s.close()
    with SessionFile(tmp_path / "s.h5") as f:
        rows = f.n_frames
    assert rows == rec.recorded > 0
    with Logbook() as book:
        assert book.hours("sim-31") * 3600 == pytest.approx(rows / 100.0)
    assert _usage_rows("sim-31") == 1


def test_a_file_sink_closed_by_its_owner_books_once(tmp_path, data_dir) -> None:
    """The way in for collect's plain recorder and the characterisation lab."""
    s = LiveAcquisition()
    engine = s.open("simulated", {"rate": "100", "speed": "0", "gesture": "idle",
                                  "seed": "32"})
    s.start()
    rec = open_file_sink(engine, tmp_path / "f.h5", {"source": "test"})
    wait_until(lambda: rec.rows_written >= 50, what="50 rows")
    close_file_sink(rec)
    close_file_sink(rec)
    s.close()
    with SessionFile(tmp_path / "f.h5") as f:
        assert f.metadata["sensor_id"] == "sim-32"
        rows = f.n_frames
    with Logbook() as book:
        assert book.hours("sim-32") * 3600 == pytest.approx(rows / 100.0)
    assert _usage_rows("sim-32") == 1


def test_only_the_file_sink_makes_a_recorder() -> None:
    """close_file_sink relies on the booking open_file_sink registered: a Recorder built
    anywhere else in the product would record hours of use nobody books."""
    from pathlib import Path

    import tactile_studio

    repo = Path(tactile_studio.__file__).parent.parent
    sources = [p for room in ("tactile_studio", "ui", "plugins")
               for p in (repo / room).rglob("*.py")]
    makers = sorted(str(p.relative_to(repo)) for p in sources
                    if p.name != "recorder.py" and "Recorder(" in p.read_text())
    assert makers == ["tactile_studio/acquisition/file_sink.py"]


LEFT_OPEN = textwrap.dedent("""
    import sys
    from tactile_studio.acquisition import LiveAcquisition
    s = LiveAcquisition()
    engine = s.open("simulated", {"rate": "100", "speed": "0", "gesture": "idle",
                                  "seed": "33"})
    rec = s.start_recording(sys.argv[1])
    s.start()
    assert engine.wait_frames(200, timeout=20)
    sys.exit(0)  # never stopped: the exit hook closes the file
""")


def test_a_recording_closed_by_the_exit_hook_books_its_hours(tmp_path, data_dir) -> None:
    out = tmp_path / "left.h5"
    env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(data_dir)}
    done = subprocess.run([sys.executable, "-c", LEFT_OPEN, str(out)], env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    with SessionFile(out) as f:
        assert f.closed_cleanly
        rows = f.n_frames
    assert rows >= 200
    with Logbook() as book:
        assert book.hours("sim-33") * 3600 == pytest.approx(rows / 100.0)
    assert _usage_rows("sim-33") == 1


def test_a_collection_without_a_session_books_its_hours_once(tmp_path, data_dir) -> None:
    """collect's plain recorder (no LiveAcquisition) is a file sink too."""
    rig = make_rig(tmp_path, mini_protocol(n_gestures=3, blocks=1), "P01", speed=0.0,
                   seed=35)
    try:
        start(rig)
    finally:
        rig.close()
    rig.session.close()  # closed twice: booked once
    with SessionFile(rig.session.path) as f:
        rows = f.n_frames
    assert rows > 0
    with Logbook() as book:
        assert book.hours("sim-35") * 3600 == pytest.approx(rows / rig.engine.nominal_rate_hz)
    assert _usage_rows("sim-35") == 1


def test_the_characterisation_lab_books_its_hours_once(tmp_path, data_dir) -> None:
    device = create_device("simulated", {"speed": 0, "gesture": "idle", "seed": 36})
    stage, force, cancel = SimulatedStage(), SimulatedForce(), CancelToken()
    stage.couple(device)  # as run_characterisation does
    force.couple(device, stage)
    lab = Lab(device, stage, force, tmp_path / "lab.h5", 50.0, cancel, {"source": "test"})
    try:
        lab.clock.sleep(0.5, cancel)  # the bench's clock: the sensor streams with it
        wait_until(lambda: lab.recorder.rows_written >= 20, what="20 rows")
    finally:
        lab.close()
        stage.close()
    with SessionFile(tmp_path / "lab.h5") as f:
        rows = f.n_frames
    with Logbook() as book:
        assert book.hours("sim-36") * 3600 == pytest.approx(rows / device.nominal_rate_hz)
    assert _usage_rows("sim-36") == 1
