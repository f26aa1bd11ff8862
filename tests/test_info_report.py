"""What ``info`` and the exports report: 1-based blocks (practice = block 0) everywhere,
gestures in the protocol's order, a stable ``info --json`` shape, one measured rate."""

from __future__ import annotations

import csv
import json

import numpy as np

from tactile_studio.cli import main
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.storage.exchange.shearsense import write_shearsense_csv
from tactile_studio.storage.format.session_file import SessionFile, user_block
from tactile_studio.storage.format.session_writer import SessionWriter

# protocol order, deliberately not alphabetical
GESTURES = ["Poke", "Wide Pinch", "Heavy Pat"]


def _collected(path, with_trials: bool = True):
    """A collection-like session: a practice trial (journal block -1), then blocks 0, 1."""
    rng = np.random.default_rng(3)
    raw = rng.integers(30000, 30100, size=(400, 180)).astype(np.uint16)
    meta = {"participant": "P05", "gestures": GESTURES, "protocol": "shear9",
            "source": "collect"}
    plan = [(-1, "Heavy Pat", "h"), (0, "Heavy Pat", "h"), (0, "Wide Pinch", "w"),
            (0, "Poke", "p"), (1, "Poke", "p")]
    with SessionWriter(path, SHEARSENSE_6X6, {"plugin": "test"}, meta) as w:
        w.add_baseline(raw[:30].mean(axis=0), 0)
        t = 1.7e9 + np.arange(400) / 43.0
        w.append_frames(raw, t, t)
        w.add_event("block_start", frame=70, block=0)  # after the practice trial
        if with_trials:
            for i, (b, g, k) in enumerate(plan):
                s = 20 + 70 * i
                w.add_trial({"index": i, "block": b, "gesture": g, "key": k, "start_sample": s,
                             "end_sample": s + 43, "start_time": t[s], "end_time": t[s] + 1.0,
                             "status": "ok", "reason": None, "flags": []})
    return path


def _info(capsys, *args) -> str:
    assert main(["info", *map(str, args)]) == 0
    return capsys.readouterr().out


def test_user_block_numbering():
    assert [user_block(b) for b in (-1, 0, 1, 7, None, "x")] == [0, 1, 2, 8, 0, 0]


