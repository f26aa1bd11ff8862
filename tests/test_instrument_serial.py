"""The gcode stage and serial load cell through real pyserial over a real pty, against the
project's printer and load-cell emulators: normal use, an error reply, a disconnect, an
abort mid-move (the stage retracts), soft limits, a stage that does not home, a load
cell that sends garbage or nothing."""

from __future__ import annotations

import os
import re
import time

import numpy as np
import pytest

from tactile_studio.characterise import check_force, check_stage
from tactile_studio.instruments import InstrumentError, SoftLimitError
from tactile_studio.instruments.loadcell_emulator import LoadCellEmulator
from tactile_studio.instruments.printer_emulator import PrinterEmulator
from tactile_studio.plugins.gcode_stage import GcodeStage
from tactile_studio.plugins.serial_force import SerialForce


@pytest.fixture
def printer():
    emu = PrinterEmulator(home_s=0.05, busy_s=0.1, home=(90.0, 95.0, 28.0))
    emu.open()
    yield emu
    emu.stop()


@pytest.fixture
def loadcell():
    emu = LoadCellEmulator(lambda t: (0.1, -0.2, 2.0), rate_hz=200, offset=(0.0, 0.0, 0.5))
    emu.open()
    yield emu
    emu.stop()


def stage_on(printer, **extra) -> GcodeStage:
    stage = GcodeStage(port=printer.port, command_timeout_s=3, home_timeout_s=5, **extra)
    stage.open()
    return stage


def test_stage_homes_moves_and_reports_position_in_sensor_coordinates(printer):
    stage = stage_on(printer)
    try:
        stage.home()
        assert stage.position() == pytest.approx((0.0, 0.0, 5.0), abs=1e-3)
        assert "G1 X100.000 Y100.000 Z28.000 F1800.0" in printer.received  # above, then down
        stage.move_to(16.0, 32.0, 1.0, speed=200.0)
        stage.wait_until_still()
        assert stage.position() == pytest.approx((16.0, 32.0, 1.0), abs=1e-3)
        assert printer.position() == pytest.approx((116.0, 132.0, 21.0), abs=1e-3)
        assert "G28" in printer.received and "M400" in printer.received
        assert any(c.startswith("G1 X116.000 Y132.000 Z21.000 F12000") for c in printer.received)
    finally:
        stage.close()
        stage.close()


def test_error_reply_soft_limits_and_a_stage_that_does_not_home(printer):
    stage = stage_on(printer, floor_z=-1.0)
    try:
        with pytest.raises(InstrumentError, match="move before home"):
            stage.move_to(z=1.0)
        stage.home()
        sent = len(printer.received)
        with pytest.raises(SoftLimitError, match=r"z=-1\.500 mm is below the floor"):
            stage.move_to(z=-1.5)
        assert len(printer.received) == sent  # refused before anything was sent
        printer.inject_error("Printer halted. kill() called!")
        with pytest.raises(InstrumentError, match="replied 'Error:Printer halted"):
            stage.move_to(z=2.0)
        with pytest.raises(InstrumentError, match="Error:Move out of range"):
            stage.command("G1 X500")
    finally:
        stage.close()
    bad = PrinterEmulator(fail_home=True, home_s=0.01, home=(90.0, 95.0, 28.0))
    bad.open()
    try:
        stage = stage_on(bad)
        with pytest.raises(InstrumentError, match="Homing failed"):
            stage.home()
        stage.close()
    finally:
        bad.stop()


class HeldClock:
    """The printer emulator's clock held at a chosen moment until the quick stop, then
    running on from there: where the head stops is then the test's choice, not how long
    a loaded machine took between the move and the abort (it slept 0.3 s and allowed
    3 s of lag)."""

    def __init__(self, printer_ref: list) -> None:
        self.printer_ref = printer_ref
        self.held: float | None = None
        self.released_at: float | None = None

    def __call__(self) -> float:
        if self.held is None:
            return time.monotonic()
        if self.printer_ref and self.printer_ref[0].stopped_at:  # stopped: time runs on
            if self.released_at is None:
                self.released_at = time.monotonic()
            return self.held + time.monotonic() - self.released_at
        return self.held


