"""Damaged run folders (issue 33, item 10): a fold that lost its model, a fold holding
another run's ONNX model, a metrics.json of the wrong shape. evaluate, export-model,
compare, live inference's model loader and the research workspace each end with one line
naming the fold or file (exit 1), never a silent score of the remaining folds; the
workspace lists the run as damaged.

Two tiny runs on one small data set: rf over 3 lopo folds (the one damaged) and knn (the
source of a foreign ONNX file).
"""

from __future__ import annotations

import json
import shutil

import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main
from tactile_studio.errors import UserError
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.results.workspace_index import scan_runs

GESTURES3 = ("Poke", "Heavy Pat", "Back & Forth Rub")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("damage")
    make_dataset_folder(root / "data", participants=3, blocks=2, gestures=GESTURES3)
    for model in ("rf", "knn"):
        code = main(["train", "--data", str(root / "data"), "--model", model, "--preset",
                     "tiny", "--eval", "lopo", "--out", str(root / "runs" / model),
                     "--cache-dir", str(root / "cache")])
        assert code == 0
    return root


def _damaged(runs, tmp_path, how: str):
    run = tmp_path / "runs" / "damaged"
    shutil.copytree(runs / "runs" / "rf", run)
    fold = run / "folds" / "r0-P02"
    if how == "missing":
        (fold / "model.onnx").unlink()
    elif how == "foreign":  # in a run written before folds kept their model's fingerprint
        shutil.copy(runs / "runs" / "knn" / "folds" / "r0-P02" / "model.onnx",
                    fold / "model.onnx")
        record = json.loads((fold / "fold.json").read_text())
        del record["model_sha256"]
        (fold / "fold.json").write_text(json.dumps(record))
    elif how == "other fold":  # the same kind of model, trained with P02 among its people
        shutil.copy(run / "folds" / "r0-P01" / "model.onnx", fold / "model.onnx")
    elif how == "fold gone":
        shutil.rmtree(fold)
    else:
        (run / "metrics.json").write_text(how)
    return run


def _one_line(capsys, *argv) -> str:
    code = main([str(a) for a in argv])
    _, err = capsys.readouterr()
    assert code == 1, err
    lines = err.strip().splitlines()
    assert lines[-1].startswith("tactile-studio: error:") and "Traceback" not in err, err
    assert sum("error" in ln for ln in lines) == 1, err
    return lines[-1]


@pytest.mark.parametrize("how, names", [
    ("missing", ("r0-P02", "model file is missing")),
    ("fold gone", ("r0-P02", "missing")),
    ("[]", ("metrics.json", "damaged")),
    ('{"folds": 3}', ("metrics.json", "damaged")),
])
def test_damaged_run_is_refused_everywhere(runs, tmp_path, capsys, how, names):
    run = _damaged(runs, tmp_path, how)
    data = ("--data", runs / "data", "--cache-dir", runs / "cache")
    for argv in (("evaluate", run, *data), ("export-model", run, "--format", "onnx", *data),
                 ("compare", run, runs / "runs" / "knn"),
                 ("compare", runs / "runs" / "knn", run)):
        line = _one_line(capsys, *argv)
        assert all(n in line for n in names), (argv, line)
    with pytest.raises(UserError, match="r0-P02" if "P02" in names[0] else "metrics.json"):
        WindowModel(run)  # live inference and the player load through it
    # the workspace lists it, as damaged, beside the sound runs
    rows = {r.name: r for r in scan_runs(run.parent.parent)} | {
        r.name: r for r in scan_runs(runs / "runs")}
    assert "damaged" in rows["damaged"].error and names[0] in rows["damaged"].error
    assert str(run) not in rows["damaged"].error  # the row is the run: named from inside
    assert rows["damaged"].accuracy is None and rows["damaged"].model == "rf"
    assert not rows["rf"].error and not rows["knn"].error


def test_foreign_model_in_a_fold_is_named(runs, tmp_path, capsys):
    run = _damaged(runs, tmp_path, "foreign")
    data = ("--data", runs / "data", "--cache-dir", runs / "cache")
    for argv in (("evaluate", run, *data), ("export-model", run, "--format", "onnx", *data)):
        line = _one_line(capsys, *argv)
        assert "r0-P02" in line and "not this run's model" in line and "knn" in line, line
    with pytest.raises(UserError, match="r0-P02.*not this run's model"):
        WindowModel(run, participant="P02")  # the fold that did not see P02


def test_a_model_copied_from_another_fold_is_named(runs, tmp_path, capsys):
    """An rf of fold P01 (which trained on P02) copied into fold P02 passes every check
    of kind, classes and shape; the fold's fingerprint tells it apart."""
    run = _damaged(runs, tmp_path, "other fold")
    data = ("--data", runs / "data", "--cache-dir", runs / "cache")
    for argv in (("evaluate", run, *data), ("export-model", run, "--format", "onnx", *data),
                 ("compare", run, runs / "runs" / "knn")):
        line = _one_line(capsys, *argv)
        assert "r0-P02" in line and "not the one trained for it" in line, line
    with pytest.raises(UserError, match="r0-P02"):
        WindowModel(run, participant="P02")


def test_runs_view_shows_a_damaged_run(runs, tmp_path, qtbot):
    from tactile_studio.ui.research.runs_view import COLUMNS, RunsView

    run = _damaged(runs, tmp_path, "missing")
    shutil.copytree(runs / "runs" / "knn", run.parent / "knn")
    view = RunsView()
    qtbot.addWidget(view)
    view.set_root(str(run.parent))
    texts = {view.table.item(r, 0).text(): view.table.item(r, COLUMNS.index("problem")).text()
             for r in range(view.table.rowCount())}
    assert set(texts) == {"damaged", "knn"}
    assert texts["damaged"].startswith("damaged: folds/r0-P02: ")
    assert texts["knn"] == ""
