"""Equilibration and calibration on the simulated sensor: truth recovered, rms <= 1%."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.health.bench import Bench, SimulatedPlacer
from tactile_studio.health.calibration import CalibrationSpec, decode_session, run_calibration
from tactile_studio.plugins.simulated import SimulatedSensor
from tactile_studio.sensor.calibration import CalibrationError, check_loads, fit_taxel
from tactile_studio.sensor.layout import SHEARSENSE_6X6 as LAY
from tactile_studio.sensor.wellness import parse_taxel
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.recording.recorder import Recorder
from tactile_studio.storage.recording.sensor_book import sensor_metadata

TAXELS = ("B2", "B5", "E2", "E5", "A1", "C4")


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


def calibrate(spec_kw, **settings):
    dev = SimulatedSensor(speed=0, gesture="idle", sensitivity_spread=0.15, **settings)
    engine = AcquisitionEngine(dev)
    engine.start()
    try:
        cal = run_calibration(engine, CalibrationSpec(dev.sensor_id(), **spec_kw),
                              placer=SimulatedPlacer(dev))
    finally:
        engine.stop()
    return cal, dev


def _check_against_truth(cal, dev):
    truth = dev.true_sensitivity()
    assert truth.std() > 0.08  # the spread is real, so matching it means something
    for f in cal["fits"]:
        assert f["sensitivity"] == pytest.approx(truth[f["index"]], rel=0.05), f["taxel"]
        assert f["rms_pct"] <= 1.0, f["taxel"]
    gains = np.array([cal["gains"][f["taxel"]] for f in cal["fits"]])
    equalised = gains * np.array([truth[f["index"]] for f in cal["fits"]])
    assert equalised.std() / equalised.mean() < 0.02 < truth.std() / truth.mean()


@pytest.mark.parametrize("seed", [3, 8])
def test_per_taxel_calibration_recovers_the_truth(seed):
    cal, dev = calibrate({"loads_g": (20, 50, 100, 200, 500), "taxels": TAXELS}, seed=seed)
    assert [f["taxel"] for f in cal["fits"]] == list(TAXELS)
    _check_against_truth(cal, dev)
    # the simulator's normal response is two-range (paper): the CV picks it, break ~9.3 kPa
    for f in cal["fits"]:
        assert f["model"] == "two-range"
        a, b, rb = f["params"]
        assert a * rb == pytest.approx(9.3, abs=1.5) and b > a


def test_plate_equilibrates_and_calibrates_every_taxel():
    cal, dev = calibrate({"loads_g": (1000, 2000, 5000, 10000, 20000), "plate": True}, seed=5)
    assert len(cal["fits"]) == 36 and cal["kind"] == "plate"
    _check_against_truth(cal, dev)
    with Logbook() as book:
        assert book.active_calibration("sim-5") == cal["calibration_id"]


def test_fit_prefers_the_simplest_model_that_fits():
    kpa = np.array([1.0, 2.0, 5.0, 10.0, 20.0])
    rng = np.random.default_rng(0)
    lin = [0.012 * k + rng.normal(0, 1e-5, 40) for k in kpa]
    power = [0.02 * k ** 0.7 + rng.normal(0, 1e-5, 40) for k in kpa]
    assert fit_taxel(LAY, 0, kpa, lin).model == "linear"
    assert fit_taxel(LAY, 0, kpa, power).model == "power"
    with pytest.raises(CalibrationError, match="A1: the response does not grow"):
        fit_taxel(LAY, 0, kpa, [np.full(5, 0.001)] * 5)


@pytest.mark.parametrize("loads, message", [
    ([20, 50], "at least 3 loads"), ([20, 100, 50], "loads out of order: 50 after 100"),
    ([0, 50, 100], "loads must be positive")])
def test_bad_loads(loads, message):
    with pytest.raises(CalibrationError, match=message):
        check_loads(loads)


def test_sessions_decode_with_any_calibration_of_their_sensor(tmp_path):
    first, dev = calibrate({"loads_g": (20, 50, 100, 200, 500), "taxels": ("C3",)}, seed=6)
    # record a known 150 g press with the active calibration
    dev = SimulatedSensor(speed=0, gesture="idle", sensitivity_spread=0.15, seed=6)
    engine = AcquisitionEngine(dev)
    rec = Recorder(engine, tmp_path / "s.h5", sensor_metadata(engine, None)).start()
    engine.start()
    assert engine.wait_frames(200, timeout=20)
    trial = dev.place_weight(150, "C3", duration_s=15)
    assert engine.wait_frames(trial.stop + 50, timeout=30)
    engine.stop()
    rec.stop()
    with SessionFile(tmp_path / "s.h5") as s:
        raw_before = s.raw().copy()
        assert s.metadata["calibration_id"] == first["calibration_id"]
    second, _ = calibrate({"loads_g": (1000, 2000, 5000, 10000, 20000), "plate": True}, seed=6)
    t = parse_taxel(LAY, "C3")
    r, c = LAY.taxel_rc(t)
    lo, hi = trial.start + round(12 * 43) - 200 + 200, trial.stop - 10  # settled part
    for cal_id in (None, second["calibration_id"]):
        frames = decode_session(tmp_path / "s.h5", cal_id)
        got = float(frames.normal[lo - trial.start + trial.start:hi, r, c].mean())
        applied = 150e-3 * 9.80665 / 0.014 ** 2 / 1e3
        assert abs(got - applied) / 25.0 < 0.02, (cal_id, got, applied)
    with SessionFile(tmp_path / "s.h5") as s:
        assert np.array_equal(s.raw(), raw_before)
    other, _ = calibrate({"loads_g": (20, 50, 100), "taxels": ("A1",)}, seed=9)
    with pytest.raises(Exception, match="is for sensor sim-9, the session was recorded with sim-6"):
        decode_session(tmp_path / "s.h5", other["calibration_id"])


def test_cli_calibrate_json_file_and_bad_input(tmp_path, capsys):
    out = tmp_path / "cal.json"
    assert main(["calibrate", "--set", "speed=0", "--set", "seed=4", "--set",
                 "sensitivity_spread=0.1", "--sensor", "sim-4", "--loads-g", "20,50,100",
                 "--taxels", "B2,E5", "--auto", "--json", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    saved = json.loads(out.read_text())
    assert summary["calibration_id"] == saved["calibration_id"]
    assert [t["taxel"] for t in summary["taxels"]] == ["B2", "E5"]
    assert saved["format"] == "tactile-studio-calibration" and saved["rms_pct_max"] < 1.0
    # a reading's error, cross-validated over the frames, beside the curve's through the
    # loads' means (which a 3-parameter curve through 3 loads makes 0 by construction)
    for fit in saved["fits"]:
        assert fit["cv_pct"] == pytest.approx(
            fit["cv_rms_kpa"][fit["model"]] / max(fit["loads_kpa"]) * 100, abs=1e-3)
        assert fit["cv_pct"] > fit["rms_pct"]
    assert summary["cv_pct_max"] == round(max(f["cv_pct"] for f in saved["fits"]), 4)
    assert [t["cv_pct"] for t in summary["taxels"]] == [f["cv_pct"] for f in saved["fits"]]
    page = (tmp_path / "cal.html").read_text()
    assert summary["report"] == str(tmp_path / "cal.html") and "residuals" not in page[:10]
    assert page.count("data:image/png;base64") == 1 and "per-taxel" in page
    for argv, msg in ((["--loads-g", "50,20,100"], "loads out of order: 20 after 50"),
                      (["--loads-g", "20,x"], "expected grams"),
                      (["--loads-g", "20,50,100", "--taxels", "Q1"], "'Q1' is not a taxel"),
                      (["--loads-g", "20,50,100", "--sensor", "sim-9"],
                       "reports sensor sim-4, not sim-9")):
        args = ["calibrate", "--set", "speed=0", "--set", "seed=4", "--sensor", "sim-4",
                "--auto", "--out", str(tmp_path / "bad.json"), *argv]
        assert main(args) == 1
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert msg in err
    assert not (tmp_path / "bad.json").exists()
    with Logbook() as book:
        assert len(book.calibrations("sim-4")) == 1


def test_wellness_uses_the_active_calibration_as_reference():
    """A sensor with a wide sensitivity spread fails a first check against the nominal
    stress, and passes once its calibration says what each spot should read."""
    from tactile_studio.health.wellness import WellnessSpec, run_wellness
    spots = ("B2", "B5", "E2", "E5", "C3")
    settings = {"speed": 0, "gesture": "idle", "seed": 8, "sensitivity_spread": 0.3}

    def check():
        dev = SimulatedSensor(**settings)
        engine = AcquisitionEngine(dev)
        engine.start()
        try:
            return run_wellness(Bench(engine, SimulatedPlacer(dev)),
                                WellnessSpec("sim-8", 200.0, spots), store=False), dev
        finally:
            engine.stop()
    before, dev = check()
    truth = dev.true_sensitivity()
    off = [s for s in spots if abs(truth[parse_taxel(LAY, s)] - 1) > 0.3]
    assert off and before["verdict"] != "pass"
    dev2 = SimulatedSensor(**settings)
    engine = AcquisitionEngine(dev2)
    engine.start()
    try:
        run_calibration(engine, CalibrationSpec("sim-8", (20, 50, 100, 200, 500), spots),
                        placer=SimulatedPlacer(dev2))
    finally:
        engine.stop()
    after, _ = check()
    assert after["reference_calibration"] is not None and after["reference_check"] is None
    assert after["verdict"] == "pass", after["reasons"]
    assert all(abs(s["ratio"] - 1) < 0.05 for s in after["spots"])
