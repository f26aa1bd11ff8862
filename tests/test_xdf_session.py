"""The XDF round trip keeps what makes a session the same recording for a researcher
(issue 47 item 7): frames came back bit-identical but without protocol, condition,
sensor id, calibration, seed and block order. A real collection (virtual participant,
calibrated sensor) is exported, read with pyxdf, and imported back."""

from __future__ import annotations

import json

import numpy as np
import pytest
import pyxdf

from tactile_studio.cli import main
from tactile_studio.storage import SessionFile
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.storage.exchange.xdf_export import export_xdf
from tactile_studio.storage.exchange.xdf_session_fields import CARRIED, session_fields

PROTOCOL_FIELDS = ("protocol", "protocol_spec", "condition", "gestures", "trial_order",
                   "seed", "order_seed", "block_order", "practice_order", "sensor_id",
                   "calibration_id")


@pytest.fixture
def collected(tmp_path, monkeypatch, capsys):
    """One block of shear9 by a virtual participant on sim-1, which has a calibration."""
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "app"))
    with Logbook() as book:
        book.ensure_sensor("sim-1")
        book.add_calibration("sim-1", "plate", 0.3, {"fits": []})
    assert main(["collect", "--protocol", "shear9", "--participant", "P08", "--device",
                 "simulated", "--virtual-participant", "--speed", "0", "--blocks", "1",
                 "--seed", "1", "--set", "seed=1", "--condition", "PILLOW",
                 "--out", str(tmp_path / "data")]) == 0
    capsys.readouterr()
    (path,) = (tmp_path / "data").glob("*.h5")
    with SessionFile(path) as s:
        meta = s.metadata
    assert meta["calibration_id"] and meta["sensor_id"] == "sim-1" and meta["block_order"]
    return path, meta


def test_an_exported_xdf_carries_the_sessions_protocol_orders_sensor_and_calibration(
        collected, tmp_path):
    path, meta = collected
    xdf = export_xdf(path, tmp_path)
    streams, _ = pyxdf.load_xdf(str(xdf))
    (frames,) = [s for s in streams if s["info"]["type"][0] == "Tactile"]
    ours = frames["info"]["desc"][0]["tactile_studio"][0]
    assert set(CARRIED) == set(PROTOCOL_FIELDS)
    carried = {k: json.loads(v[0]) for k, v in ours["session"][0].items()}
    assert carried == {k: meta[k] for k in PROTOCOL_FIELDS if meta.get(k) is not None}
    assert carried["condition"] == "PILLOW" and carried["seed"] == 1
    # the sensor's id is the session's (it had said none: the device's settings hold none)
    assert ours["sensor_id"][0] == "sim-1"
    assert frames["info"]["desc"][0]["acquisition"][0]["serial_number"][0] == "sim-1"


def test_what_a_stranger_writes_there_is_read_only_when_it_is_what_it_should_be():
    values = {"protocol": "shear9", "condition": "FLAT", "seed": 3, "calibration_id": 2,
              "block_order": [["Poke", "Twist"], ["Twist", "Poke"]], "sensor_id": "S-042"}
    assert session_fields({k: [json.dumps(v)] for k, v in values.items()}) == values
    assert session_fields({"protocol": ["shear9"]}) == {}  # JSON text only, as written
    bad = {"protocol": [json.dumps("x" * 500)],             # too long
           "condition": [json.dumps("a\x1b[31mred")],        # not printable
           "seed": [json.dumps(True)],                       # not a number
           "block_order": [json.dumps([["Poke", 3]])],       # not names
           "gestures": ["[" * 100_000],                      # nested past the stack
           "sensor_id": ["{not json"],
           "protocol_spec": [json.dumps({"name": "x", "trial_s": "long"})],
           "unknown_key": [json.dumps("ignored")]}
    assert session_fields(bad) == {}
    assert session_fields("not an element") == {} and session_fields({"seed": []}) == {}


def test_an_xdf_exported_and_imported_back_is_the_same_session_for_a_researcher(
        collected, tmp_path, capsys):
    path, meta = collected
    xdf = export_xdf(path, tmp_path)
    assert main(["import", "xdf", str(xdf), "--out", str(tmp_path / "back")]) == 0
    capsys.readouterr()
    (again,) = (tmp_path / "back").glob("*.h5")
    with SessionFile(path) as a, SessionFile(again) as b:
        np.testing.assert_array_equal(b.raw(), a.raw())
        assert {k: b.metadata.get(k) for k in PROTOCOL_FIELDS} == \
            {k: a.metadata.get(k) for k in PROTOCOL_FIELDS}
        assert b.metadata["source"] == "import:xdf"  # an import, with its own id
        assert b.session_id != a.session_id and b.recording == a.recording
    assert main(["check", str(again)]) == 0  # its trials' blocks agree with block_order
