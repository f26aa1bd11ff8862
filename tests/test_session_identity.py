"""Session identity: every file has a session_id, resume keeps it, imports derive it from
the source, and a dataset never counts a session twice (resume backups, copies)."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import uuid
from pathlib import Path

import h5py
import numpy as np
from collect_fixtures import do_trial, drive, make_rig, mini_protocol, start
from learn_fixtures import write_participant

from tactile_studio.cli import main
from tactile_studio.learn.data.dataset import build_dataset, read_sessions
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage.exchange.importers import import_shearsense
from tactile_studio.storage.exchange.shearsense import write_shearsense_csv
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.session_set import is_resume_backup, select_sessions
from tactile_studio.storage.format.session_writer import SessionWriter

SHOTS = Path(os.environ.get("TACTILE_STUDIO_SCREENSHOTS") or tempfile.gettempdir())


def _resumed_session(folder: Path) -> tuple[Path, Path, list[str]]:
    """A real collection session: 2 trials, closed mid-block, resumed and finished.
    Returns (session, backup, gestures in trial order)."""
    protocol = mini_protocol(n_gestures=3, blocks=2)
    rig = make_rig(folder, protocol)
    try:
        start(rig)
        order = rig.runner.orders
        for g in order[0][:2]:
            do_trial(rig, g)
    finally:
        rig.close()
    path = rig.session.path
    rig2 = make_rig(folder, protocol, resume=path)
    r2 = rig2.runner
    try:
        r2.start()
        drive(rig2, lambda: r2.state == "waiting_for_key")
        for g in [order[0][2], *order[1]]:
            do_trial(rig2, g)
        assert r2.state == "finished"
    finally:
        rig2.close()
    return path, rig2.session.backup, order[0] + order[1]


def test_resumed_session_keeps_its_id_and_a_dataset_counts_each_trial_once(tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    path, backup, gestures = _resumed_session(data)
    assert is_resume_backup(backup) and backup.parent == data
    with SessionFile(path) as s, SessionFile(backup) as b:
        sid = s.session_id
        assert uuid.UUID(sid).version == 4 and s.metadata["session_id"] == sid
        assert b.metadata["session_id"] == sid  # the original and its resume: one session
        assert len(b.trials) == 2 and len(s.trials) == 6
        assert s.metadata["resumes"] == 1
    assert main(["info", str(path)]) == 0
    assert f"session:    {sid}" in capsys.readouterr().out
    # a copy of the finished session in another folder is the same session again
    (data / "copy").mkdir()
    shutil.copy2(path, data / "copy" / "again.h5")

    ds = read_sessions([data])
    assert len(ds) == 6  # 6 trials, not 6 + 2 (backup) + 6 (copy)
    assert len(set(ds.uids)) == 6 and all(u.startswith(path.name) for u in ds.uids)
    assert sorted(ds.label_names[i] for i in ds.labels) == sorted(gestures)
    kinds = sorted((s["reason"], s["file"]) for s in ds.skipped)
    assert kinds == [("duplicate session", "copy/again.h5"), ("resume backup", backup.name)]
    text = ds.summary()["skipped_text"]
    assert text.startswith("skipped 1 resume backup, 1 duplicate session")
    assert f"copy/again.h5: same session_id as {path.name}" in text

    # the CLI says what it left out; two more participants make LOPO possible
    for p, seed in (("P02", 202), ("P03", 303)):
        write_participant(data / f"{p}.h5", p, seed, gestures=sorted(set(gestures)), blocks=2)
    code = main(["train", "--data", str(data), "--model", "rf", "--preset", "tiny",
                 "--eval", "lopo", "--out", str(tmp_path / "run"),
                 "--cache-dir", str(tmp_path / "cache"), "--set", "n_estimators=10"])
    out = capsys.readouterr().out
    assert code == 0
    assert "data: skipped 1 resume backup, 1 duplicate session" in out
    resolved = json.loads((tmp_path / "run" / "config.json").read_text())["resolved"]
    assert resolved["dataset"]["trials"] == 6 + 2 * 6
    assert len(resolved["dataset"]["skipped"]) == 2
    assert main(["evaluate", str(tmp_path / "run")]) == 0
    assert "data: skipped 1 resume backup, 1 duplicate session" in capsys.readouterr().out
    # from the cache the same files are left out and reported
    ds2 = build_dataset([data], cache_dir=tmp_path / "cache")
    assert len(ds2) == 18 and len(ds2.skipped) == 2


def test_a_backup_named_explicitly_loses_to_its_session(tmp_path):
    path, backup, _ = _resumed_session(tmp_path)
    chosen = select_sessions([backup, path])
    assert chosen.files == [path.resolve()]
    assert chosen.skipped[0]["reason"] == "duplicate session"
    assert chosen.skipped[0]["file"] == backup.name


def _old_style_file(path: Path, frames: np.ndarray) -> Path:
    """A session as written before ids existed: no session_id in its metadata."""
    w = SessionWriter(path, SHEARSENSE_6X6, {"plugin": "test"},
                      {"participant": "P01", "created": "2025-01-01T00:00:00+00:00"})
    w.metadata.pop("session_id")
    w._record({"type": "metadata", "update": {"session_id": None}})  # noqa: SLF001
    w.append_frames(frames, np.arange(len(frames)) / 43.0, np.arange(len(frames)) / 43.0)
    w.close()
    return path


def test_files_without_an_id_get_a_stable_fingerprint(tmp_path):
    rng = np.random.default_rng(1)
    frames = rng.integers(20000, 30000, size=(100, 180)).astype(np.uint16)
    a = _old_style_file(tmp_path / "a.h5", frames)
    b = _old_style_file(tmp_path / "b.h5", frames[:80])  # the same start: a backup's view
    c = _old_style_file(tmp_path / "c.h5", frames[::-1].copy())
    with SessionFile(a) as sa, SessionFile(b) as sb, SessionFile(c) as sc:
        assert not sa.metadata.get("session_id")
        assert sa.session_id == sb.session_id != sc.session_id
        assert uuid.UUID(sa.session_id).version == 5
        again = SessionFile(a)
        assert again.session_id == sa.session_id  # stable across reads
        again.close()
    with h5py.File(a, "r") as f:  # reading derives the id, it never writes it
        assert json.loads(f.attrs["metadata_json"])["session_id"] is None


def test_the_same_csv_imported_twice_is_one_session(tmp_path):
    rng = np.random.default_rng(2)
    raw = rng.integers(20000, 30000, size=(300, 180)).astype(np.uint16)
    labels = np.zeros(300, dtype=np.int64)
    labels[50:130] = ord("p")
    labels[180:260] = ord("h")
    csv = write_shearsense_csv(tmp_path / "P01_x_FLAT.csv", raw, 1.7e9 + np.arange(300) / 43,
                               labels, raw[:10].mean(axis=0))
    other = write_shearsense_csv(tmp_path / "P02_x_FLAT.csv", raw[::-1],
                                 1.7e9 + np.arange(300) / 43,
                                 labels, raw[:10].mean(axis=0))
    (tmp_path / "one").mkdir()
    (tmp_path / "two").mkdir()
    [a] = import_shearsense([csv], tmp_path / "one")
    [b, c] = import_shearsense([csv, other], tmp_path / "two")
    with SessionFile(a) as sa, SessionFile(b) as sb, SessionFile(c) as sc:
        assert sa.session_id == sb.session_id != sc.session_id
        assert uuid.UUID(sa.session_id).version == 5
    ds = read_sessions([tmp_path / "one", tmp_path / "two"])
    assert len(ds) == 4 and sorted(set(ds.participants)) == ["P01", "P02"]
    assert [s["reason"] for s in ds.skipped] == ["duplicate session"]


def test_hidden_folders_hold_no_sessions(tmp_path):
    """A study folder with a virtual environment or a cache inside: the HDF5 files of a
    library's tests there are not sessions, so neither train nor the workspace reads them
    (a file named by the user, hidden or not, is read)."""
    from tactile_studio.learn.results.workspace_index import scan_sessions

    (tmp_path / "study").mkdir()
    write_participant(tmp_path / "study" / "P01.h5", "P01", 1, blocks=1, trial_s=0.5)
    stray = tmp_path / "study" / ".venv" / "lib" / "h5py" / "data.h5"
    stray.parent.mkdir(parents=True)
    with h5py.File(stray, "w") as f:
        f["x"] = np.zeros(3)
    chosen = select_sessions([tmp_path / "study"])
    assert [p.name for p in chosen.files] == ["P01.h5"]
    assert [Path(r.path).name for r in scan_sessions([tmp_path / "study"])] == ["P01.h5"]


def _reimported(tmp_path: Path) -> tuple[Path, Path]:
    """A study folder: P01..P03 in data/, and P01 exported as the old CSV and imported
    back into reimported/ (a new session_id, the importer's, from the CSV)."""
    study = tmp_path / "study"
    data = study / "data"
    data.mkdir(parents=True)
    gestures = ("Poke", "Heavy Pat", "Tickle")
    for p, seed in (("P01", 101), ("P02", 202), ("P03", 303)):
        write_participant(data / f"{p}.h5", p, seed, gestures=gestures, blocks=2)
    assert main(["export", str(data / "P01.h5"), "--format", "shearsense-csv",
                 "--out", str(tmp_path / "csv")]) == 0
    assert main(["import", "shearsense", *map(str, (tmp_path / "csv").glob("*.csv")),
                 "--out", str(study / "reimported")]) == 0
    (again,) = (study / "reimported").glob("*.h5")
    return study, again


def test_a_session_imported_back_from_its_export_is_the_same_recording(tmp_path, capsys):
    """A session re-imported from its own CSV export got a new session id, so the same
    person's trials were trained on twice (the issue's 162 trials for 81)."""
    study, again = _reimported(tmp_path)
    with SessionFile(study / "data" / "P01.h5") as a, SessionFile(again) as b, \
            SessionFile(study / "data" / "P02.h5") as c:
        assert a.session_id != b.session_id  # the import's own id...
        assert a.recording == b.recording  # ...but the same frames
        assert c.recording != a.recording
    chosen = select_sessions([study])
    assert [p.name for p in chosen.files] == ["P01.h5", "P02.h5", "P03.h5"]  # the original
    assert chosen.skipped == [{"file": "reimported/P01_FLAT.h5", "reason": "same recording",
                               "kept": "data/P01.h5"}]
    capsys.readouterr()
    code = main(["train", "--data", str(study), "--model", "rf", "--preset", "tiny",
                 "--eval", "lopo", "--out", str(tmp_path / "run"),
                 "--cache-dir", str(tmp_path / "cache"), "--set", "n_estimators=10"])
    out = capsys.readouterr().out
    assert code == 0
    assert ("data: skipped 1 copy of a recording already in the data "
            "(reimported/P01_FLAT.h5: the same frames as data/P01.h5)") in out
    resolved = json.loads((tmp_path / "run" / "config.json").read_text())["resolved"]
    assert resolved["dataset"]["trials"] == 3 * 6  # each person's trials once


def test_the_workspace_shows_folders_and_marks_copies_and_backups(tmp_path, qtbot,
                                                                   monkeypatch):
    """The workspace listed the re-import beside its original (same participant, no
    folder column) and a .bak resume backup unmarked, all selected: 189 ok trials for
    135."""
    from tactile_studio.ui.research.sessions_view import COLUMNS, SessionsView

    monkeypatch.setenv("TACTILE_STUDIO_SETTINGS", str(tmp_path / "settings.ini"))
    study, again = _reimported(tmp_path)
    shutil.copy(study / "data" / "P02.h5", study / "data" / "P02.bak-1.h5")
    view = SessionsView()
    qtbot.addWidget(view)
    view.resize(1300, 400)
    view.set_folders([str(study)])

    def cell(name: str, column: str) -> str:
        r = next(r for r in range(view.table.rowCount())
                 if view.table.item(r, 0).text() == name
                 and view.table.item(r, COLUMNS.index("folder")).text() ==
                 ("reimported" if name == again.name else "data"))
        return view.table.item(r, COLUMNS.index(column)).text()

    assert cell(again.name, "folder") == "reimported" and cell("P01.h5", "folder") == "data"
    assert cell(again.name, "note") == "copy of data/P01.h5 (same frames)"
    assert cell("P02.bak-1.h5", "note") == "resume backup of data/P02.h5"
    assert cell("P01.h5", "note") == cell("P02.h5", "note") == ""
    # the copies start unselected: the selection is what a run reads
    assert sorted(Path(p).name for p in view.selected_paths()) == ["P01.h5", "P02.h5",
                                                                     "P03.h5"]
    assert view.summary.text() == ("3 of 5 sessions selected: 3 participants, 18 ok trials"
                                   " — 2 listed copies not selected (see the note column)")
    SHOTS.mkdir(parents=True, exist_ok=True)
    view.grab().save(str(SHOTS / "research_sessions_copies.png"))
    view.table.selectAll()  # selected anyway: counted once, and said
    assert view.summary.text().startswith(
        "5 of 5 sessions selected: 3 participants, 18 ok trials (2 not counted: "
        "a resume backup, a copy of a recording)")
