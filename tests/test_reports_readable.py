"""Reports an engineer can attach to a lab notebook: human headers with units, no dict
reprs or raw JSON keys, maps scaled against the nominal value, readable colour bars, no
"-0.0%". Real runs on the simulated sensor and instruments; the HTML and figures as
written.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from tactile_studio.characterise import CharacterisationRequest, Plan, run_characterisation
from tactile_studio.characterise.report import _map_scale, maps_figure, pct
from tactile_studio.cli import main
from tactile_studio.devices.registry import create_device
from tactile_studio.plugins.sim_force import SimulatedForce
from tactile_studio.plugins.sim_stage import SimulatedStage
from tactile_studio.sensor.layout import SHEARSENSE_6X6 as LAY
from tactile_studio.sensor.taxels import parse_taxels

QUICK = Plan(sequences=("normal", "shear"), dwell_s=0.5, normal_steps=4, relax_hold_s=2,
             settle_s=0.5, window_s=0.2, directions=("+x", "+y"))
RAW_KEY = re.compile(r"<th>[a-z0-9]+(_[a-z0-9]+)+</th>")  # a JSON key as a header
DICT_REPR = re.compile(r"\{'[a-z_]+':")


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def test_the_characterisation_report_reads_like_a_lab_notebook(tmp_path):
    dev = create_device("simulated", {"speed": "0", "gesture": "idle", "seed": "3"})
    result = run_characterisation(dev, SimulatedStage(), SimulatedForce(), CharacterisationRequest(
        QUICK, parse_taxels(LAY, "B2,B5,E2"), tmp_path, sensor_id="S-1"))
    page = (tmp_path / "report.html").read_text()
    assert not RAW_KEY.search(page) and not DICT_REPR.search(page)
    assert "<th>Breakpoint (kPa)</th>" in page and "Normal crosstalk, worst neighbour (%)" in page
    assert "-0.0" not in page and " UTC" in page
    assert len(result["taxels"]) == 3


def test_maps_scale_sensitivity_against_the_nominal_and_r2_reads_plainly():
    taxels = {n: {"normal_sensitivity_low": 0.01 * (1 + 0.01 * i), "shear_sensitivity_x": 0.08,
                  "r2_shear": 0.99985 + 1e-5 * i, "crosstalk_max": -1e-5}
              for i, n in enumerate(("A1", "B2", "C3", "D4"))}
    grid = np.array([[taxels["A1"]["normal_sensitivity_low"],
                      taxels["D4"]["normal_sensitivity_low"]]])
    shown, _, lo, hi, label, _ = _map_scale("normal_sensitivity_low", grid)
    assert (lo, hi) == (-20.0, 20.0) and np.nanmax(np.abs(shown)) < 3  # a 3% spread is pale
    assert "tolerance" in label
    fig = maps_figure(LAY, taxels)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    FigureCanvasAgg(fig).draw()
    bars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    ticks = [t.get_text() for ax in bars for t in ax.get_yticklabels()]
    assert ticks and not any("e" in t or "+" in t for t in ticks)  # not "1e-5+9.998e-1"
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert "0.0%" in texts and "-0.0%" not in texts
    assert pct(-0.0001) == "0.0%" and pct(0.0234) == "2.3%"


def test_the_wellness_report_names_what_it_shows(tmp_path, capsys):
    report = tmp_path / "check.html"
    main(["wellness", "--set", "speed=0", "--set", "difficulty=easy", "--set", "seed=4",
          "--set", "fault=stuck_channel", "--set", "fault_taxel=E5", "--sensor", "sim-4",
          "--weight-g", "200", "--auto", "--json", "--report", str(report)])
    out = json.loads(capsys.readouterr().out)
    page = report.read_text()
    assert not DICT_REPR.search(page) and "noise_counts_median" not in page
    assert "Noise, median channel (counts)" in page and "Stuck (never moves)" in page
    stuck = out["channels"]["stuck"]
    assert stuck and "E5/centre" in page  # channels by taxel, not by number
    assert "Sensitivity vs reference" in page


def test_the_calibration_report_lists_loads_in_words(tmp_path, capsys):
    assert main(["calibrate", "--set", "speed=0", "--set", "seed=4", "--sensor", "sim-4",
                 "--loads-g", "20,50,100", "--taxels", "B2,E5", "--auto", "--json",
                 "--out", str(tmp_path / "cal.json")]) == 0
    page = (tmp_path / "cal.html").read_text()
    assert "loads 20, 50, 100 g" in page and "[" not in page.split("<img")[0]