def test_abort_mid_move_quick_stops_and_retracts():
    ref: list = []
    clock = HeldClock(ref)
    printer = PrinterEmulator(home_s=0.05, busy_s=0.1, home=(90.0, 95.0, 28.0), clock=clock)
    ref.append(printer)
    printer.open()
    stage = stage_on(printer)
    try:
        stage.home()
        stage.move_to(z=-0.5, speed=2.0)  # machine z 25 -> 19.5 at 2 mm/s: 2.75 s
        (began, start, end, _), = printer._moves  # noqa: SLF001 - the emulator's own move
        assert (start[2], end[2]) == (25.0, 19.5)
        clock.held = began + 1.5  # 3 mm down when the abort comes
        stage.retract()
        assert "M410" in printer.received
        # stopped part-way down, where the move had got to, well above the skin at z 20
        assert len(printer.stopped_at) == 1
        assert printer.stopped_at[0][2] == pytest.approx(22.0, abs=1e-6)
        assert stage.position() == pytest.approx((0.0, 0.0, 5.0), abs=1e-3)
    finally:
        stage.close()
        printer.stop()


def test_stage_disconnect_is_one_line(printer):
    stage = stage_on(printer)
    try:
        stage.home()
        printer.unplug()
        with pytest.raises(InstrumentError, match="disconnected|no 'ok'") as info:
            stage.position()
        assert "\n" not in str(info.value)
    finally:
        stage.close()


def test_an_unplugged_instrument_link_is_gone_until_it_is_plugged_back(tmp_path):
    # the kernel gives a freed pty number to the next pty opened anywhere: a link left
    # behind would lead a reconnecting stage to that stranger's port
    link = tmp_path / "printer"
    emu = PrinterEmulator(link=str(link))
    first = emu.open()
    try:
        assert os.readlink(link) == first
        emu.unplug()
        assert not link.is_symlink()
        second = emu.open()
        assert os.readlink(link) == second
    finally:
        emu.stop()
    assert not link.is_symlink()


def test_load_cell_streams_tares_and_scales(loadcell):
    force = SerialForce(port=loadcell.port, factor=2.0)
    force.open()
    try:
        force.tare()
        s = samples_until(force, lambda got: len(got) > 10)
        assert np.all(np.diff(s.t) >= 0)
        assert s.f.mean(axis=0) == pytest.approx((0.0, 0.0, 0.0), abs=1e-6)
        loadcell.source = lambda t: (0.1, -0.2, 3.0)
        # the new force once a line of it has come (a loaded machine: later, not never)
        s = samples_until(force, lambda got: len(got) and got.f[-1][2] > 1.0)
        assert s.f[-1] == pytest.approx((0.0, 0.0, 2.0), abs=1e-6)  # (3.0 - 2.0) x 2
    finally:
        force.close()


def samples_until(force: SerialForce, done, timeout: float = 15.0):  # noqa: ANN001
    """Read ``force`` until the samples read so far satisfy ``done`` (bounded; a read
    that finds nothing yet, or only the silence before data, is tried again)."""
    from tactile_studio.instruments.contract import ForceSamples

    got = ForceSamples(np.empty(0), np.empty((0, 3)), {})
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            s = force.read()
        except InstrumentError:
            s = None
        if s is not None and len(s):
            got = ForceSamples(np.concatenate([got.t, s.t]), np.concatenate([got.f, s.f]), {})
        if done(got):
            return got
        time.sleep(0.01)
    raise AssertionError(f"no such samples from the load cell in {timeout:g} s")


def raises_within(fn, match: str, timeout: float = 15.0) -> None:  # noqa: ANN001
    """``fn`` raises InstrumentError matching ``match`` once the emulator's change has
    reached the reader (bounded): lines already on their way are read first, and the
    state before the change is still said until it has lasted ``silence_s`` (garbage
    seen 0.1 s ago still names garbage when the cell has since gone silent)."""
    deadline, last = time.monotonic() + timeout, "none"
    while time.monotonic() < deadline:
        try:
            fn()
        except InstrumentError as exc:
            if re.search(match, str(exc)):
                return
            last = str(exc)
        time.sleep(0.02)
    raise AssertionError(f"no error matching {match!r} in {timeout:g} s (last: {last})")