def test_blocks_are_one_based_in_info_json_npz_and_csv(tmp_path, capsys):
    path = _collected(tmp_path / "s.h5")
    js = json.loads(_info(capsys, path, "--json"))
    assert [t["block"] for t in js["trials"]] == [0, 1, 1, 1, 2]
    assert [e["block"] for e in js["events"] if e["kind"] == "block_start"] == [1]
    with SessionFile(path) as s:  # the journal keeps the runner's numbering
        assert [t.block for t in s.trials] == [-1, 0, 0, 0, 1]
    text = _info(capsys, path)
    assert "blocks: 2 (1..2)" in text and "practice trials: 1" in text

    out = tmp_path / "out"
    out.mkdir()
    assert main(["export", str(path), "--format", "npz", "--out", str(out)]) == 0
    blocks = {}
    for f in sorted(out.glob("*.npz")):
        with np.load(f) as z:
            blocks[int(z["index"])] = int(z["block"])
    assert blocks == {0: 0, 1: 1, 2: 1, 3: 1, 4: 2}
    assert main(["export", str(path), "--format", "csv-trials", "--out", str(out)]) == 0
    with open(out / "s_trials.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["block"]) for r in rows] == [0, 1, 1, 1, 2]
    capsys.readouterr()


def test_info_lists_gestures_in_protocol_order(tmp_path, capsys):
    text = _info(capsys, _collected(tmp_path / "s.h5"))
    rows = [ln for ln in text.splitlines() if ln.startswith(tuple(GESTURES))]
    assert [next(g for g in GESTURES if r.startswith(g)) for r in rows] == GESTURES


def test_info_json_has_the_same_shape_with_and_without_trials(tmp_path, capsys):
    full = json.loads(_info(capsys, _collected(tmp_path / "a.h5"), "--json"))
    empty = json.loads(_info(capsys, _collected(tmp_path / "b.h5", with_trials=False), "--json"))
    assert set(full) == set(empty)
    for key in ("trials", "gestures", "unmapped_keys", "events"):
        assert isinstance(full[key], list) and isinstance(empty[key], list), key
    assert empty["trials"] == [] and len(full["trials"]) == 5
    assert full["participant"] == empty["participant"] == "P05"
    assert full["gestures"] == GESTURES
    assert full["session_id"] and full["session_id"] != empty["session_id"]


def test_imported_rate_is_one_measured_figure(tmp_path, capsys):
    rng = np.random.default_rng(5)
    raw = rng.integers(20000, 30000, size=(500, 180)).astype(np.uint16)
    times = 1.7e9 + np.arange(500) / 44.0
    times[250:] += 3.0  # a pause: mean and median frame rates now differ
    labels = np.zeros(500, dtype=np.int64)
    labels[100:180] = ord("p")
    src = write_shearsense_csv(tmp_path / "P01_FLAT.csv", raw, times, labels, raw[:5].mean(0))
    assert main(["import", "shearsense", str(src), "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    js = json.loads(_info(capsys, tmp_path / "P01_FLAT.h5", "--json"))
    assert js["rate_hz"] == js["metadata"]["device"]["rate_hz"]
    # measured without the pause (a gap the import found): the file's 44 Hz
    spanned = (times[249] - times[0]) + (times[-1] - times[250])
    assert abs(js["rate_hz"] - 498 / spanned) < 1e-3 and abs(js["rate_hz"] - 44.0) < 1e-3
    text = _info(capsys, tmp_path / "P01_FLAT.h5")
    assert f"({js['rate_hz']:.2f} Hz)" in text


def test_info_on_a_folder_adds_up_the_study_and_names_who_lacks_a_gesture(tmp_path, capsys):
    from learn_fixtures import write_participant

    from tactile_studio.storage.format.study_summary import study_counts
    gestures = ["Poke", "Twist", "Tickle"]
    for i, (person, surface, done) in enumerate([
            ("P01", "FLAT", gestures), ("P01", "PILLOW", gestures),
            ("P02", "FLAT", gestures), ("P02", "PILLOW", ["Poke", "Tickle"]),
            ("P03", "FLAT", ["Poke"])]):
        write_participant(tmp_path / f"{person}_{surface}.h5", person, i, done, blocks=1,
                          trial_s=0.3, gap_s=0.1, condition=surface)
    assert main(["info", str(tmp_path)]) == 0
    assert capsys.readouterr().out.splitlines()[-4:] == [
        "participants: 3 (P01, P02, P03)",
        "conditions: FLAT 3 session(s), PILLOW 2 session(s)",
        "ok trials: 12 of 3 gestures (3-5; fewer than 5: Tickle 4, Twist 3)",
        "P03 has no ok trial of Tickle, Twist"]  # P02 did Twist on the table: no gap
    counts = study_counts([("P01", "", {"Poke": 2, "Twist": 1}), ("P02", "", {"Poke": 1}),
                           ("P03", "", {"Poke": 1, "Twist": 0}), ("P04", "", {})])
    assert counts.missing == {"P02": ["Twist"], "P03": ["Twist"], "P04": ["Poke", "Twist"]}
    assert counts.conditions == {} and counts.ok_trials == 5
    assert counts.missing_text(people=2) == "P02 has no Twist; P03 has no Twist; 1 more"
    assert study_counts([]).lines() == []


def test_info_on_recordings_without_participants_or_trials_adds_nothing_up(tmp_path, capsys):
    """``info a.h5 b.h5`` on two plain recordings (no participant, no trials) ended in a
    traceback (IndexError in the study lines); it lists them and says no study."""
    for name in ("a.h5", "b.h5"):
        assert main(["record", "--seconds", "0.3", "--set", "speed=10",
                     "--out", str(tmp_path / name)]) == 0
    capsys.readouterr()
    assert main(["info", str(tmp_path / "a.h5"), str(tmp_path / "b.h5")]) == 0
    out = capsys.readouterr().out
    assert "2 session file(s)" in out and "participants:" not in out


def test_info_on_a_run_folder_says_what_it_is_and_where_to_go(tmp_path, capsys):
    """A researcher's first guess on a training run's folder: one line saying it is a run,
    not a bare 'no session files', and which commands read it."""
    run = tmp_path / "runs" / "cnn1d-1"
    (run / "folds").mkdir(parents=True)
    (run / "config.json").write_text("{}")
    assert main(["info", str(run)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("tactile-studio: error: ")
    assert f"{run}: a run folder (trained models), not sessions" in err
    assert f"tactile-studio evaluate {run}" in err


def test_info_says_a_collection_is_unfinished_and_a_resume_is_a_gap(tmp_path, capsys):
    """Issue 47 item 11: `info` on a half-done collection said "closed: cleanly" and
    nothing of the blocks left, and after a resume "gaps: 1" was not explained."""
    from collect_fixtures import do_trial, drive, make_rig, mini_protocol, start

    rig = make_rig(tmp_path, mini_protocol(n_gestures=2, blocks=2))
    try:
        start(rig)
        for g in rig.runner.orders[0]:
            do_trial(rig, g)
    finally:
        rig.close()  # the experimenter closes the console after block 1
    path = rig.session.path
    out = _info(capsys, path)
    assert ("collection: unfinished, 1 of 2 blocks done (2 of 4 trials); resume with "
            f"tactile-studio collect --resume {path}") in out
    assert "gaps:       0   reconnects 0" in out
    assert json.loads(_info(capsys, path, "--json"))["collection"] == {
        "trials_done": 2, "trials_total": 4, "blocks_done": 1, "blocks_total": 2,
        "finished": False}
    rig = make_rig(tmp_path, None, resume=path)
    try:
        start(rig)
        for g in rig.runner.orders[1]:
            do_trial(rig, g)
        drive(rig, lambda: rig.runner.state == "finished")
    finally:
        rig.close()
    out = _info(capsys, path)
    assert "gaps:       1 (1 resume: the recording continued later)   reconnects 0" in out
    assert "collection: finished (2 of 2 blocks, 4 of 4 trials)" in out
    backup = next(tmp_path.glob("*.bak-1.h5"))  # the backup's session goes on elsewhere
    assert "collection:" not in _info(capsys, backup)
    assert json.loads(_info(capsys, _collected(tmp_path / "c.h5"), "--json"))[
        "collection"] is None  # no stored block orders: not a collection the runner made
