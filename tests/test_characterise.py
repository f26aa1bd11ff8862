"""Characterisation on the simulated bench: recovered parameters vs the simulator's truth,
the files written, and every bad-input path keeping the data measured so far."""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest

from tactile_studio.characterise import (
    CharacterisationRequest,
    Plan,
    RunControl,
    check_force,
    check_stage,
    run_characterisation,
)
from tactile_studio.characterise.analyse import drift_corrected
from tactile_studio.cli import main
from tactile_studio.devices.registry import create_device
from tactile_studio.errors import Cancelled, SettingsError, UserError
from tactile_studio.instruments import (
    SoftLimitError,
    create_force,
    create_stage,
)
from tactile_studio.plugins.sim_force import SimulatedForce
from tactile_studio.plugins.sim_stage import SimulatedStage
from tactile_studio.sensor.characterise import parse_taxels
from tactile_studio.simulate.indenter import true_parameters
from tactile_studio.storage.format.session_file import SessionFile

RECOVERED = ("normal_sensitivity_low", "normal_sensitivity_high", "breakpoint_kpa",
             "shear_sensitivity_x", "shear_sensitivity_y", "crosstalk_max", "relaxation_s",
             "shear_offset")
QUICK = Plan(sequences=("normal",), dwell_s=0.5, normal_steps=4, relax_hold_s=0.5,
             settle_s=0.5, window_s=0.2)


def sim_device(**extra):
    return create_device("simulated", {"speed": 0, "gesture": "idle", **extra})


def events(path, kind):
    with SessionFile(path) as s:
        return [e for e in s.events if e["kind"] == kind]


def test_analysis_recovers_the_simulators_true_parameters_within_10_percent(tmp_path):
    dev = sim_device(seed=3)
    stage, force = SimulatedStage(), SimulatedForce()
    layout = dev.layout
    taxels = parse_taxels(layout, "B2,A1")
    result = run_characterisation(dev, stage, force, CharacterisationRequest(
        Plan(sequences=("normal", "shear")), taxels, tmp_path))
    assert result["complete"]
    for t in taxels:
        name = layout.taxel_name(*layout.taxel_rc(t))
        got = result["taxels"][name]
        truth = true_parameters(dev.simulator, stage.skin, t)
        for key in RECOVERED:
            assert got[key] == pytest.approx(truth[key], rel=0.10), (name, key)
        assert got["r2_shear"] > 0.98
    # what is on disk matches what was returned
    on_disk = json.loads((tmp_path / "characterisation.json").read_text())
    assert on_disk["taxels"]["B2"]["breakpoint_kpa"] == result["taxels"]["B2"]["breakpoint_kpa"]
    calib = json.loads((tmp_path / "calibration.json").read_text())
    assert calib["format"] == "tactile-studio-calibration"
    assert set(calib["taxels"]) == {"B2", "A1"}
    for png in ("maps.png", "B2.png", "A1.png"):
        assert (tmp_path / "figures" / png).stat().st_size > 10_000
    raw = json.loads((tmp_path / "raw" / "B2.json").read_text())
    assert len(raw["normal"]["points"]) == 2 * 16 + 1 + 2  # load, unload, lifted, relaxed
    assert "B2" in (tmp_path / "report.html").read_text()
    # one session: sensor frames, stage positions, load-cell samples, measured points
    with SessionFile(tmp_path / "session.h5") as s:
        assert s.metadata["characterisation_clock"] == "device_time"
        n_frames = len(s.column("device_time"))
        kinds = {e["kind"] for e in s.events}
    assert n_frames > 2000
    assert {"stage", "force", "char_point", "char_taxel"} <= kinds


def test_cli_runs_headless_and_writes_the_json(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["characterise", "--set", "speed=0", "--set", "gesture=idle", "--taxels", "C4",
                 "--sequence", "repeat", "--cycles", "4", "--param", "cycle_hold_s=0.3",
                 "--param", "settle_s=0.5", "--sensor", "S-7", "--json", "--out", str(out)])
    assert code == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["C4"]["repeat_cycles"] == 4
    # short rests: the viscoelastic lag ratchets the peaks up a little, cycle after cycle
    assert 0 < printed["C4"]["repeat_drift"] < 0.2
    saved = json.loads((out / "characterisation.json").read_text())
    assert saved["sensor"] == "S-7" and saved["plan"]["cycles"] == 4
    assert len(events(out / "session.h5", "char_cycle")) == 4


