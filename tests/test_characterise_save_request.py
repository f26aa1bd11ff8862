"""`characterise --save-calibration` refuses, before the stage moves, what it could only
refuse at the end: a plan without the normal sequence (the run went through, hours for
`repeat`, then 'gave no normal fit'); a sensor ID the logbook would not take."""

from __future__ import annotations

import pytest
from fault_helpers import one_error_line

from tactile_studio.cli import main

SIM = ["characterise", "--device", "simulated", "--set", "speed=0", "--set", "gesture=idle",
       "--taxels", "B2"]


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def test_save_calibration_without_the_normal_sequence_is_refused_before_the_run(tmp_path,
                                                                                capsys):
    out = tmp_path / "char"
    assert main([*SIM, "--sequence", "shear", "--sensor", "sim-0", "--save-calibration",
                 "--out", str(out)]) == 1
    assert not (out / "session.h5").exists()  # nothing ran
    line = one_error_line(capsys)
    assert "normal sequence" in line and "only shear" in line


def test_a_sensor_id_the_logbook_would_not_take_is_refused_before_the_run(tmp_path, capsys):
    out = tmp_path / "char"
    assert main([*SIM, "--sequence", "normal", "--sensor", "x" * 65, "--save-calibration",
                 "--out", str(out)]) == 1
    assert not (out / "session.h5").exists()
    assert "bad sensor ID" in one_error_line(capsys)
