"""What the app exposes (issue 33, item 12): an LSL stream's metadata, which anyone on the
network can read, names a replayed file by its name only (it published the absolute path,
with the user's folders); a recording whose --out name is not UTF-8 finishes and books
its time in the sensor logbook (it ended in a UnicodeEncodeError traceback). The local
Ray instance's isolation is tested with the Ray sweep in test_sweep.py (one Ray start).
"""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
from pathlib import Path

from learn_fixtures import write_participant

from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.devices.registry import create_device
from tactile_studio.storage.books.logbook import default_path
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.streams import load_pylsl, measure_offset
from tactile_studio.streams.lsl_meta import frame_stream_info, read_tactile_desc

EXE = str(Path(sys.executable).parent / "tactile-studio")


def test_stream_metadata_names_a_replayed_file_without_its_folders(tmp_path):
    folder = tmp_path / "home" / "alice" / "study P01"
    folder.mkdir(parents=True)
    path = write_participant(folder / "P01.h5", "P01", 101, gestures=("Poke",), blocks=1)
    pylsl = load_pylsl()
    engine = AcquisitionEngine(create_device("replay", {"path": str(path), "speed": 0}))
    info = frame_stream_info(pylsl, engine.layout, engine.device_info(), "raw", "ts-exposure",
                             "ts-exposure-src", measure_offset(pylsl.local_clock))
    xml = info.as_xml()
    assert "P01.h5" in xml
    assert str(tmp_path) not in xml and "alice" not in xml and "study P01" not in xml
    assert read_tactile_desc(info)["device"] == "replay"
    settings = info.desc().child("tactile_studio").child_value("settings")
    assert '"path": "P01.h5"' in settings, settings


def test_a_non_utf8_out_name_records_and_books_its_time(tmp_path):
    name = os.fsencode(tmp_path) + b"/caf\xff.h5"
    env = {**os.environ, "TACTILE_STUDIO_DATA_DIR": str(tmp_path / "data")}
    proc = subprocess.run([EXE, "record", "--device", "simulated", "--set", "rate=200",
                           "--seconds", "1", "--out", name], capture_output=True, env=env,
                          timeout=120)
    err = proc.stderr.decode("utf-8", "replace")
    assert proc.returncode == 0 and "Traceback" not in err, err
    with SessionFile(os.fsdecode(name)) as s:
        assert s.n_frames > 0 and s.closed_cleanly
    assert subprocess.run([EXE, "info", name], capture_output=True, env=env,
                          timeout=60).returncode == 0
    with sqlite3.connect(tmp_path / "data" / default_path().name) as db:
        sources = [row[0] for row in db.execute("SELECT source FROM usage")]
    assert sources == [os.fsencode(name).decode("utf-8", "backslashreplace")]
    assert sources[0].endswith("caf\\xff.h5")
