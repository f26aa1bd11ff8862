"""One writer per file as a busy lab meets it (issue 43's hunt): two windows, a resume
while another resume runs, two collections in one second, two trains, sweeps, exports or
characterisations into one output, a recording's own source as its output.

A second writer is held off by a claim taken first, by a real process (a small helper
taking the claim as every writer does) or by a window of this process; never by timing.

Budget: ~15 s.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from collect_fixtures import mini_protocol
from learn_fixtures import make_dataset_folder
from waiting import wait_until

from tactile_studio.cli import main
from tactile_studio.devices import AcquisitionEngine, create_device
from tactile_studio.file_claims import FileBusy, NameTaken, first_free
from tactile_studio.protocol.collect import CollectionSettings, open_collection, resume_collection
from tactile_studio.protocol.trial_runner import StreamClock
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage import SessionFile, SessionWriter

WAIT_S = 30.0
HELPER = ("import sys; from tactile_studio.file_claims import claim, claim_folder; "
          "held = (claim_folder if sys.argv[2] == 'folder' else claim)(sys.argv[1]); "
          "print('held', flush=True); sys.stdin.read()")


class Holder:
    """Another process holding ``path``'s claim until :meth:`release`."""

    def __init__(self, path: Path, folder: bool = False) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", HELPER, str(path),
                                      "folder" if folder else "file"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        line = self.proc.stdout.readline()
        assert line == "held\n", line + self.proc.stderr.read()

    def release(self) -> None:
        self.proc.communicate("", timeout=WAIT_S)

    def __enter__(self) -> Holder:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.proc.poll() is None:
            self.release()


def busy_line(capsys, what: str, path: Path, pid: int) -> None:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    (line,) = [ln for ln in err.splitlines() if ln.startswith("tactile-studio:")]
    assert line.startswith(f"tactile-studio: error: {path}: this {what} is being written "
                           f"by another process (pid {pid}: "), line


def _session(path: Path, frames: int = 50, **kw) -> Path:
    t = 1.7e9 + np.arange(frames) / 43.0
    with SessionWriter(path, SHEARSENSE_6X6, {"plugin": "test"}, {"participant": "P01"},
                       **kw) as w:
        w.append_frames(np.full((frames, 180), 30000, np.uint16), t - 1.7e9, t)
    return path


# ---- session files ------------------------------------------------------------------
def test_a_writer_refuses_an_existing_file_unless_asked_and_a_claimed_one_always(tmp_path):
    path = _session(tmp_path / "s.h5")
    with pytest.raises(NameTaken, match="already exists; not overwritten"):
        _session(path)
    with Holder(path) as other:
        with pytest.raises(FileBusy, match=f"pid {other.proc.pid}: "):
            _session(path, overwrite=True)
        with SessionFile(path) as s:  # untouched
            assert s.n_frames == 50
    _session(path, frames=60, overwrite=True)
    with SessionFile(path) as s:
        assert s.n_frames == 60
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.h5"]


def test_a_staged_writer_shows_nothing_until_it_closes_whole(tmp_path):
    path = tmp_path / "imp.h5"
    w = SessionWriter(path, SHEARSENSE_6X6, {"plugin": "test"}, {}, staged=True)
    t = np.arange(20) / 43.0
    w.append_frames(np.full((20, 180), 30000, np.uint16), t, t)
    assert not path.exists() and w.file.name.startswith(".imp.h5.")
    w.close()
    with SessionFile(path) as s:
        assert s.n_frames == 20 and s.closed_cleanly
    w = SessionWriter(tmp_path / "gone.h5", SHEARSENSE_6X6, {"plugin": "test"}, {},
                      staged=True)
    w.discard()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["imp.h5"]


def test_a_second_window_cannot_record_into_the_file_the_first_records(qtbot, tmp_path,
                                                                      monkeypatch):
    from tactile_studio.ui.main_window import MainWindow
    from tactile_studio.ui.settings import SETTINGS_ENV

    monkeypatch.setenv(SETTINGS_ENV, str(tmp_path / "settings.ini"))
    path = tmp_path / "s.h5"
    windows = []
    for _ in range(2):
        w = MainWindow(device="simulated", settings={"rate": "200"}, connect=True,
                       persist=False)
        qtbot.addWidget(w)
        w.show()
        windows.append(w)
    first, second = windows
    try:
        assert first.panel.start_recording(str(path))
        qtbot.waitUntil(lambda: first.acquisition.status().recorded_frames > 10,
                        timeout=WAIT_S * 1000)
        assert not second.panel.start_recording(str(path))  # the save dialog said replace
        assert second.panel.error_text() == (
            f"{path}: this session file is being written already by this program (another "
            "recording, job or window); nothing was written to it")
        assert second.acquisition.recorder is None
        with Holder(tmp_path / "other.h5") as other:  # and a file another process writes
            assert not second.panel.start_recording(str(tmp_path / "other.h5"))
            assert f"another process (pid {other.proc.pid}:" in second.panel.error_text()
        first.panel.stop_recording()
    finally:
        for w in windows:
            w.shutdown()
    with SessionFile(path) as s:
        assert s.closed_cleanly and s.n_frames > 10
    assert not (tmp_path / "other.h5").exists()


def _engine(seed: int = 0) -> AcquisitionEngine:
    return AcquisitionEngine(create_device("simulated", {"seed": seed, "speed": 0,
                                                        "gesture": "idle"}))


