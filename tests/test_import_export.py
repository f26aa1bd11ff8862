"""Importers (ShearSense, CoST, HAART), exporters (ShearSense CSV, NPZ, trial CSV) and
their CLI: round trips, trials, one-line errors and Ctrl-C.

Budget: ~10 s. Fixtures are small files generated in tmp_path (no downloads).
"""

from __future__ import annotations

import csv
import json
import os
import signal

import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.errors import Cancelled
from tactile_studio.jobs import CancelToken
from tactile_studio.sensor.decode import decode
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage import SessionFile, SessionWriter
from tactile_studio.storage.exchange.exporters import export_npz, export_session
from tactile_studio.storage.exchange.importers import _common, import_shearsense
from tactile_studio.storage.exchange.shearsense import read_shearsense_csv, write_shearsense_csv
from tactile_studio.storage.format.protocol_file import load_protocol

COST_NAMES = ["grab", "hit", "massage", "pat", "pinch", "poke", "press", "rub", "scratch",
              "slap", "stroke", "squeeze", "tap", "tickle"]


# ---- fixtures ------------------------------------------------------------------------
def shearsense_csv(folder, name="P04_lab_PILLOW.csv", n=400, seed=1, keys="rpz"):
    """Touches under labelled runs (known keys r, p and an unknown z), plus one short and
    one merged row so the session must count them."""
    rng = np.random.default_rng(seed)
    raw = rng.integers(30000, 30200, size=(n, 180)).astype(np.uint16)
    times = 1690000000.0 + np.arange(n) / 43.0
    labels = np.zeros(n, dtype=np.int64)
    for i, k in enumerate(keys):
        labels[40 + i * 110: 40 + i * 110 + 86] = ord(k)
    raw[labels > 0, 10:40] -= 3000
    path = folder / name
    write_shearsense_csv(path, raw, times, labels, raw[:30].mean(axis=0))
    lines = path.read_text().splitlines()
    lines.insert(5, '"1690000000.1","5","114"')
    lines.insert(9, ",".join(['"1690000000.2"'] + ['"1"'] * 179 + ['"3000030000"', '"0"', '"0"']))
    path.write_text("\n".join(lines) + "\n")
    return path


def cost_csv(folder):
    """Two subjects; subject 1 repeats gesture 1 (frame numbers restart) then tickles."""
    rng = np.random.default_rng(2)
    header = "subject, variant, gesture, frame, " + ", ".join(f"ch{i}" for i in range(1, 65))
    rows, channels = [header], []
    captures = [(1, "normal", 1, 20), (1, "normal", 1, 15), (1, "gentle", 14, 10),
                (2, "rough", 5, 12)]
    for subject, variant, gesture, frames in captures:
        for f in range(1, frames + 1):
            ch = rng.integers(0, 1024, 64)
            channels.append(ch)
            rows.append(f"{subject}, {variant}, {gesture}, {f}, " + ", ".join(map(str, ch)))
    rows.insert(7, "1, normal, 1, 99, 5, 6")                            # short row
    rows.insert(12, "1, normal, 1, 99, " + ", ".join(["x"] * 64))       # unparsable
    path = folder / "CoST.csv"
    path.write_text("\n".join(rows) + "\n")
    return path, np.array(channels), captures


def haart_csvs(folder):
    rng = np.random.default_rng(3)
    ch_names = ",".join(f"ch{i}" for i in range(1, 65))
    train = ["Subject,Cover,Gesture," + ch_names]
    for subject, gesture, frames in [(1, "stroke", 864), (1, "notouch", 432), (2, "Constant", 500)]:
        for _ in range(frames):
            train.append(f"{subject},none,{gesture},"
                         + ",".join(map(str, rng.integers(0, 1024, 64))))
    test = ["Subject,Cover,Gesture,Sequence," + ch_names]
    for seq, (gesture, frames) in enumerate([(3, 432), (7, 432)]):   # pat, tickle by number
        for _ in range(frames):
            test.append(f"9,fur,{gesture},{seq}," + ",".join(map(str, rng.integers(0, 1024, 64))))
    a, b = folder / "training.csv", folder / "testWITHLABELS.csv"
    a.write_text("\n".join(train) + "\n")
    b.write_text("\n".join(test) + "\n")
    return a, b


