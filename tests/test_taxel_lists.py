"""A taxel named twice ("B2,b2", "B2,7") is bad input, refused in one line before any
measuring: calibrate stored two curves for one taxel in one calibration, characterise
measured it twice and kept the second."""

from __future__ import annotations

import pytest
from fault_helpers import one_error_line

from tactile_studio.cli import main
from tactile_studio.storage.books.logbook import Logbook


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def test_calibrate_refuses_a_taxel_named_twice(tmp_path, capsys):
    code = main(["calibrate", "--device", "simulated", "--set", "speed=0", "--sensor", "sim-0",
                 "--auto", "--loads-g", "20,50,100", "--taxels", "B2,B5,b2",
                 "--out", str(tmp_path / "cal.json")])
    assert code == 1
    with Logbook() as book:
        assert "sim-0" not in book.sensor_ids() or book.calibrations("sim-0") == []
    assert one_error_line(capsys) == "tactile-studio: error: taxels named more than once: B2"


def test_characterise_refuses_a_taxel_named_twice_before_the_run(tmp_path, capsys):
    out = tmp_path / "char"
    code = main(["characterise", "--device", "simulated", "--set", "speed=0", "--set",
                 "gesture=idle", "--taxels", "B2,7", "--sequence", "normal",
                 "--out", str(out)])  # index 7 is B2
    assert code == 1 and not (out / "session.h5").exists()
    assert "taxels named more than once: B2" in one_error_line(capsys)