def test_a_resume_while_another_resume_of_the_file_runs_is_refused(tmp_path):
    engines = [_engine(), _engine()]
    first = open_collection(CollectionSettings(mini_protocol(), "P01", tmp_path), engines[0],
                            clock=StreamClock(engines[0]))
    engines[0].start()
    wait_until(lambda: first.recorder.rows_written >= 20, what="frames")
    first.close()
    engines[0].stop()
    path = first.path
    engines = [_engine(), _engine()]
    a = resume_collection(path, engines[0], clock=StreamClock(engines[0]))
    try:
        with pytest.raises(FileBusy, match="being written already"):
            resume_collection(path, engines[1], clock=StreamClock(engines[1]))
        engines[0].start()
        wait_until(lambda: a.recorder.rows_written >= 40, what="resumed frames")
    finally:
        a.close()
        engines[0].stop()
    with SessionFile(path) as s:
        assert s.closed_cleanly and s.n_frames >= 40
        assert [e["backup"] for e in s.events if e["kind"] == "resume"] == [
            f"{path.stem}.bak-1.h5"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [path.name, f"{path.stem}.bak-1.h5"])  # no second backup, no temporary, no lock


def test_a_backup_name_taken_meanwhile_is_never_overwritten(tmp_path):
    engine = _engine()
    first = open_collection(CollectionSettings(mini_protocol(), "P01", tmp_path), engine,
                            clock=StreamClock(engine))
    first.close()
    path = first.path
    (tmp_path / f"{path.stem}.bak-1.h5").write_bytes(b"someone's copy")
    again = resume_collection(path, engine, clock=StreamClock(engine))
    again.close()
    assert again.backup.name == f"{path.stem}.bak-2.h5"
    assert (tmp_path / f"{path.stem}.bak-1.h5").read_bytes() == b"someone's copy"


def test_a_name_the_program_picks_moves_on_while_it_is_taken_or_claimed(tmp_path):
    """What two collections starting in one second get (protocol/collect.py): the first
    free of ``P01_x_<time>.h5``, ``-2``, ``-3``..."""
    names = lambda k: tmp_path / ("c.h5" if k == 0 else f"c-{k + 1}.h5")  # noqa: E731
    (tmp_path / "c.h5").write_bytes(b"taken")
    with Holder(tmp_path / "c-2.h5"):
        w = first_free(names, lambda p: SessionWriter(p, SHEARSENSE_6X6, {}, {}))
        w.close()
    assert w.path == tmp_path / "c-3.h5"


def test_two_collections_into_one_folder_each_get_their_own_file(tmp_path):
    engines = [_engine(), _engine(1)]
    sessions = [open_collection(CollectionSettings(mini_protocol(), "P01", tmp_path), e,
                                clock=StreamClock(e))
                for e in engines]
    for s in sessions:
        s.close()
    assert sessions[0].path != sessions[1].path
    for s in sessions:
        with SessionFile(s.path) as f:
            assert f.closed_cleanly


def test_a_replay_cannot_record_over_the_file_it_plays(tmp_path, capsys):
    src = _session(tmp_path / "s.h5", frames=200)
    before = src.read_bytes()
    code = main(["record", "--device", "replay", "--set", f"path={src}", "--seconds", "1",
                 "--force", "--out", str(src)])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err
    assert f"{src}: is the file being replayed; record to another name" in err
    assert src.read_bytes() == before


# ---- outputs other than sessions ------------------------------------------------------
@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("lab")
    make_dataset_folder(root / "data", participants=2, blocks=1, gestures=("Poke", "Twist"))
    return root / "data"


def test_a_second_train_or_sweep_into_a_folder_being_written_is_refused(data, tmp_path,
                                                                       capsys):
    out = tmp_path / "run"
    with Holder(out, folder=True) as other:
        assert main(["train", "--data", str(data), "--model", "knn", "--eval", "lopo",
                     "--out", str(out), "--cache-dir", str(tmp_path / "cache")]) == 1
        busy_line(capsys, "run folder", out, other.proc.pid)
        assert main(["sweep", "--data", str(data), "--models", "knn", "--out", str(out),
                     "--cache-dir", str(tmp_path / "cache")]) == 1
        busy_line(capsys, "sweep folder", out, other.proc.pid)
    assert not out.exists()  # nothing was written into it


def test_a_second_export_to_a_file_being_written_is_refused(tmp_path, capsys):
    src = _session(tmp_path / "s.h5")
    out = tmp_path / "out"
    out.mkdir()
    with Holder(out / "s.xdf") as other:
        assert main(["export", str(src), "--format", "xdf", "--out", str(out)]) == 1
        busy_line(capsys, "output", out / "s.xdf", other.proc.pid)
    assert list(out.iterdir()) == []
    assert main(["export", str(src), "--format", "xdf", "--out", str(out)]) == 0
    assert [p.name for p in out.iterdir()] == ["s.xdf"]


def test_a_second_characterisation_into_a_running_ones_folder_clears_nothing(tmp_path,
                                                                            capsys):
    out = tmp_path / "char"
    out.mkdir()
    (out / "characterisation.json").write_text('{"complete": false, "taxels": {}}')
    (out / "raw").mkdir()
    (out / "raw" / "B2.json").write_text("{}")
    with Holder(out, folder=True) as other:
        assert main(["characterise", "--set", "speed=0", "--set", "gesture=idle",
                     "--sequence", "normal", "--taxels", "C4", "--overwrite",
                     "--out", str(out)]) == 1
        busy_line(capsys, "characterisation folder", out, other.proc.pid)
    assert (out / "raw" / "B2.json").exists() and (out / "characterisation.json").exists()