@pytest.mark.parametrize("argv, message", [
    (["--taxels", "B2,G7"], "'G7' is not a taxel of shearsense-6x6"),
    (["--stage-set", "fail_home=1"], "did not home"),
    (["--force-set", "silent=1"], "no load-cell samples"),
    (["--stage-set", "floor_z=-0.3"], "below the floor"),
    (["--param", "dwell=3"], "unknown characterisation parameter 'dwell'"),
])
def test_bad_input_is_one_line_and_keeps_the_data(tmp_path, capsys, argv, message):
    out = tmp_path / "run"
    code = main(["characterise", "--set", "speed=0", "--set", "gesture=idle", "--taxels", "B2",
                 "--sequence", "normal", "--param", "dwell_s=0.5", "--param", "normal_steps=4",
                 "--param", "settle_s=0.5", "--out", str(out), *argv])
    err = capsys.readouterr().err
    assert code == 1
    # piped progress prints plain "label [ 0%] ..." lines, and a run that began says its
    # plan ("characterise: 1 taxel(s) x normal: ..."); the error itself is one line
    lines = [ln for ln in err.splitlines() if not ln.startswith(("characterise [",
                                                                 "characterise: "))]
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in err
    if argv[0] in ("--stage-set", "--force-set"):
        saved = json.loads((out / "characterisation.json").read_text())
        assert saved["complete"] is False and message in saved["aborted"]
        assert len(events(out / "session.h5", "char_aborted")) == 1
        with SessionFile(out / "session.h5") as s:
            assert s.closed_cleanly and len(s.column("device_time")) > 0


def test_soft_limit_abort_retracts_the_stage_first(tmp_path):
    dev = sim_device()
    stage = SimulatedStage(floor_z=-0.3)
    with pytest.raises(SoftLimitError):
        run_characterisation(dev, stage, SimulatedForce(),
                             CharacterisationRequest(QUICK, [7], tmp_path))
    # the last stage record is the retract to the safe height, after the refused move
    moves = events(tmp_path / "session.h5", "stage")
    assert moves[-1]["z"] == pytest.approx(stage.settings["safe_z"])
    assert min(m["z"] for m in moves) >= -0.3


def test_abort_keeps_finished_taxels_and_pause_resumes_with_the_next(tmp_path):
    control = RunControl()
    seen = []

    def progress(fraction, message):
        seen.append(message)
        if message == "B2 done":
            control.pause()
            threading.Timer(0.3, control.resume).start()
        if message.startswith("C3"):
            control.cancel()
    taxels = parse_taxels(sim_device().layout, "B2,B3,C3")
    with pytest.raises(Cancelled):
        run_characterisation(sim_device(), SimulatedStage(), SimulatedForce(),
                             CharacterisationRequest(QUICK, taxels, tmp_path),
                             progress=progress, control=control)
    saved = json.loads((tmp_path / "characterisation.json").read_text())
    assert list(saved["taxels"]) == ["B2", "B3"] and saved["aborted"]
    assert any(m.startswith("paused before B3") for m in seen)
    assert len(events(tmp_path / "session.h5", "char_resumed")) == 1
    assert events(tmp_path / "session.h5", "stage")[-1]["z"] == pytest.approx(5.0)


def test_simulated_instruments_meet_their_contracts():
    dev = sim_device(speed=50)
    stage = create_stage("simulated")
    stage.couple(dev)
    observed = check_stage(SimulatedStage, device=dev)
    assert observed["moved"][0] == pytest.approx(observed["home"][0] + 1.0)
    dev2 = sim_device(speed=50)
    stage2 = SimulatedStage()
    stage2.couple(dev2)
    assert check_force(SimulatedForce, device=dev2, stage=stage2)["samples"] >= 5
    assert isinstance(create_force("simulated"), SimulatedForce)


def test_plan_and_instrument_settings_are_validated():
    with pytest.raises(SettingsError, match="stage simulated: setting safe_z"):
        create_stage("simulated", {"safe_z": "-1"})
    with pytest.raises(UserError, match="unknown stage 'nope'"):
        create_stage("nope")
    with pytest.raises(SettingsError, match="unknown shear direction"):
        Plan.with_overrides({"directions": "+x,up"})
    assert Plan.with_overrides({"dwell_s": "1.5"}).dwell_s == 1.5
    # the averaged end of a hold cannot be longer than the hold
    with pytest.raises(SettingsError, match=r"window_s \(10 s\) is longer than dwell_s"):
        Plan.with_overrides({"window_s": "10"})
    assert Plan().cycles == 22000 and Plan().shear_step_mm == 0.2  # the paper's defaults
    assert len(parse_taxels(sim_device().layout, "all")) == 36
    assert np.isfinite(true_parameters(sim_device().simulator, SimulatedStage().skin, 0)
                       ["breakpoint_kpa"])