def mixed_session(path):
    """A session with ok, redone and discarded trials, as the collection runner leaves."""
    rng = np.random.default_rng(4)
    raw = rng.integers(30000, 30100, size=(300, 180)).astype(np.uint16)
    raw[50:250, 20:60] -= 2500
    meta = {"participant": "P09", "condition": "FLAT", "gestures": ["Poke", "Twist", "Tickle"],
            "protocol": "shear9", "source": "collect"}
    with SessionWriter(path, SHEARSENSE_6X6, {"plugin": "test"}, meta) as w:
        w.add_baseline(raw[:30].mean(axis=0), 0)
        t = 1.7e9 + np.arange(300) / 43.0
        w.append_frames(raw, t, t)
        for i, (g, k, s, status) in enumerate([("Poke", "p", 50, "ok"), ("Twist", "t", 140, "ok"),
                                               ("Tickle", "i", 200, "ok"),
                                               ("Poke", "p", 250, "ok")]):
            w.add_trial({"index": i, "block": 0, "gesture": g, "key": k, "start_sample": s,
                         "end_sample": s + 43, "start_time": t[s], "end_time": t[s] + 1.0,
                         "status": status, "reason": None, "flags": []})
        w.update_trial(2, status="redone")
        w.update_trial(3, status="discarded", reason="sneezed")
    return path, raw


