"""A protocol's [wellness] requirement: CLI collect and the console ask for an override."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest

from tactile_studio.cli import main
from tactile_studio.health.gate import WellnessRequired, admit, wellness_status
from tactile_studio.storage.books.logbook import Logbook
from tactile_studio.storage.format.protocol_file import ProtocolError, load_protocol
from tactile_studio.storage.format.session_file import SessionFile

PROTO = """
name = "mini1"
trial_s = 0.3
blocks = 1
free_play_s = 0.0

[wellness]
required = true
max_age_h = 2.0

[[gestures]]
name = "Poke"
key = "p"
definition = "Press one fingertip into the sensor."
"""


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


@pytest.fixture
def proto(tmp_path) -> Path:
    path = tmp_path / "mini1.toml"
    path.write_text(PROTO)
    return path


def _check(sensor: str, verdict: str) -> int:
    with Logbook() as book:
        book.ensure_sensor(sensor)
        return book.add_check(sensor, {"verdict": verdict, "weight_g": 200.0, "spots": []})


def test_protocol_wellness_table(proto, tmp_path):
    p = load_protocol(proto)
    assert p.wellness_required and p.wellness_max_age_h == 2.0
    assert not load_protocol("shear9").wellness_required
    bad = tmp_path / "bad.toml"
    bad.write_text(PROTO.replace("required = true", "required = 3"))
    with pytest.raises(ProtocolError, match="wellness.required: must be true or false"):
        load_protocol(bad)
    bad.write_text(PROTO.replace("max_age_h = 2.0", "max_age = 2.0"))
    with pytest.raises(ProtocolError, match="wellness.max_age"):
        load_protocol(bad)


def test_status_missing_failed_stale_and_fresh():
    assert wellness_status("S1", True).problem == "sensor S1 has no wellness check"
    assert wellness_status(None, True).problem.startswith("the device reports no sensor ID")
    cid = _check("S1", "fail")
    st = wellness_status("S1", True, 2.0)
    assert st.check_id == cid and "last wellness check failed" in st.problem and not st.ok
    with pytest.raises(WellnessRequired, match="failed.*override note"):
        admit(st)
    meta = admit(st, "participant waiting; E5 known weak")
    assert meta["override"] == "participant waiting; E5 known weak" and meta["verdict"] == "fail"
    assert admit(wellness_status("S1", required=False))["override"] is None  # not required
    ok = _check("S1", "warn")
    st = wellness_status("S1", True, 2.0)
    assert st.ok and st.check_id == ok and st.text().startswith("Sensor S1: last check WARN")
    with Logbook() as book:  # make it old
        old = (dt.datetime.now(dt.timezone.utc) - dt.timedelta(hours=5)).isoformat()
        book._db.execute("UPDATE checks SET at=? WHERE id=?", (old, ok))
    st = wellness_status("S1", True, 2.0)
    assert not st.ok and "5.0 h old (the protocol allows 2 h)" in st.problem


def _collect(capsys, proto, out, *extra):
    code = main(["collect", "--protocol", str(proto), "--participant", "P01",
                 "--virtual-participant", "--set", "seed=5", "--speed", "40", "--out", str(out),
                 *extra])
    return code, *capsys.readouterr()


def test_cli_collect_requires_a_check_or_an_override(capsys, proto, tmp_path):
    code, _, err = _collect(capsys, proto, tmp_path / "a")
    assert code == 1 and "sensor sim-5 has no wellness check" in err.strip().splitlines()[-1]
    assert list((tmp_path / "a").glob("*.h5")) == []
    code, out, err = _collect(capsys, proto, tmp_path / "b", "--wellness-override", "no weight")
    assert code == 0, err
    with SessionFile(out.strip().splitlines()[-1]) as s:
        w = s.metadata["wellness"]
        assert w["override"] == "no weight" and w["check_id"] is None
        assert s.metadata["sensor_id"] == "sim-5"
    assert main(["wellness", "--set", "speed=0", "--set", "difficulty=easy", "--set", "seed=5",
                 "--sensor", "sim-5",
                 "--weight-g", "200", "--auto", "--json"]) == 0
    capsys.readouterr()
    code, out, err = _collect(capsys, proto, tmp_path / "c")
    assert code == 0, err
    assert "Sensor sim-5: last check PASS" in err
    with SessionFile(out.strip().splitlines()[-1]) as s:
        w = s.metadata["wellness"]
        assert w["verdict"] == "pass" and w["override"] is None and w["check_id"] == 1


def test_console_asks_for_an_override_note(qtbot, proto, tmp_path, monkeypatch):
    from PySide6.QtCore import Qt

    from tactile_studio.ui.collect.console import CollectConsole
    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    _check("sim-9", "fail")
    console = CollectConsole()
    qtbot.addWidget(console)
    console.show()
    s = console.setup
    s.set_protocol_file(str(proto))
    assert s.set_device("simulated", {"speed": 8, "gesture": "idle", "seed": 9})
    qtbot.keyClicks(s.participant, "P02")
    s.out_dir.setText(str(tmp_path))
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert console.session is None and "last wellness check failed" in s.error.text()
    dlg = console.dialog
    assert dlg is not None and dlg.windowTitle() == "Wellness check needed"
    qtbot.keyClicks(dlg.edit, "re-checked E5 by hand")
    dlg.accept()
    qtbot.waitUntil(lambda: console.session is not None, timeout=10000)
    assert "Sensor sim-9: last check FAIL" in console.file_label.text()
    path = console.session.path
    console.close_session()
    with SessionFile(path) as sess:
        assert sess.metadata["wellness"]["override"] == "re-checked E5 by hand"
        assert sess.metadata["wellness"]["verdict"] == "fail"
        assert sess.metadata["sensor_id"] == "sim-9"