def test_load_cell_garbage_silence_and_disconnect_are_one_line(loadcell):
    force = SerialForce(port=loadcell.port, silence_s=0.3)
    force.open()
    try:
        loadcell.set_mode("garbage")
        raises_within(force.read, r"only garbage from .* bad lines, last 'ovf")
        loadcell.set_mode("silent")
        raises_within(force.read, "no data from")
        loadcell.set_mode("ok")
        assert len(samples_until(force, lambda got: len(got) > 0)) > 0
        loadcell.unplug()
        raises_within(force.read, "disconnected|no data")
    finally:
        force.close()


def test_z_only_bridge_and_conformance(printer, loadcell):
    loadcell.axes = "z"
    assert check_force(SerialForce, {"port": loadcell.port, "axes": "z"})["samples"] >= 5
    observed = check_stage(GcodeStage, {"port": printer.port, "command_timeout_s": 5})
    assert observed["moved"][0] == pytest.approx(observed["home"][0] + 1.0, abs=1e-3)


def test_emulator_commands_serve_a_real_port(tmp_path):
    import subprocess
    import sys

    link = tmp_path / "printer"
    proc = subprocess.Popen([sys.executable, "-m", "tactile_studio", "emulate-printer",
                             "--link", str(link), "--seconds", "20"], stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 15
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        stage = GcodeStage(port=str(link), command_timeout_s=5)
        stage.open()
        try:
            assert stage.position() == pytest.approx((-100.0, -100.0, 180.0), abs=1e-3)
        finally:
            stage.close()
    finally:
        proc.terminate()
        proc.wait(10)


@pytest.mark.slow
def test_characterise_with_printer_and_load_cell_emulators_then_a_disconnect(tmp_path, printer):
    """End to end on the host clock: a load cell pressed by the printer's indenter (a
    spring under the skin surface at machine z 20); unplugging it mid-run is one line,
    the stage retracts and the session keeps what was recorded."""
    import json

    from tactile_studio.characterise import CharacterisationRequest, Plan, run_characterisation
    from tactile_studio.devices.registry import create_device
    from tactile_studio.storage.format.session_file import SessionFile

    spring = LoadCellEmulator(lambda t: (0.0, 0.0, 20.0 * max(0.0, 20.0 - printer.position()[2])),
                              rate_hz=200)
    spring.open()
    plan = Plan(sequences=("normal",), dwell_s=0.2, window_s=0.1, settle_s=0.3, normal_steps=4,
                relax_hold_s=0.3, approach_mm=0.05, travel_speed_mm_s=50, speed_mm_s=20)
    device = create_device("simulated", {"speed": 1, "gesture": "idle"})
    stage = GcodeStage(port=printer.port, command_timeout_s=5)
    force = SerialForce(port=spring.port, silence_s=0.5)
    try:
        result = run_characterisation(device, stage, force,
                                      CharacterisationRequest(plan, [0], tmp_path / "ok"))
        points = json.loads((tmp_path / "ok" / "raw" / "A1.json").read_text())["normal"]["points"]
        loads = [p["pz"] for p in points if p["phase"] == "load"]
        assert result["complete"] and result["clock"] == "host_time"
        # the surface is found where the spring starts: 0.8 mm x 20 N/mm over 196 mm2
        assert loads == sorted(loads) and loads[-1] == pytest.approx(16.0 / 0.196, rel=0.02)
        stage = GcodeStage(port=printer.port, command_timeout_s=5)
        force = SerialForce(port=spring.port, silence_s=0.5)
        seen: list[str] = []

        def unplug_in_the_second_taxel(name: str, point: dict) -> None:
            # a condition on the run, not a timer: under load a 2 s timer fired before the
            # first taxel's skin had settled, or after the run had ended
            seen.append(name)
            if seen.count(name) == 2 and name != "A1":
                spring.unplug()

        with pytest.raises(InstrumentError, match="force serial: .*(disconnected|no data)"):
            run_characterisation(device, stage, force,
                                 CharacterisationRequest(plan, [0, 1], tmp_path / "cut"),
                                 on_point=unplug_in_the_second_taxel)
        assert printer.position()[2] == pytest.approx(25.0, abs=1e-3)  # retracted
        with SessionFile(tmp_path / "cut" / "session.h5") as s:
            assert s.closed_cleanly and len(s.column("host_time")) > 20
            assert any(e["kind"] == "char_aborted" for e in s.events)
    finally:
        spring.stop()
