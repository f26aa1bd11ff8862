"""A run folder that cannot be written part way (a full disk, a file-size limit) ends
train in one line naming the file, keeps the finished folds and resumes.

The fault is real: a file-size limit (``RLIMIT_FSIZE``) makes writes past it fail with
EFBIG, as a full disk fails with ENOSPC, inside PIL, safetensors and skl2onnx's writes,
which name no file themselves. Real tiny torch training and rf.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import signal
import threading
import time

import pytest
from fault_helpers import file_size_limit
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main

GESTURES3 = ("Poke", "Heavy Pat", "Back & Forth Rub")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("faults")
    make_dataset_folder(root / "data", participants=3, blocks=2, gestures=GESTURES3)
    return root


def _train(capsys, data, out, model: str, *extra: str) -> tuple[int, str, str]:
    argv = ["train", "--data", data / "data", "--model", model, "--preset", "tiny",
            "--eval", "lopo", "--out", out, "--no-cache", "--threads", "1", *extra]
    code = main([str(a) for a in argv])
    stdout, err = capsys.readouterr()
    return code, stdout, err


def _error_line(err: str) -> str:
    assert "Traceback" not in err
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip()]
    assert lines[-1].startswith("tactile-studio: error: ")
    return lines[-1]


def test_a_plot_that_cannot_be_written_keeps_the_folds_and_resumes(data, capsys, tmp_path):
    out = tmp_path / "run"
    # the folds' files (~10 KB) and metrics.json fit, the training-curves PNG does not
    with file_size_limit(60_000):
        code, _, err = _train(capsys, data, out, "cnn1d", "--epochs", "2")
    line = _error_line(err)
    assert code == 3, err
    assert f"{out}{os.sep}" in line and ".png: cannot write (File too large)" in line
    assert "3 finished fold(s)" in line and "same --out" in line
    assert len(list((out / "folds").glob("*/fold.json"))) == 3
    before = {p: p.stat().st_mtime_ns for p in (out / "folds").glob("*/fold.json")}
    code, stdout, err = _train(capsys, data, out, "cnn1d", "--epochs", "2")
    assert code == 0, err
    assert {p: p.stat().st_mtime_ns for p in before} == before  # resumed, not retrained
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["complete"] and len(metrics["per_fold"]) == 3
    assert f"{metrics['accuracy']:.3f}" in stdout
    assert max(p.stat().st_size for p in out.glob("*.png")) > 60_000


@pytest.mark.parametrize("model, limit, name", [("rf", 15_000, "model.onnx"),
                                                 ("cnn1d", 6_000, "model.safetensors")])
def test_a_fold_model_that_cannot_be_written_is_one_line(data, capsys, tmp_path, model,
                                                         limit, name):
    out = tmp_path / model
    # the first fold's model (rf's ONNX forest ~25 KB, the tiny network's ~8 KB) is the
    # first file past the limit
    with file_size_limit(limit):
        code, _, err = _train(capsys, data, out, model, "--epochs", "1")
    line = _error_line(err)
    assert code == 1, err
    assert line == (f"tactile-studio: error: {out / 'folds' / 'r0-P01' / name}: "
                    "cannot write (File too large)")
    assert not list((out / "folds").glob("*/fold.json"))


def test_more_shots_than_anyone_can_give_is_refused(data, capsys, tmp_path):
    """Two performances of each gesture per person: one can be given (one stays to test).
    K = 2 trained the K = 1 folds again and reported them as K = 2 (+0.0 points)."""
    out = tmp_path / "shots"
    code, _, err = _train(capsys, data, out, "rf", "--shots", "0,1,2")
    line = _error_line(err)
    assert code == 1, err
    assert "K = 2" in line and "at most 2 performances" in line and "up to 1" in line
    assert not out.exists()


def test_an_export_that_cannot_be_written_leaves_no_cut_model(data, capsys, tmp_path):
    out = tmp_path / "run"
    code, _, err = _train(capsys, data, out, "cnn1d", "--epochs", "1")
    assert code == 0, err
    with file_size_limit(4_000):  # the fold's ONNX model (~10 KB) does not fit
        code = main(["export-model", str(out), "--format", "onnx", "--threads", "1",
                     "--cache-dir", str(tmp_path / "cache")])
    line = _error_line(capsys.readouterr().err)
    assert code == 1
    assert line == (f"tactile-studio: error: {out / 'export' / 'r0-P01.onnx'}: cannot "
                    "write the ONNX model (File too large)")
    # a cut file would load as a model (or fail later, far from here): none is left
    assert not [p.name for p in (out / "export").iterdir()]


def test_runs_on_other_recordings_with_the_same_file_names_are_not_paired(data, capsys,
                                                                            tmp_path):
    """Another study's P01.h5..P03.h5 (other people, other gesture orders): trial P01.h5#0
    is another performance there, so no trial pairs with its namesake (compare had run
    McNemar on "54 matched test trials" pairing a Poke with a Heavy Pat)."""
    other = tmp_path / "other"
    make_dataset_folder(other / "data", participants=3, blocks=2, gestures=GESTURES3,
                        first_style=201)
    a, b = tmp_path / "a", tmp_path / "b"
    assert _train(capsys, data, a, "rf")[0] == 0
    assert _train(capsys, other, b, "rf")[0] == 0
    code = main(["compare", str(a), str(b)])
    out, err = capsys.readouterr()
    line = _error_line(err)
    assert code == 1 and "McNemar" not in out
    assert "not tested on the same recordings" in line and "trial 1 of P01.h5 is" in line
    # the same recordings in another folder still pair trial by trial
    moved = tmp_path / "moved"
    make_dataset_folder(moved / "data", participants=3, blocks=2, gestures=GESTURES3)
    c = tmp_path / "c"
    assert _train(capsys, moved, c, "knn")[0] == 0
    assert main(["compare", str(a), str(c)]) == 0
    assert "McNemar on 18 matched test trials" in capsys.readouterr().out


def test_resume_trains_again_a_fold_whose_model_was_replaced(data, capsys, tmp_path):
    """A fold whose model file is not the one trained for it (copied over from another
    fold) was taken as finished on resume: train said exit 0 and the accuracy, and every
    reader of the folder then refused it."""
    out = tmp_path / "run"
    assert _train(capsys, data, out, "rf")[0] == 0
    folds = out / "folds"
    (folds / "r0-P02" / "model.onnx").write_bytes((folds / "r0-P01" / "model.onnx").read_bytes())
    assert main(["evaluate", str(out)]) == 1
    assert "not the one trained for it" in _error_line(capsys.readouterr().err)
    before = {p.parent.name: p.stat().st_mtime_ns for p in folds.glob("*/fold.json")}
    code, _, err = _train(capsys, data, out, "rf")
    assert code == 0, err
    after = {p.parent.name: p.stat().st_mtime_ns for p in folds.glob("*/fold.json")}
    assert after["r0-P02"] != before["r0-P02"]  # trained again
    assert after["r0-P01"] == before["r0-P01"] and after["r0-P03"] == before["r0-P03"]
    code = main(["evaluate", str(out)])
    assert code == 0, capsys.readouterr().err


def test_a_sweep_whose_worker_is_killed_names_the_lost_tasks_and_keeps_the_rest(
        data, capsys, tmp_path):
    """kill -9 of a sweep's worker process (the OOM killer, a user) mid-run: one line naming
    the tasks that were running, the finished ones kept with their table, exit 3, and the
    same command resumes. It had ended in a BrokenProcessPool traceback."""
    out = tmp_path / "sweep"
    argv = ["sweep", "--data", str(data / "data"), "--models", "cnn1d", "rf", "--channels",
            "normal", "both", "--eval", "lopo", "--preset", "tiny", "--epochs", "2",
            "--jobs", "2", "--no-cache", "--out", str(out)]
    killed: list[int] = []

    def kill_a_worker() -> None:  # once the first task has finished, more are running
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not list((out / "tasks").glob("*.json")):
            time.sleep(0.05)
        workers = multiprocessing.active_children()
        if workers:
            killed.append(workers[0].pid)
            os.kill(workers[0].pid, signal.SIGKILL)

    killer = threading.Thread(target=kill_a_worker)
    killer.start()
    code = main(argv)
    killer.join()
    stdout, err = capsys.readouterr()
    assert killed
    line = _error_line(err)
    assert code == 3, err
    assert "worker process ended abruptly" in line and "same command" in line
    done = sorted(p.stem for p in (out / "tasks").glob("*.json"))
    assert f"{len(done)} of 12 tasks finished" in line
    lost = line.split("running: ")[1].split(";")[0].split(", ")
    assert lost and not set(lost) & set(done) and all("-r0-P0" in t for t in lost)
    results = json.loads((out / "results.json").read_text())
    assert results["complete"] is False
    # the same command trains only what was lost or never started
    assert main(argv) == 0
    assert len(list((out / "tasks").glob("*.json"))) == 12
    assert json.loads((out / "results.json").read_text())["complete"] is True


def test_evaluate_on_other_recordings_with_the_same_names_scores_them_as_new_data(
        data, capsys, tmp_path):
    """evaluate --data with another study's P01.h5..P03.h5: they are new people to every
    fold model (external mode), not the run's held-out trials re-scored (folds mode, as
    it had said, each fold model meeting only its namesake person)."""
    out = tmp_path / "run"
    assert _train(capsys, data, out, "rf")[0] == 0
    other = tmp_path / "other"
    make_dataset_folder(other, participants=3, blocks=2, gestures=GESTURES3, first_style=201)
    cache = ["--cache-dir", str(tmp_path / "cache")]
    code = main(["evaluate", str(out), "--data", str(other), *cache])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    assert "external mode" in stdout
    rescore = json.loads((out / "rescore.json").read_text())
    assert rescore["mode"] == "external" and rescore["n_trials"] == 3 * 18
    # each fold model was tested on the other study's people, not on the run's own held-out
    # person its fold is named after (issue 43, case 9: the rows said P01, P02, P03 alone)
    people = ["P01", "P02", "P03"]
    assert [f["test_participants"] for f in rescore["per_fold"]] == [people] * 3
    assert [f["n_test_trials"] for f in rescore["per_fold"]] == [18] * 3  # 3 people x 6
    rows = [ln.split() for ln in stdout.splitlines() if ln.split()[1:2] in (["P01"], ["P02"])]
    assert rows and all(r[2] == "P01,P02,P03" for r in rows), stdout
    # the run's own recordings are still its folds, re-scored
    assert main(["evaluate", str(out), *cache]) == 0
    assert "folds mode" in capsys.readouterr().out


def test_a_dataset_cache_that_cannot_be_written_leaves_no_cut_file(data, capsys, tmp_path):
    """The cache is optional (training goes on without it), but a cut temporary file of
    the size of the data had stayed in the cache folder at every run on a full disk."""
    cache = tmp_path / "cache"
    argv = ["train", "--data", str(data / "data"), "--model", "rf", "--preset", "tiny",
            "--eval", "lopo", "--out", str(tmp_path / "run"), "--cache-dir", str(cache)]
    with file_size_limit(100_000):  # the run's files fit; the decoded dataset does not
        code = main(argv)
    assert code == 0, capsys.readouterr().err
    assert not [p.name for p in (cache / "datasets").iterdir()]


def test_compare_says_when_a_run_has_test_trials_the_other_lacks(data, capsys, tmp_path):
    """A run stopped after one fold against a finished one: the accuracies are over the
    trials both have, not the finished run's own figure, and compare says so."""
    full, part = tmp_path / "full", tmp_path / "part"
    assert _train(capsys, data, full, "rf")[0] == 0
    assert _train(capsys, data, part, "knn")[0] == 0
    for fold in ("r0-P02", "r0-P03"):
        shutil.rmtree(part / "folds" / fold)
    (part / "metrics.json").unlink()
    assert main(["compare", str(full), str(part)]) == 0
    out = capsys.readouterr().out
    assert "accuracies over the 6 test trials both runs have (rf: 18, knn: 6)" in out


@pytest.mark.parametrize("content", ['{"trials": 3}', "[1, 2]", '{"trials": [1]}'])
def test_a_damaged_trial_table_is_one_line(data, capsys, tmp_path, content):
    out = tmp_path / "run"
    assert _train(capsys, data, out, "rf")[0] == 0
    (out / "trials.json").write_text(content)
    assert main(["compare", str(out), str(out)]) == 1  # the research window reads it too
    assert f"{out / 'trials.json'}: damaged" in _error_line(capsys.readouterr().err)
