"""Replaying an old CSV with bad rows reports them by kind, as ``import`` counts them."""

from __future__ import annotations

import time

import numpy as np

from tactile_studio.cli import main
from tactile_studio.devices.engine import FINISHED, AcquisitionEngine
from tactile_studio.devices.registry import create_device
from tactile_studio.storage import SessionFile
from tactile_studio.storage.exchange.shearsense import read_shearsense_csv, write_shearsense_csv


def _bad_csv(folder):
    """A real-format CSV with 6 short rows and 2 rows with two numbers run together."""
    rng = np.random.default_rng(8)
    raw = rng.integers(20000, 40000, size=(120, 180)).astype(np.uint16)
    path = write_shearsense_csv(folder / "P03_old_FLAT.csv", raw, 1.7e9 + np.arange(120) / 44,
                                np.zeros(120, int), raw[0].astype(float))
    lines = path.read_text().splitlines()
    for i in range(6):
        lines.insert(10 + 7 * i, '"1700000000.5","12","13"')
    for i in range(2):
        lines.insert(70 + i, ",".join(['"1700000001.0"'] + ['"25000"'] * 179
                                      + ['"2500025000"', '"0"', '"0"']))
    path.write_text("\n".join(lines) + "\n")
    return path, raw


def test_replay_reports_malformed_rows_by_kind_like_import(tmp_path, capsys):
    path, raw = _bad_csv(tmp_path)
    expected = read_shearsense_csv(path).malformed_by_kind
    assert expected == {"short_row": 6, "merged_number": 2}
    engine = AcquisitionEngine(create_device("replay", {"path": str(path), "speed": "0"}))
    engine.start()
    end = time.monotonic() + 30
    while engine.state != FINISHED:
        assert time.monotonic() < end, engine.state
        time.sleep(0.01)
    engine.stop()
    assert np.array_equal(engine.read_since(0).raw, raw)  # every good row, in order
    assert dict(engine.malformed) == expected

    out = tmp_path / "rec.h5"
    assert main(["record", "--device", "replay", "--set", f"path={path}", "--set", "speed=0",
                 "--seconds", "5", "--out", str(out)]) == 0
    assert "malformed 8" in capsys.readouterr().out
    with SessionFile(out) as s:
        assert s.summary()["malformed_by_kind"] == expected