def run_cli(capsys, *argv):
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def assert_one_line_error(rc, err, *words, after_progress=False):
    """Exactly one line (besides a progress bar drawn before the problem was found)."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if after_progress:
        lines = [ln for ln in lines if "] " not in ln.split("error:")[0]]
    assert rc == 1 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("tactile-studio: error:")
    for w in words:
        assert w in lines[0]


# ---- ShearSense ------------------------------------------------------------------------
def test_shearsense_import_makes_a_session_with_trials_and_malformed_counts(tmp_path, capsys):
    src = shearsense_csv(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    rc, stdout, _ = run_cli(capsys, "import", "shearsense", str(src), "--out", str(out))
    assert rc == 0 and "P04_lab_PILLOW.h5" in stdout
    data = read_shearsense_csv(src)
    shear9 = load_protocol("shear9")
    with SessionFile(out / "P04_lab_PILLOW.h5") as s:
        assert s.layout.name == "shearsense-6x6" and s.n_frames == data.n_frames
        np.testing.assert_array_equal(s.raw(), data.raw)
        np.testing.assert_array_equal(s.column("device_time"), data.times)
        np.testing.assert_array_equal(s.column("host_time"), data.times)
        np.testing.assert_array_equal(s.baseline(0), data.baseline)
        m = s.metadata
        assert (m["participant"], m["condition"], m["source"]) == ("P04", "PILLOW",
                                                                  "import:shearsense")
        assert m["device"]["plugin"] == "import" and m["malformed_rows"] == 2
        assert m["gestures"][:9] == shear9.gesture_names and m["gestures"][9:] == ["z"]
        summary = s.summary()
        assert summary["malformed_by_kind"] == {"short_row": 1, "merged_number": 1}
        trials = s.trials
    assert [t.gesture for t in trials] == [shear9.gesture_by_key("r").name,
                                             shear9.gesture_by_key("p").name, "z"]
    assert [t.key for t in trials] == ["r", "p", "z"]
    assert [t.block for t in trials] == [0, 1, 2] and [t.index for t in trials] == [0, 1, 2]
    for t in trials:
        run = data.labels[t.start_sample:t.end_sample]
        assert len(run) == 86 and (run == ord(t.key)).all() and t.status == "ok"
        assert data.labels[t.start_sample - 1] == 0 and data.labels[t.end_sample] == 0
        assert t.start_time == data.times[t.start_sample]


def test_info_on_a_folder_has_a_row_per_imported_file_with_what_to_check(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    assert run_cli(capsys, "import", "shearsense", str(shearsense_csv(tmp_path)),
                   "--out", str(out))[0] == 0
    (out / "broken.h5").write_bytes(b"not a session")
    rc, stdout, err = run_cli(capsys, "info", str(out))
    assert rc == 1 and "Traceback" not in err  # the unreadable file is named, the rest shown
    rows = {line.split()[0]: line for line in stdout.splitlines()[1:] if line.strip()}
    cells = rows["P04_lab_PILLOW.h5"].split()
    assert cells[1:3] == ["P04", "PILLOW"] and cells[-3:] == ["3/3", "2", "z"]
    assert "unreadable:" in rows["broken.h5"] and "broken.h5: not an HDF5 file" in stdout
    assert "2 session file(s)" in stdout and "1 unreadable" in stdout
    (out / "broken.h5").unlink()
    rc, stdout, _ = run_cli(capsys, "info", str(out / "P04_lab_PILLOW.h5"), str(out), "--json")
    listed = json.loads(stdout)
    assert rc == 0 and len(listed) == 1 and listed[0]["unmapped_keys"] == ["z"]
    assert listed[0]["malformed"] == 2


def test_import_export_import_round_trips_frames_labels_and_trials(tmp_path, capsys):
    src = shearsense_csv(tmp_path)
    for d in ("a", "b", "c", "d"):
        (tmp_path / d).mkdir()
    assert main(["import", "shearsense", str(src), "--out", str(tmp_path / "a")]) == 0
    assert main(["export", str(tmp_path / "a" / "P04_lab_PILLOW.h5"), "--format",
                 "shearsense-csv", "--out", str(tmp_path / "b")]) == 0
    exported = tmp_path / "b" / "P04_lab_PILLOW.csv"
    assert main(["import", "shearsense", str(exported), "--out", str(tmp_path / "c")]) == 0
    with SessionFile(tmp_path / "a" / "P04_lab_PILLOW.h5") as a, \
            SessionFile(tmp_path / "c" / "P04_lab_PILLOW.h5") as c:
        np.testing.assert_array_equal(a.raw(), c.raw())
        np.testing.assert_array_equal(a.column("device_time"), c.column("device_time"))
        np.testing.assert_array_equal(a.baseline(0), c.baseline(0))
        assert a.trials == c.trials
        assert c.metadata["participant"] == "P04" and c.metadata["condition"] == "PILLOW"
    np.testing.assert_array_equal(read_shearsense_csv(src).labels,
                                  read_shearsense_csv(exported).labels)
    assert main(["export", str(tmp_path / "c" / "P04_lab_PILLOW.h5"), "--format",
                 "shearsense-csv", "--out", str(tmp_path / "d")]) == 0
    assert (tmp_path / "d" / "P04_lab_PILLOW.csv").read_bytes() == exported.read_bytes()
    capsys.readouterr()


def test_cancel_keeps_finished_sessions_and_removes_the_half_written_one(tmp_path, monkeypatch):
    files = [shearsense_csv(tmp_path, f"P0{i}_x_FLAT.csv", seed=i) for i in (1, 2, 3)]
    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.setattr(_common, "WRITE_CHUNK", 50)    # several cancel checks per write
    token = CancelToken()

    def progress(fraction, message=""):
        if "P02_x_FLAT.h5" in message and "100 of" in message:
            token.cancel()                              # in the middle of the 2nd write

    with pytest.raises(Cancelled):
        import_shearsense(files, out, progress, token)
    assert sorted(p.name for p in out.iterdir()) == ["P01_x_FLAT.h5"]
    with SessionFile(out / "P01_x_FLAT.h5") as s:
        assert s.closed_cleanly and len(s.trials) == 3


def test_ctrl_c_during_cli_import_exits_130_and_keeps_finished_sessions(tmp_path, capsys,
                                                                        monkeypatch):
    import tactile_studio.cli.import_export as cli_mod

    files = [shearsense_csv(tmp_path, f"P0{i}_x_FLAT.csv", seed=i) for i in (1, 2)]
    out = tmp_path / "out"
    out.mkdir()

    class CtrlCOnSecondFile:
        def __init__(self, label):
            self.sent = False

        def close(self):
            pass

        def __call__(self, fraction, message=""):
            if "P02" in message and not self.sent:
                self.sent = True
                os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(cli_mod, "TerminalProgress", CtrlCOnSecondFile)
    rc, stdout, err = run_cli(capsys, "import", "shearsense", *map(str, files), "--out", str(out))
    assert rc == 130 and "cancelled" in err and "Traceback" not in err
    assert "P01_x_FLAT.h5" in stdout
    assert [p.name for p in out.iterdir()] == ["P01_x_FLAT.h5"]


# ---- CoST and HAART --------------------------------------------------------------------
def test_cost_import_one_session_per_subject_one_trial_per_capture(tmp_path, capsys):
    src, channels, captures = cost_csv(tmp_path)
    rc, _, _ = run_cli(capsys, "import", "cost", str(src), "--out", str(tmp_path))
    assert rc == 0
    with SessionFile(tmp_path / "cost_P01.h5") as s:
        assert s.layout.name == "cost-8x8" and s.n_frames == 45
        assert s.summary()["rate_hz"] == pytest.approx(135.0)
        np.testing.assert_array_equal(s.raw(), channels[:45].astype(np.float32))
        assert [(t.gesture, t.extra["variant"], t.block, t.end_sample - t.start_sample)
                for t in s.trials] == [("grab", "normal", 0, 20), ("grab", "normal", 1, 15),
                                       ("tickle", "gentle", 0, 10)]
        assert s.metadata["participant"] == "P01" and s.metadata["source"] == "import:cost"
        assert s.metadata["gestures"] == COST_NAMES
        assert s.summary()["malformed_by_kind"] == {"short_row": 1, "unparsable": 1}
    with SessionFile(tmp_path / "cost_P02.h5") as s:
        assert [t.gesture for t in s.trials] == ["pinch"] and s.n_frames == 12


def test_haart_train_and_test_files_map_subjects_gestures_and_captures(tmp_path, capsys):
    train, test = haart_csvs(tmp_path)
    rc, _, _ = run_cli(capsys, "import", "haart", str(train), str(test), "--out", str(tmp_path))
    assert rc == 0
    names = load_protocol("haart7").gesture_names
    with SessionFile(tmp_path / "haart_training_P01.h5") as s:
        assert s.layout.name == "haart-8x8" and s.n_frames == 1296
        assert [(t.gesture, t.end_sample - t.start_sample, t.block) for t in s.trials] \
            == [("stroke", 432, 0), ("stroke", 432, 1), (names[1], 432, 0)]
        assert s.metadata["participant"] == "P01" and s.metadata["covers"] == ["none"]
        assert s.summary()["rate_hz"] == pytest.approx(54.0)
    with SessionFile(tmp_path / "haart_training_P02.h5") as s:
        assert [(t.gesture, list(t.flags)) for t in s.trials] == [
            ("constant", []), ("constant", ["short_capture"])]
    with SessionFile(tmp_path / "haart_testWITHLABELS_P09.h5") as s:
        assert [t.gesture for t in s.trials] == ["pat", "tickle"]
        assert all(t.gesture in names for t in s.trials)


def test_haart_without_header_reads_columns_by_position(tmp_path):
    from tactile_studio.storage.exchange.importers import import_haart

    rows = [",".join(["3", "1", "rub", "0"] + ["5"] * 64) for _ in range(432)]
    path = tmp_path / "test.csv"
    path.write_text("\n".join(rows))
    (out,) = import_haart(path, tmp_path)
    with SessionFile(out) as s:
        assert s.metadata["participant"] == "P03" and [t.gesture for t in s.trials] == ["rub"]


# ---- exporters ---------------------------------------------------------------------------
def test_npz_export_has_paper_shape_and_only_ok_trials_by_default(tmp_path):
    session, raw = mixed_session(tmp_path / "P09_s.h5")
    out = tmp_path / "npz"
    out.mkdir()
    files = export_npz(session, out)
    assert len(files) == 2
    with SessionFile(session) as s:
        base = s.baseline(0)
    d = np.load(files[1])
    assert d["x"].shape == (3, 43, 11, 11) and d["x"].dtype == np.float32
    expected = decode(SHEARSENSE_6X6, raw[140:183], base, virtual=True).stack()
    np.testing.assert_array_equal(d["x"], expected)
    assert (str(d["gesture"]), int(d["label"]), str(d["participant"]), int(d["index"])) == \
        ("Twist", 1, "P09", 1)
    assert list(d["gestures"]) == ["Poke", "Twist", "Tickle"]
    everything = export_npz(session, tmp_path / "npz", all_trials=True, force=True)
    assert len(everything) == 4
    assert str(np.load(everything[3])["status"]) == "discarded"


def test_npz_of_a_pressure_grid_keeps_the_dataset_values(tmp_path):
    src, channels, _ = cost_csv(tmp_path)
    from tactile_studio.storage.exchange.importers import import_cost
    sessions = import_cost(src, tmp_path)
    files = export_session(sessions[0], "npz", tmp_path)
    x = np.load(files[2])["x"]
    assert x.shape == (3, 10, 8, 8) and not x[1:].any()
    np.testing.assert_array_equal(x[0], channels[35:45].reshape(10, 8, 8).astype(np.float32))


def test_csv_trials_has_one_row_per_trial_with_metadata_and_features(tmp_path, capsys):
    session, _ = mixed_session(tmp_path / "P09_s.h5")
    rc, _, _ = run_cli(capsys, "export", str(session), "--format", "csv-trials",
                       "--all-trials", "--out", str(tmp_path))
    assert rc == 0
    with open(tmp_path / "P09_s_trials.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["ok", "ok", "redone", "discarded"]
    assert [r["gesture"] for r in rows] == ["Poke", "Twist", "Tickle", "Poke"]
    assert rows[3]["reason"] == "sneezed" and rows[0]["participant"] == "P09"
    assert all(int(r["n_frames"]) == 43 for r in rows)
    touched = float(rows[1]["mean_normal"])          # pressed between rows 50 and 250
    assert touched > 0 and float(rows[1]["contact_area"]) > 0
    assert rows[0]["movement"] in {"static", "transversal", "convergent", "divergent"}


def test_cancelled_npz_export_keeps_finished_files_only(tmp_path):
    session, _ = mixed_session(tmp_path / "P09_s.h5")
    out = tmp_path / "npz"
    out.mkdir()
    token = CancelToken()
    seen = []

    def progress(fraction, message=""):
        seen.append(message)
        if len(seen) == 3:
            token.cancel()

    with pytest.raises(Cancelled):
        export_npz(session, out, all_trials=True, progress=progress, cancel=token)
    names = sorted(p.name for p in out.iterdir())
    assert len(names) == 3 and all(n.endswith(".npz") for n in names)


# ---- one-line errors ---------------------------------------------------------------------
def test_bad_inputs_give_one_line_errors(tmp_path, capsys):
    notcsv = tmp_path / "notes.csv"
    notcsv.write_text("hello,world\n1,2\n")
    assert_one_line_error(*run_cli(capsys, "import", "shearsense", str(tmp_path / "nope.csv"),
                                   "--out", str(tmp_path))[::2], "nope.csv", "no such file")
    assert_one_line_error(*run_cli(capsys, "import", "shearsense", str(notcsv),
                                   "--out", str(tmp_path))[::2], "notes.csv", "not a ShearSense")
    assert_one_line_error(*run_cli(capsys, "import", "cost", str(notcsv),
                                   "--out", str(tmp_path))[::2], "notes.csv", "CoST")
    wide = tmp_path / "wide.csv"
    wide.write_text(",".join(["1"] * 50) + "\n")
    assert_one_line_error(*run_cli(capsys, "import", "haart", str(wide),
                                   "--out", str(tmp_path))[::2], "wide.csv", "50 columns")
    assert_one_line_error(*run_cli(capsys, "export", str(tmp_path / "none.h5"), "--format", "npz",
                                   "--out", str(tmp_path))[::2], "none.h5")
    src, _, _ = cost_csv(tmp_path)
    assert main(["import", "cost", str(src), "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    assert_one_line_error(*run_cli(capsys, "export", str(tmp_path / "cost_P01.h5"), "--format",
                                   "shearsense-csv", "--out", str(tmp_path))[::2], "cost-8x8")
    assert_one_line_error(*run_cli(capsys, "import", "cost", str(src),
                                   "--out", str(tmp_path))[::2], "already exists",
                          after_progress=True)
    assert main(["import", "cost", str(src), "--out", str(tmp_path / "new" / "dir")]) == 0
    assert len(list((tmp_path / "new" / "dir").glob("*.h5"))) == 2  # the folder was made
    capsys.readouterr()
    assert_one_line_error(*run_cli(capsys, "import", "cost", str(src),
                                   "--out", str(notcsv / "sub"))[::2],
                          f"{notcsv / 'sub'}: cannot write (Not a directory)")  # the house's line
    assert main(["import", "cost", str(src), "--out", str(tmp_path), "--force"]) == 0


def test_a_virtual_participants_session_exported_as_shearsense_csv_imports_with_its_names(
        tmp_path, capsys):
    """The learn fixtures press each gesture's protocol key, as a participant does, so an
    exported fixture session names its gestures again on import (default map: shear9's;
    cost14's keys with ``--gestures`` built from cost14)."""
    from learn_fixtures import write_participant
    shear9 = [g.name for g in load_protocol("shear9").gestures]
    cost14 = load_protocol("cost14").gestures
    for gestures, extra in ((shear9, []), ([g.name for g in cost14], [
            "--gestures", ",".join(f"{g.key}={g.name}" for g in cost14)])):
        folder = tmp_path / gestures[0]
        (folder / "csv").mkdir(parents=True)
        (folder / "back").mkdir()
        h5 = write_participant(folder / "P01_lab_FLAT.h5", "P01", 1, gestures, blocks=1,
                               trial_s=0.5, gap_s=0.2)
        assert main(["export", str(h5), "--format", "shearsense-csv",
                     "--out", str(folder / "csv")]) == 0
        assert main(["import", "shearsense", str(folder / "csv" / "P01_lab_FLAT.csv"),
                     "--out", str(folder / "back"), *extra]) == 0
        with SessionFile(h5) as made, SessionFile(folder / "back" / "P01_lab_FLAT.h5") as back:
            assert [t.gesture for t in back.trials] == [t.gesture for t in made.trials]
            assert sorted(t.gesture for t in back.trials) == sorted(gestures)
            assert back.metadata.get("unmapped_keys") in (None, [])
    capsys.readouterr()


def test_shearsense_csv_with_all_trials_says_the_statuses_it_cannot_keep(tmp_path, capsys):
    """The old CSV labels rows by key and has no status: ``--all-trials`` wrote the redone
    and the discarded trial like ok ones, and importing the CSV back made them ok, with
    nothing said. The export now says which statuses the file does not keep."""
    session, _ = mixed_session(tmp_path / "P09_s_FLAT.h5")
    rc, out, _ = run_cli(capsys, "export", str(session), "--format", "shearsense-csv",
                         "--all-trials", "--out", str(tmp_path))
    assert rc == 0
    assert ("P09_s_FLAT.h5: 2 of 4 trials exported are not ok (1 discarded, 1 redone); the "
            "ShearSense CSV has no status, so they read back as ok") in out
    rc, out, _ = run_cli(capsys, "export", str(session), "--format", "shearsense-csv",
                         "--out", str(tmp_path / "ok"), "--force")
    assert rc == 0 and "read back as ok" not in out  # ok trials only: nothing to say
