"""A calibration says how much its taxels differ, measured (issue 47, item 23: it carried
only the simulated device's ``sensitivity_spread`` setting, 0.0, beside taxel
sensitivities from 0.94 to 1.20)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactile_studio.cli import main

PLATE = ["--loads-g", "1000,2000,5000,10000,20000", "--plate", "--auto"]


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


@pytest.mark.parametrize("extra", [0.0, 0.15])
def test_the_spread_is_the_measured_one_and_matches_the_sensors(capsys, tmp_path, extra):
    out = tmp_path / "cal.json"
    assert main(["calibrate", "--device", "simulated", "--set", "speed=0", "--set",
                 f"sensitivity_spread={extra}", "--sensor", "sim-0", *PLATE,
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    cal = json.loads(out.read_text())
    sens = np.array([f["sensitivity"] for f in cal["fits"]])
    assert cal["sensitivity_spread"] == pytest.approx(sens.std() / np.median(sens), abs=1e-4)
    assert cal["sensitivity_range"] == pytest.approx([sens.min(), sens.max()], abs=1e-4)
    assert cal["sensitivity_spread"] > 0.02  # the default sensor differs per taxel too
    # the simulated sensor's own truth beside its setting, and the calibration measured it
    truth = cal["device"]["true_sensitivity"]["sensitivity_spread"]
    assert cal["sensitivity_spread"] == pytest.approx(truth, rel=0.05)
    assert cal["device"]["settings"]["sensitivity_spread"] == extra
    lo, hi = cal["sensitivity_range"]
    assert (f"sensitivity {lo:.3f}-{hi:.3f} across 36 taxels measured (spread "
            f"{cal['sensitivity_spread'] * 100:.1f}%") in printed
