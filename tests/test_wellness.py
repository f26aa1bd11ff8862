"""Wellness checks on the simulated sensor: healthy seeds pass, every fault is named."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.errors import Cancelled
from tactile_studio.health.bench import Bench, SimulatedPlacer, Timing
from tactile_studio.health.events import KINDS, Misplaced, SpotMeasured
from tactile_studio.health.wellness import WellnessSpec, run_wellness
from tactile_studio.jobs import CancelToken
from tactile_studio.plugins.simulated import SimulatedSensor
from tactile_studio.sensor.layout import SHEARSENSE_6X6 as LAY
from tactile_studio.sensor.wellness import DEFAULT_SPOTS, parse_taxel, taxel_label
from tactile_studio.storage.books.logbook import Logbook


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))
    return tmp_path / "data"


def check(spots=DEFAULT_SPOTS, placer_cls=SimulatedPlacer, cancel=None, on_event=None,
          **settings):
    # a sensor without the sensor-to-sensor variation of the default difficulty, so each
    # fault is the only thing that differs from the nominal response (see the calibrated
    # test below for a sensor that varies like real ones)
    settings.setdefault("difficulty", "easy")
    dev = SimulatedSensor(speed=0, **settings)
    engine = AcquisitionEngine(dev)
    engine.start()
    try:
        bench = Bench(engine, placer_cls(dev), cancel=cancel, on_event=on_event)
        result = run_wellness(bench, WellnessSpec(dev.sensor_id(), 200.0, tuple(spots)))
    finally:
        engine.stop()
    return result, dev


def flagged(result):
    return {s["taxel"] for s in result["spots"] if s["verdict"] != "pass"}


@pytest.mark.slow
def test_healthy_sensor_passes_on_20_seeds():
    for seed in range(20):
        result, _ = check(seed=seed)
        assert result["verdict"] == "pass", (seed, result["reasons"])
        assert result["channels"] == {"dead": [], "stuck": [], "noisy": [], "saturated": []}
        ratios = [s["ratio"] for s in result["spots"]]
        assert all(0.85 < r < 1.15 for r in ratios), (seed, ratios)


@pytest.mark.parametrize("taxel", ["B2", "E5", "C3", "A1", "F6"])
def test_dead_taxel_is_named(taxel):
    t = parse_taxel(LAY, taxel)
    spots = DEFAULT_SPOTS if taxel in DEFAULT_SPOTS else (*DEFAULT_SPOTS, taxel)
    result, _ = check(spots, seed=11, fault="dead_taxel", fault_taxel=t)
    assert result["verdict"] == "fail"
    assert flagged(result) == {taxel}
    assert result["channels"]["dead"] == list(range(5 * t, 5 * t + 5))
    assert any(r.startswith(f"{taxel}: no response") for r in result["reasons"])


@pytest.mark.parametrize("t", [0, 9, 17, 35])
def test_stuck_channel_is_named_anywhere(t):
    result, _ = check(seed=12, fault="stuck_channel", fault_taxel=t)
    assert result["verdict"] == "fail"
    assert result["channels"]["stuck"] == [5 * t + 2]
    assert result["channels"]["dead"] == [] and result["channels"]["noisy"] == []
    assert flagged(result) <= {taxel_label(LAY, t)}
    assert any(f"channel {5 * t + 2} ({taxel_label(LAY, t)}/centre): stuck" in r
               for r in result["reasons"])


@pytest.mark.parametrize("taxel", ["B5", "E2", "D4"])
def test_worn_taxel_is_named(taxel):
    t = parse_taxel(LAY, taxel)
    spots = DEFAULT_SPOTS if taxel in DEFAULT_SPOTS else (*DEFAULT_SPOTS, taxel)
    result, dev = check(spots, seed=13, fault="worn", fault_taxel=t)
    worn = {taxel_label(LAY, i) for i in np.nonzero(dev.simulator.taxel_gain < 0.9)[0]}
    assert result["verdict"] == "fail"
    assert taxel in flagged(result) and flagged(result) <= worn
    spot = next(s for s in result["spots"] if s["taxel"] == taxel)
    assert spot["verdict"] == "fail" and 0.35 < spot["ratio"] < 0.55
    assert (f"{taxel}: {spot['ratio'] * 100:.0f}% of reference sensitivity — worn?"
            in result["reasons"])


@pytest.mark.parametrize("taxel", ["E2", "C3", "A6"])
def test_delaminated_taxel_reads_shear_and_is_named(taxel):
    t = parse_taxel(LAY, taxel)
    spots = DEFAULT_SPOTS if taxel in DEFAULT_SPOTS else (*DEFAULT_SPOTS, taxel)
    result, _ = check(spots, seed=14, fault="delaminated", fault_taxel=t)
    assert flagged(result) == {taxel}
    assert result["channels"] == {"dead": [], "stuck": [], "noisy": [], "saturated": []}
    assert any(r.startswith(f"{taxel}: reads") and "delaminated" in r for r in result["reasons"])


def test_second_check_uses_the_first_passing_one_as_reference():
    first, _ = check(seed=5)
    second, _ = check(seed=5)
    assert second["reference_check"] == first["check_id"]
    ref = {s["taxel"]: s["normal_kpa"] for s in first["spots"]}
    assert all(s["reference_kpa"] == ref[s["taxel"]] for s in second["spots"])
    assert all(abs(s["ratio"] - 1) < 0.05 for s in second["spots"])
    assert second["rest"]["baseline_shift_pct_max"] is not None
    with Logbook() as book:
        assert [c["id"] for c in book.checks("sim-5")] == [first["check_id"], second["check_id"]]


class _WrongPlacer(SimulatedPlacer):
    def place(self, mass_g, taxel, contact_mm):
        return super().place(mass_g, "C4", contact_mm)


def test_weight_on_the_wrong_taxel_stores_nothing():
    events = []
    with pytest.raises(Exception, match="the weight is on C4, not on B2; nothing was stored"):
        check(placer_cls=_WrongPlacer, seed=1, on_event=events.append)
    assert Misplaced("C4", "The weight is on C4, not on B2: move it") in events
    assert all(isinstance(e, KINDS) for e in events), events
    with Logbook() as book:
        assert book.checks("sim-1") == []


def test_cancelled_check_stores_nothing():
    token = CancelToken()

    def cancel_after_first_spot(event):
        if isinstance(event, SpotMeasured):
            token.cancel()
    with pytest.raises(Cancelled):
        check(seed=2, cancel=token, on_event=cancel_after_first_spot)
    with Logbook() as book:
        assert book.checks("sim-2") == []


def test_device_that_stops_mid_check_is_a_clear_error(tmp_path):
    session = tmp_path / "short.h5"
    assert main(["record", "--set", "speed=0", "--set", "gesture=idle", "--seconds", "0.05",
                 "--out", str(session)]) == 0
    from tactile_studio.plugins.replay import ReplayDevice
    dev = ReplayDevice(path=str(session), speed=0)
    engine = AcquisitionEngine(dev)
    with Logbook() as book:
        book.ensure_sensor("bench-1")
    engine.start()
    with pytest.raises(Exception, match=r"device replay stopped during the check \(finished\); "
                                        "nothing was stored"):
        run_wellness(Bench(engine, timing=Timing(rest_s=600)), WellnessSpec("bench-1", 200.0))
    engine.stop()
    with Logbook() as book:
        assert book.checks("bench-1") == []


def test_cli_auto_json_and_report(tmp_path, capsys):
    report = tmp_path / "check.html"
    assert main(["wellness", "--set", "speed=0", "--set", "difficulty=easy", "--set", "seed=4",
                 "--set", "fault=worn",
                 "--set", "fault_taxel=28", "--sensor", "sim-4", "--weight-g", "200",
                 "--auto", "--json", "--report", str(report)]) == 5  # FAIL: EXIT_CHECK_FAIL
    out = json.loads(capsys.readouterr().out)
    assert out["sensor"] == "sim-4" and out["verdict"] == "fail"
    assert set(out["channels"]) >= {"dead", "stuck", "noisy", "saturated"}
    assert [s["taxel"] for s in out["spots"]] == list(DEFAULT_SPOTS)
    assert all({"taxel", "normal_kpa", "shear_kpa", "ratio", "verdict"} <= set(s)
               for s in out["spots"])
    assert isinstance(out["check_id"], int)
    page = report.read_text()
    assert "FAIL" in page and "E5: " in page and page.count("data:image/png;base64") == 2


@pytest.mark.parametrize("argv, message", [
    (["--sensor", "nope"], "device simulated reports sensor sim-0, not nope"),
    (["--sensor", "sim-0", "--spots", "B2,Z9"], "'Z9' is not a taxel of shearsense-6x6 (A1..F6)"),
    (["--sensor", "sim-0"], "no weight detected on B2 within 30 s; nothing was stored"),
    (["--sensor", "sim-0", "--auto", "--weight-g", "-5"], "weight -5 g on 14 mm"),
])
def test_cli_bad_input_is_one_line_and_stores_nothing(argv, message, capsys):
    args = ["wellness", "--set", "speed=0", "--set", "gesture=idle", "--weight-g", "200", *argv]
    assert main(args) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1] and err[-1].startswith("tactile-studio: error:")
    with Logbook() as book:
        assert all(book.checks(s) == [] for s in book.sensor_ids())


def test_cli_unknown_sensor_on_a_device_without_identity(tmp_path, capsys):
    session = tmp_path / "s.h5"
    assert main(["record", "--set", "speed=0", "--seconds", "0.05", "--out", str(session)]) == 0
    capsys.readouterr()
    assert main(["wellness", "--device", "replay", "--set", f"path={session}", "--sensor",
                 "ghost", "--weight-g", "200"]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "unknown sensor 'ghost'" in err and "known: sim-0" in err


@pytest.mark.parametrize("seed", [0, 7])
def test_a_sensor_varying_like_real_ones_passes_once_calibrated(seed, tmp_path):
    """The default simulator's sensors differ by ~10% in sensitivity (as real ones do): a
    plate calibration becomes the reference and the first check then passes."""
    assert main(["calibrate", "--set", "speed=0", "--set", f"seed={seed}", "--sensor",
                 f"sim-{seed}", "--loads-g", "1000,2000,5000,10000,20000", "--plate", "--auto",
                 "--out", str(tmp_path / "cal.json")]) == 0
    result, _ = check(seed=seed, difficulty="real")
    assert result["verdict"] == "pass", result["reasons"]
    assert result["reference_calibration"] is not None
    assert all(0.9 < s["ratio"] < 1.1 for s in result["spots"])


def test_every_event_of_a_health_run_is_a_declared_type():
    """A whole check through HealthCheck (as the wizard runs it): each event it queues is
    one of health/events.py's types, the bench's steps and the run's own alike."""
    from tactile_studio.health.events import CheckDone, Phase, Progress
    from tactile_studio.health.health_check import HealthCheck

    run = HealthCheck("simulated", {"speed": 0, "difficulty": "easy", "seed": 3},
                      WellnessSpec("sim-3", 200.0, ("B2",)), auto=True).start()
    assert run.join(120), "the check did not end"
    seen = run.events()
    assert run.error is None, run.error
    assert seen and all(isinstance(e, KINDS) for e in seen), seen
    assert {Phase, SpotMeasured, Progress, CheckDone} <= {type(e) for e in seen}