def test_all_taxels_are_mapped(tmp_path):
    from tactile_studio.characterise.report import MAPS, maps_figure

    dev = sim_device()
    plan = Plan(sequences=("normal",), dwell_s=0.3, normal_steps=4, relax_hold_s=0.5,
                settle_s=0.3, window_s=0.1)
    result = run_characterisation(dev, SimulatedStage(), SimulatedForce(), CharacterisationRequest(
        plan, parse_taxels(dev.layout, "all"), tmp_path, report=False))
    assert len(result["taxels"]) == 36
    fig = maps_figure(dev.layout, result["taxels"])
    maps = dict(zip((k for k, _ in MAPS),
                    (ax.images[0].get_array() for ax in fig.axes[:len(MAPS)])))
    for key in ("normal_sensitivity_low", "crosstalk_max"):
        assert maps[key].shape == (6, 6) and not np.ma.getmaskarray(maps[key]).any(), key
    # shear was not run: its maps are all grey (masked), not zeros
    assert np.ma.getmaskarray(maps["shear_sensitivity_x"]).all()


def test_derived_calibration_goes_to_the_logbook_and_maps_readings_to_kpa(tmp_path, capsys,
                                                                          monkeypatch):
    from tactile_studio.storage.books.logbook import Logbook
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))
    out = tmp_path / "run"
    assert main(["characterise", "--set", "speed=0", "--set", "gesture=idle", "--taxels", "B2",
                 "--sequence", "normal", "--sensor", "S-9", "--save-calibration",
                 "--out", str(out)]) == 0
    assert "saved to the logbook (active)" in capsys.readouterr().err
    with Logbook() as book:
        cal_id = book.active_calibration("S-9")
        assert cal_id is not None and book.calibrations("S-9")[0]["kind"] == "characterisation"
    cal = json.loads((out / "calibration.json").read_text())
    (fit,) = cal["fits"]
    assert fit["taxel"] == "B2" and fit["model"] == "two-range"
    # the stored curve, applied as documented, turns the sensor's readings (less the
    # baseline's drift over the staircase, which the analysis takes out) back into the
    # load cell's stress
    a, b, rb = fit["params"]
    pts = drift_corrected(json.loads((out / "raw" / "B2.json").read_text())["normal"])
    pts = [p for p in pts if p["phase"] in ("load", "unload")]
    r = np.array([p["normal"] for p in pts])
    kpa = np.array([p["pz"] for p in pts])
    back = a * np.minimum(r, rb) + b * np.maximum(r - rb, 0.0)
    rms_pct = np.sqrt(np.mean((back - kpa) ** 2)) / (kpa.max() - kpa.min()) * 100
    assert rms_pct < 5 and rms_pct == pytest.approx(fit["rms_pct"], abs=0.01)


def test_save_calibration_needs_a_sensor(tmp_path, capsys):
    assert main(["characterise", "--set", "speed=0", "--taxels", "B2", "--sequence", "normal",
                 "--save-calibration", "--out", str(tmp_path / "run")]) == 1
    assert "--save-calibration needs --sensor" in capsys.readouterr().err


def test_a_second_ctrl_c_mid_taxel_still_lifts_the_indenter_and_saves(tmp_path):
    """Ctrl-C twice: the second interrupts at once (jobs.ctrl_c_cancels raises
    KeyboardInterrupt wherever the run is, here mid-taxel). The indenter is lifted first
    all the same and what was measured is saved as aborted; before, only Cancelled and
    UserError retracted, so the indenter stayed pressed into the sensor."""
    def progress(fraction, message):
        if message.startswith("C3"):
            raise KeyboardInterrupt  # where the second Ctrl-C's handler raises it
    taxels = parse_taxels(sim_device().layout, "B2,C3")
    stage = SimulatedStage()
    with pytest.raises(KeyboardInterrupt):
        run_characterisation(sim_device(), stage, SimulatedForce(),
                             CharacterisationRequest(QUICK, taxels, tmp_path), progress=progress)
    retracts = [e for e in events(tmp_path / "session.h5", "stage") if e.get("retract")]
    assert retracts and events(tmp_path / "session.h5", "char_aborted")
    saved = json.loads((tmp_path / "characterisation.json").read_text())
    assert saved["aborted"] == "KeyboardInterrupt" and list(saved["taxels"]) == ["B2"]


def test_a_step_that_must_finish_holds_ctrl_c_until_it_has():
    """signals_deferred: a Ctrl-C during the step does not cut it; it is raised after."""
    import os
    import signal

    from tactile_studio.jobs import signals_deferred

    finished = False
    with pytest.raises(KeyboardInterrupt):
        with signals_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            finished = True  # the step went on after the signal
    assert finished
