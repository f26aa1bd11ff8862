"""Requests that cannot be honoured end in one line and a non-zero exit (issue 33):
non-finite plugin settings, CLI options and protocol fields; ``collect --blocks`` beyond
the protocol; an import that finds no frames. Through the real CLI and real files."""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from csv_fixtures import labelled_csv

from tactile_studio.cli import build_parser, main
from tactile_studio.cli.argtypes import finite_float
from tactile_studio.devices.registry import available_plugins
from tactile_studio.errors import (
    EXIT_ERROR,
    EXIT_INCOMPLETE,
    EXIT_USAGE,
    SettingsError,
    UserError,
)
from tactile_studio.instruments.registry import FORCE_GROUP, STAGE_GROUP, available
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage.exchange.shearsense import write_shearsense_csv
from tactile_studio.storage.format.protocol_file import load_protocol
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_writer import SessionWriter

NON_FINITE = ("nan", "NaN", "inf", "-inf", "Infinity", "1e999")


def run_cli(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


PROGRESS = re.compile(r"^\S.* \[\s*\d+%\] ")  # a progress bar drawn before the problem


def one_line(err: str) -> str:
    """The single error line (asserts there is exactly one and no traceback)."""
    lines = [ln for ln in err.splitlines() if ln.strip() and not PROGRESS.match(ln)]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("tactile-studio: error: "), err
    return lines[0]


def usage_error(capsys, *argv) -> str:
    """argparse refuses ``argv`` (exit 2, no traceback): its error line, the first of the
    two it prints (the second says where to look). Only the parser runs, so an option
    that slipped through fails here instead of hanging a recording."""
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args([str(a) for a in argv])
    err = capsys.readouterr().err
    assert exc.value.code == EXIT_USAGE and "Traceback" not in err, err
    return err.strip().splitlines()[0]


@pytest.mark.parametrize("argv, command, message", [
    (["record", "--seconds", "nan"], "tactile-studio record",
     "argument --seconds: 'nan' is not a finite number"),
    (["import", "xdf"], "tactile-studio import xdf",
     "the following arguments are required: files"),
    (["frob"], "tactile-studio", "argument COMMAND: invalid choice: 'frob'"),
])
def test_a_usage_error_is_its_line_and_where_to_look_not_the_usage_block(capsys, argv,
                                                                         command, message):
    """argparse printed the command's whole usage block above the line; now two lines."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == EXIT_USAGE
    error, hint = capsys.readouterr().err.strip().splitlines()
    assert error.startswith(f"{command}: error: {message}"), error
    assert hint == f"try '{command} --help'"


# ---- plugin settings: one validation point, every plugin kind ---------------------------
def _every_plugin() -> list[tuple[str, type]]:
    """(kind as messages name it, class) of every registered device, stage and force."""
    found = [("device", available_plugins()), ("stage", available(STAGE_GROUP)),
             ("force", available(FORCE_GROUP))]
    out = [(kind, cls) for kind, plugins in found for cls in plugins.values()
           if not isinstance(cls, Exception)]
    names = {(kind, cls.name) for kind, cls in out}
    assert {("device", "simulated"), ("device", "serial"), ("device", "replay"),
            ("device", "ble"), ("stage", "simulated"), ("stage", "gcode"),
            ("force", "simulated"), ("force", "serial")} <= names
    return out


def test_every_float_setting_of_every_registered_plugin_refuses_non_finite_values():
    checked = 0
    for kind, cls in _every_plugin():
        for setting in cls.settings_schema:
            if setting.kind != "float":
                continue
            for value in (*NON_FINITE, math.nan, math.inf, -math.inf):
                with pytest.raises(SettingsError) as exc:
                    cls.validate_settings({setting.name: value})
                message = str(exc.value)
                assert message.startswith(f"{kind} {cls.name}: setting {setting.name}: "), \
                    message
                assert "is not a finite number" in message and "\n" not in message
            checked += 1
    assert checked >= 20  # simulated alone has 7 float settings


def test_an_int_setting_given_infinity_is_one_settings_error_not_an_overflow():
    from tactile_studio.plugin_settings import Setting

    with pytest.raises(SettingsError, match="device x: setting seed: inf is not a valid int"):
        Setting("seed", "int", 0).parse(math.inf, "x")


def test_record_refuses_a_nan_setting_and_writes_nothing(capsys, tmp_path):
    for device, setting in (("simulated", "noise=nan"), ("simulated", "rate=nan"),
                            ("simulated", "speed=inf"), ("simulated", "drift=-inf"),
                            ("serial", "rate=nan"), ("ble", "scan_timeout=nan")):
        out = tmp_path / f"{device}.h5"
        code, _, err = run_cli(capsys, "record", "--device", device, "--set", setting,
                               "--seconds", "0.2", "--out", out)
        key, value = setting.split("=")
        assert code == EXIT_ERROR
        assert one_line(err).endswith(f"device {device}: setting {key}: {float(value)} is not "
                                      "a finite number")
        assert not out.exists()


def test_replay_at_nan_speed_is_refused(capsys, tmp_path):
    source = tmp_path / "P01_FLAT.csv"
    labelled_csv(tmp_path, source.name, 1)
    out = tmp_path / "replayed.h5"
    code, _, err = run_cli(capsys, "record", "--device", "replay", "--set", f"path={source}",
                           "--set", "speed=nan", "--seconds", "1", "--out", out)
    assert code == EXIT_ERROR and "device replay: setting speed: nan is not a finite number" \
        in one_line(err)
    assert not out.exists()


def test_characterisation_parameters_must_be_finite(capsys, tmp_path):
    code, _, err = run_cli(capsys, "characterise", "--param", "dwell_s=nan",
                           "--out", tmp_path / "run")
    assert code == EXIT_ERROR
    assert one_line(err).endswith("characterisation parameter dwell_s: nan is not a finite "
                                  "number")
    assert not (tmp_path / "run").exists()


def test_calibration_loads_must_be_finite(capsys, tmp_path):
    code, _, err = run_cli(capsys, "calibrate", "--sensor", "sim-0", "--loads-g",
                           "100,200,nan", "--out", tmp_path / "cal.json")
    assert code == EXIT_ERROR
    assert one_line(err).endswith("loads must be finite numbers: 100, 200, nan")
    assert not (tmp_path / "cal.json").exists()


def test_info_json_is_strict_json_even_for_an_old_file_holding_nan(capsys, tmp_path):
    """Files written before the check may hold ``rate=nan``: JSON has no NaN, so it is null."""
    path = tmp_path / "old.h5"
    device = {"plugin": "serial", "settings": {"rate": math.nan, "port": "/dev/ttyUSB0"}}
    with SessionWriter(path, SHEARSENSE_6X6, device, {"gain": [1.0, math.inf]}) as w:
        n = 5
        w.append_frames(np.full((n, SHEARSENSE_6X6.n_channels), 30000, np.uint16),
                        np.arange(n) / 44.0, np.arange(n) / 44.0)

    def strict(text: str):
        def refuse(constant: str):
            raise AssertionError(f"invalid JSON constant {constant}")
        return json.loads(text, parse_constant=refuse)

    for argv in (["info", path, "--json"], ["info", tmp_path, "--json"]):
        code, out, err = run_cli(capsys, *argv)
        assert code == 0, err
        doc = strict(out)
        summary = doc[0] if isinstance(doc, list) else doc
        assert summary["metadata"]["device"]["settings"]["rate"] is None
        assert summary["metadata"]["gain"] == [1.0, None]
        assert summary["frames"] == n


# ---- CLI options: one argparse type for every float option ------------------------------
def _float_options(parser: argparse.ArgumentParser, where: str = "tactile-studio"):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _float_options(sub, f"{where} {name}")
        elif action.type is float:
            yield f"{where} {'/'.join(action.option_strings) or action.dest}"


def test_no_cli_option_parses_a_bare_float():
    """``type=float`` takes nan and inf; every number option uses cli.argtypes instead."""
    assert list(_float_options(build_parser())) == []


def test_finite_float_is_what_the_options_use():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    record = sub.choices["record"]
    seconds = next(a for a in record._actions if "--seconds" in a.option_strings)
    assert seconds.type is finite_float


@pytest.mark.parametrize("option, value, argv", [
    ("--seconds", "nan", ["record", "--seconds", "nan", "--out", "x.h5"]),
    ("--seconds", "inf", ["record", "--seconds", "inf", "--out", "x.h5"]),
    ("--seconds", "-inf", ["record", "--seconds=-inf", "--out", "x.h5"]),
    ("--rate", "nan", ["emulate-serial", "--rate", "nan"]),
    ("--corrupt", "nan", ["emulate-serial", "--corrupt", "nan"]),
    ("--speed", "nan", ["collect", "--speed", "nan", "--virtual-participant"]),
    ("--seconds", "inf", ["stream", "--seconds", "inf"]),
    ("--lsl-wait", "nan", ["record", "--seconds", "1", "--out", "x.h5", "--lsl-wait", "nan"]),
    ("--weight-g", "nan", ["wellness", "--sensor", "s", "--weight-g", "nan"]),
    ("--window", "inf", ["train", "--data", "d", "--window", "inf"]),
    ("--overlap", "nan", ["train", "--data", "d", "--overlap", "nan"]),
    ("--force", "nan", ["emulate-loadcell", "--force", "0", "nan", "0"]),
    ("--rate", "1e999", ["emulate-loadcell", "--rate", "1e999"]),
    ("--silence-warning", "nan", ["record", "--seconds", "1", "--out", "x.h5",
                                  "--silence-warning", "nan"]),
    ("--silence-warning", "inf", ["gui", "--silence-warning", "inf"]),
])
def test_float_options_refuse_non_finite_numbers(capsys, option, value, argv):
    line = usage_error(capsys, *argv)
    assert f"argument {option}" in line and f"'{value}' is not a finite number" in line


# ---- protocol files -----------------------------------------------------------------------
GESTURE = '[[gestures]]\nname = "Poke"\nkey = "p"\ndefinition = "poke it"\n'


@pytest.mark.parametrize("table, key, value", [
    ("", "trial_s", "nan"), ("", "free_play_s", "inf"), ("beep", "frequency_hz", "-inf"),
    ("quality", "centre_fraction", "nan"), ("wellness", "max_age_h", "inf"),
])
def test_protocol_float_fields_refuse_non_finite_values(capsys, tmp_path, table, key, value):
    top = {"name": '"t"', "trial_s": "2.0", "blocks": "1"}
    if not table:
        top[key] = value
    text = "".join(f"{k} = {v}\n" for k, v in top.items()) + GESTURE
    if table:
        text += f"[{table}]\n{key} = {value}\n"
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code, _, err = run_cli(capsys, "collect", "--protocol", path, "--participant", "P01",
                           "--virtual-participant", "--out", tmp_path / "out")
    assert code == EXIT_ERROR
    field = f"{table}.{key}" if table else key
    assert one_line(err).endswith(f"bad.toml: {field}: {float(value)} is not a finite number")
    assert not list(tmp_path.glob("**/*.h5"))


# ---- collect --blocks beyond the protocol ---------------------------------------------------
def test_collect_refuses_more_blocks_than_the_protocol_has(capsys, tmp_path):
    blocks = load_protocol("shear9").blocks
    code, _, err = run_cli(capsys, "collect", "--protocol", "shear9", "--participant", "P01",
                           "--virtual-participant", "--blocks", blocks + 1,
                           "--out", tmp_path / "out")
    assert code == EXIT_ERROR
    assert one_line(err).endswith(f"--blocks {blocks + 1}: protocol shear9 has {blocks} blocks")
    assert not list(tmp_path.glob("**/*.h5"))


# ---- imports that find no frames --------------------------------------------------------------
def _header_and_baseline_only(folder: Path, name: str) -> Path:
    """A ShearSense CSV as the old software leaves it when stopped at once."""
    return write_shearsense_csv(folder / name, np.zeros((0, 180), np.uint16), np.zeros(0),
                                np.zeros(0, np.int64), np.full(180, 30000.0))


def test_import_of_a_csv_without_frames_writes_no_session_and_exits_1(capsys, tmp_path):
    empty = _header_and_baseline_only(tmp_path, "P01_FLAT.csv")
    out = tmp_path / "out"
    code, stdout, err = run_cli(capsys, "import", "shearsense", empty, "--out", out)
    assert code == EXIT_ERROR
    assert one_line(err).endswith(f"{empty}: no frames after the baseline row, nothing imported")
    assert not list(out.glob("*.h5"))


def test_import_of_several_csvs_without_frames_names_them_all(capsys, tmp_path):
    a = _header_and_baseline_only(tmp_path, "P01_FLAT.csv")
    b = _header_and_baseline_only(tmp_path, "P02_FLAT.csv")
    code, _, err = run_cli(capsys, "import", "shearsense", a, b, "--out", tmp_path / "out")
    assert code == EXIT_ERROR
    line = one_line(err)
    assert "nothing imported" in line and "P01_FLAT.csv" in line and "P02_FLAT.csv" in line
    assert not list((tmp_path / "out").glob("*.h5"))


def test_import_keeps_the_good_files_lists_the_empty_one_and_exits_3(capsys, tmp_path):
    good = labelled_csv(tmp_path, "P01_FLAT.csv", 3)
    empty = _header_and_baseline_only(tmp_path, "P02_FLAT.csv")
    out = tmp_path / "out"
    code, stdout, err = run_cli(capsys, "import", "shearsense", good, empty, "--out", out)
    assert code == EXIT_INCOMPLETE
    assert f"{empty}: no frames after the baseline row, nothing imported" in stdout
    assert "imported 1 session(s)" in stdout
    assert one_line(err.split("\r")[-1]).endswith(
        "1 of 2 file(s) not imported (no frames after the baseline row)")
    assert sorted(p.name for p in out.glob("*.h5")) == ["P01_FLAT.h5"]
    with SessionFile(out / "P01_FLAT.h5") as s:
        assert s.n_frames > 0 and len(s.trials) == 3


# ---- model and training options (`train --set`) -------------------------------------------
def test_every_float_option_of_every_registered_model_refuses_non_finite_values():
    from tactile_studio.learn.models import resolve_options
    from tactile_studio.learn.models.registry import get_model_spec, model_names

    checked = 0
    for name in model_names():
        options = get_model_spec(name).options
        for key, default in options["tiny"].items():
            if not isinstance(default, float):
                continue
            for value in ("nan", "inf", "-inf", math.nan):
                with pytest.raises(UserError, match=f"model '{name}': option {key}=.* is "
                                                    "not a finite number"):
                    resolve_options(name, "tiny", options, {key: value})
            checked += 1
    assert checked >= 3  # dropouts at least


@pytest.mark.parametrize("setting, message", [
    ("lr=nan", "training option lr='nan' is not a finite number"),
    ("weight_decay=inf", "training option weight_decay='inf' is not a finite number"),
    ("epochs=inf", "training option epochs='inf' is not a valid int"),
    ("view_frames=inf", "view_frames='inf' must be a positive whole number"),
])
def test_training_options_refuse_non_finite_values(capsys, tmp_path, setting, message):
    (tmp_path / "data").mkdir()
    code, _, err = run_cli(capsys, "train", "--data", tmp_path / "data", "--model", "cnn1d",
                           "--preset", "tiny", "--set", setting, "--out", tmp_path / "run")
    assert code == EXIT_ERROR and one_line(err).endswith(message)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("loads", [[20.0, 50.0, math.nan], [20.0, 50.0, math.inf],
                                   [math.nan, 50.0, 100.0]])
def test_calibration_loads_are_checked_finite_where_cli_and_wizard_meet(loads):
    from tactile_studio.sensor.calibration import CalibrationError, check_loads

    with pytest.raises(CalibrationError, match="loads must be finite numbers"):
        check_loads(loads)


def test_the_workspace_import_lists_a_csv_without_frames_and_imports_the_rest(
        qtbot, tmp_path, monkeypatch):
    from tactile_studio.ui.research.window import ResearchWindow

    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    window = ResearchWindow()
    qtbot.addWidget(window)
    good = labelled_csv(tmp_path, "P01_FLAT.csv", 3)
    empty = _header_and_baseline_only(tmp_path, "P02_FLAT.csv")
    dialog = window.open_import()
    dialog.add_files([str(good), str(empty)])
    out = tmp_path / "sessions"
    dialog.out.setText(str(out))
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert dialog.status.text().startswith(f"Imported 1 session(s) into {out}")
    assert "1 file(s) had no frames and were not imported" in dialog.status.text()
    assert f"{empty}: no frames after the baseline row, nothing imported" in \
        dialog.summary.toPlainText()
    assert sorted(p.name for p in out.glob("*.h5")) == ["P01_FLAT.h5"]

    dialog.files.clear()  # only the empty one: refused in one line, nothing written
    dialog.add_files([str(empty)])
    dialog.force.setChecked(True)
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert dialog.status.text() == f"{empty}: no frames after the baseline row, nothing imported"
    assert sorted(p.name for p in out.glob("*.h5")) == ["P01_FLAT.h5"]


def test_the_collection_setup_offers_no_more_blocks_than_the_protocol_has(qtbot, tmp_path):
    from PySide6.QtCore import QSettings

    from tactile_studio.ui.collect.setup import CollectSetup

    setup = CollectSetup(QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat))
    qtbot.addWidget(setup)
    setup.prefill(protocol="shear9", blocks=999)
    blocks = load_protocol("shear9").blocks
    assert setup.blocks.maximum() == blocks and setup.blocks.value() == blocks
    setup.prefill(protocol="haart7")
    assert setup.blocks.maximum() == load_protocol("haart7").blocks


def test_a_non_finite_device_setting_is_named_in_the_collection_setup(qtbot, tmp_path):
    from PySide6.QtCore import QSettings

    from tactile_studio.ui.collect.setup import CollectSetup

    setup = CollectSetup(QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat))
    qtbot.addWidget(setup)
    editor = setup.device_form.fields["noise"].editor
    editor.clear()
    qtbot.keyClicks(editor, "nan")
    assert setup.device_error.text() == "noise: nan is not a finite number"
    with pytest.raises(UserError, match="device simulated: noise: nan is not a finite number"):
        setup.device_choice()


def _xdf(path: Path, mats: dict[str, int]) -> Path:
    """An XDF file with a 64-channel pressure mat per name, each with that many samples."""
    from test_xdf import chunk, footer, header_xml, numeric_samples

    parts = [b"XDF:", chunk(1, b'<?xml version="1.0"?><info><version>1.0</version></info>')]
    for k, name in enumerate(mats, 1):
        parts.append(chunk(2, header_xml(name, "Pressure", 64, 100, "float32"), k))
    for k, (name, n) in enumerate(mats.items(), 1):
        if n:
            t = 10.0 + np.arange(n) / 100.0
            parts.append(chunk(3, numeric_samples(t, np.full((n, 64), 5.0, np.float32), "f"), k))
    parts += [footer(k, n) for k, n in enumerate(mats.values(), 1)]
    path.write_bytes(b"".join(parts))
    return path


def test_xdf_import_lists_a_tactile_stream_without_samples_and_imports_the_rest(capsys, tmp_path):
    src = _xdf(tmp_path / "two.xdf", {"MatA": 50, "MatB": 0})
    out = tmp_path / "out"
    code, stdout, err = run_cli(capsys, "import", "xdf", src, "--out", out)
    assert code == EXIT_INCOMPLETE
    assert f"{src}: stream 'MatB' has no samples, nothing imported" in stdout
    assert "numbering" not in stdout  # CoST's and HAART's label maps are not an XDF's
    assert one_line(err).endswith("1 tactile stream(s) not imported (no samples; listed above)")
    assert sorted(p.name for p in out.glob("*.h5")) == ["two_MatA.h5"]
    with SessionFile(out / "two_MatA.h5") as s:
        assert s.n_frames == 50


def test_xdf_import_whose_only_tactile_stream_is_empty_writes_nothing(capsys, tmp_path):
    src = _xdf(tmp_path / "empty.xdf", {"MatA": 0})
    out = tmp_path / "out"
    code, _, err = run_cli(capsys, "import", "xdf", src, "--out", out)
    assert code == EXIT_ERROR
    assert one_line(err).endswith(f"{src}: stream 'MatA' has no samples, nothing imported")
    assert not list(out.glob("*.h5"))


def test_the_workspace_xdf_import_says_which_stream_had_no_samples(qtbot, tmp_path,
                                                                    monkeypatch):
    from tactile_studio.ui.research.window import ResearchWindow

    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    window = ResearchWindow()
    qtbot.addWidget(window)
    src = _xdf(tmp_path / "two.xdf", {"MatA": 50, "MatB": 0})
    dialog = window.open_import_xdf()
    out = tmp_path / "sessions"
    dialog.out.setText(str(out))
    dialog.add_files([str(src)])
    assert dialog.start()
    qtbot.waitUntil(lambda: not dialog.job.running, timeout=20000)
    assert dialog.status.text() == (
        f"Imported 1 session(s) into {out}; they are listed in the Sessions tab.\n"
        f"Not imported: {src}: stream 'MatB' has no samples, nothing imported")
    assert sorted(p.name for p in out.glob("*.h5")) == ["two_MatA.h5"]


# ---- --json output is strict JSON ------------------------------------------------------
def test_print_json_writes_null_for_nan_and_infinity(capsys):
    from tactile_studio.cli.json_output import print_json

    print_json({"rate": math.nan, "gain": [1.0, math.inf, -math.inf], "n": np.int64(3)},
               indent=None)
    assert capsys.readouterr().out == '{"rate": null, "gain": [1.0, null, null], "n": 3}\n'


def test_every_command_prints_its_json_through_print_json():
    """A new ``--json`` that calls json.dump(s) itself could print NaN again."""
    import tactile_studio.cli as cli

    folder = Path(cli.__file__).parent
    own = [f.name for f in sorted(folder.glob("*.py"))
           if f.name != "json_output.py" and re.search(r"\bjson\.dumps?\(", f.read_text())]
    assert own == []
